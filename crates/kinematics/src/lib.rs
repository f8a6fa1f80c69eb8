#![doc = include_str!("../README.md")]

mod axis;
pub mod cardan;
mod coupling;
mod error;
mod error_model;
pub mod euler;
mod fk;
mod gravity;
mod ik;
pub mod input;
mod jacobian;
pub mod lumped;
mod model;
#[cfg(test)]
mod test_fixtures;
mod true_fk;
pub mod trunk;
mod urdf_patch;

/// The nalgebra this crate's API is written in (`Isometry3`, `Point3`, `Vector3`, `DVector`, …).
/// Use `kinematics::nalgebra::…` (or pin the same nalgebra version, see the README) so your types
/// are the ones these functions take.
pub use nalgebra;

pub use axis::Axis;
pub use cardan::{
    quaternion_wxyz, rotation_from_quaternion_wxyz, rotation_from_zyx, zyx_from_rotation,
    ZYX_LOCK_COS,
};
pub use coupling::{JointCoupling, LinearCoupling};
pub use error::{KinematicsError, ModelError, UrdfPatchError};
pub use error_model::{all_params, all_params_for, ErrorParam, KinematicErrors};
pub use euler::{
    rotation_from_zyz, wrap_angle, zyz_canonical, zyz_canonical_within, zyz_from_rotation,
    zyz_nearest, ZYZ_CANONICAL_TILT_RAD,
};
pub use fk::{
    base_from_flange, base_from_flange_unchecked, base_from_tip, base_from_tip_unchecked,
};
pub use gravity::{gravity_torque_jacobian, gravity_torques};
pub use ik::{ik_tip_position, IkOptions, IkSolution, IkStatus, IkStopReason};
pub use jacobian::{geometric_jacobian, tip_position_jacobian, JacobianFrame};
pub use lumped::{
    lumped_canonical, lumped_compliance_from_masses, lumped_deflections, lumped_params,
    LUMPED_G_REF,
};
pub use model::{
    origin_isometry, rotation_from_rpy, Joint, JointKind, LumpedInertial, RobotModel,
    MAX_CHAIN_LENGTH_M, MAX_PRISMATIC_TRAVEL_M, PRISMATIC_READING_SLACK_M, WORLD_LINK,
};
pub use true_fk::{
    check_tip_inputs, tip_error_jacobian, tip_error_jacobian_unchecked, tip_joint_jacobian_true,
    true_base_from_flange, true_base_from_flange_unchecked, true_base_from_tip,
    true_base_from_tip_unchecked, true_tip_with_error_jacobian,
    true_tip_with_error_jacobian_unchecked, PreparedTip,
};
pub use trunk::{
    branch_deflections, branch_regressor, branch_torques, is_branch_param,
    shared_trunk_lumped_from_masses, TRUNK_MATCH_TOL,
};
pub use urdf_patch::{
    patch_urdf_text, split_for_urdf, verify_patched_urdf, PATCH_TOLERANCE_M, VERIFY_CONFIGURATIONS,
};
