#![doc = include_str!("../README.md")]

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
    predict_work_site, read_work_points, workspace_map, Acceptance, RotationPredictionReport,
    UnreachableReport, Verdict, WorkPointReport, WorkSiteReport, WorkspaceMap,
};

#[cfg(test)]
mod tests;
