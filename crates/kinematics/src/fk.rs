//! Forward kinematics: `base_from_flange(q)` and `base_from_tip(q)`.
//! Lengths in metres, angles in radians; `base` is the URDF root link.

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};

use crate::error::KinematicsError;
use crate::model::{RobotModel, Step};

/// Rotation of one joint by `q` rad about its axis, as a unit quaternion (fast path for ±x/±y/±z).
#[inline]
pub(crate) fn joint_rotation(step: &Step, q: f64) -> UnitQuaternion<f64> {
    if step.axis_kind < 3 {
        let (s, c) = (0.5 * q * step.axis_sign).sin_cos();
        let q = match step.axis_kind {
            0 => Quaternion::new(c, s, 0.0, 0.0),
            1 => Quaternion::new(c, 0.0, s, 0.0),
            _ => Quaternion::new(c, 0.0, 0.0, s),
        };
        UnitQuaternion::new_unchecked(q)
    } else {
        UnitQuaternion::from_axis_angle(&step.axis, q)
    }
}

/// `base_from_flange(q)` without any check of `q` (caller guarantees `q.len() == dof`, finite).
/// Allocation-free; used by IK and benches. Panics only if `q` is shorter than `dof`.
#[inline]
pub fn base_from_flange_unchecked(model: &RobotModel, q: &[f64]) -> Isometry3<f64> {
    let mut t = Isometry3::identity();
    for (step, &qi) in model.steps.iter().zip(q) {
        t *= step.prev_from_joint;
        t.rotation *= joint_rotation(step, qi);
    }
    t * model.last_from_flange()
}

/// Pose of the flange (tool link) in the base frame at joint angles `q` (rad).
///
/// Errors: `q` of the wrong length, non-finite, in degrees, or outside the joint limits.
pub fn base_from_flange(model: &RobotModel, q: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
    model.check_q(q)?;
    Ok(base_from_flange_unchecked(model, q))
}

/// `base_from_tip` without checks; see [`base_from_flange_unchecked`].
#[inline]
pub fn base_from_tip_unchecked(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
) -> Isometry3<f64> {
    let mut t = base_from_flange_unchecked(model, q);
    t.translation = Translation3::from(t * Point3::from(*flange_from_tip));
    t
}

/// Pose of the tip in the base frame: the flange pose moved by `flange_from_tip` (m, flange axes);
/// the tip's orientation is the flange's.
///
/// Errors: as [`base_from_flange`], plus a non-finite tip offset.
pub fn base_from_tip(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
) -> Result<Isometry3<f64>, KinematicsError> {
    model.check_q(q)?;
    check_tip(flange_from_tip)?;
    Ok(base_from_tip_unchecked(model, q, flange_from_tip))
}

pub(crate) fn check_tip(flange_from_tip: &Vector3<f64>) -> Result<(), KinematicsError> {
    if flange_from_tip.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(KinematicsError::InvalidInput(format!(
            "tip offset {:?} m is not finite; give a finite flange_from_tip",
            flange_from_tip.as_slice()
        )))
    }
}

/// Poses `base_from_joint_k` (after joint k's rotation) for every actuated joint, and the flange.
/// Used by the Jacobians. No checks.
pub(crate) fn joint_frames(model: &RobotModel, q: &[f64], out: &mut Vec<Isometry3<f64>>) -> Isometry3<f64> {
    out.clear();
    let mut t = Isometry3::identity();
    for (step, &qi) in model.steps.iter().zip(q) {
        t *= step.prev_from_joint;
        t.rotation *= joint_rotation(step, qi);
        out.push(t);
    }
    t * model.last_from_flange()
}
