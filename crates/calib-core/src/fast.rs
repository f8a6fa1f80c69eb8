//! Allocation-free registration kernels for Monte Carlo (no diagnostics, no uncertainty).
//!
//! The core is [`rotation_maximizing_trace`]: the rotation `R` maximising `tr(Rᵀ·M)` for a 3×3
//! matrix `M`. That is both the Frobenius-nearest rotation of `M` (`‖R − M‖²_F = const − 2·tr(RᵀM)`)
//! and the rigid least-squares rotation when `M` is the cross-covariance `Σ (p1 − c1)(p2 − c2)ᵀ`.
//! It is solved by Horn's quaternion method: the maximising unit quaternion is the eigenvector of the
//! largest eigenvalue of a symmetric traceless 4×4 matrix `N(M)`. The eigenvalue is found by Newton's
//! method on the characteristic quartic `λ⁴ − 2‖M‖²_F·λ² − 8·det(M)·λ + det(N)` (Theobald's QCP),
//! started at `√3·‖M‖_F`, an upper bound of the largest root that is tight when `M` is near a scaled
//! rotation (the usual case: 1–3 iterations), and the eigenvector as the largest column of the
//! adjugate of `N − λI`. The result matches the SVD polar factor ([`crate::nearest_rotation`]) to
//! round-off (tested).

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
    let n = horn_matrix(m);
    let fro2 = m.norm_squared();
    if !fro2.is_finite() || fro2 == 0.0 {
        return None;
    }
    // Characteristic polynomial of traceless symmetric N: λ⁴ + c2·λ² + c1·λ + c0, with
    // c2 = −tr(N²)/2 = −2‖M‖²_F, c1 = −tr(N³)/3 = −8·det(M), c0 = det(N) (tested against the traces).
    let c2 = -2.0 * fro2;
    let c1 = -8.0 * m.determinant();
    let c0 = det4(&n);
    // The eigenvalues of N are ±s1 ± s2 ± d·s3 (s the singular values of M, d = sign det M), so the
    // largest is ≤ s1 + s2 + s3 ≤ √3·‖M‖_F; Newton from above the largest root of a real-rooted
    // polynomial decreases monotonically onto it.
    let mut lambda = (3.0 * fro2).sqrt();
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
    let adj = adjugate4(&a);
    let mut best_col = 0;
    let mut best_norm = -1.0;
    for col in 0..4 {
        let nq = adj.column(col).norm_squared();
        if nq > best_norm {
            best_norm = nq;
            best_col = col;
        }
    }
    let scale = fro2 * fro2 * fro2; // adjugate entries scale like ‖M‖³, squared → ‖M‖⁶
    if best_norm.partial_cmp(&(DEGENERATE_REL * scale)) != Some(std::cmp::Ordering::Greater)
        || !best_norm.is_finite()
    {
        return None;
    }
    let q = adj.column(best_col);
    Some(UnitQuaternion::from_quaternion(Quaternion::new(
        q[0], q[1], q[2], q[3],
    )))
}

/// Horn's symmetric traceless 4×4 matrix `N(M)`: `qᵀ·N·q = tr(R(q)ᵀ·M)` for unit quaternions
/// `q = (w, x, y, z)`.
fn horn_matrix(m: &Matrix3<f64>) -> Matrix4<f64> {
    // Horn's S_ab = Σ x2_a · x1_b = Mᵀ (rotating set 2 onto set 1).
    let (sxx, sxy, sxz) = (m[(0, 0)], m[(1, 0)], m[(2, 0)]);
    let (syx, syy, syz) = (m[(0, 1)], m[(1, 1)], m[(2, 1)]);
    let (szx, szy, szz) = (m[(0, 2)], m[(1, 2)], m[(2, 2)]);
    Matrix4::new(
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
    )
}

