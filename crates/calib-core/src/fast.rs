//! Allocation-free registration kernels for Monte Carlo (no diagnostics, no uncertainty).
//!
//! The core is [`rotation_maximizing_trace`]: the rotation `R` maximising `tr(Rᵀ·M)` for a 3×3
//! matrix `M`. That is both the Frobenius-nearest rotation of `M` (`‖R − M‖²_F = const − 2·tr(RᵀM)`)
//! and the rigid least-squares rotation when `M` is the cross-covariance `Σ (p1 − c1)(p2 − c2)ᵀ`.
//! It is solved by Horn's quaternion method: the maximising unit quaternion is the eigenvector of the
//! largest eigenvalue of a symmetric traceless 4×4 matrix `N(M)`. The eigenvalue is found by Newton's
//! method on the characteristic quartic, started above the largest root (Theobald's QCP), and the
//! eigenvector as the largest column of the adjugate of `N − λI`. The result matches the SVD polar
//! factor ([`crate::nearest_rotation`]) to round-off (tested).

use crate::registration::{project_rotation_family_fast, MountPair};
use nalgebra::{
    Isometry3, Matrix3, Matrix4, Point3, Quaternion, Translation3, UnitQuaternion, Vector3,
};

/// Relative convergence of the Newton iteration on the largest eigenvalue.
const NEWTON_REL_TOL: f64 = 1e-13;
/// Newton iterations cap (convergence takes 3–8 in practice).
const NEWTON_MAX_ITER: usize = 50;
/// Below this (squared adjugate column relative to `‖M‖_F⁶`) the maximiser is taken as not unique.
/// The ratio is about `64·(s₂/s₁)²` for singular values `s` of M, so this rejects `s₂/s₁ < ~1e-8`
/// (points collinear to ~1e-4 of their spread); exactly rank-1 M gives ~1e-17 after Newton round-off.
const DEGENERATE_REL: f64 = 1e-14;

/// The rotation maximising `tr(Rᵀ·M)` (= the Frobenius-nearest rotation to `M`, determinant guarded),
/// by Horn's quaternion method. `None` when the maximiser is not unique (rank(M) ≤ 1, e.g. collinear
/// points) or `M` is not finite. Allocation-free.
pub fn rotation_maximizing_trace(m: &Matrix3<f64>) -> Option<UnitQuaternion<f64>> {
    // Horn's S_ab = Σ x2_a · x1_b = Mᵀ (rotating set 2 onto set 1).
    let (sxx, sxy, sxz) = (m[(0, 0)], m[(1, 0)], m[(2, 0)]);
    let (syx, syy, syz) = (m[(0, 1)], m[(1, 1)], m[(2, 1)]);
    let (szx, szy, szz) = (m[(0, 2)], m[(1, 2)], m[(2, 2)]);
    let n = Matrix4::new(
        sxx + syy + szz,
        syz - szy,
        szx - sxz,
        sxy - syx,
        syz - szy,
        sxx - syy - szz,
        sxy + syx,
        szx + sxz,
        szx - sxz,
        sxy + syx,
        -sxx + syy - szz,
        syz + szy,
        sxy - syx,
        szx + sxz,
        syz + szy,
        -sxx - syy + szz,
    );
    let fro2 = m.norm_squared();
    if !fro2.is_finite() {
        return None;
    }
    if fro2 == 0.0 {
        return None;
    }
    // Characteristic polynomial of traceless symmetric N: λ⁴ + c2·λ² + c1·λ + c0.
    let n2 = n * n;
    let tr2 = n2.trace();
    let tr3 = (n2.component_mul(&n.transpose())).sum(); // tr(N²·N) = Σ (N²)_ij N_ji
    let c2 = -0.5 * tr2;
    let c1 = -tr3 / 3.0;
    let c0 = det4(&n);
    // Start above the largest eigenvalue (|λ| ≤ √tr(N²) = ‖N‖_F); Newton from above the largest
    // root of a real-rooted polynomial decreases monotonically onto it.
    let mut lambda = (tr2).sqrt();
    for _ in 0..NEWTON_MAX_ITER {
        let l2 = lambda * lambda;
        let p = (l2 + c2) * l2 + c1 * lambda + c0;
        let dp = 4.0 * l2 * lambda + 2.0 * c2 * lambda + c1;
        if dp == 0.0 {
            break;
        }
        let step = p / dp;
        lambda -= step;
        if step.abs() <= NEWTON_REL_TOL * lambda.abs().max(f64::MIN_POSITIVE) {
            break;
        }
    }
    let a = n - Matrix4::identity() * lambda;
    // Columns of adj(A) are eigenvectors of the null space (rank 3). Pick the largest.
    let mut best_q = [0.0; 4];
    let mut best_norm = -1.0;
    for col in 0..4 {
        let q = adjugate_column(&a, col);
        let nq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
        if nq > best_norm {
            best_norm = nq;
            best_q = q;
        }
    }
    let scale = fro2 * fro2 * fro2; // adjugate entries scale like ‖M‖³, squared → ‖M‖⁶
    if best_norm.partial_cmp(&(DEGENERATE_REL * scale)) != Some(std::cmp::Ordering::Greater)
        || !best_norm.is_finite()
    {
        return None;
    }
    let q = Quaternion::new(best_q[0], best_q[1], best_q[2], best_q[3]);
    Some(UnitQuaternion::from_quaternion(q))
}

