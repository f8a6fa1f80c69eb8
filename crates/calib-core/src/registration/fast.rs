//! Allocation-free registration kernels for Monte Carlo (no diagnostics, no uncertainty): the same
//! maths as [`super::rigid_lsq`], [`super::generic_4point`], [`super::paper_constrained`] and
//! [`super::constrained_lsq`], with the rotation by [`rotation_maximizing_trace`].

use super::family::project_rotation_family_fast;
use super::four_point::{affine_4point, translation_eq12};
use super::mount::MountPair;
use super::rotation::rotation_maximizing_trace;
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

/// Centroids and cross-covariance `M = Σ (p1 − c1)(p2 − c2)ᵀ` of paired points (m, m, m²).
fn centroids_and_cross(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
) -> (Vector3<f64>, Vector3<f64>, Matrix3<f64>) {
    let n = p_b1.len() as f64;
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        c1 += a.coords;
        c2 += b.coords;
    }
    c1 /= n;
    c2 /= n;
    let mut m = Matrix3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        m += (a.coords - c1) * (b.coords - c2).transpose();
    }
    (c1, c2, m)
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
    Some(Isometry3::from_parts(Translation3::from(t), q))
}

/// The paper's generic 4-point method, allocation-free: `H = A·B⁻¹`, the nearest rotation of its
/// 3×3 block, then eq (12) (`affine_translation = false`) or H's own translation column
/// (`affine_translation = true`). `None` if the points are coplanar (B singular) or degenerate.
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
    Some(Isometry3::from_parts(Translation3::from(t), q))
}

/// The paper's constrained 4-point method, allocation-free: `H = A·B⁻¹`, projection of its 3×3 block
/// onto the rotations the mounts allow (eq 11 floor–floor, eq 30 floor–ceiling, eqs 16–21
/// floor–wall, and the same projection generalised to tilted mounts), then eq (12).
/// `None` if the points are coplanar or the mount pair is unsupported (both `Wall`).
pub fn paper_fast(
    p_b1: &[Point3<f64>; 4],
    p_b2: &[Point3<f64>; 4],
    mounts: &MountPair,
) -> Option<Isometry3<f64>> {
    let (m, _) = affine_4point(p_b1, p_b2)?;
    let r = project_rotation_family_fast(&m, mounts)?;
    let q = UnitQuaternion::from_rotation_matrix(&r);
    let t = translation_eq12(p_b1, p_b2, &q);
    Some(Isometry3::from_parts(Translation3::from(t), q))
}

/// Installation-constrained least squares, allocation-free (see [`crate::constrained_lsq`]):
/// the rotation is restricted to the mounts' family inside the least-squares cost. `None` on
/// length mismatch, n < 2, or unsupported mounts.
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
    Some(Isometry3::from_parts(Translation3::from(t), q))
}
