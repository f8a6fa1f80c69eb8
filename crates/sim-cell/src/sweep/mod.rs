//! Monte Carlo sweeps over noise × spread × number of points × mounts × methods.
//!
//! Two modes:
//! - **geometry**: teach points from a [`crate::Layout`] around the cell's centre, robot 2's reading
//!   perturbed by the operator's alignment error, fitted by calib-core's allocation-free kernels
//!   ([`calib_core::generic_fast`], [`calib_core::paper_fast`], [`calib_core::rigid_fit_fast`],
//!   [`calib_core::constrained_fast`]); no robots, millions of trials per second.
//! - **robot**: each trial simulates a full session on a [`handclasp_cell::Cell`] ([`crate::simulate::generate_session`]:
//!   IK of both true robots, reach limits, encoder quantisation, repeatability, nominal-model tips),
//!   optionally with kinematic errors drawn per trial from the robots' tolerances
//!   ([`KinematicErrorDraw`]) and a planned layout ([`SweepLayout::Planned`]); besides the
//!   registration methods it fits the whole-cell methods ([`SweepMethod`]) and scores every fit
//!   by its cooperative accuracy over held-out pairs ([`robot`] module docs, [`Cooperative`]).
//!
//! Trial `k` (global index over grid cells × trials) draws only from [`crate::trial_rng`]`(seed, k)` and every
//! method is fitted on that trial's points (common random numbers), so results are identical for
//! any thread count. Grid cells are ordered mounts, noise, spread, n (n fastest).

mod config;
mod geometry;
mod output;
pub mod robot;
mod run;
#[cfg(test)]
mod tests;

pub use calib_core::{e_rot_fast, fit_fast, ErotTruth, TrialErrors};
pub use config::{GridCell, KinematicErrorDraw, Mode, SweepConfig, SweepLayout, SweepMethod};
pub use geometry::{draw_geometry, geometry_trial, geometry_trial_into, GeometrySpec};
pub use output::{
    render_table, summarize_cells, summarize_pooled, summary_header, write_summary_csv,
    write_trials_csv, SummaryRow, TRIALS_HEADER,
};
pub use robot::{
    draw_kinematic_errors, most_spread_four, robot_setup, setup_rng, RobotSetup, EVAL_PAIRS,
    PLAN_CANDIDATES, SPREAD4_EXHAUSTIVE,
};
pub use run::{run_sweep, Cooperative, Failure, Outcome, SweepResult, TrialOutcome, TrialRngs};

/// Largest point count of a geometry-mode trial.
pub const MAX_GEOMETRY_POINTS: usize = 256;
/// Trials per parallel work item (also the progress-bar step).
pub(super) const CHUNK: usize = 2048;
