//! The simulation beside the paper's Table 1 (Gan et al. 2014), and the diagnosis of what it gets
//! wrong (`handclasp paper diagnose`, `sim-cell paper`).
//!
//! | file | job |
//! |---|---|
//! | `experiments.rs` | Table 1 as [`Experiment`]s; the metrics: e_tran (eq 34, ∞-norm, mm) and e_rot (eq 33 on ZYZ for floor–wall; `max(tilt, |yaw|)` for the two cells near the ZYZ singularity, as the paper prints them) |
//! | `simulate.rs` | the protocol: 4 points on a 1 m regular tetrahedron around the cell's teach-point centre, N(0, σ²·I) alignment noise on robot 1's point, both methods (`generic_fast`, `paper_fast`); every error is `bias + σ·slope`, so one run at σ = 1 mm gives all σ |
//! | `sigma_fit.rs` | σ̂ by maximum likelihood of the published `(e_tran, e_rot)` under a kernel density of the simulation, with its 95 % profile interval |
//! | `study.rs` | σ̂ per cell and method, one σ for all cells (LR test, χ² df 2), both methods share σ (parametric bootstrap), published vs simulated bands |
//! | `candidates.rs` | candidate causes ([`Candidate`]) and their mean columns on the signed generic errors |
//! | `model_fit.rs` | each model fitted by maximum likelihood (GLS for the mean, closed-form σ², 1-D searches for the noise shape), AIC, held-out likelihood |
//! | `diagnosis.rs` | signed errors, per-cell findings, forward selection (LR p below 0.05 / candidates tried, lower AIC, best held-out score) |
//! | `render.rs` | all text: the reports, the study's notes, the conclusions |
//!
//! A mount tilt is not a free candidate: the CMM truth already carries it (floor–wall
//! θ = 89.874°), and the simulated constrained method inherits it.

mod candidates;
mod diagnosis;
mod experiments;
mod model_fit;
mod render;
mod sigma_fit;
mod simulate;
mod study;
#[cfg(test)]
mod tests;

pub use candidates::Candidate;
pub use diagnosis::{
    diagnose_experiments, run_paper_diagnosis, CellFinding, PaperDiagnosis, SignedRow,
};
pub use experiments::{
    paper_errors, table1_experiments, table1_truths, Experiment, PaperCell, PaperMethod,
};
pub use model_fit::{CandidateResult, ParamEstimate};
pub use render::{diagnosis_text, study_text};
pub use sigma_fit::{Band, SigmaFit};
pub use simulate::{synthetic_experiments, PlantedEffects};
pub use study::{
    run_paper_study, study_experiments, CellSigma, CommonSigmaTest, MethodsShareSigma, PaperStudy,
    StudyOptions, StudyRow,
};

use calib_core::CalibError;

/// Handclasp points per experiment in the paper.
pub const PAPER_POINTS: usize = 4;
/// Edge of the simulated teach-point tetrahedron, m (the paper: points ≥ 1 m apart).
pub const PAPER_SPREAD_M: f64 = 1.0;
/// Default Monte Carlo trials per cell.
pub const DEFAULT_TRIALS: usize = 2000;
/// Default parametric-bootstrap replicates of the methods-share-σ test.
pub const DEFAULT_BOOTSTRAP: usize = 40;
/// Default seed.
pub const DEFAULT_SEED: u64 = 2014;
/// Fewest trials accepted (the kernel density and the 5–95 % band need a few hundred).
pub const MIN_TRIALS: usize = 200;
/// Significance level of the tests and of the selection (before Bonferroni).
pub(super) const ALPHA: f64 = 0.05;
/// Search range of σ, mm (the fit reports when an interval end reaches it).
pub const SIGMA_RANGE_MM: [f64; 2] = [0.05, 50.0];
/// Search range of the anisotropy factor (σ along the approach axis / σ across it).
pub const ANISOTROPY_RANGE: [f64; 2] = [0.1, 10.0];
/// Tetrahedron edges tried by the `layout_spread` candidate, m (the paper asks for ≥ 1 m; the
/// baseline uses [`PAPER_SPREAD_M`], index `SPREAD_BASE`).
pub const SPREAD_GRID_M: [f64; 6] = [0.8, 1.0, 1.25, 1.5, 1.75, 2.0];
/// Index of [`PAPER_SPREAD_M`] in [`SPREAD_GRID_M`].
pub(super) const SPREAD_BASE: usize = 1;
/// Lower and upper quantile of the simulated band.
pub(super) const BAND: [f64; 2] = [0.05, 0.95];

pub(super) const MM_PER_M: f64 = 1000.0;
pub(super) const MRAD_PER_RAD: f64 = 1000.0;

/// Errors of the paper study.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PaperError {
    /// Table 1 could not be read.
    #[error("paper Table 1: {0}")]
    Table(#[from] CalibError),
    /// An option is out of range; the message says what would work.
    #[error("paper study option {option}: {message}")]
    Option {
        /// The option's name.
        option: &'static str,
        /// What is wrong and what would work.
        message: String,
    },
    /// The experiments given are not usable; the message says why.
    #[error("paper experiments: {0}")]
    Experiments(String),
}
