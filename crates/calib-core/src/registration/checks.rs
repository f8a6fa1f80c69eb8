//! Input checks shared by the registration methods: lengths, finiteness, point count, and the
//! spread of the points (collinear: σ₂/σ₁ ≤ [`COLLINEAR_REL`]; coplanar: σ₃/σ₁ ≤ [`COPLANAR_REL`],
//! σ the singular values of the centred points).

use super::method::{build_uncertainty, residuals, Fit, Method};
use crate::error::CalibError;
use crate::points::PointPairs;
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Translation3, Vector3};

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

/// Orthonormality and determinant tolerance of the output check: a rotation from the SVD or a
/// unit quaternion is orthonormal to ~1e-15; 1e-9 leaves room for round-off, never for a NaN.
pub(super) const ROTATION_CHECK_TOL: f64 = 1e-9;

/// Why `b1_from_b2` is not a finite proper rotation with a finite translation, or `None` when it is.
fn pose_problem(b1_from_b2: &Isometry3<f64>) -> Option<String> {
    let r = b1_from_b2.rotation.to_rotation_matrix().into_inner();
    let t = b1_from_b2.translation.vector;
    if !r.iter().all(|v| v.is_finite()) {
        return Some("the fitted rotation is not finite".into());
    }
    if !t.iter().all(|v| v.is_finite()) {
        return Some("the fitted translation is not finite".into());
    }
    let ortho = (r.transpose() * r - Matrix3::identity()).amax();
    let det = r.determinant();
    if ortho > ROTATION_CHECK_TOL || (det - 1.0).abs() > ROTATION_CHECK_TOL {
        return Some(format!(
            "the fitted rotation is not a proper rotation (‖RᵀR − I‖_max = {ortho:.3e}, det = {det})"
        ));
    }
    None
}

/// The output check every fit passes before it is returned: `b1_from_b2` is a finite proper
/// rotation (orthonormal and det +1 to [`ROTATION_CHECK_TOL`]) with a finite translation, and the
/// residuals are finite. A non-finite uncertainty is dropped (`None`), as when it is not computed.
pub(super) fn checked(mut fit: Fit) -> Result<Fit, CalibError> {
    let problem = pose_problem(&fit.b1_from_b2).or_else(|| {
        (!fit
            .residuals
            .iter()
            .all(|r| r.iter().all(|v| v.is_finite())))
        .then(|| "the residuals overflow".to_string())
    });
    if let Some(message) = problem {
        return Err(CalibError::NumericalFailure {
            method: fit.method.name().into(),
            message,
        });
    }
    if let Some(u) = &fit.uncertainty {
        let finite = u.covariance.iter().all(|v| v.is_finite())
            && [u.sigma_point_m, u.e_tran_1sigma_m, u.e_rot_1sigma_rad]
                .iter()
                .all(|v| v.is_finite());
        if !finite {
            fit.uncertainty = None;
        }
    }
    Ok(fit)
}

/// Runs `inner` on `pairs`; if its fit fails the output check, runs it again on centred and
/// rescaled copies (`p' = (p − cₖ)/s`, one scale s for both robots so the motion stays rigid) and
/// maps the result back (also when `inner` itself reports [`CalibError::NumericalFailure`]): `R` unchanged, `T = c1 + s·T' − R·c2`, residuals recomputed on the inputs,
/// covariance `G·C'·Gᵀ` with `δθ = δθ'`, `δt = s·δt' + c1 × δθ'`. Valid inputs never take the
/// rescaled path, so their results are unchanged to the bit. Errors of `inner` on the inputs
/// (invalid input) are returned as they are.
pub(super) fn fit_rescued(
    pairs: &PointPairs,
    inner: impl Fn(&PointPairs) -> Result<Fit, CalibError>,
) -> Result<Fit, CalibError> {
    let first_err = match inner(pairs).and_then(checked) {
        Ok(f) => return Ok(f),
        Err(e @ CalibError::NumericalFailure { .. }) => e,
        Err(e) => return Err(e),
    };
    let centroid = |pts: &[Point3<f64>]| {
        let n = pts.len() as f64;
        pts.iter()
            .fold(Vector3::zeros(), |acc, p| acc + p.coords / n)
    };
    let c1 = centroid(&pairs.p_b1);
    let c2 = centroid(&pairs.p_b2);
    let s = pairs
        .p_b1
        .iter()
        .map(|p| (p.coords - c1).amax())
        .chain(pairs.p_b2.iter().map(|p| (p.coords - c2).amax()))
        .fold(0.0f64, f64::max);
    if !(s.is_finite() && s > 0.0) {
        return Err(first_err);
    }
    let scaled = PointPairs {
        p_b1: pairs
            .p_b1
            .iter()
            .map(|p| Point3::from((p.coords - c1) / s))
            .collect(),
        p_b2: pairs
            .p_b2
            .iter()
            .map(|p| Point3::from((p.coords - c2) / s))
            .collect(),
        rows: pairs.rows.clone(),
    };
    let Ok(f) = inner(&scaled).and_then(checked) else {
        return Err(first_err);
    };
    let rot = f.b1_from_b2.rotation;
    let t = c1 + f.b1_from_b2.translation.vector * s - rot * c2;
    let b1_from_b2 = Isometry3::from_parts(Translation3::from(t), rot);
    let uncertainty = f.uncertainty.map(|u| {
        let mut g = Matrix6::zeros();
        g.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::identity());
        g.fixed_view_mut::<3, 3>(3, 0).copy_from(&c1.cross_matrix());
        g.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(Matrix3::identity() * s));
        build_uncertainty(
            g * u.covariance * g.transpose(),
            u.sigma_point_m * s,
            u.dof,
            &b1_from_b2,
        )
    });
    checked(Fit {
        method: f.method,
        residuals: residuals(pairs, &b1_from_b2),
        b1_from_b2,
        condition: f.condition,
        uncertainty,
    })
}
