//! Allocation-free registration kernels for Monte Carlo (no diagnostics, no uncertainty): the same
//! maths as [`super::rigid_lsq`], [`super::generic_4point`], [`super::paper_constrained`] and
//! [`super::constrained_lsq`], with the rotation by [`rotation_maximizing_trace`], and
//! [`fit_fast`], the allocation-free twin of [`crate::fit`] that dispatches among them.

use super::family::{project_rotation_family, project_rotation_family_fast};
use super::four_point::{affine_4point, translation_eq12};
use super::method::Method;
use super::mount::MountPair;
use super::rotation::rotation_maximizing_trace;
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

/// Centroids and cross-covariance `M = Σ (p1 − c1)(p2 − c2)ᵀ` of paired points (m, m, m²).
fn centroids_and_cross(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
) -> (Vector3<f64>, Vector3<f64>, Matrix3<f64>) {
    centroids_and_cross_of(p_b1.iter().zip(p_b2))
}

/// [`centroids_and_cross`] over pairs given by an iterator (walked twice, in the same order, so
/// the sums are those of the same pairs gathered into slices, bit for bit).
fn centroids_and_cross_of<'a, I>(pairs: I) -> (Vector3<f64>, Vector3<f64>, Matrix3<f64>)
where
    I: Iterator<Item = (&'a Point3<f64>, &'a Point3<f64>)> + Clone,
{
    let mut n = 0usize;
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for (a, b) in pairs.clone() {
        c1 += a.coords;
        c2 += b.coords;
        n += 1;
    }
    let n = n as f64;
    c1 /= n;
    c2 /= n;
    let mut m = Matrix3::zeros();
    for (a, b) in pairs {
        m += (a.coords - c1) * (b.coords - c2).transpose();
    }
    (c1, c2, m)
}

/// `Some(x)` when every component of `x` is finite: a NaN, ±∞ or overflowing input gives `None`
/// instead of a non-finite transform (found by the issue-10 property test: `constrained_fast`
/// returned a NaN transform for a point with a NaN coordinate).
fn finite(x: Isometry3<f64>) -> Option<Isometry3<f64>> {
    let ok = x.translation.vector.iter().all(|v| v.is_finite())
        && x.rotation.coords.iter().all(|v| v.is_finite());
    ok.then_some(x)
}

/// Rigid least-squares `b1_from_b2` (no scale): minimises `Σ ‖p_b1_i − (R·p_b2_i + T)‖²`, n ≥ 3.
///
/// Same maths as [`crate::rigid_lsq`] without weights, diagnostics or allocation. `None` when the
/// lengths differ, n < 3, a value is not finite, or the points are collinear (rotation not unique).
/// Points in metres.
pub fn rigid_fit_fast(p_b1: &[Point3<f64>], p_b2: &[Point3<f64>]) -> Option<Isometry3<f64>> {
    if p_b1.len() != p_b2.len() || p_b1.len() < 3 {
        return None;
    }
    let (c1, c2, m) = centroids_and_cross(p_b1, p_b2);
    let q = rotation_maximizing_trace(&m)?;
    let t = c1 - q * c2;
    finite(Isometry3::from_parts(Translation3::from(t), q))
}

/// [`rigid_fit_fast`] of the pairs `(p_b1[i], p_b2[i])` for `i` in `idx`, without gathering them:
/// bit-identical to `rigid_fit_fast` of the gathered slices (the same sums in the same order), so
/// a robust fit over subsets of a million points allocates nothing per subset. `None` as
/// [`rigid_fit_fast`], or when an index is out of range.
pub(crate) fn rigid_fit_fast_indexed(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
    idx: &[usize],
) -> Option<Isometry3<f64>> {
    if p_b1.len() != p_b2.len() || idx.len() < 3 || idx.iter().any(|&i| i >= p_b1.len()) {
        return None;
    }
    let (c1, c2, m) = centroids_and_cross_of(idx.iter().map(|&i| (&p_b1[i], &p_b2[i])));
    let q = rotation_maximizing_trace(&m)?;
    let t = c1 - q * c2;
    finite(Isometry3::from_parts(Translation3::from(t), q))
}

/// The paper's generic 4-point method, allocation-free: `H = A·B⁻¹`, the nearest rotation of its
/// 3×3 block, then eq (12) (`affine_translation = false`) or H's own translation column
/// (`affine_translation = true`). `None` if the points are coplanar (B singular) or degenerate, or
/// a value is not finite.
pub fn generic_fast(
    p_b1: &[Point3<f64>; 4],
    p_b2: &[Point3<f64>; 4],
    affine_translation: bool,
) -> Option<Isometry3<f64>> {
    let (m, t_h) = affine_4point(p_b1, p_b2)?;
    let q = rotation_maximizing_trace(&m)?;
    let t = if affine_translation {
        t_h
    } else {
        translation_eq12(p_b1, p_b2, &q)
    };
    finite(Isometry3::from_parts(Translation3::from(t), q))
}

