//! Weighted rigid and installation-constrained least squares, with the covariance of the fit
//! (see [`Uncertainty`]).

use super::checks::{check_pairs, fit_rescued, spread_singular_values};
use super::family::{family_axes, project_rotation_family};
use super::method::{build_uncertainty, residuals, Fit, Method, Uncertainty};
use super::mount::MountPair;
use super::rotation::nearest_rotation;
use crate::error::CalibError;
use crate::points::PointPairs;
use nalgebra::{DMatrix, Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector3};

fn weights_checked(pairs: &PointPairs, weights: Option<&[f64]>) -> Result<Vec<f64>, CalibError> {
    let n = pairs.p_b1.len();
    match weights {
        None => Ok(vec![1.0; n]),
        Some(w) => {
            if w.len() != n {
                return Err(CalibError::LengthMismatch {
                    what: "weights and points".into(),
                    a: w.len(),
                    b: n,
                });
            }
            for (i, &wi) in w.iter().enumerate() {
                if !wi.is_finite() || wi < 0.0 {
                    return Err(CalibError::NonFinite {
                        row: pairs.row(i),
                        what: format!("weight {wi} (must be finite and ≥ 0)"),
                    });
                }
            }
            if w.iter().filter(|&&x| x > 0.0).count() < 3 {
                return Err(CalibError::TooFewPoints {
                    method: "lsq (points with weight > 0)".into(),
                    needed: 3,
                    got: w.iter().filter(|&&x| x > 0.0).count(),
                });
            }
            Ok(w.to_vec())
        }
    }
}

fn weighted_cross(pairs: &PointPairs, w: &[f64]) -> (Vector3<f64>, Vector3<f64>, Matrix3<f64>) {
    let sw: f64 = w.iter().sum();
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for ((a, b), wi) in pairs.p_b1.iter().zip(&pairs.p_b2).zip(w) {
        c1 += a.coords * *wi;
        c2 += b.coords * *wi;
    }
    c1 /= sw;
    c2 /= sw;
    let mut m = Matrix3::zeros();
    for ((a, b), wi) in pairs.p_b1.iter().zip(&pairs.p_b2).zip(w) {
        m += (a.coords - c1) * (b.coords - c2).transpose() * *wi;
    }
    (c1, c2, m)
}

/// Jacobian of the weighted residuals `√wᵢ·(p1ᵢ − X·p2ᵢ)` with respect to rotations about `axes`
/// (b1 frame, left perturbation, rad) followed by `δt` (m): column for axis a is `√wᵢ·(X·p2ᵢ) × a`,
/// translation block `−√wᵢ·I`. Written into `j` (3n × (axes + 3)).
pub(crate) fn fill_fit_jacobian(
    pairs: &PointPairs,
    w: &[f64],
    b1_from_b2: &Isometry3<f64>,
    axes: &[Vector3<f64>],
    j: &mut DMatrix<f64>,
) {
    for i in 0..pairs.p_b1.len() {
        let sw = w[i].sqrt();
        let y = b1_from_b2 * pairs.p_b2[i];
        for (c, a) in axes.iter().enumerate() {
            let col = y.coords.cross(a) * sw;
            for r in 0..3 {
                j[(3 * i + r, c)] = col[r];
            }
        }
        for r in 0..3 {
            j[(3 * i + r, axes.len() + r)] = -sw;
        }
    }
}

