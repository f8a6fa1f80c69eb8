//! The noise level per observation kind ([`KINDS`]): the robust scale of the whitened residuals
//! of the fit with every family free, and the problem with every row's σ scaled by it.

use calib_core::whole_cell::{CellFitError, CellProblem, Noise3, ObservationKind};

use super::held_out::{fit_model, residuals_at};
use super::{CellDiagnoseOptions, Family};

/// Observation kinds in report order (each its own noise scale).
pub const KINDS: [&str; 5] = ["contact", "tracker", "plane", "coincident", "face_contact"];

/// Per kind ([`KINDS`] order), `max(1, 1.4826·median|w|)` of the whitened residuals of the fit
/// with every family free on `rows`.
pub(super) fn noise_scales(
    problem: &CellProblem,
    families: &[Family],
    rows: &[usize],
    options: &CellDiagnoseOptions,
    x0: nalgebra::Isometry3<f64>,
) -> Result<[f64; KINDS.len()], CellFitError> {
    let (sub, fit) = fit_model(problem, families, rows, None, options, x0)?;
    let scored = residuals_at(&sub, &fit.layout, &fit.estimate, &fit.active)?;
    let mut out = [1.0; KINDS.len()];
    for (k, kind) in KINDS.iter().enumerate() {
        let mut w: Vec<f64> = scored
            .iter()
            .filter(|r| r.kind == *kind)
            .flat_map(|r| r.whitened.iter().map(|v| v.abs()).collect::<Vec<_>>())
            .collect();
        if w.is_empty() {
            continue;
        }
        w.sort_by(f64::total_cmp);
        let median = if w.len() % 2 == 1 {
            w[w.len() / 2]
        } else {
            0.5 * (w[w.len() / 2 - 1] + w[w.len() / 2])
        };
        out[k] = (1.4826 * median).max(1.0);
    }
    Ok(out)
}

/// `problem` with every row's σ multiplied by its kind's scale ([`KINDS`] order).
pub(super) fn scaled_noise(problem: &CellProblem, scale: &[f64; KINDS.len()]) -> CellProblem {
    let mut p = problem.clone();
    for o in &mut p.observations {
        let k = KINDS.iter().position(|k| *k == o.kind.name()).unwrap_or(0);
        let s = scale[k];
        match &mut o.kind {
            ObservationKind::Contact { sigma_m, .. }
            | ObservationKind::FaceContact { sigma_m, .. }
            | ObservationKind::Plane { sigma_m, .. } => {
                *sigma_m *= s;
            }
            ObservationKind::Coincident { noise, .. } | ObservationKind::Tracker { noise, .. } => {
                *noise = match *noise {
                    Noise3::Isotropic { sigma_m } => Noise3::Isotropic {
                        sigma_m: sigma_m * s,
                    },
                    Noise3::Covariance { cov_m2 } => Noise3::Covariance {
                        cov_m2: cov_m2 * (s * s),
                    },
                    other => other,
                };
            }
            _ => {}
        }
    }
    p
}
