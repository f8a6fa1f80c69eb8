//! Allocation-free twins of the reference metrics, for Monte Carlo hot loops: eq (33) against a
//! precomputed truth ([`ErotTruth`], [`e_rot_fast`]; equal to [`e_rot_zyz`](super::e_rot_zyz) to round-off, tested)
//! and all of one estimate's errors ([`TrialErrors`]).

use super::{e_rot, e_tran, geodesic_angle, ZYZ_SINGULAR_BAND_RAD};
use kinematics::euler::{wrap_angle, zyz_from_rotation};
use nalgebra::{Isometry3, Rotation3, Vector3};

/// Errors of one estimate of `b1_from_b2` against the truth (a Monte Carlo trial's metrics).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialErrors {
    /// eq (34): largest per-axis translation error, m.
    pub e_tran: f64,
    /// eq (33): largest ZYZ angle error (branch-matched, wrapped; at the floor–floor /
    /// floor–ceiling singularity max(tilt, |yaw error|), see [`e_rot_zyz`](super::e_rot_zyz)), rad.
    pub e_rot: f64,
    /// Geodesic angle between the true and estimated rotations, rad.
    pub geodesic: f64,
    /// Signed translation error `T_est − T_true`, m, b1 axes.
    pub translation_error: Vector3<f64>,
    /// Rotation error as a rotation vector of `R_est·R_trueᵀ`, rad, b1 axes.
    pub rotation_error: Vector3<f64>,
}

impl TrialErrors {
    /// Errors of `est` against `truth` (both `b1_from_b2`), with the reference metrics ([`e_tran`], [`e_rot`], [`geodesic_angle`]).
    pub fn between(truth: &Isometry3<f64>, est: &Isometry3<f64>) -> Self {
        TrialErrors {
            e_tran: e_tran(truth, est),
            e_rot: e_rot(truth, est),
            geodesic: geodesic_angle(truth, est),
            translation_error: est.translation.vector - truth.translation.vector,
            rotation_error: (est.rotation * truth.rotation.inverse()).scaled_axis(),
        }
    }

    /// As [`TrialErrors::between`] with the truth's eq 33 reading precomputed
    /// ([`ErotTruth::new`] of its eq 32 angles), allocation-free (e_rot by [`ErotTruth::e_rot`];
    /// the geodesic angle and rotation vector from one quaternion `atan2`); equal to it to
    /// round-off (tested).
    pub fn between_fast(
        truth: &Isometry3<f64>,
        erot_truth: &ErotTruth,
        est: &Isometry3<f64>,
    ) -> Self {
        let dt = est.translation.vector - truth.translation.vector;
        let dq = (est.rotation * truth.rotation.inverse()).into_inner();
        let (w, v) = if dq.w < 0.0 {
            (-dq.w, -dq.imag())
        } else {
            (dq.w, dq.imag())
        };
        let n = v.norm();
        let angle = 2.0 * n.atan2(w);
        TrialErrors {
            e_tran: dt.amax(),
            e_rot: erot_truth.e_rot(&est.rotation.to_rotation_matrix()),
            geodesic: angle,
            translation_error: dt,
            rotation_error: if n > 0.0 { v * (angle / n) } else { v * 2.0 },
        }
    }
}

/// The true rotation as [`e_rot_fast`] reads estimates against it (eq 33), precomputed once per
/// grid cell: the true ZYZ angles and, when they lie within [`ZYZ_SINGULAR_BAND_RAD`] of θ = 0 or
/// 180°, the true z axis and yaw (see [`e_rot_zyz`](super::e_rot_zyz)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErotTruth {
    /// True ZYZ angles `[φ, θ, ψ]`, rad, as given.
    zyz: [f64; 3],
    /// The same wrapped to (−π, π], for the regular reading.
    zyz_wrapped: [f64; 3],
    /// At the singularity: the reading's constants.
    singular: Option<SingularTruth>,
}

/// A true rotation at the ZYZ singularity, as eq 33 reads estimates against it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SingularTruth {
    /// θ near 0 (yaw `φ + ψ`) rather than near π (yaw `φ − ψ`).
    near_zero: bool,
    /// The true z axis (third column), b1.
    a: Vector3<f64>,
    /// `(cos, sin)` of the true yaw.
    yaw: (f64, f64),
}