/// `JᵀJ` (k × k, k = axes + 3 ≤ 6; panics on more than 3 axes, a caller bug) of the weighted fit Jacobian of [`fill_fit_jacobian`], accumulated
/// point by point: memory O(k²) whatever the number of points (the 3n × k Jacobian is never
/// formed; at 1e6 points it would take 3n·k·8 bytes ≈ 144 MB, twice with its scaled copy).
pub(crate) fn fit_jtj(
    pairs: &PointPairs,
    w: &[f64],
    b1_from_b2: &Isometry3<f64>,
    axes: &[Vector3<f64>],
) -> DMatrix<f64> {
    assert!(axes.len() <= 3, "at most 3 rotation axes");
    let k = axes.len() + 3;
    let mut jtj = DMatrix::zeros(k, k);
    let mut row = [0.0f64; 6];
    let mut cols = [Vector3::zeros(); 3];
    for (p_b2, wi) in pairs.p_b2.iter().zip(w) {
        let sw = wi.sqrt();
        let y = b1_from_b2 * p_b2;
        for (col, a) in cols.iter_mut().zip(axes) {
            *col = y.coords.cross(a) * sw;
        }
        for r in 0..3 {
            for (c, col) in cols[..axes.len()].iter().enumerate() {
                row[c] = col[r];
            }
            for c in 0..3 {
                row[axes.len() + c] = if c == r { -sw } else { 0.0 };
            }
            for a in 0..k {
                if row[a] == 0.0 {
                    continue;
                }
                for b in 0..k {
                    jtj[(a, b)] += row[a] * row[b];
                }
            }
        }
    }
    jtj
}

/// Uncertainty and conditioning for a least-squares fit with free rotation axes `axes` (b1 frame)
/// plus a free translation. Memory and time linear in the points, O(k²) extra memory
/// ([`fit_jtj`]).
fn lsq_uncertainty(
    pairs: &PointPairs,
    w: &[f64],
    b1_from_b2: &Isometry3<f64>,
    res: &[Vector3<f64>],
    axes: &[Vector3<f64>],
) -> (f64, Option<Uncertainty>) {
    let n = pairs.p_b1.len();
    let k = axes.len() + 3;
    // Jacobian of r_i = p1 − X·p2 w.r.t. [rotation angles about axes; δt]: [ (X p2) × a ; −I ].
    let mut g = nalgebra::DMatrix::zeros(6, k);
    for (c, a) in axes.iter().enumerate() {
        for r in 0..3 {
            g[(r, c)] = a[r];
        }
    }
    for r in 0..3 {
        g[(3 + r, axes.len() + r)] = 1.0;
    }
    let jtj = fit_jtj(pairs, w, b1_from_b2, axes);
    let radius = {
        let sv = spread_singular_values(&pairs.p_b2);
        ((sv[0] * sv[0] + sv[1] * sv[1] + sv[2] * sv[2]) / n as f64)
            .sqrt()
            .max(1e-12)
    };
    // The conditioning uses the rotation columns divided by the points' RMS radius:
    // JsᵀJs = D·JᵀJ·D with D = diag(1/radius (rotation), 1 (translation)).
    let scale = |c: usize| if c < axes.len() { 1.0 / radius } else { 1.0 };
    let js = DMatrix::from_fn(k, k, |a, b| jtj[(a, b)] * scale(a) * scale(b));
    let ev = js.symmetric_eigenvalues();
    let (mn, mx) = ev
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &e| (a.min(e), b.max(e)));
    let condition = if mn > 0.0 {
        (mx / mn).sqrt()
    } else {
        f64::INFINITY
    };
    let m_eff = 3 * w.iter().filter(|&&x| x > 0.0).count();
    if m_eff <= k {
        return (condition, None);
    }
    let dof = m_eff - k;
    let rss: f64 = res.iter().zip(w).map(|(r, wi)| wi * r.norm_squared()).sum();
    let sigma2 = rss / dof as f64;
    let Some(inv) = jtj.try_inverse() else {
        return (condition, None);
    };
    let cov_dyn = &g * inv * g.transpose() * sigma2;
    let covariance = Matrix6::from_fn(|r, c| cov_dyn[(r, c)]);
    let unc = build_uncertainty(covariance, sigma2.sqrt(), dof, b1_from_b2);
    (condition, Some(unc))
}

