//! Error metrics between a true and an estimated `b1_from_b2` (eqs 33/34) and the geodesic angle.

use kinematics::euler::{wrap_angle, zyz_from_rotation, zyz_nearest};
use nalgebra::{Isometry3, Rotation3};

/// eq (34): `e_tran = ‖T_true − T_est‖_∞`, m (largest per-axis translation difference).
pub fn e_tran(b1_from_b2_true: &Isometry3<f64>, est: &Isometry3<f64>) -> f64 {
    (b1_from_b2_true.translation.vector - est.translation.vector).amax()
}

/// eq (33): `e_rot = ‖Euler(R_true) − Euler(R_est)‖_∞`, rad, with ZYZ angles. The true angles are
/// read by eq (32); the estimate's on the branch nearest them ([`zyz_nearest`]), and each difference
/// is wrapped to (−π, π]. This is what keeps the metric meaningful at θ ≈ 0° / 180°.
pub fn e_rot(b1_from_b2_true: &Isometry3<f64>, est: &Isometry3<f64>) -> f64 {
    let r_true = b1_from_b2_true.rotation.to_rotation_matrix();
    let r_est = est.rotation.to_rotation_matrix();
    e_rot_zyz(zyz_from_rotation(&r_true), &r_est)
}

/// eq (33) against given true ZYZ angles (rad), e.g. as published: the estimate's angles are read on
/// the branch nearest `zyz_true`, differences wrapped to (−π, π], the largest absolute one returned (rad).
pub fn e_rot_zyz(zyz_true: [f64; 3], r_est: &Rotation3<f64>) -> f64 {
    let z = zyz_nearest(r_est, zyz_true);
    (0..3)
        .map(|i| wrap_angle(z[i] - zyz_true[i]).abs())
        .fold(0.0, f64::max)
}

/// eq (33) on two angle triples as given (rad), no re-reading: the largest wrapped difference.
pub fn e_rot_raw(zyz_true: [f64; 3], zyz_est: [f64; 3]) -> f64 {
    (0..3)
        .map(|i| wrap_angle(zyz_est[i] - zyz_true[i]).abs())
        .fold(0.0, f64::max)
}

/// Geodesic rotation angle `|log(R_trueᵀ·R_est)|`, rad, in [0, π].
pub fn geodesic_angle(b1_from_b2_true: &Isometry3<f64>, est: &Isometry3<f64>) -> f64 {
    b1_from_b2_true.rotation.angle_to(&est.rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::euler::rotation_from_zyz;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    fn iso(xyz: [f64; 3], zyz: [f64; 3]) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(xyz[0], xyz[1], xyz[2]),
            UnitQuaternion::from_rotation_matrix(&rotation_from_zyz(zyz)),
        )
    }

    #[test]
    fn e_tran_is_inf_norm() {
        let a = iso([0.0, 0.0, 0.0], [0.0; 3]);
        let b = iso([0.001, -0.004, 0.002], [0.0; 3]);
        assert!((e_tran(&a, &b) - 0.004).abs() < 1e-15);
    }

    #[test]
    fn e_rot_at_singularity_is_small_and_geodesic_agrees() {
        let d = 0.1f64.to_radians();
        let truth = iso([0.0; 3], [-1e-5, 1e-5, -0.78]);
        let est = iso([0.0; 3], [0.0, -d, -0.78 - d / 2.0]);
        let e = e_rot(&truth, &est);
        assert!(e < 1.5 * d, "e_rot = {} deg", e.to_degrees());
        let g = geodesic_angle(&truth, &est);
        assert!(g < 1.5 * d && g > 0.5 * d);
        // Rotation about a fixed axis: geodesic equals the angle.
        let a = Isometry3::rotation(Vector3::new(0.0, 0.0, 0.3));
        let b = Isometry3::rotation(Vector3::new(0.0, 0.0, 0.5));
        assert!((geodesic_angle(&a, &b) - 0.2).abs() < 1e-12);
        assert!((e_rot(&a, &b) - 0.2).abs() < 1e-12);
    }

    #[test]
    fn e_rot_wraps_at_180() {
        let t = [179.941f64.to_radians(), 90f64.to_radians(), 0.0];
        let r = rotation_from_zyz([(-179.999f64).to_radians(), 90f64.to_radians(), 0.0]);
        let e = e_rot_zyz(t, &r).to_degrees();
        assert!((e - 0.06).abs() < 1e-9, "{e}");
        assert!(
            (e_rot_raw(t, [(-179.999f64).to_radians(), t[1], 0.0]).to_degrees() - 0.06).abs()
                < 1e-9
        );
    }

    proptest::proptest! {
        /// eq 31/32 round trip and the branch reading return the same rotation for any angles,
        /// including θ near 0 and π; a rotation's e_rot and geodesic angle to itself are zero
        /// (tolerances: round-off on unit matrices).
        #[test]
        fn zyz_round_trip_and_self_error_zero(
            phi in -4.0..4.0f64, theta in -0.01..3.16f64, psi in -4.0..4.0f64,
            rphi in -3.2..3.2f64, rtheta in -3.2..3.2f64, rpsi in -3.2..3.2f64,
        ) {
            let r = rotation_from_zyz([phi, theta, psi]);
            let z = zyz_from_rotation(&r);
            proptest::prop_assert!((rotation_from_zyz(z).matrix() - r.matrix()).amax() < 1e-12);
            proptest::prop_assert!(z[1] >= 0.0 && z[1] <= std::f64::consts::PI);
            let zn = zyz_nearest(&r, [rphi, rtheta, rpsi]);
            proptest::prop_assert!((rotation_from_zyz(zn).matrix() - r.matrix()).amax() < 1e-8);
            let x = iso([0.1, 0.2, 0.3], [phi, theta, psi]);
            proptest::prop_assert!(e_rot(&x, &x) < 1e-7);
            proptest::prop_assert!(geodesic_angle(&x, &x) < 1e-7);
            proptest::prop_assert!(e_tran(&x, &x) == 0.0);
        }
    }
}
