//! Bad-handclasp detection by leave-one-out residuals.

use crate::error::CalibError;
use crate::points::PointPairs;
use crate::registration::{fit, Method, MountPair};

/// A point is flagged when its leave-one-out residual exceeds this multiple of the residual scale of
/// the fit without it (an externally studentised residual) …
pub const OUTLIER_FACTOR: f64 = 5.0;
/// … and also exceeds this absolute floor, m (so that noise-free data flags nothing).
pub const OUTLIER_MIN_M: f64 = 1e-3;

/// Leave-one-out residuals of every point, and the points flagged as bad handclasps.
#[derive(Debug, Clone, PartialEq)]
pub struct OutlierReport {
    /// Source rows, one per point.
    pub rows: Vec<usize>,
    /// `‖p1ᵢ − X₋ᵢ·p2ᵢ‖` with `X₋ᵢ` fitted without point i, m.
    pub loo_residuals_m: Vec<f64>,
    /// Per point, the threshold used, m: `max(OUTLIER_FACTOR·s₋ᵢ, OUTLIER_MIN_M)` with
    /// `s₋ᵢ = √(3·RSS₋ᵢ/(3(n−1) − 6))` the per-point residual scale of the fit without point i.
    pub thresholds_m: Vec<f64>,
    /// Per point: flagged as a bad handclasp.
    pub flagged: Vec<bool>,
}

impl OutlierReport {
    /// Source rows of the flagged points.
    pub fn flagged_rows(&self) -> Vec<usize> {
        self.rows
            .iter()
            .zip(&self.flagged)
            .filter(|(_, f)| **f)
            .map(|(r, _)| *r)
            .collect()
    }
}

/// Fits `method` once per point with that point left out and measures how far the left-out point
/// falls from that fit (its leave-one-out residual). A point is flagged when this exceeds
/// `max(OUTLIER_FACTOR × s₋ᵢ, OUTLIER_MIN_M)`, `s₋ᵢ` being the residual scale of the fit without it
/// (a bad point inflates the others' leave-one-out residuals, but also the scale they are judged
/// against, while its own fit-without-it is clean). Needs one point more than the method needs
/// (`TooFewPoints` otherwise); with 4–5 points read a flag as "look at this row", not as proof.
pub fn leave_one_out(
    pairs: &PointPairs,
    method: Method,
    mounts: &MountPair,
) -> Result<OutlierReport, CalibError> {
    let n = pairs.len();
    if n < method.min_points() + 1 {
        return Err(CalibError::TooFewPoints {
            method: format!("leave-one-out with {}", method.name()),
            needed: method.min_points() + 1,
            got: n,
        });
    }
    let mut loo = Vec::with_capacity(n);
    let mut thresholds_m = Vec::with_capacity(n);
    for i in 0..n {
        let sub = pairs.without(i);
        let f = fit(&sub, method, mounts)?;
        loo.push((pairs.p_b1[i] - f.b1_from_b2 * pairs.p_b2[i]).norm());
        let rss: f64 = f.residuals.iter().map(|r| r.norm_squared()).sum();
        let dof = (3 * (n - 1)).saturating_sub(6).max(1) as f64;
        let scale = (3.0 * rss / dof).sqrt();
        thresholds_m.push((OUTLIER_FACTOR * scale).max(OUTLIER_MIN_M));
    }
    let flagged = loo.iter().zip(&thresholds_m).map(|(r, t)| r > t).collect();
    Ok(OutlierReport {
        rows: (0..n).map(|i| pairs.row(i)).collect(),
        loo_residuals_m: loo,
        thresholds_m,
        flagged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3, Vector3};

    #[test]
    fn bad_handclasp_is_flagged_by_row() {
        let truth = Isometry3::new(
            Vector3::new(0.04, 1.48, 0.05),
            Vector3::new(0.0, 0.0, -0.78),
        );
        let p_b2: Vec<Point3<f64>> = (0..8)
            .map(|i| {
                let a = i as f64 * 0.8;
                Point3::new(0.9 * a.cos(), 0.9 * a.sin(), 0.2 + 0.12 * i as f64)
            })
            .collect();
        // Small deterministic "noise" (±0.2 mm) and one 15 mm bad handclasp at index 5.
        let mut p_b1: Vec<Point3<f64>> = p_b2
            .iter()
            .enumerate()
            .map(|(i, p)| truth * p + Vector3::new(0.2e-3 * ((i % 3) as f64 - 1.0), 0.0, 0.1e-3))
            .collect();
        p_b1[5].y += 0.015;
        let mut pairs = PointPairs::new(p_b1, p_b2).unwrap();
        pairs.rows = (10..18).collect();
        for method in [Method::Lsq, Method::Constrained] {
            let rep = leave_one_out(&pairs, method, &MountPair::floor_floor()).unwrap();
            assert_eq!(rep.flagged_rows(), vec![15], "{rep:?}");
        }
        // Clean data: nothing flagged.
        let mut clean = pairs.clone();
        clean.p_b1[5].y -= 0.015;
        let rep = leave_one_out(&clean, Method::Lsq, &MountPair::floor_floor()).unwrap();
        assert!(rep.flagged_rows().is_empty());
        // Too few points.
        let few = PointPairs::new(pairs.p_b1[..3].to_vec(), pairs.p_b2[..3].to_vec()).unwrap();
        assert!(leave_one_out(&few, Method::Lsq, &MountPair::floor_floor()).is_err());
    }
}
