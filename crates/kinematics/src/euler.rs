//! ZYZ Euler angles as used by the robot controllers (eqs 31/32 of Gan et al. 2014).
//!
//! Convention: `R = Rz(φ)·Ry(θ)·Rz(ψ)`, all angles in radians. [`zyz_from_rotation`] follows
//! eq 32 literally, so `θ ∈ [0, π]`, `φ, ψ ∈ (−π, π]`, and at the singularity (`a_x = a_y = 0`,
//! i.e. `θ = 0` or `θ = π`) it takes `φ = 0`. [`zyz_nearest`] returns, among all angle triples
//! that produce the same rotation, the one nearest a reference triple (the way the paper's Table 1
//! reads an estimate at the floor–floor / floor–ceiling singularity). [`zyz_canonical`] is what
//! files and reports write: a tilt below [`ZYZ_CANONICAL_TILT_RAD`] is written as a pure yaw
//! with `φ = 0`.

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

/// Tilt (rad) below which [`zyz_canonical`] writes a rotation as a pure yaw: `θ` within this of
/// 0 or π. 1e-8 rad is 10 nm per metre of lever, far below what any robot, tracker or
/// calibration here resolves (a laser tracker's angular uncertainty is ~6e-6 rad), and above
/// the tilts a fit leaves on a placement held at the identity (measured 5e-11–2e-9 rad on the
/// CTU cells), whose φ would otherwise print as an arbitrary angle with ψ ≈ −φ.
pub const ZYZ_CANONICAL_TILT_RAD: f64 = 1e-8;

/// ZYZ angles `[φ, θ, ψ]` (rad) of `r` as files and reports write them: [`zyz_from_rotation`],
/// except that a tilt within [`ZYZ_CANONICAL_TILT_RAD`] of θ = 0 or θ = π, where φ and ψ are
/// degenerate (only φ + ψ, resp. φ − ψ, is defined; a near-identity would print as e.g.
/// `[1.34°, 0°, −1.34°]`), is written canonically: `θ = 0` (resp. π) exactly, `φ = 0`, and ψ
/// carries the defined angle (`φ + ψ`, resp. `ψ − φ`), wrapped to `(−π, π]`.
///
/// The canonical triple reproduces `r` to within its dropped tilt, i.e. to a rotation angle
/// below [`ZYZ_CANONICAL_TILT_RAD`]; elsewhere the result is exactly [`zyz_from_rotation`]'s.
/// Never panics; a non-finite matrix gives NaN angles.
pub fn zyz_canonical(r: &Rotation3<f64>) -> [f64; 3] {
    zyz_canonical_within(r, ZYZ_CANONICAL_TILT_RAD)
}

