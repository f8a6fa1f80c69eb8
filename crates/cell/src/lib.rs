#![doc = include_str!("../README.md")]

pub mod cell;
mod error;
pub mod export;
pub mod export_formats;
#[cfg(test)]
mod fixtures;
pub mod import;
mod lumped_file;
pub mod output;
pub mod problem;
pub mod session;

pub use cell::{Cell, CellRobot, Noise, PlacementSigma, TIP_TOOL};
pub use error::FormatError;
pub use export::{export_calibrated_cell, ExportNames, CALIBRATE_EXPORT_NAMES};
pub use export_formats::{export_placement, ControllerFormat, PlacementExport, PlacementFormats};
pub use import::{ImportCount, ImportMap};
pub use problem::{cell_problem, FitModel};
pub use session::{
    check_session_inputs, joint_column, Session, SessionCheckError, SessionKind,
    SessionObservation, SessionPoint, SessionRow,
};
