//! Installation-constrained least squares with a soft mount: the tilt is uncertain.
//!
//! The mounts say the relative tilt between the two bases is zero (e.g. both level), but a real floor
//! or pedestal is off by a fraction of a degree. This fit treats the constraint as a Gaussian prior:
//!
//! `min Σ ‖p1ᵢ − X·p2ᵢ‖²/σ_p² + ‖P·ω‖²/σ_t²`, `X = Translation(t)·Rotation(ω)·X₀`,
//!
//! where X₀ is the hard [`crate::constrained_lsq`] solution, ω (rad, b1 axes) the rotation away from
//! it, and P projects ω onto the directions the family forbids (for a yaw family the two tilt
//! directions orthogonal to the gravity axis; for the wall family the direction normal to both free
//! axes). Solved by Gauss–Newton. σ_t → ∞ gives rigid least squares, σ_t → 0 the hard constraint.

use crate::error::CalibError;
use crate::points::PointPairs;
use crate::registration::{
    build_uncertainty, constrained_lsq, family_axes, fill_fit_jacobian, residuals,
    ConstrainedOptions, Fit, Method, MountPair,
};
use crate::stop::StopReason;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Matrix6, Vector3};

/// Gauss–Newton iterations cap (the problem is nearly linear; 3–5 suffice).
const SOFT_MAX_ITER: usize = 20;
/// Stop when the update is below this, rad or m.
const SOFT_STEP_TOL: f64 = 1e-13;

/// Result of [`constrained_soft`].
#[derive(Debug, Clone, PartialEq)]
pub struct SoftFit {
    /// The fit (method `constrained`); its uncertainty is the posterior covariance with the given σ_p.
    pub fit: Fit,
    /// Estimated relative tilt away from the mount family: `P·ω`, rad, b1 axes.
    pub tilt_rad: Vector3<f64>,
    /// Magnitude of [`SoftFit::tilt_rad`], rad.
    pub tilt_angle_rad: f64,
    /// Gauss–Newton iterations used.
    pub iterations: usize,
    /// Why Gauss–Newton stopped: [`StopReason::StepTooSmall`] (update below 1e-13 rad or m),
    /// [`StopReason::Singular`] (information matrix not positive definite) or
    /// [`StopReason::IterationCap`] (20 iterations).
    pub stopped: StopReason,
}

/// Soft-mount constrained least squares (see the module doc). `tilt_sigma_rad` is the prior σ of the
/// mount tilt (rad, > 0), `point_sigma_m` the per-coordinate point noise (m, > 0). Needs n ≥ 3
/// non-collinear points; the same mount errors as [`constrained_lsq`].
pub fn constrained_soft(
    pairs: &PointPairs,
    mounts: &MountPair,
    tilt_sigma_rad: f64,
    point_sigma_m: f64,
) -> Result<SoftFit, CalibError> {
    soft_with_cap(pairs, mounts, tilt_sigma_rad, point_sigma_m, SOFT_MAX_ITER)
}