/// The paper's constrained 4-point method, allocation-free: `H = A·B⁻¹`, projection of its 3×3 block
/// onto the rotations the mounts allow (eq 11 floor–floor, eq 30 floor–ceiling, eqs 16–21
/// floor–wall, and the same projection generalised to tilted mounts), then eq (12).
/// `None` if the points are coplanar, the mount pair is unsupported (both `Wall`), or a value is
/// not finite.
pub fn paper_fast(
    p_b1: &[Point3<f64>; 4],
    p_b2: &[Point3<f64>; 4],
    mounts: &MountPair,
) -> Option<Isometry3<f64>> {
    let (m, _) = affine_4point(p_b1, p_b2)?;
    let r = project_rotation_family_fast(&m, mounts)?;
    let q = UnitQuaternion::from_rotation_matrix(&r);
    let t = translation_eq12(p_b1, p_b2, &q);
    finite(Isometry3::from_parts(Translation3::from(t), q))
}

/// Installation-constrained least squares, allocation-free (see [`crate::constrained_lsq`]):
/// the rotation is restricted to the mounts' family inside the least-squares cost. `None` on
/// length mismatch, n < 2, unsupported mounts, or a value that is not finite.
pub fn constrained_fast(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
    mounts: &MountPair,
) -> Option<Isometry3<f64>> {
    if p_b1.len() != p_b2.len() || p_b1.len() < 2 {
        return None;
    }
    let (c1, c2, m) = centroids_and_cross(p_b1, p_b2);
    let r = project_rotation_family_fast(&m, mounts)?;
    let q = UnitQuaternion::from_rotation_matrix(&r);
    let t = c1 - q * c2;
    finite(Isometry3::from_parts(Translation3::from(t), q))
}

/// Centred affine least squares `p1 ≈ M·p2 + t` (n ≥ 4, allocation-free): `(M, t)` (M unitless,
/// t in m). `None` when the centred `p_b2` do not span 3-D (their scatter matrix is singular) or
/// a value is not finite.
pub fn affine_lsq_fast(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let n = p_b1.len() as f64;
    let c1 = p_b1.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let c2 = p_b2.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let mut s12 = Matrix3::zeros();
    let mut s22 = Matrix3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        let d1 = a.coords - c1;
        let d2 = b.coords - c2;
        s12 += d1 * d2.transpose();
        s22 += d2 * d2.transpose();
    }
    let m = s12 * s22.try_inverse()?;
    m.iter().all(|v| v.is_finite()).then(|| (m, c1 - m * c2))
}

/// Fits `b1_from_b2` by `method` without allocation: the allocation-free twin of [`crate::fit`]
/// (equal to it to round-off, tested). The fast kernels above for 4 points (and for `lsq` /
/// `constrained` at any n); for the 4-point methods with n > 4, the affine least-squares `H`
/// ([`affine_lsq_fast`], as [`crate::generic_4point`] does) then the same rotation step and
/// eq (12). Points in metres. `None` when the lengths differ, the method needs more points, the
/// points are degenerate for it, the mounts are unsupported, or a value (input, or result through
/// overflow) is not finite: every `Some` is a finite proper rotation and translation.
pub fn fit_fast(
    method: Method,
    mounts: &MountPair,
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
) -> Option<Isometry3<f64>> {
    let n = p_b1.len();
    if n != p_b2.len() || n < method.min_points() {
        return None;
    }
    match method {
        Method::Lsq => rigid_fit_fast(p_b1, p_b2),
        Method::Constrained => constrained_fast(p_b1, p_b2, mounts),
        Method::Generic | Method::GenericAffine | Method::Paper if n == 4 => {
            let a: &[Point3<f64>; 4] = p_b1.try_into().ok()?;
            let b: &[Point3<f64>; 4] = p_b2.try_into().ok()?;
            match method {
                Method::Paper => paper_fast(a, b, mounts),
                m => generic_fast(a, b, m == Method::GenericAffine),
            }
        }
        Method::Generic | Method::GenericAffine | Method::Paper => {
            let (m, t_h) = affine_lsq_fast(p_b1, p_b2)?;
            let q = if method == Method::Paper {
                UnitQuaternion::from_rotation_matrix(&project_rotation_family(&m, mounts).ok()?)
            } else {
                rotation_maximizing_trace(&m)?
            };
            let t = if method == Method::GenericAffine {
                t_h
            } else {
                translation_eq12(p_b1, p_b2, &q)
            };
            finite(Isometry3::from_parts(Translation3::from(t), q))
        }
    }
}
