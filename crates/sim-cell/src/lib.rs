#![doc = include_str!("../README.md")]

pub mod cell;
#[cfg(feature = "cli")]
pub mod cli_support;
mod error;
pub mod export;
pub mod export_formats;
pub mod layout;
pub mod paper;
pub mod placement;
pub mod plan;
pub mod plot;
pub mod session;
pub mod session_kinds;
pub mod sweep;
pub mod whole_cell;

pub use cell::{Cell, CellRobot, Noise, PlacementSigma};
pub use error::SimError;
pub use export::{export_calibrated_cell, ExportNames, CALIBRATE_EXPORT_NAMES};
pub use export_formats::{export_placement, ControllerFormat, PlacementExport, PlacementFormats};
pub use layout::{teach_points, Layout};
pub use session::{
    generate_session, Session, SessionKind, SessionObservation, SessionPoint, SessionRow,
    SessionSpec,
};
pub use session_kinds::{
    generate_kind_session, read_points_b1_csv, teach_from_plan, KindSpec, NuisanceTruth, SimKind,
    Teach,
};
pub use sweep::{geometry_trial, GeometrySpec, TrialErrors};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The generator of Monte Carlo trial `index` under master `seed`: ChaCha8 seeded with `seed`,
/// stream `index`. Any trial can be replayed alone, and results never depend on thread count.
pub fn trial_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}
