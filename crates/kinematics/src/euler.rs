//! ZYZ Euler angles as used by the robot controllers (eqs 31/32 of Gan et al. 2014).
//!
//! Convention: `R = Rz(φ)·Ry(θ)·Rz(ψ)`, all angles in radians. [`zyz_from_rotation`] follows
//! eq 32 literally, so `θ ∈ [0, π]`, `φ, ψ ∈ (−π, π]`, and at the singularity (`a_x = a_y = 0`,
//! i.e. `θ = 0` or `θ = π`) it takes `φ = 0`. [`zyz_nearest`] returns, among all angle triples
//! that produce the same rotation, the one nearest a reference triple (the way the paper's Table 1
//! reads an estimate at the floor–floor / floor–ceiling singularity).

use nalgebra::{Rotation3, Vector3};
use std::f64::consts::{PI, TAU};

/// Wraps an angle (rad) into `(−π, π]`.
///
/// Non-finite input is returned unchanged (NaN stays NaN).
pub fn wrap_angle(a: f64) -> f64 {
    if !a.is_finite() {
        return a;
    }
    let mut w = a.rem_euclid(TAU); // [0, 2π)
    if w > PI {
        w -= TAU;
    }
    // rem_euclid can round up to exactly TAU for tiny negative input.
    if w <= -PI {
        w += TAU;
    }
    w
}

/// Rotation `Rz(φ)·Ry(θ)·Rz(ψ)` from ZYZ angles `[φ, θ, ψ]` in radians (eq 31).
pub fn rotation_from_zyz(zyz: [f64; 3]) -> Rotation3<f64> {
    let [phi, theta, psi] = zyz;
    Rotation3::from_axis_angle(&Vector3::z_axis(), phi)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), theta)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), psi)
}

/// ZYZ angles `[φ, θ, ψ]` (rad) of a rotation by eq 32 of the paper.
///
/// With `n, o, a` the columns of `r`: `φ = atan2(a_y, a_x)`,
/// `θ = atan2(cos φ·a_x + sin φ·a_y, a_z)`,
/// `ψ = atan2(−sin φ·n_x + cos φ·n_y, −sin φ·o_x + cos φ·o_y)`. When `a_x = a_y = 0`
/// (θ = 0 or π exactly) `φ = 0` and the whole in-plane angle goes to ψ.
/// Result: `θ ∈ [0, π]`, `φ, ψ ∈ (−π, π]`. Never panics; a non-finite matrix gives NaN angles.
pub fn zyz_from_rotation(r: &Rotation3<f64>) -> [f64; 3] {
    let m = r.matrix();
    let (nx, ny) = (m[(0, 0)], m[(1, 0)]);
    let (ox, oy) = (m[(0, 1)], m[(1, 1)]);
    let (ax, ay, az) = (m[(0, 2)], m[(1, 2)], m[(2, 2)]);
    let phi = if ax == 0.0 && ay == 0.0 {
        0.0
    } else {
        ay.atan2(ax)
    };
    let (s, c) = phi.sin_cos();
    let theta = (c * ax + s * ay).atan2(az);
    let psi = (-s * nx + c * ny).atan2(-s * ox + c * oy);
    [wrap_angle(phi), theta, wrap_angle(psi)]
}

/// Below this `sin θ` the split between φ and ψ is treated as free (only φ ± ψ is defined).
const SINGULAR_SIN_THETA: f64 = 1e-9;

