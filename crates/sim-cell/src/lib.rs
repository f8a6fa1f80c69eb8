#![doc = include_str!("../README.md")]

mod error;
pub mod honest;
pub mod layout;
pub mod oracle;
pub mod paper;
pub mod placement;
pub mod plan;
pub mod plot;
pub mod session_kinds;
pub mod simulate;
pub mod sweep;
mod trunk;

pub use error::SimError;
pub use layout::{teach_points, Layout};
pub use session_kinds::{
    generate_kind_session, read_points_b1_csv, teach_from_plan, KindSpec, NuisanceTruth, SimKind,
    Teach,
};
pub use simulate::{generate_session, SessionSpec};
pub use sweep::{geometry_trial, GeometrySpec, TrialErrors};

/// The generator of one Monte Carlo trial; defined in [`calib_core::stats::trial_rng`] and
/// re-exported for the simulator's users.
pub use calib_core::stats::trial_rng;