impl ErotTruth {
    /// From the true ZYZ angles (rad, eq 32 or published).
    pub fn new(zyz_true: [f64; 3]) -> Self {
        let [phi, theta, psi] = zyz_true;
        let (st, ct) = theta.sin_cos();
        let singular = (st.abs() < ZYZ_SINGULAR_BAND_RAD.sin()).then(|| {
            let near_zero = ct > 0.0;
            let (sp, cp) = phi.sin_cos();
            let yaw = if near_zero { phi + psi } else { phi - psi };
            let (sy, cy) = yaw.sin_cos();
            SingularTruth {
                near_zero,
                a: Vector3::new(cp * st, sp * st, ct),
                yaw: (cy, sy),
            }
        });
        ErotTruth {
            zyz: zyz_true,
            zyz_wrapped: zyz_true.map(wrap_angle),
            singular,
        }
    }

    /// The true ZYZ angles, rad.
    pub fn zyz(&self) -> [f64; 3] {
        self.zyz
    }

    /// eq (33) of `r_est` against this truth, rad: [`e_rot_fast`].
    pub fn e_rot(&self, r_est: &Rotation3<f64>) -> f64 {
        let Some(t) = &self.singular else {
            return e_rot_regular(self.zyz_wrapped, r_est);
        };
        let m = r_est.matrix();
        // tilt = ∠(a_true, a_est) = atan2(|a_true × a_est|, a_true·a_est), accurate at any angle.
        let a = m.column(2);
        let (tilt_x, tilt_y) = (t.a.dot(&a), t.a.cross(&a).norm());
        // The estimate's yaw as a (cos, sin) pair scaled by 1 ± cos θ_est ≥ 0 (zero only for an
        // estimate flipped upside down, whose tilt is then 180° anyway):
        // R₀₀ + R₁₁ = (1 + cos θ)·cos(φ + ψ), R₁₀ − R₀₁ = (1 + cos θ)·sin(φ + ψ);
        // R₁₁ − R₀₀ = (1 − cos θ)·cos(φ − ψ), −(R₁₀ + R₀₁) = (1 − cos θ)·sin(φ − ψ).
        let (c, s) = if t.near_zero {
            (m[(0, 0)] + m[(1, 1)], m[(1, 0)] - m[(0, 1)])
        } else {
            (m[(1, 1)] - m[(0, 0)], -(m[(1, 0)] + m[(0, 1)]))
        };
        // An estimate exactly upside down has no yaw: read it as 0 like calib-core's atan2(0, 0).
        let (c, s) = if c == 0.0 && s == 0.0 {
            (1.0, 0.0)
        } else {
            (c, s)
        };
        // |wrap(yaw_est − yaw_true)| = atan2(yaw_y, yaw_x), the angle between the yaw directions.
        let (ct, st) = t.yaw;
        let (yaw_x, yaw_y) = (c * ct + s * st, (s * ct - c * st).abs());
        // Both angles are atan2(y, x) with y ≥ 0, in [0, π]: the larger one's vector lies
        // counter-clockwise of the other's (positive cross product), so only it is evaluated. On a
        // tie (parallel or opposite vectors, or NaN) both are, and the larger is returned.
        let ccw = yaw_x * tilt_y - yaw_y * tilt_x;
        if ccw > 0.0 {
            tilt_y.atan2(tilt_x)
        } else if ccw < 0.0 {
            yaw_y.atan2(yaw_x)
        } else {
            tilt_y.atan2(tilt_x).max(yaw_y.atan2(yaw_x))
        }
    }
}

/// eq (33) against true ZYZ angles `zyz_true` (rad), allocation-free; the same value as
/// [`e_rot_zyz`](super::e_rot_zyz) (tested), rad. At a true θ within [`ZYZ_SINGULAR_BAND_RAD`] of 0 or
/// 180°: `max(tilt of the z axis, |yaw error|)`; elsewhere the smallest, over the exact ZYZ
/// readings of `r_est` that [`zyz_nearest`](crate::zyz_nearest) chooses among, of the largest wrapped angle
/// difference. For many estimates against one truth, build the [`ErotTruth`] once.
pub fn e_rot_fast(zyz_true: [f64; 3], r_est: &Rotation3<f64>) -> f64 {
    ErotTruth::new(zyz_true).e_rot(r_est)
}

