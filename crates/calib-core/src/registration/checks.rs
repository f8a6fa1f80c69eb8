//! Input checks shared by the registration methods: lengths, finiteness, point count, and the
//! spread of the points (collinear: σ₂/σ₁ ≤ [`COLLINEAR_REL`]; coplanar: σ₃/σ₁ ≤ [`COPLANAR_REL`],
//! σ the singular values of the centred points).

use super::method::Method;
use crate::error::CalibError;
use crate::points::PointPairs;
use nalgebra::{Matrix3, Point3, Vector3};

/// Relative singular value (σ₂/σ₁ of the centred points) below which points count as collinear.
pub const COLLINEAR_REL: f64 = 1e-3;
/// Relative singular value (σ₃/σ₁ of the centred points) below which points count as coplanar
/// for the 4-point affine methods.
pub const COPLANAR_REL: f64 = 1e-3;

/// Singular values (m, descending) of the centred points.
pub fn spread_singular_values(points: &[Point3<f64>]) -> [f64; 3] {
    if points.is_empty() {
        return [0.0; 3];
    }
    let n = points.len() as f64;
    let c = points
        .iter()
        .fold(Vector3::zeros(), |acc, p| acc + p.coords)
        / n;
    let mut s = Matrix3::zeros();
    for p in points {
        let d = p.coords - c;
        s += d * d.transpose();
    }
    let mut ev: Vec<f64> = s
        .symmetric_eigenvalues()
        .iter()
        .map(|e| e.max(0.0).sqrt())
        .collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    [ev[0], ev[1], ev[2]]
}

/// Checks lengths, finiteness, point count and collinearity (and coplanarity when `need_volume`).
pub(super) fn check_pairs(pairs: &PointPairs, method: Method) -> Result<(), CalibError> {
    let n = pairs.p_b1.len();
    if n != pairs.p_b2.len() {
        return Err(CalibError::LengthMismatch {
            what: "p_b1 and p_b2".into(),
            a: n,
            b: pairs.p_b2.len(),
        });
    }
    for i in 0..n {
        if !pairs.p_b1[i]
            .iter()
            .chain(pairs.p_b2[i].iter())
            .all(|v| v.is_finite())
        {
            return Err(CalibError::NonFinite {
                row: pairs.row(i),
                what: "a coordinate".into(),
            });
        }
    }
    if n < method.min_points() {
        return Err(CalibError::TooFewPoints {
            method: method.name().into(),
            needed: method.min_points(),
            got: n,
        });
    }
    let rows: Vec<usize> = (0..n).map(|i| pairs.row(i)).collect();
    for (robot, pts) in [(1u8, &pairs.p_b1), (2u8, &pairs.p_b2)] {
        let sv = spread_singular_values(pts);
        let sv_mm = sv.map(|s| s * 1e3);
        if sv[1] <= COLLINEAR_REL * sv[0] {
            return Err(CalibError::Collinear {
                rows: rows.clone(),
                robot,
                singular_values_mm: sv_mm,
            });
        }
        if method.min_points() == 4 && sv[2] <= COPLANAR_REL * sv[0] {
            return Err(CalibError::Coplanar {
                rows: rows.clone(),
                robot,
                singular_values_mm: sv_mm,
            });
        }
    }
    Ok(())
}