/// The 2×2 minors of rows (0, 1) (`s`) and rows (2, 3) (`c`) of a 4×4 matrix, in the order of
/// the Laplace expansion of the determinant by complementary minors:
/// `det = s0·c5 − s1·c4 + s2·c3 + s3·c2 − s4·c1 + s5·c0`.
fn minors4(m: &Matrix4<f64>) -> ([f64; 6], [f64; 6]) {
    let s = [
        m[(0, 0)] * m[(1, 1)] - m[(1, 0)] * m[(0, 1)],
        m[(0, 0)] * m[(1, 2)] - m[(1, 0)] * m[(0, 2)],
        m[(0, 0)] * m[(1, 3)] - m[(1, 0)] * m[(0, 3)],
        m[(0, 1)] * m[(1, 2)] - m[(1, 1)] * m[(0, 2)],
        m[(0, 1)] * m[(1, 3)] - m[(1, 1)] * m[(0, 3)],
        m[(0, 2)] * m[(1, 3)] - m[(1, 2)] * m[(0, 3)],
    ];
    let c = [
        m[(2, 0)] * m[(3, 1)] - m[(3, 0)] * m[(2, 1)],
        m[(2, 0)] * m[(3, 2)] - m[(3, 0)] * m[(2, 2)],
        m[(2, 0)] * m[(3, 3)] - m[(3, 0)] * m[(2, 3)],
        m[(2, 1)] * m[(3, 2)] - m[(3, 1)] * m[(2, 2)],
        m[(2, 1)] * m[(3, 3)] - m[(3, 1)] * m[(2, 3)],
        m[(2, 2)] * m[(3, 3)] - m[(3, 2)] * m[(2, 3)],
    ];
    (s, c)
}

/// Determinant of a 4×4 matrix by 2×2 minors (Laplace on the top two rows).
fn det4(m: &Matrix4<f64>) -> f64 {
    let (s, c) = minors4(m);
    s[0] * c[5] - s[1] * c[4] + s[2] * c[3] + s[3] * c[2] - s[4] * c[1] + s[5] * c[0]
}