/// Rigid least squares (Arun/Umeyama/Horn, no scale): minimises `Σ wᵢ‖p1ᵢ − R·p2ᵢ − T‖²` over all
/// rotations R and translations T; `weights` default to 1 (must be finite and ≥ 0, at least 3 > 0).
/// Needs n ≥ 3 non-collinear points. The result carries the covariance from the residuals and the
/// Jacobian ([`Uncertainty`]) when n ≥ 3 (3n > 6).
///
/// # Examples
/// ```
/// use calib_core::{rigid_lsq, PointPairs};
/// use nalgebra::{Isometry3, Point3, Vector3};
/// let b1_from_b2 = Isometry3::new(Vector3::new(1.0, 0.5, 0.0), Vector3::new(0.0, 0.0, 0.7));
/// let p_b2 = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0),
///                 Point3::new(0.0, 1.0, 0.2), Point3::new(0.3, 0.2, 1.0)];
/// let p_b1 = p_b2.iter().map(|p| b1_from_b2 * p).collect();
/// let fit = rigid_lsq(&PointPairs::new(p_b1, p_b2).unwrap(), None).unwrap();
/// assert!((fit.b1_from_b2.translation.vector - b1_from_b2.translation.vector).norm() < 1e-9);
/// ```
pub fn rigid_lsq(pairs: &PointPairs, weights: Option<&[f64]>) -> Result<Fit, CalibError> {
    fit_rescued(pairs, |p| rigid_lsq_raw(p, weights))
}

fn rigid_lsq_raw(pairs: &PointPairs, weights: Option<&[f64]>) -> Result<Fit, CalibError> {
    check_pairs(pairs, Method::Lsq)?;
    let w = weights_checked(pairs, weights)?;
    let (c1, c2, m) = weighted_cross(pairs, &w);
    let r = nearest_rotation(&m);
    let t = c1 - r * c2;
    let b1_from_b2 = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    let res = residuals(pairs, &b1_from_b2);
    let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let (condition, uncertainty) = lsq_uncertainty(pairs, &w, &b1_from_b2, &res, &axes);
    Ok(Fit {
        method: Method::Lsq,
        b1_from_b2,
        residuals: res,
        condition,
        uncertainty,
    })
}

/// Options of [`constrained_lsq`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ConstrainedOptions {
    /// Per-point weights (default: all 1), finite and ≥ 0.
    pub weights: Option<Vec<f64>>,
}

/// Installation-constrained least squares: minimises `Σ wᵢ‖p1ᵢ − R·p2ᵢ − T‖²` with R restricted to
/// the mounts' family inside the fit (not a projection of an unconstrained estimate): with both
/// gravity directions known only the yaw about gravity is free (closed form), with a [`Mount::Wall`](super::Mount::Wall)
/// the paper's two angles (1-D global search, see the module doc). The optimum over the family is
/// the member maximising `tr(Rᵀ·M)` with M the weighted cross-covariance, and `T = c1 − R·c2`.
/// Needs n ≥ 3 non-collinear points (the constraint would allow 2, but then nothing checks it).
pub fn constrained_lsq(
    pairs: &PointPairs,
    mounts: &MountPair,
    options: &ConstrainedOptions,
) -> Result<Fit, CalibError> {
    fit_rescued(pairs, |p| constrained_lsq_raw(p, mounts, options))
}

fn constrained_lsq_raw(
    pairs: &PointPairs,
    mounts: &MountPair,
    options: &ConstrainedOptions,
) -> Result<Fit, CalibError> {
    check_pairs(pairs, Method::Constrained)?;
    let w = weights_checked(pairs, options.weights.as_deref())?;
    let (c1, c2, m) = weighted_cross(pairs, &w);
    let r = project_rotation_family(&m, mounts)?;
    let t = c1 - r * c2;
    let b1_from_b2 = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    let res = residuals(pairs, &b1_from_b2);
    let axes = family_axes(mounts, &r)?;
    let (condition, uncertainty) = lsq_uncertainty(pairs, &w, &b1_from_b2, &res, &axes);
    Ok(Fit {
        method: Method::Constrained,
        b1_from_b2,
        residuals: res,
        condition,
        uncertainty,
    })
}
