#![doc = include_str!("../README.md")]

mod error;
mod errors;
pub mod euler;
mod fk;
mod gravity;
mod ik;
mod jacobian;
mod model;

pub use error::{KinematicsError, ModelError};
pub use errors::*;
pub use euler::{rotation_from_zyz, wrap_angle, zyz_from_rotation, zyz_nearest};
pub use fk::{
    base_from_flange, base_from_flange_unchecked, base_from_tip, base_from_tip_unchecked,
};
pub use gravity::*;
pub use ik::{ik_tip_position, IkOptions, IkSolution, IkStatus};
pub use jacobian::{geometric_jacobian, tip_position_jacobian, JacobianFrame};
pub use model::{origin_isometry, rotation_from_rpy, Joint, LumpedInertial, RobotModel};
