//! What the front ends (the `handclasp` binary and the Python package) share around a page: the
//! calibration page assembled from a fit ([`calibration_page_of_fit`]), the JSON objects that
//! carry the verdict at the work site after a command's own report ([`CalibrationWithSite`],
//! [`CellDiagnosisWithSite`]), and the verdict's text lines ([`work_site_text`],
//! [`unreachable_lines`]). One function each, so `calibrate --cell --report`,
//! `diagnose --report` and Python's `CellResult.report` / `DiagnoseResult.report` write the
//! same page from the same inputs.

use calib_core::whole_cell::{CellCalibration, CellProblem};
use handclasp_cell::Cell;
use serde::Serialize;

use crate::fit_data::{joint_coverage, row_residuals};
use crate::page::{calibration_page, CalibrationPage, Invocation, MeetingPairsAccuracy};
use crate::work_site::{workspace_map, VerdictModel, WorkSiteReport};
use crate::ReportError;

/// A whole-cell calibration's report (`R`, the `calibrate --cell --json` object) with the
/// verdict at the work site when asked for (`work_site`, after the report's own keys) and,
/// with `--export`, the do-no-harm rule's verdict (`D`, absent when `None`).
#[derive(Debug, Serialize)]
pub struct CalibrationWithSite<R, D> {
    /// The report, its keys flattened into this object.
    #[serde(flatten)]
    pub report: R,
    /// The verdict at the work site.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_site: Option<WorkSiteReport>,
    /// The do-no-harm rule's verdict (`calibrate --cell --export`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub do_no_harm: Option<D>,
}

/// The whole-cell diagnosis's JSON (`diagnose --json` on a session with contact, tracker or
/// plane rows): its report with, when asked for, the verdict at the work site (`work_site`, the
/// object `calibrate --cell` gives) and which model it is for (`work_site_model`), after the
/// report's own keys.
#[derive(Debug, Serialize)]
pub struct CellDiagnosisWithSite<'a> {
    /// The diagnosis, its keys flattened into this object.
    #[serde(flatten)]
    pub report: &'a diagnose::CellDiagnoseReport,
    /// The verdict at the work site.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_site: Option<&'a WorkSiteReport>,
    /// The model the verdict is for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub work_site_model: Option<&'a VerdictModel>,
}

/// What the calibration page shows besides the fit: where the inputs came from, the model, the
/// session's size, the verdict and the command's JSON.
#[derive(Debug, Clone, Copy)]
pub struct CalibrationPageInputs<'a> {
    /// The cell file, as given (or how the cell was given).
    pub cell: &'a str,
    /// The session file, as given (or how the session was given).
    pub session: &'a str,
    /// The model's name (`kinematic`, `kinematic+compliance`, `placement`).
    pub model: &'a str,
    /// The session's rows of all kinds.
    pub rows: usize,
    /// The prediction over the session's meeting pairs, if it has any.
    pub meeting_pairs: Option<MeetingPairsAccuracy>,
    /// The verdict at the work site.
    pub work_site: &'a WorkSiteReport,
    /// The command's JSON report, embedded as it is.
    pub json: &'a str,
    /// Command line and version.
    pub invocation: &'a Invocation,
}

/// The HTML page of a whole-cell calibration `cal` of `problem` (built from `cell`), as
/// `calibrate --cell … --report FILE` writes it ([`calibration_page`]): the fit's
/// [`calib_core::whole_cell::CalibrationReport`], every row's residual, each joint's coverage
/// and the workspace map (whose failure the page says in its place, seed `seed`).
///
/// Errors: a row's residual cannot be evaluated ([`ReportError::Residual`]).
pub fn calibration_page_of_fit(
    cell: &Cell,
    problem: &CellProblem,
    cal: &CellCalibration,
    inputs: &CalibrationPageInputs<'_>,
    seed: u64,
) -> Result<String, ReportError> {
    let calibration = &cal.report(problem);
    let residuals = row_residuals(problem, cal)?;
    let coverage = joint_coverage(cell, &residuals);
    let workspace = workspace_map(problem, cal, seed).ok();
    Ok(calibration_page(&CalibrationPage {
        cell: inputs.cell,
        session: inputs.session,
        model: inputs.model,
        rows: inputs.rows,
        report: calibration,
        work_site: inputs.work_site,
        meeting_pairs: inputs.meeting_pairs,
        residuals: &residuals,
        coverage: &coverage,
        workspace: workspace.as_ref(),
        dof: [cell.robot1.model.dof(), cell.robot2.model.dof()],
        shared_trunk: cell.shared_joints > 0,
        json: inputs.json,
        invocation: inputs.invocation,
    }))
}

/// The text lines of a verdict at the work site: the prediction, the placement's rotation
/// error (which figure it is, and the marginal one when it differs), then `verdict: …`.
pub fn work_site_text(w: &WorkSiteReport) -> String {
    let rotation = match &w.placement_rotation {
        Some(r) => {
            let marginal = if r.conditional_on.is_empty() {
                String::new()
            } else {
                format!(
                    "; marginal (their prior included): rms {:.4}°, p95 {:.4}°",
                    r.marginal.rms_deg, r.marginal.p95_deg
                )
            };
            format!(
                "placement rotation error: rms {:.4}°, p95 {:.4}° (95 % interval {:.4}–{:.4}°), {}{marginal}\n",
                r.rms_deg, r.p95_deg, r.p95_ci_deg[0], r.p95_ci_deg[1], r.basis
            )
        }
        None => String::new(),
    };
    format!(
        "predicted {} at the work site ({}): rms {:.3} mm, p95 {:.3} mm (95 % interval {:.3}–{:.3} mm)\n{rotation}verdict: {}: {}\n",
        w.accuracy_name(),
        w.source,
        w.predicted_rms_mm,
        w.predicted_p95_mm,
        w.predicted_p95_ci_mm[0],
        w.predicted_p95_ci_mm[1],
        w.verdict.headline(),
        w.why
    )
}

/// One warning per work point of `w` that was not predicted (row, position in mm, why),
/// without the `warning: ` prefix.
pub fn unreachable_lines(w: &WorkSiteReport) -> Vec<String> {
    w.unreachable
        .iter()
        .map(|u| {
            format!(
                "work point row {} ({:.1}, {:.1}, {:.1} mm) is not predicted: {}",
                u.row, u.p_b1_mm[0], u.p_b1_mm[1], u.p_b1_mm[2], u.why
            )
        })
        .collect()
}