/// [`constrained_soft`] with an iteration cap `max_iter` (≥ 1).
fn soft_with_cap(
    pairs: &PointPairs,
    mounts: &MountPair,
    tilt_sigma_rad: f64,
    point_sigma_m: f64,
    max_iter: usize,
) -> Result<SoftFit, CalibError> {
    for (name, v) in [
        ("tilt_sigma_rad", tilt_sigma_rad),
        ("point_sigma_m", point_sigma_m),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(CalibError::InvalidOption {
                name: name.into(),
                value: v.to_string(),
                message: "must be finite and > 0".into(),
            });
        }
    }
    let hard = constrained_lsq(pairs, mounts, &ConstrainedOptions::default())?;
    let x0 = hard.b1_from_b2;
    let axes = family_axes(mounts, &x0.rotation.to_rotation_matrix())?;
    // P: projector onto the forbidden rotation directions.
    let p = if axes.len() == 1 {
        Matrix3::identity() - axes[0] * axes[0].transpose()
    } else {
        let nrm = axes[0].cross(&axes[1]);
        let nrm = if nrm.norm() > 0.0 {
            nrm.normalize()
        } else {
            Vector3::zeros()
        };
        nrm * nrm.transpose()
    };
    let q_prior = p.transpose() * p / (tilt_sigma_rad * tilt_sigma_rad);
    let n = pairs.len();
    let w = vec![1.0; n];
    let all_axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let mut x = x0;
    let mut omega = Vector3::zeros();
    let mut iterations = 0;
    let mut stopped = StopReason::IterationCap;
    let mut info = DMatrix::zeros(6, 6);
    for it in 0..max_iter {
        iterations = it + 1;
        let mut j = DMatrix::zeros(3 * n, 6);
        fill_fit_jacobian(pairs, &w, &x, &all_axes, &mut j);
        let r = residuals(pairs, &x);
        let r = DVector::from_iterator(3 * n, r.iter().flat_map(|v| [v.x, v.y, v.z]));
        let s2 = point_sigma_m * point_sigma_m;
        info = j.transpose() * &j / s2;
        let mut g = j.transpose() * &r / s2;
        for a in 0..3 {
            for b in 0..3 {
                info[(a, b)] += q_prior[(a, b)];
            }
        }
        let prior_grad = q_prior * omega;
        for a in 0..3 {
            g[a] += prior_grad[a];
        }
        let Some(delta) = info.clone().cholesky().map(|c| c.solve(&(-g))) else {
            stopped = StopReason::Singular;
            break;
        };
        let d_omega = Vector3::new(delta[0], delta[1], delta[2]);
        let d_t = Vector3::new(delta[3], delta[4], delta[5]);
        x = Isometry3::translation(d_t.x, d_t.y, d_t.z) * Isometry3::rotation(d_omega) * x;
        omega += d_omega;
        if delta.amax() < SOFT_STEP_TOL {
            stopped = StopReason::StepTooSmall;
            break;
        }
    }
    let res = residuals(pairs, &x);
    let covariance = info
        .try_inverse()
        .map(|c| Matrix6::from_fn(|r, cc| c[(r, cc)]));
    let uncertainty =
        covariance.map(|c| build_uncertainty(c, point_sigma_m, (3 * n).saturating_sub(6), &x));
    let tilt_rad = p * omega;
    Ok(SoftFit {
        fit: Fit {
            method: Method::Constrained,
            b1_from_b2: x,
            residuals: res,
            condition: hard.condition,
            uncertainty,
        },
        tilt_angle_rad: tilt_rad.norm(),
        tilt_rad,
        iterations,
        stopped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::{e_tran, geodesic_angle};
    use crate::registration::rigid_lsq;
    use nalgebra::Point3;

    fn cloud() -> Vec<Point3<f64>> {
        (0..7)
            .map(|i| {
                let a = i as f64 * 0.9;
                Point3::new(0.9 * a.cos(), 0.8 * a.sin(), 0.1 + 0.15 * i as f64)
            })
            .collect()
    }

    /// A floor–floor cell whose robot 2 actually stands 0.5° tilted about x.
    #[test]
    fn soft_fit_estimates_the_actual_tilt() {
        let tilt = 0.5f64.to_radians();
        let truth = Isometry3::new(
            Vector3::new(0.04, 1.48, 0.05),
            Vector3::new(0.0, 0.0, -0.78),
        ) * Isometry3::rotation(Vector3::new(tilt, 0.0, 0.0));
        let p_b2 = cloud();
        let pairs = PointPairs::new(p_b2.iter().map(|p| truth * p).collect(), p_b2).unwrap();
        let mounts = MountPair::floor_floor();
        // Loose prior: the data decide, the truth is recovered (zero noise), tilt ≈ 0.5°.
        let soft = constrained_soft(&pairs, &mounts, 5f64.to_radians(), 0.5e-3).unwrap();
        assert!(geodesic_angle(&truth, &soft.fit.b1_from_b2) < 1e-6);
        assert!(e_tran(&truth, &soft.fit.b1_from_b2) < 1e-6);
        assert!(
            (soft.tilt_angle_rad - tilt).abs() < 1e-3 * tilt,
            "{}",
            soft.tilt_angle_rad
        );
        // Very tight prior: back to the hard constraint.
        let tight = constrained_soft(&pairs, &mounts, 1e-9, 0.5e-3).unwrap();
        let hard = constrained_lsq(&pairs, &mounts, &ConstrainedOptions::default()).unwrap();
        assert!(geodesic_angle(&hard.b1_from_b2, &tight.fit.b1_from_b2) < 1e-8);
        // The hard fit is biased by the tilt, rigid lsq is not.
        assert!(geodesic_angle(&truth, &hard.b1_from_b2) > 0.5 * tilt);
        let lsq = rigid_lsq(&pairs, None).unwrap();
        assert!(geodesic_angle(&lsq.b1_from_b2, &soft.fit.b1_from_b2) < 1e-6);
        // Invalid options are errors.
        assert!(constrained_soft(&pairs, &mounts, 0.0, 0.5e-3).is_err());
        assert!(constrained_soft(&pairs, &mounts, 0.01, f64::NAN).is_err());
        assert_eq!(soft.stopped, StopReason::StepTooSmall);
    }

    /// One Gauss–Newton step from the hard solution of a tilted cell cannot meet the 1e-13 step
    /// tolerance (the first update is the whole 0.5° tilt): the run reports its cap.
    #[test]
    fn capped_soft_fit_reports_iteration_cap() {
        let truth = Isometry3::new(
            Vector3::new(0.04, 1.48, 0.05),
            Vector3::new(0.0, 0.0, -0.78),
        ) * Isometry3::rotation(Vector3::new(0.5f64.to_radians(), 0.0, 0.0));
        let p_b2 = cloud();
        let pairs = PointPairs::new(p_b2.iter().map(|p| truth * p).collect(), p_b2).unwrap();
        let mounts = MountPair::floor_floor();
        let capped = soft_with_cap(&pairs, &mounts, 5f64.to_radians(), 0.5e-3, 1).unwrap();
        assert_eq!(capped.iterations, 1);
        assert_eq!(capped.stopped, StopReason::IterationCap);
    }
}
