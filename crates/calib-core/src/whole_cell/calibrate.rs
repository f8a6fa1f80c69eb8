//! The one-call whole-cell calibration a CLI needs: starting values, base-parameter reduction,
//! MAP fit with blunder screening, and a serialisable report.

use nalgebra::Isometry3;
use serde::Serialize;

use super::blunders::{fit_screened, RejectedRow, ScreenOptions};
use super::reduce::{reduce, Reduction, ReductionEntry};
use super::solve::{CellFit, FittedParam, SolveOptions, StopReason};
use super::{initial_estimate, CellFitError, CellProblem};

/// Result of [`calibrate_cell`].
#[derive(Debug, Clone)]
pub struct CellCalibration {
    /// The MAP fit on the reduced unknowns without the rejected rows.
    pub fit: CellFit,
    /// What the data cannot determine (dropped or merged) and why.
    pub reduction: Reduction,
    /// Rejected blunders.
    pub rejected: Vec<RejectedRow>,
}

/// A serialisable summary of a calibration (SI units: m, rad; field names say so).
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// Base 2 in base 1 (translation m, unit quaternion).
    pub b1_from_b2: Isometry3<f64>,
    /// Every fitted unknown with prior and posterior σ.
    pub parameters: Vec<FittedParam>,
    /// Dropped / merged parameters and why.
    pub unidentifiable: Vec<ReductionEntry>,
    /// Rejected rows with their size in σ.
    pub rejected_points: Vec<RejectedRow>,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// Solver iterations of the final fit.
    pub iterations: usize,
    /// Data χ² of the final fit and its residual rows.
    pub data_chi2: f64,
    /// Residual rows used.
    pub residual_rows: usize,
}

impl CellCalibration {
    /// The serialisable summary.
    pub fn report(&self, problem: &CellProblem) -> CalibrationReport {
        CalibrationReport {
            b1_from_b2: self.fit.estimate.b1_from_b2,
            parameters: self.fit.parameters(problem),
            unidentifiable: self.reduction.dropped.clone(),
            rejected_points: self.rejected.clone(),
            stopped: self.fit.stopped,
            iterations: self.fit.iterations,
            data_chi2: self.fit.data_chi2,
            residual_rows: self.fit.residual_rows,
        }
    }
}

/// Calibrates the whole cell: starting values ([`initial_estimate`]), base-parameter reduction
/// at the start ([`reduce`]), then the screened MAP fit ([`fit_screened`]) on the reduced
/// unknowns.
///
/// Errors: invalid input, no starting placement, model failures, or too few rows after
/// rejecting blunders (naming the rows to re-record).
pub fn calibrate_cell(
    problem: &CellProblem,
    solve: &SolveOptions,
    screen: &ScreenOptions,
) -> Result<CellCalibration, CellFitError> {
    problem.check()?;
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let start = initial_estimate(problem, solve.initial_b1_from_b2, &all)?;
    let reduction = reduce(problem, &start, &all)?;
    let screened = fit_screened(problem, Some(reduction.layout.clone()), solve, screen)?;
    Ok(CellCalibration {
        fit: screened.fit,
        reduction,
        rejected: screened.rejected,
    })
}