/// Adjugate of a 4×4 matrix (`adj(A)·A = det(A)·I`) from its 2×2 minors ([`minors4`]).
fn adjugate4(a: &Matrix4<f64>) -> Matrix4<f64> {
    let (s, c) = minors4(a);
    let e = |i: usize, j: usize| a[(i, j)];
    Matrix4::new(
        e(1, 1) * c[5] - e(1, 2) * c[4] + e(1, 3) * c[3],
        -e(0, 1) * c[5] + e(0, 2) * c[4] - e(0, 3) * c[3],
        e(3, 1) * s[5] - e(3, 2) * s[4] + e(3, 3) * s[3],
        -e(2, 1) * s[5] + e(2, 2) * s[4] - e(2, 3) * s[3],
        -e(1, 0) * c[5] + e(1, 2) * c[2] - e(1, 3) * c[1],
        e(0, 0) * c[5] - e(0, 2) * c[2] + e(0, 3) * c[1],
        -e(3, 0) * s[5] + e(3, 2) * s[2] - e(3, 3) * s[1],
        e(2, 0) * s[5] - e(2, 2) * s[2] + e(2, 3) * s[1],
        e(1, 0) * c[4] - e(1, 1) * c[2] + e(1, 3) * c[0],
        -e(0, 0) * c[4] + e(0, 1) * c[2] - e(0, 3) * c[0],
        e(3, 0) * s[4] - e(3, 1) * s[2] + e(3, 3) * s[0],
        -e(2, 0) * s[4] + e(2, 1) * s[2] - e(2, 3) * s[0],
        -e(1, 0) * c[3] + e(1, 1) * c[1] - e(1, 2) * c[0],
        e(0, 0) * c[3] - e(0, 1) * c[1] + e(0, 2) * c[0],
        -e(3, 0) * s[3] + e(3, 1) * s[1] - e(3, 2) * s[0],
        e(2, 0) * s[3] - e(2, 1) * s[1] + e(2, 2) * s[0],
    )
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
/// Returns `(M, t_H)`: H's 3×3 block and its translation column. `None` if B is singular
/// (coplanar points) or H is not finite.
///
/// Computed without the 4×4 inverse: H maps each `p2_k` to `p1_k`, so with the edge matrices
/// `D1 = [p1_2 − p1_1, p1_3 − p1_1, p1_4 − p1_1]` and `D2` likewise, `M·D2 = D1`, hence
/// `M = D1·D2⁻¹` and `t_H = p1_1 − M·p2_1` (`|det B| = |det D2|`, so B is singular exactly when
/// D2 is). Same solution as the 4×4 solve, to round-off (tested).
pub fn affine_4point(
    p_b1: &[Point3<f64>; 4],
    p_b2: &[Point3<f64>; 4],
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let edges =
        |p: &[Point3<f64>; 4]| Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    let d2_inv = edges(p_b2).try_inverse()?;
    let m = edges(p_b1) * d2_inv;
    let t = p_b1[0].coords - m * p_b2[0].coords;
    (m.iter().chain(t.iter()).all(|v| v.is_finite())).then_some((m, t))
}

/// eq (12): `T = (1/n)·Σ (p1_i − R·p2_i)`, evaluated as `c1 − R·c2` (c the centroids; the same
/// sum regrouped, one rotation instead of n).
fn translation_eq12(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
    q: &UnitQuaternion<f64>,
) -> Vector3<f64> {
    let n = p_b1.len() as f64;
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        c1 += a.coords;
        c2 += b.coords;
    }
    c1 / n - q * (c2 / n)
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

    /// Deterministic uniform numbers in [−1, 1) for the tests.
    fn lcg(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// The closed-form quartic coefficients equal the trace formulas, the adjugate satisfies
    /// `adj(A)·A = det(A)·I`, and `qᵀNq = tr(R(q)ᵀM)` (tolerances: round-off on O(1) entries).
    #[test]
    fn quartic_coefficients_adjugate_and_horn_matrix() {
        let mut next = lcg(777);
        for _ in 0..200 {
            let m = Matrix3::from_fn(|_, _| next());
            let n = horn_matrix(&m);
            let n2 = n * n;
            assert!((-0.5 * n2.trace() - (-2.0 * m.norm_squared())).abs() < 1e-12);
            assert!((-(n2 * n).trace() / 3.0 - (-8.0 * m.determinant())).abs() < 1e-12);
            assert!((det4(&n) - n.determinant()).abs() < 1e-12);
            let a = Matrix4::from_fn(|_, _| next());
            let lhs = adjugate4(&a) * a;
            assert!((lhs - Matrix4::identity() * a.determinant()).amax() < 1e-12);
            let q =
                UnitQuaternion::from_quaternion(Quaternion::new(next(), next(), next(), next()));
            let qv = q.coords; // (x, y, z, w)
            let qv = nalgebra::Vector4::new(qv[3], qv[0], qv[1], qv[2]);
            let r = q.to_rotation_matrix();
            assert!(
                ((qv.transpose() * n * qv)[0] - (r.matrix().transpose() * m).trace()).abs() < 1e-12
            );
        }
    }

    /// The 4-point affine solve by edge matrices equals `H = A·B⁻¹` with the 4×4 inverse (relative
    /// round-off on metre-scale points), and coplanar points give `None`.
    #[test]
    fn affine_4point_equals_the_4x4_solve() {
        let mut next = lcg(4242);
        for _ in 0..200 {
            let p1: [Point3<f64>; 4] = std::array::from_fn(|_| Point3::new(next(), next(), next()));
            let p2: [Point3<f64>; 4] = std::array::from_fn(|_| {
                Point3::new(next(), next(), next()) + Vector3::new(1.5, 0.5, 1.5)
            });
            let (m, t) = affine_4point(&p1, &p2).unwrap();
            let mut a = Matrix4::zeros();
            let mut b = Matrix4::zeros();
            for k in 0..4 {
                for r in 0..3 {
                    a[(r, k)] = p1[k][r];
                    b[(r, k)] = p2[k][r];
                }
                a[(3, k)] = 1.0;
                b[(3, k)] = 1.0;
            }
            let h = a * b.try_inverse().unwrap();
            // Random point sets can be ill-conditioned; scale the tolerance by the condition.
            let tol = 1e-12 * h.amax().max(1.0) * b.try_inverse().unwrap().amax().max(1.0);
            assert!((h.fixed_view::<3, 3>(0, 0) - m).amax() < tol, "{h} {m}");
            assert!((h.fixed_view::<3, 1>(0, 3) - t).amax() < tol);
        }
        let flat: [Point3<f64>; 4] = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        assert!(affine_4point(&flat, &flat).is_none());
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
