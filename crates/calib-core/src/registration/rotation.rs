//! The rotation maximising `tr(Rᵀ·M)` for a 3×3 matrix `M`: the Frobenius-nearest rotation of `M`
//! (`‖R − M‖²_F = const − 2·tr(RᵀM)`, eqs 1–3) and the rigid least-squares rotation when `M` is the
//! cross-covariance `Σ (p1 − c1)(p2 − c2)ᵀ`. Two solvers:
//! - [`nearest_rotation`]: SVD `M = U·Σ·Vᵀ`, `R = U·diag(1, 1, det(U·Vᵀ))·Vᵀ`;
//! - [`rotation_maximizing_trace`]: Horn's quaternion method, allocation-free. The maximising unit
//!   quaternion is the eigenvector of the largest eigenvalue of a symmetric traceless 4×4 matrix
//!   `N(M)`. The eigenvalue is found by Newton's method on the characteristic quartic
//!   `λ⁴ − 2‖M‖²_F·λ² − 8·det(M)·λ + det(N)` (Theobald's QCP), started at `√3·‖M‖_F`, an upper bound
//!   of the largest root that is tight when `M` is near a scaled rotation (1–3 iterations), and the
//!   eigenvector as the largest column of the adjugate of `N − λI`. Both agree to round-off (tested).

use nalgebra::{Matrix3, Matrix4, Quaternion, Rotation3, UnitQuaternion};

/// The rotation nearest `m` in the Frobenius norm: `argmin ‖R − M‖_F` over `RᵀR = I, det R = +1`
/// (eqs 1–3). SVD `M = U·Σ·Vᵀ`, `R = U·diag(1, 1, det(U·Vᵀ))·Vᵀ` (the determinant guard avoids a
/// reflection). For rank(M) ≤ 1 the minimiser is not unique and one of them is returned; non-finite
/// input returns the identity.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    if !m.iter().all(|v| v.is_finite()) {
        return Rotation3::identity();
    }
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Rotation3::identity();
    };
    let d = (u * v_t).determinant();
    let mut s = Matrix3::identity();
    if d < 0.0 {
        s[(2, 2)] = -1.0;
    }
    Rotation3::from_matrix_unchecked(u * s * v_t)
}

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

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use nalgebra::Vector3;

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
    pub(in crate::registration) fn lcg(seed: u64) -> impl FnMut() -> f64 {
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

    #[test]
    fn degenerate_is_none() {
        assert!(rotation_maximizing_trace(&Matrix3::zeros()).is_none());
        let mut m = Matrix3::zeros();
        m[(0, 0)] = 1.0; // rank 1: rotation about x undetermined
        assert!(rotation_maximizing_trace(&m).is_none());
        assert!(rotation_maximizing_trace(&Matrix3::from_element(f64::NAN)).is_none());
    }
}
