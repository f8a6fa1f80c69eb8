//! The report crate's errors.

use std::path::PathBuf;

/// What went wrong building a report page's data.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// The work-points CSV cannot be read or holds a bad row.
    #[error("{path}: {message}")]
    WorkPoints {
        /// The file.
        path: PathBuf,
        /// What is wrong and how to fix it (names the row or column).
        message: String,
    },
    /// No work point is reachable by both robots head-on, so nothing can be predicted.
    #[error("no work point is reachable by both robots head-on ({points} tried): {first}")]
    NoReachableWorkPoint {
        /// Points tried.
        points: usize,
        /// Why the first one failed.
        first: String,
    },
    /// The calibration's prediction failed (a configuration the models reject).
    #[error("predicting the cooperative accuracy at the work site")]
    Prediction(#[source] calib_core::whole_cell::CellFitError),
    /// A residual of the fitted cell cannot be evaluated.
    #[error("evaluating the fit's residual of session row {row}")]
    Residual {
        /// The 1-based session row.
        row: usize,
        /// The cause.
        #[source]
        source: calib_core::whole_cell::CellFitError,
    },
    /// An acceptance threshold is not a positive finite number.
    #[error("acceptance {name} = {value}: give a positive number")]
    Acceptance {
        /// `mm` or `deg`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
}