/// ZYZ angles (rad) of `r` on the branch nearest `reference` (rad), every angle wrapped to `(−π, π]`.
///
/// A rotation has two regular ZYZ triples, `(φ, θ, ψ)` and `(φ+π, −θ, ψ+π)`; this returns the one
/// whose largest wrapped difference to `reference` is smallest. At the singularity
/// (`|sin θ| < 1e-9`) only `φ + ψ` (θ ≈ 0) or `φ − ψ` (θ ≈ π) is defined; there φ is set to the
/// reference's φ (eq 32 sets it to 0) and ψ carries the defined combination, so a pure yaw error
/// shows in full in ψ.
/// This is how an estimate's angles are read against the true angles in eq 33.
pub fn zyz_nearest(r: &Rotation3<f64>, reference: [f64; 3]) -> [f64; 3] {
    let [phi, theta, psi] = zyz_from_rotation(r);
    let diff = |a: [f64; 3]| -> f64 {
        (0..3)
            .map(|i| wrap_angle(a[i] - reference[i]).abs())
            .fold(0.0, f64::max)
    };
    let mut candidates: Vec<[f64; 3]> = vec![
        [phi, theta, psi],
        [wrap_angle(phi + PI), -theta, wrap_angle(psi + PI)],
    ];
    if theta.sin().abs() < SINGULAR_SIN_THETA {
        // θ near 0: R ≈ Rz(φ+ψ); θ near π: R ≈ Rz(φ−ψ)·Ry(π). Keep θ and the defined combination,
        // and anchor φ at the reference's φ (eq 32 anchors it at 0); ψ takes the rest. This is how
        // the paper's Table 1 reads an estimate at θ = 0 (e.g. experiment 1's e_rot2 = 0.093°).
        let near_zero = theta.cos() > 0.0;
        let phi_n = reference[0];
        let psi_n = if near_zero {
            phi + psi - phi_n
        } else {
            // Ry(−π) = Ry(π), so with θ → −θ the defined combination stays φ − ψ.
            phi_n - (phi - psi)
        };
        for th in [theta, -theta] {
            candidates.push([wrap_angle(phi_n), th, wrap_angle(psi_n)]);
        }
    }
    let mut best = candidates[0];
    let mut best_d = diff(best);
    for c in &candidates[1..] {
        let d = diff(*c);
        if d < best_d {
            best_d = d;
            best = *c;
        }
    }
    [best[0], wrap_angle(best[1]), best[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tolerance for rotation-matrix agreement after a round trip (pure round-off).
    const ROUND_TRIP_TOL: f64 = 1e-12;

    fn max_abs_diff(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
        (a.matrix() - b.matrix()).amax()
    }

    #[test]
    fn wrap_angle_range() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.1 - TAU) - 0.1).abs() < 1e-12);
        assert_eq!(wrap_angle(0.0), 0.0);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-15);
        assert!(wrap_angle(f64::NAN).is_nan());
        for k in -50..50 {
            let a = k as f64 * 0.37;
            let w = wrap_angle(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            assert!(((a - w) / TAU - ((a - w) / TAU).round()).abs() < 1e-9);
        }
    }

    #[test]
    fn round_trip_regular() {
        for &phi in &[-3.0, -1.0, 0.0, 0.4, 2.9] {
            for &theta in &[1e-6, 0.3, 1.5, 2.8, PI - 1e-6] {
                for &psi in &[-2.5, 0.0, 1.2, 3.1] {
                    let r = rotation_from_zyz([phi, theta, psi]);
                    let z = zyz_from_rotation(&r);
                    let back = rotation_from_zyz(z);
                    assert!(max_abs_diff(&r, &back) < ROUND_TRIP_TOL);
                    // Away from the singularity the angles themselves come back.
                    if theta > 1e-3 && theta < PI - 1e-3 {
                        assert!(wrap_angle(z[0] - phi).abs() < 1e-9, "{z:?}");
                        assert!((z[1] - theta).abs() < 1e-9);
                        assert!(wrap_angle(z[2] - psi).abs() < 1e-9);
                    }
                }
            }
        }
    }

    #[test]
    fn known_matrix_matches_eq31() {
        // Rz(90°)·Ry(90°): a = Rz(90)·x = y, so φ = 90°, θ = 90°, ψ = 0.
        let r = rotation_from_zyz([PI / 2.0, PI / 2.0, 0.0]);
        let m = r.matrix();
        assert!((m[(1, 2)] - 1.0).abs() < 1e-15); // a_y = 1
        let z = zyz_from_rotation(&r);
        assert!((z[0] - PI / 2.0).abs() < 1e-12);
        assert!((z[1] - PI / 2.0).abs() < 1e-12);
        assert!(z[2].abs() < 1e-12);
    }

    #[test]
    fn identity_and_exact_180() {
        let z = zyz_from_rotation(&Rotation3::identity());
        assert_eq!(z, [0.0, 0.0, 0.0]);
        // Exactly 180° about y: a = (0,0,-1).
        let r = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0,
        ));
        let z = zyz_from_rotation(&r);
        assert_eq!(z[0], 0.0);
        assert!((z[1] - PI).abs() < 1e-15);
        assert!(z[2].abs() < 1e-15);
        assert!(max_abs_diff(&r, &rotation_from_zyz(z)) < ROUND_TRIP_TOL);
        // 180° about y composed with a yaw: only φ − ψ defined.
        let r = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0,
        ));
        let z = zyz_from_rotation(&r);
        assert!((z[1] - PI).abs() < 1e-15);
        assert!(max_abs_diff(&r, &rotation_from_zyz(z)) < ROUND_TRIP_TOL);
        // Pure yaw at θ = 0.
        let r = rotation_from_zyz([0.0, 0.0, 0.7]);
        let z = zyz_from_rotation(&r);
        assert_eq!(z[1], 0.0);
        assert!((z[0] + z[2] - 0.7).abs() < 1e-12);
    }

    #[test]
    fn tiny_angles() {
        for &theta in &[1e-12, 1e-9, 1e-7, 1e-4] {
            let r = rotation_from_zyz([0.3, theta, -0.2]);
            let z = zyz_from_rotation(&r);
            assert!(max_abs_diff(&r, &rotation_from_zyz(z)) < ROUND_TRIP_TOL);
            assert!((z[1] - theta).abs() < 1e-12);
            let r = rotation_from_zyz([0.3, PI - theta, -0.2]);
            let z = zyz_from_rotation(&r);
            assert!(max_abs_diff(&r, &rotation_from_zyz(z)) < ROUND_TRIP_TOL);
        }
    }

    #[test]
    fn nearest_branch_at_singularity() {
        // Floor–ceiling style: true angles near θ = 180°, estimate a tenth of a degree off.
        let d = 0.1_f64.to_radians();
        let truth = [1.0, PI - 1e-12, 0.2];
        let est = rotation_from_zyz([1.0 + d, PI - d, 0.2 - d]);
        let z = zyz_nearest(&est, truth);
        assert!(max_abs_diff(&est, &rotation_from_zyz(z)) < 1e-9);
        let worst = (0..3)
            .map(|i| wrap_angle(z[i] - truth[i]).abs())
            .fold(0.0, f64::max);
        assert!(worst < 2.0 * d, "worst {worst} z {z:?}");
        // Wrap: −179.941° vs 180.001° is 0.058°.
        let truth = [PI - 1e-5, 0.5, 0.3];
        let est = rotation_from_zyz([-PI + 1e-3, 0.5, 0.3]);
        let z = zyz_nearest(&est, truth);
        assert!(wrap_angle(z[0] - truth[0]).abs() < 2e-3);
        // Second regular branch chosen when the reference sits there.
        let r = rotation_from_zyz([0.4, 1.0, -0.6]);
        let alt = [wrap_angle(0.4 + PI), -1.0, wrap_angle(-0.6 + PI)];
        let z = zyz_nearest(&r, alt);
        for i in 0..3 {
            assert!(wrap_angle(z[i] - alt[i]).abs() < 1e-9);
        }
        // Exactly singular estimate: φ anchored at the reference's, the yaw error in ψ.
        let z = zyz_nearest(&rotation_from_zyz([0.0, 0.0, 0.5]), [0.1, 1e-5, 0.3]);
        assert!((z[0] - 0.1).abs() < 1e-12 && z[1] == 0.0 && (z[2] - 0.4).abs() < 1e-12);
        // At θ = π the printed triple (0, π, 0.5) is already within 0.2 of this reference, nearer
        // than the φ-anchored reading (0.1, π, 0.6): the nearest one is returned.
        let z = zyz_nearest(&rotation_from_zyz([0.0, PI, 0.5]), [0.1, PI - 1e-5, 0.3]);
        assert!(z[0].abs() < 1e-12 && (z[2] - 0.5).abs() < 1e-12, "{z:?}");
        let z = zyz_nearest(&rotation_from_zyz([0.0, PI, 0.5]), [1.0, PI - 1e-5, 1.4]);
        assert!(
            (z[0] - 1.0).abs() < 1e-12 && (z[2] - 1.5).abs() < 1e-12,
            "{z:?}"
        );
        let back = rotation_from_zyz(z);
        assert!(max_abs_diff(&back, &rotation_from_zyz([0.0, PI, 0.5])) < ROUND_TRIP_TOL);
    }
}