/// Determinant of a 4×4 matrix by 2×2 minors (Laplace on the top two rows).
fn det4(m: &Matrix4<f64>) -> f64 {
    let s0 = m[(0, 0)] * m[(1, 1)] - m[(1, 0)] * m[(0, 1)];
    let s1 = m[(0, 0)] * m[(1, 2)] - m[(1, 0)] * m[(0, 2)];
    let s2 = m[(0, 0)] * m[(1, 3)] - m[(1, 0)] * m[(0, 3)];
    let s3 = m[(0, 1)] * m[(1, 2)] - m[(1, 1)] * m[(0, 2)];
    let s4 = m[(0, 1)] * m[(1, 3)] - m[(1, 1)] * m[(0, 3)];
    let s5 = m[(0, 2)] * m[(1, 3)] - m[(1, 2)] * m[(0, 3)];
    let c5 = m[(2, 2)] * m[(3, 3)] - m[(3, 2)] * m[(2, 3)];
    let c4 = m[(2, 1)] * m[(3, 3)] - m[(3, 1)] * m[(2, 3)];
    let c3 = m[(2, 1)] * m[(3, 2)] - m[(3, 1)] * m[(2, 2)];
    let c2 = m[(2, 0)] * m[(3, 3)] - m[(3, 0)] * m[(2, 3)];
    let c1 = m[(2, 0)] * m[(3, 2)] - m[(3, 0)] * m[(2, 2)];
    let c0 = m[(2, 0)] * m[(3, 1)] - m[(3, 0)] * m[(2, 1)];
    s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0
}

/// Column `col` of the adjugate of a 4×4 matrix: entry i is the cofactor C(col, i).
fn adjugate_column(a: &Matrix4<f64>, col: usize) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (i, o) in out.iter_mut().enumerate() {
        // adj(A)_{i,col} = (−1)^{i+col} · det(A without row col and column i)
        let rows: [usize; 3] = skip3(col);
        let cols: [usize; 3] = skip3(i);
        let d = det3_sub(a, rows, cols);
        *o = if (i + col) % 2 == 0 { d } else { -d };
    }
    out
}

fn skip3(k: usize) -> [usize; 3] {
    match k {
        0 => [1, 2, 3],
        1 => [0, 2, 3],
        2 => [0, 1, 3],
        _ => [0, 1, 2],
    }
}

fn det3_sub(a: &Matrix4<f64>, r: [usize; 3], c: [usize; 3]) -> f64 {
    let m = |i: usize, j: usize| a[(r[i], c[j])];
    m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
        - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
        + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0))
}

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

/// The affine `H = A·B⁻¹` of the 4-point generic method (A, B: homogeneous point columns).
/// Returns `(M, t_H)`: H's 3×3 block and its translation column. `None` if B is singular.
pub fn affine_4point(
    p_b1: &[Point3<f64>; 4],
    p_b2: &[Point3<f64>; 4],
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let mut a = Matrix4::zeros();
    let mut b = Matrix4::zeros();
    for k in 0..4 {
        for r in 0..3 {
            a[(r, k)] = p_b1[k][r];
            b[(r, k)] = p_b2[k][r];
        }
        a[(3, k)] = 1.0;
        b[(3, k)] = 1.0;
    }
    let b_inv = b.try_inverse()?;
    let h = a * b_inv;
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    let m = h.fixed_view::<3, 3>(0, 0).into_owned();
    let t = Vector3::new(h[(0, 3)], h[(1, 3)], h[(2, 3)]);
    Some((m, t))
}

/// eq (12): `T = (1/n)·Σ (p1_i − R·p2_i)`.
fn translation_eq12(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
    q: &UnitQuaternion<f64>,
) -> Vector3<f64> {
    let mut t = Vector3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        t += a.coords - q * b.coords;
    }
    t / p_b1.len() as f64
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registration::nearest_rotation;
    use nalgebra::Rotation3;

    /// Horn/QCP vs SVD polar factor: both are exact methods, agreement to round-off.
    const HORN_VS_SVD_TOL: f64 = 1e-9;

    #[test]
    fn horn_matches_svd_on_random_matrices() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for _ in 0..500 {
            let m = Matrix3::from_fn(|_, _| next());
            let r_svd = nearest_rotation(&m);
            let q = rotation_maximizing_trace(&m).expect("generic matrix");
            let r_horn = q.to_rotation_matrix();
            assert!(
                (r_svd.matrix() - r_horn.matrix()).amax() < HORN_VS_SVD_TOL,
                "m = {m}"
            );
        }
        // Nearly a rotation (the usual case), including exactly 180°.
        for angle in [0.0, 1e-9, 0.3, std::f64::consts::PI] {
            let r = Rotation3::from_axis_angle(&Vector3::x_axis(), angle);
            let m = r.matrix() * 2.5;
            let q = rotation_maximizing_trace(&m).unwrap();
            assert!((q.to_rotation_matrix().matrix() - r.matrix()).amax() < HORN_VS_SVD_TOL);
        }
    }

    #[test]
    fn degenerate_is_none() {
        assert!(rotation_maximizing_trace(&Matrix3::zeros()).is_none());
        let mut m = Matrix3::zeros();
        m[(0, 0)] = 1.0; // rank 1: rotation about x undetermined
        assert!(rotation_maximizing_trace(&m).is_none());
        assert!(rotation_maximizing_trace(&Matrix3::from_element(f64::NAN)).is_none());
    }
}
