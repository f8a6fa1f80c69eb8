#![doc = include_str!("../README.md")]

pub mod assemble;
pub mod error;
pub mod fit_data;
pub mod page;
pub mod plot;
pub mod work_site;

pub use assemble::{
    calibration_page_of_fit, unreachable_lines, work_site_text, CalibrationPageInputs,
    CalibrationWithSite, CellDiagnosisWithSite,
};
pub use error::ReportError;
pub use fit_data::{joint_coverage, row_residuals, JointCoverage, RowResidual};
pub use page::{
    calibration_page, cell_diagnosis_page, coincident_diagnosis_page, CalibrationPage, Invocation,
    MeetingPairsAccuracy,
};
pub use work_site::{
    diagnosis_work_site, placement_rotation_report, predict_work_site, predict_work_site_of_fit,
    read_work_points, work_site_points, workspace_map, Acceptance, RotationFigures,
    RotationPredictionReport, UnreachableReport, Verdict, VerdictModel, WorkPointReport,
    WorkSiteReport, WorkspaceMap,
};

#[cfg(test)]
mod tests;
