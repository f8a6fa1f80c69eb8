//! The residual structure of a fit: which residual components correlate with the joint angles,
//! the tip position or the reach (Pearson, Bonferroni-corrected t tests).

use calib_core::stats::{pearson, t_two_sided_p};
use handclasp_cell::Session;
use nalgebra::Vector3;

use crate::report::CorrelationReport;

/// Pearson correlations of the residual components (b1 axes) and norms with each joint angle,
/// the tip position (b1) and each robot's reach (tip distance from its base origin); those
/// significant at 5% after a Bonferroni correction over all pairs tested.
pub fn correlations(session: &Session, residuals: &[Vector3<f64>]) -> Vec<CorrelationReport> {
    let n = residuals.len();
    let pts = &session.points;
    let mut targets: Vec<(String, Vec<f64>)> = Vec::new();
    for r in [1u8, 2] {
        let dof = pts
            .first()
            .map_or(0, |p| if r == 1 { p.q1.len() } else { p.q2.len() });
        for k in 0..dof {
            targets.push((
                format!("r{r}_q{}", k + 1),
                pts.iter()
                    .map(|p| if r == 1 { p.q1[k] } else { p.q2[k] })
                    .collect(),
            ));
        }
    }
    for (a, name) in ["x", "y", "z"].iter().enumerate() {
        targets.push((name.to_string(), pts.iter().map(|p| p.p_b1[a]).collect()));
    }
    targets.push((
        "reach1".into(),
        pts.iter().map(|p| p.p_b1.coords.norm()).collect(),
    ));
    targets.push((
        "reach2".into(),
        pts.iter().map(|p| p.p_b2.coords.norm()).collect(),
    ));
    let comps: Vec<(String, Vec<f64>)> = vec![
        ("x".into(), residuals.iter().map(|r| r.x).collect()),
        ("y".into(), residuals.iter().map(|r| r.y).collect()),
        ("z".into(), residuals.iter().map(|r| r.z).collect()),
        ("norm".into(), residuals.iter().map(|r| r.norm()).collect()),
    ];
    let tests = (targets.len() * comps.len()) as f64;
    let mut out = Vec::new();
    for (cn, cv) in &comps {
        for (tn, tv) in &targets {
            let r = pearson(cv, tv);
            let stat = r * ((n as f64 - 2.0) / (1.0 - r * r).max(1e-300)).sqrt();
            let p = t_two_sided_p(stat, n.saturating_sub(2));
            let p_adj = (p * tests).min(1.0);
            if p_adj < 0.05 {
                out.push(CorrelationReport {
                    residual: cn.clone(),
                    against: tn.clone(),
                    r,
                    p_adjusted: p_adj,
                });
            }
        }
    }
    out
}