/// eq (33) on the nearest exact branch (both regular branches and, at `|sin θ_est| < 1e-9`, the
/// reference-anchored singular readings of [`zyz_nearest`](crate::zyz_nearest)), rad. `zyz_true` must be
/// wrapped to (−π, π] ([`ErotTruth::new`] does it), so that every difference below lies in
/// (−2π, 2π) and [`wrap_difference`] applies.
pub(crate) fn e_rot_regular(zyz_true: [f64; 3], r_est: &Rotation3<f64>) -> f64 {
    use std::f64::consts::PI;
    let [phi, theta, psi] = zyz_from_rotation(r_est);
    let diff = |a: [f64; 3]| -> f64 {
        let mut d: f64 = 0.0;
        for i in 0..3 {
            d = d.max(wrap_difference(a[i] - zyz_true[i]).abs());
        }
        d
    };
    // φ, ψ ∈ (−π, π] and θ ∈ [0, π] (eq 32), so φ + π, ψ + π ∈ (0, 2π].
    let mut best = diff([phi, theta, psi]).min(diff([
        wrap_difference(phi + PI),
        -theta,
        wrap_difference(psi + PI),
    ]));
    // |sin θ| < 1e-9 needs θ within 1e-6 of 0 or π: test that first and skip the sine otherwise.
    if !(1e-6..=PI - 1e-6).contains(&theta) && theta.sin().abs() < 1e-9 {
        let phi_n = zyz_true[0];
        let psi_n = if theta.cos() > 0.0 {
            phi + psi - phi_n
        } else {
            phi_n - (phi - psi)
        };
        for th in [theta, -theta] {
            best = best.min(diff([phi_n, th, wrap_difference(psi_n)]));
        }
    }
    best
}

