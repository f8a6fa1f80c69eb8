#![doc = include_str!("../README.md")]

pub mod cell;
mod error;

pub use cell::{Cell, CellRobot, Noise, PlacementSigma, TIP_TOOL};
pub use error::FormatError;