/// [`zyz_canonical`] with a wider singular band: a tilt within `tilt_rad` (rad; never narrower
/// than [`ZYZ_CANONICAL_TILT_RAD`]) of θ = 0 or θ = π is written as a pure yaw `[0, 0, φ + ψ]`
/// (resp. `[0, π, ψ − φ]`). What a text report prints: a tilt below the printed resolution,
/// or below its posterior σ, leaves φ and ψ each meaningless (a near-identity printed as
/// `[48.3°, 0.0008°, −48.3°]`), while their combination is well defined.
///
/// The triple reproduces `r` to within the dropped tilt (a rotation angle below
/// `max(tilt_rad, ZYZ_CANONICAL_TILT_RAD)`, plus round-off); outside the band it is exactly
/// [`zyz_from_rotation`]'s. Never panics; a non-finite matrix gives NaN angles.
pub fn zyz_canonical_within(r: &Rotation3<f64>, tilt_rad: f64) -> [f64; 3] {
    let band = if tilt_rad.is_finite() {
        tilt_rad.max(ZYZ_CANONICAL_TILT_RAD)
    } else {
        ZYZ_CANONICAL_TILT_RAD
    };
    let [phi, theta, psi] = zyz_from_rotation(r);
    if theta < band {
        // Rz(φ)·Ry(θ)·Rz(ψ) → Rz(φ + ψ) as θ → 0.
        [0.0, 0.0, wrap_angle(phi + psi)]
    } else if PI - theta < band {
        // Rz(φ)·Ry(π)·Rz(ψ) = Ry(π)·Rz(ψ − φ), since Rz(φ)·Ry(π) = Ry(π)·Rz(−φ).
        [0.0, PI, wrap_angle(psi - phi)]
    } else {
        [phi, theta, psi]
    }
}

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

    /// The rotation angle between two rotations, rad, accurate for tiny angles (2·atan2 of the
    /// quaternion's vector and scalar parts; `acos` of the trace loses ~1e-8 rad near 0).
    fn angle_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
        let q = nalgebra::UnitQuaternion::from_rotation_matrix(&a.rotation_to(b));
        2.0 * q.vector().norm().atan2(q.scalar().abs())
    }

    #[test]
    fn canonical_near_identity_is_a_pure_yaw_with_phi_zero() {
        // The reported case: a fitted placement 2e-9 rad from the identity read as
        // [1.34°, 1.1e-7°, −1.34°] by eq 32.
        let r = rotation_from_zyz([1.34f64.to_radians(), 2e-9, (-1.3353f64).to_radians()]);
        let raw = zyz_from_rotation(&r);
        assert!(
            raw[0].to_degrees() > 1.0,
            "eq 32 keeps the degenerate φ: {raw:?}"
        );
        let z = zyz_canonical(&r);
        assert_eq!((z[0], z[1]), (0.0, 0.0));
        assert!(
            (z[2] - (1.34f64 - 1.3353).to_radians()).abs() < 1e-12,
            "{z:?}"
        );
        assert!(angle_between(&rotation_from_zyz(z), &r) < ZYZ_CANONICAL_TILT_RAD);
        // The exact identity and an exact yaw are unchanged.
        assert_eq!(zyz_canonical(&Rotation3::identity()), [0.0, 0.0, 0.0]);
        let yaw = rotation_from_zyz([0.0, 0.0, -0.7]);
        assert_eq!(zyz_canonical(&yaw), zyz_from_rotation(&yaw));
    }

    #[test]
    fn canonical_near_180_keeps_the_defined_difference() {
        for &tilt in &[0.0, 1e-12, 5e-9] {
            let r = rotation_from_zyz([0.9, PI - tilt, -0.4]);
            let z = zyz_canonical(&r);
            assert_eq!((z[0], z[1]), (0.0, PI), "{z:?}");
            assert!(wrap_angle(z[2] - (-0.4 - 0.9)).abs() < 1e-9, "{z:?}");
            // Tolerance: the dropped tilt plus round-off.
            assert!(angle_between(&rotation_from_zyz(z), &r) < tilt + 1e-12);
        }
    }

    #[test]
    fn canonical_is_eq32_outside_the_band() {
        for &theta in &[2e-8, 1e-4, 1.0, PI - 2e-8] {
            let r = rotation_from_zyz([0.3, theta, -0.2]);
            assert_eq!(zyz_canonical(&r), zyz_from_rotation(&r), "θ = {theta}");
        }
    }

    proptest::proptest! {
        /// With a wider band the canonical triple is still the same rotation to within the
        /// dropped tilt (below the band), and exactly eq 32's outside it; φ = 0 on the band.
        #[test]
        fn canonical_within_a_band_gives_the_same_rotation(
            phi in -4.0..4.0f64, psi in -4.0..4.0f64,
            band in 1e-8..1e-2f64,
            theta in proptest::prop_oneof![
                -2e-2..2e-2f64,
                0.0..std::f64::consts::PI,
                (std::f64::consts::PI - 2e-2)..(std::f64::consts::PI + 2e-2),
            ],
        ) {
            let r = rotation_from_zyz([phi, theta, psi]);
            let z = zyz_canonical_within(&r, band);
            // Round-off of the matrix products and of the extraction on unit matrices.
            const ROUND_OFF_RAD: f64 = 1e-12;
            let d = angle_between(&rotation_from_zyz(z), &r);
            let tilt = zyz_from_rotation(&r)[1];
            if tilt < band || PI - tilt < band {
                proptest::prop_assert_eq!(z[0], 0.0);
                proptest::prop_assert!(z[1] == 0.0 || z[1] == PI);
                proptest::prop_assert!(d <= tilt.min(PI - tilt) + ROUND_OFF_RAD, "{z:?}: {d}");
            } else {
                proptest::prop_assert_eq!(z, zyz_from_rotation(&r));
                proptest::prop_assert!(d <= ROUND_OFF_RAD, "{z:?}: {d}");
            }
        }

        /// The canonical triple is the same rotation: within the dropped tilt (< 1e-8 rad) in the
        /// singular band, within round-off elsewhere; φ = 0 whenever θ is 0 or π; θ ∈ [0, π].
        #[test]
        fn canonical_form_gives_the_same_rotation(
            phi in -4.0..4.0f64, psi in -4.0..4.0f64,
            theta in proptest::prop_oneof![
                -1e-8..1e-8f64,
                0.0..std::f64::consts::PI,
                (std::f64::consts::PI - 1e-8)..(std::f64::consts::PI + 1e-8),
            ],
        ) {
            let r = rotation_from_zyz([phi, theta, psi]);
            let z = zyz_canonical(&r);
            let back = rotation_from_zyz(z);
            // Round-off of the matrix products and of the extraction on unit matrices.
            const ROUND_OFF_RAD: f64 = 1e-12;
            let tilt = theta.sin().abs();
            let bound = if tilt < 2.0 * ZYZ_CANONICAL_TILT_RAD { tilt + ROUND_OFF_RAD } else { ROUND_OFF_RAD };
            proptest::prop_assert!(angle_between(&back, &r) <= bound, "{z:?}");
            proptest::prop_assert!(z[1] >= 0.0 && z[1] <= PI);
            if z[1] == 0.0 || z[1] == PI {
                proptest::prop_assert_eq!(z[0], 0.0);
            }
            proptest::prop_assert!(z[0] > -PI && z[0] <= PI && z[2] > -PI && z[2] <= PI);
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
