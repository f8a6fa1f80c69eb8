//! The report page of a calibration or a diagnosis: one self-contained HTML file (inline CSS,
//! inline SVG plots, one small inline script; nothing fetched from the network) that a person
//! opens in a browser, rendered from the same typed reports the commands print as JSON.
//!
//! 1. [`work_site`]: the verdict first — the calibration's predicted cooperative accuracy at the
//!    work site ([`read_work_points`], [`predict_work_site`]) against what the user accepts
//!    ([`Acceptance`]), PASS or FAIL and why ([`WorkSiteReport`], also in the JSON report).
//! 2. [`fit_data`]: the plots' data from the same fit: each row's residual
//!    ([`row_residuals`]) and each joint's coverage ([`joint_coverage`]).
//! 3. [`plot`]: the SVG plots (plotters' SVG backend into a string).
//! 4. [`page`]: the HTML (maud): [`calibration_page`], [`coincident_diagnosis_page`],
//!    [`cell_diagnosis_page`].
//!
//! Layering: above `sim-cell` (the head-on placement of a work point) and `diagnose` (its
//! reports), below the `handclasp` binary.

pub mod error;
pub mod fit_data;
pub mod page;
pub mod plot;
pub mod work_site;

pub use error::ReportError;
pub use fit_data::{joint_coverage, row_residuals, JointCoverage, RowResidual};
pub use page::{
    calibration_page, cell_diagnosis_page, coincident_diagnosis_page, CalibrationPage, Invocation,
    MeetingPairsAccuracy,
};
pub use work_site::{
    predict_work_site, read_work_points, Acceptance, RotationPredictionReport, UnreachableReport,
    Verdict, WorkPointReport, WorkSiteReport,
};

#[cfg(test)]
mod tests;