/// [`wrap_angle`] for `x ∈ (−3π, 3π)` (sums and differences of angles in (−π, π]): one exact
/// add or subtract of 2π (exact by Sterbenz's lemma for `π ≤ |x| ≤ 4π`), no `fmod`. Equal to
/// [`wrap_angle`] up to its own round-off (it keeps tiny negative angles that `wrap_angle` rounds
/// to 0). Outside that range, or NaN, it defers to [`wrap_angle`].
#[inline]
pub(crate) fn wrap_difference(x: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if x > PI {
        if x < 3.0 * PI {
            x - TAU
        } else {
            wrap_angle(x)
        }
    } else if x <= -PI {
        if x > -3.0 * PI {
            x + TAU
        } else {
            wrap_angle(x)
        }
    } else {
        x // (−π, π], and NaN
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation_from_zyz;
    use nalgebra::{Translation3, UnitQuaternion};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::f64::consts::PI;

    /// Fast and reference paths compute the same maths: agreement to round-off (m, rad).
    const SAME_MATHS_TOL: f64 = 1e-9;

    #[test]
    fn e_rot_fast_matches_e_rot_zyz_including_singular_angles() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let deg = |a: [f64; 3]| a.map(f64::to_radians);
        // Table 1's cells (floor–floor, floor–wall, floor–ceiling), exactly at θ = 0 and 180°,
        // tiny angles either side, the band's edges (1°) and a regular truth next to them.
        let band = ZYZ_SINGULAR_BAND_RAD;
        let truths = [
            deg([-0.001, 0.001, -44.5]),
            deg([180.0, 89.874, -179.997]),
            deg([-135.0, 180.001, -135.0]),
            [0.0, 0.0, 0.0],
            [0.3, 0.0, -0.7],
            [0.3, 1e-12, -0.7],
            [0.3, -1e-9, 2.9],
            [0.0, PI, 0.0],
            [0.3, PI, -0.7],
            [-3.0, PI - 1e-12, 3.1],
            [1.0, -PI + 1e-9, 0.2],
            [0.2, 0.999 * band, -1.0],
            [0.2, PI - 0.999 * band, -1.0],
            [0.2, 1.001 * band, -1.0],
            [0.2, PI - 1.001 * band, -1.0],
        ];
        for zyz_true in truths {
            let r_true = rotation_from_zyz(zyz_true);
            let truth = ErotTruth::new(zyz_true);
            assert_eq!(truth.zyz(), zyz_true);
            for k in 0..300 {
                // Perturbations from 1e-12 rad (singular branch) to 1 rad, and exactly 0.
                let scale = if k == 299 { 0.0 } else { 10f64.powi(-(k % 13)) };
                let v = Vector3::new(
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                ) * scale;
                let r_est = Rotation3::new(v) * r_true;
                let a = e_rot_fast(zyz_true, &r_est);
                let b = super::super::e_rot_zyz(zyz_true, &r_est);
                assert!(
                    (a - b).abs() < SAME_MATHS_TOL,
                    "{zyz_true:?} {v:?}: {a} vs {b}"
                );
                assert_eq!(a, truth.e_rot(&r_est));
            }
            // A half turn about z (yaw error exactly 180°) and about x (estimate upside down).
            for axis in [Vector3::z_axis(), Vector3::x_axis()] {
                let r_est = Rotation3::from_axis_angle(&axis, PI) * r_true;
                let (a, b) = (
                    e_rot_fast(zyz_true, &r_est),
                    super::super::e_rot_zyz(zyz_true, &r_est),
                );
                assert!(
                    (a - b).abs() < SAME_MATHS_TOL,
                    "{zyz_true:?} {axis:?}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn wrap_difference_equals_wrap_angle() {
        use std::f64::consts::TAU;
        assert_eq!(wrap_difference(PI), PI);
        assert_eq!(wrap_difference(-PI), PI);
        assert_eq!(wrap_difference(TAU), 0.0);
        assert_eq!(wrap_difference(-1e-300), -1e-300); // wrap_angle rounds this to 0
        assert!(wrap_difference(f64::NAN).is_nan());
        let mut x: f64 = -12.0;
        while x < 12.0 {
            for y in [x, x + 4e-15, x - 4e-15] {
                let (a, b) = (wrap_difference(y), wrap_angle(y));
                assert!(a > -PI && a <= PI, "{y} -> {a}");
                // wrap_angle's own round-off: one ulp of 2π.
                assert!((a - b).abs() <= 1e-15, "{y}: {a} vs {b}");
            }
            x += PI / 64.0;
        }
    }

    proptest::proptest! {
        /// The allocation-free metrics equal the reference ones for any truth and estimate
        /// (tolerance: round-off, rad and m).
        #[test]
        fn fast_metrics_equal_the_reference(
            phi in -3.2f64..3.2, theta in 0.0f64..PI, psi in -3.2f64..3.2,
            ex in -0.5f64..0.5, ey in -0.5f64..0.5, ez in -0.5f64..0.5, scale_exp in 0i32..12,
            tx in -2.0f64..2.0,
        ) {
            let truth = Isometry3::from_parts(
                Translation3::new(tx, 0.3, -0.2),
                UnitQuaternion::from_rotation_matrix(&rotation_from_zyz([phi, theta, psi])),
            );
            let d = Vector3::new(ex, ey, ez) * 10f64.powi(-scale_exp);
            let est = Isometry3::from_parts(
                Translation3::new(tx + ex * 1e-3, 0.3, -0.2),
                UnitQuaternion::new(d) * truth.rotation,
            );
            let a = TrialErrors::between(&truth, &est);
            let zyz = zyz_from_rotation(&truth.rotation.to_rotation_matrix());
            let b = TrialErrors::between_fast(&truth, &ErotTruth::new(zyz), &est);
            proptest::prop_assert!((a.e_tran - b.e_tran).abs() < SAME_MATHS_TOL);
            proptest::prop_assert!((a.e_rot - b.e_rot).abs() < SAME_MATHS_TOL);
            proptest::prop_assert!((a.geodesic - b.geodesic).abs() < SAME_MATHS_TOL);
            proptest::prop_assert!((a.rotation_error - b.rotation_error).amax() < SAME_MATHS_TOL);
        }
    }
}
