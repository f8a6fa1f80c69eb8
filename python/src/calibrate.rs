//! `calibrate_cell` and `diagnose`: the whole-cell calibration and the diagnosis of a session,
//! as `handclasp calibrate --cell` and `handclasp diagnose` compute them.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use calib_core::whole_cell::HarmDesign;
use cli_support::cell_report::{
    calibrate_session, render_text, CellModel, CellReport, SessionCalibration, P95_SEED,
};
use cli_support::do_no_harm::DoNoHarmReport;
use cli_support::export_dir::check_output_folder;
use cli_support::result_check::ScreenMode;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use report::{
    calibration_page_of_fit, cell_diagnosis_page, coincident_diagnosis_page, diagnosis_work_site,
    predict_work_site, unreachable_lines, CalibrationPageInputs, CalibrationWithSite,
    CellDiagnosisWithSite, MeetingPairsAccuracy, VerdictModel, WorkSiteReport,
};

use crate::arrays::{json_to_py, pose_array, vector};
use crate::cell::{Cell, Session};
use crate::errors::{to_py, value_error, Otherwise};
use crate::work_site::{invocation, shown, SiteInputs};

/// Refuses a non-empty export folder unless `overwrite` (the CLI's rule, `--overwrite`), as
/// `OSError`/`ValueError`; `force=True` (the old way to overwrite) is refused with the new one.
fn check_folder(dir: &std::path::Path, overwrite: bool, force: bool) -> PyResult<()> {
    if force {
        return Err(value_error(
            "export(force=True) no longer overwrites an export: use overwrite=True (as the CLI's \
             --overwrite; calibrate_cell(force=True) keeps a refused result)",
        ));
    }
    check_output_folder(dir, overwrite, "export", "overwrite=True").map_err(|e| match e {
        cli_support::export_dir::OutputFolderError::NotEmpty { .. } => {
            crate::errors::os_error(std::io::ErrorKind::AlreadyExists, e.to_string())
        }
        e => to_py(&e, "", Otherwise::Value),
    })
}

/// An export's error inside the folder's lock ([`handclasp_cell::output::with_export_lock`]):
/// the lock's own refusals and the writer's, as Python exceptions.
struct LockedExportError(PyErr);

impl From<handclasp_cell::FormatError> for LockedExportError {
    fn from(e: handclasp_cell::FormatError) -> Self {
        let refused_folder = matches!(e, handclasp_cell::FormatError::OutputFolder { .. });
        if refused_folder {
            // Another export holds the lock, or the folder filled meanwhile.
            LockedExportError(crate::errors::os_error(
                std::io::ErrorKind::AlreadyExists,
                e.to_string(),
            ))
        } else {
            LockedExportError(to_py(&e, "export", Otherwise::Value))
        }
    }
}

/// Runs `write` into `dir` under the CLI's export lock, with the CLI's overwrite rule
/// (`overwrite`, checked before and again under the lock): a concurrent export into the same
/// folder is refused, and a failed export leaves none of its files. Releases the GIL.
fn locked_export<E: std::error::Error + 'static>(
    py: Python<'_>,
    dir: &std::path::Path,
    overwrite: bool,
    force: bool,
    write: impl FnOnce() -> Result<Vec<PathBuf>, E> + Send,
) -> PyResult<Vec<String>> {
    check_folder(dir, overwrite, force)?;
    let files = py
        .detach(|| {
            handclasp_cell::output::with_export_lock(dir, overwrite, "export", || {
                write().map_err(|e| {
                    LockedExportError(to_py(
                        &e,
                        &format!("export {}", dir.display()),
                        Otherwise::Value,
                    ))
                })
            })
        })
        .map_err(|e| e.0)?;
    Ok(paths(files))
}

/// The written files as strings.
fn paths(files: Vec<PathBuf>) -> Vec<String> {
    files.iter().map(|p| p.display().to_string()).collect()
}

/// The result of [`calibrate_cell`]: the fitted placement and kinematic parameters, the
/// predicted cooperative accuracy, and the CLI's report.
#[pyclass(module = "handclasp", frozen)]
pub struct CellResult {
    /// The report, the problem fitted and the calibration.
    calibrated: SessionCalibration,
    /// The verdict at the work site, when `calibrate_cell` was asked for it.
    work_site: Option<WorkSiteReport>,
    cell: Arc<handclasp_cell::Cell>,
    /// The session calibrated (the do-no-harm check refits it).
    session: handclasp_cell::Session,
    /// The do-no-harm decision ([`cli_support::do_no_harm::check`], without `force`) and the
    /// refit it exports when it withholds; computed on first use (`export`, `do_no_harm`).
    /// `None` inside: nothing to check (a placement-only calibration).
    harm: OnceLock<Option<(DoNoHarmReport, Option<SessionCalibration>)>>,
    /// The cell's and the session's files as the page names them.
    cell_path: String,
    session_path: String,
    json: String,
}

/// The report's JSON with the verdict at the work site after its keys, as `calibrate --cell
/// --json` prints it (pretty).
fn cell_json(report: &CellReport, work_site: Option<&WorkSiteReport>) -> PyResult<String> {
    serde_json::to_string_pretty(&CalibrationWithSite::<_, ()> {
        report,
        work_site: work_site.cloned(),
        do_no_harm: None,
    })
    .map_err(|e| value_error(format!("serialising the report: {e}")))
}

/// Issues a `UserWarning` per work point of `w` that was not predicted (the CLI's `warning:`
/// lines).
fn warn_unreachable(py: Python<'_>, w: &WorkSiteReport) -> PyResult<()> {
    for line in unreachable_lines(w) {
        crate::errors::user_warning(py, &line)?;
    }
    Ok(())
}

/// Whether any of the verdict's arguments was given.
fn wants_site(
    work_points: Option<&Bound<'_, PyAny>>,
    accept_mm: Option<f64>,
    accept_deg: Option<f64>,
) -> bool {
    work_points.is_some() || accept_mm.is_some() || accept_deg.is_some()
}

#[pymethods]
impl CellResult {
    /// The fitted `b1_from_b2` (base 2 in base 1), 4×4, translation in mm.
    #[getter]
    fn b1_from_b2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_array(py, &self.calibrated.calibration.fit.estimate.b1_from_b2)
    }

    /// The verdict at the work site (`calibrate --cell --work-points F --accept-mm X
    /// --accept-deg Y`'s JSON `work_site`: the predicted cooperative accuracy there, mm, the
    /// placement's rotation error, deg, PASS/FAIL and why), or `None` when `calibrate_cell` was
    /// given none of `work_points`, `accept_mm`, `accept_deg`.
    #[getter]
    fn work_site<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?
            .get_item("work_site")
            .or_else(|_| Ok(py.None().into_bound(py)))
    }

    /// Writes the HTML page `calibrate --cell … --report PATH` writes (the verdict at the work
    /// site first, then the placement, the parameters and the plots), with the CLI's function.
    ///
    /// The verdict: from `work_points` (an (n, 3) array of tool positions in base 1, mm, or a
    /// CSV path with header `x_mm,y_mm,z_mm`), `accept_mm` (the largest cooperative position
    /// error accepted at the work site, mm) and `accept_deg` (the largest rotation error of
    /// `b1_from_b2`, deg) when any is given; else `calibrate_cell`'s verdict when it was asked
    /// for one; else at the cell's `[teach]` centre with no acceptance. The page's last line
    /// names this call instead of a command line. Releases the GIL. Errors: `ValueError` for bad
    /// arguments, `OSError` subclasses when the page cannot be written, `CalibrationError` when
    /// the prediction fails. Returns the path written.
    #[pyo3(signature = (path, work_points=None, accept_mm=None, accept_deg=None))]
    fn report(
        &self,
        py: Python<'_>,
        path: PathBuf,
        work_points: Option<&Bound<'_, PyAny>>,
        accept_mm: Option<f64>,
        accept_deg: Option<f64>,
    ) -> PyResult<String> {
        let fresh = if wants_site(work_points, accept_mm, accept_deg) || self.work_site.is_none() {
            let site = SiteInputs::read(&self.cell, work_points, accept_mm, accept_deg)?;
            let w = self.predict(py, &site)?;
            warn_unreachable(py, &w)?;
            Some(w)
        } else {
            None
        };
        let Some(work_site) = fresh.as_ref().or(self.work_site.as_ref()) else {
            return Err(value_error(
                "internal: the page needs the work-site verdict",
            ));
        };
        let json = cell_json(&self.calibrated.report, Some(work_site))?;
        let c = &self.calibrated;
        let inv = invocation("CellResult.report");
        let html = py
            .detach(|| {
                calibration_page_of_fit(
                    &self.cell,
                    &c.problem,
                    &c.calibration,
                    &CalibrationPageInputs {
                        cell: &self.cell_path,
                        session: &self.session_path,
                        model: c.report.model.name(),
                        rows: c.report.rows,
                        meeting_pairs: c.report.cooperative_accuracy_mm.as_ref().map(|m| {
                            MeetingPairsAccuracy {
                                pairs: m.pairs,
                                rms_mm: m.predicted_rms,
                                p95_mm: m.predicted_p95,
                            }
                        }),
                        work_site,
                        json: &json,
                        invocation: &inv,
                    },
                    P95_SEED,
                )
            })
            .map_err(|e| to_py(&e, "report: the rows' residuals", Otherwise::Calibration))?;
        write_page(&path, &html)
    }

    /// The fitted kinematic parameters as columns: `name`, `value`, `sigma` (posterior 1σ),
    /// `prior_sigma`, `unit` (deg, mm, ratio, deg/kNm). `handclasp` wraps it in a DataFrame when
    /// pandas is installed.
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let p = &self.calibrated.report.parameters;
        let out = PyDict::new(py);
        out.set_item("name", p.iter().map(|p| p.name.clone()).collect::<Vec<_>>())?;
        out.set_item("value", vector(py, p.iter().map(|p| p.value).collect()))?;
        out.set_item("sigma", vector(py, p.iter().map(|p| p.sigma).collect()))?;
        out.set_item(
            "prior_sigma",
            vector(py, p.iter().map(|p| p.prior_sigma).collect()),
        )?;
        out.set_item("unit", p.iter().map(|p| p.unit.name()).collect::<Vec<_>>())?;
        Ok(out)
    }

    /// `b1_from_b2`'s posterior σ per axis (translation x, y, z in mm; rotation x, y, z in deg),
    /// shape (6,).
    #[getter]
    fn b1_from_b2_sigma<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        vector(
            py,
            self.calibrated
                .report
                .b1_from_b2
                .sigma
                .iter()
                .map(|s| s.sigma)
                .collect(),
        )
    }

    /// The predicted cooperative accuracy over the session's meeting pairs (dict: `pairs`,
    /// `predicted_rms`, `predicted_p95`, mm), or `None` without coincident or contact rows.
    #[getter]
    fn cooperative_accuracy_mm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?.get_item("cooperative_accuracy_mm")
    }

    /// Writes the calibrated cell into `dir` (`cell.toml`, `robot1.urdf`, `robot2.urdf`), as
    /// `calibrate --cell --export DIR`, under the same folder lock: a non-empty folder raises
    /// `FileExistsError` unless `overwrite` (`--overwrite`), as does a concurrent export into
    /// it. Returns the files written.
    ///
    /// It runs the CLI's do-no-harm check first (the same library function,
    /// `cli_support::do_no_harm::check`; the verdict is [`CellResult::do_no_harm`]): the model
    /// against nominal by region-held-out cross-validation; when the model is worse than
    /// nominal in a held-out region, the error families that harm are withheld family by family
    /// and the export is a refit of the session without them (the placement only when every
    /// family harms), with a `UserWarning` naming what was withheld and why. `force=True`
    /// (`--force`) exports the full model as fitted, with a `UserWarning` when it harms.
    /// (Before, `force=True` raised `ValueError`: it was the old way to overwrite; overwriting is
    /// `overwrite=True`.)
    #[pyo3(signature = (dir, overwrite=false, force=false))]
    fn export(
        &self,
        py: Python<'_>,
        dir: PathBuf,
        overwrite: bool,
        force: bool,
    ) -> PyResult<Vec<String>> {
        check_folder(&dir, overwrite, false)?;
        let harm = self.harm(py)?;
        let model = self.calibrated.report.model;
        let safe = match harm {
            Some((r, safe)) => {
                let mut r = r.clone();
                r.forced = force && r.check.harmful();
                // The CLI's `warning: ` lines (something withheld, or kept by `force`) as
                // warnings, and its `note: ` line when the check could not run; the other notes
                // (folds in row order, rows kept in training) are in `do_no_harm()` only, not
                // a warning on every export.
                let not_checked = r.check.design == HarmDesign::NotChecked;
                for line in cli_support::do_no_harm::messages(&r, model, "force=True") {
                    if let Some(w) = line.strip_prefix("warning: ") {
                        crate::errors::user_warning(py, w)?;
                    } else if not_checked && line.contains("not checked") {
                        crate::errors::user_warning(py, &line)?;
                    }
                }
                if force {
                    None
                } else {
                    safe.as_ref()
                }
            }
            None => None,
        };
        let estimate = &safe.unwrap_or(&self.calibrated).calibration.fit.estimate;
        if let Some((_, note)) =
            handclasp_cell::cell::refitted_robot2_mount(&self.cell, &estimate.b1_from_b2)
        {
            crate::errors::user_warning(py, &note)?;
        }
        locked_export(py, &dir, overwrite, false, || {
            handclasp_cell::export_calibrated_cell(
                &self.cell,
                estimate,
                &dir,
                &handclasp_cell::CALIBRATE_EXPORT_NAMES,
            )
        })
    }

    /// The do-no-harm verdict [`CellResult::export`] applies (the CLI's JSON `do_no_harm`
    /// object of `calibrate --cell --export`, as a dict: the full model's folds against
    /// nominal, `exported` (the model's name, `partial` or `placement`), `kept` and `withheld`
    /// (each family with the held-out regions that decided it), `families`, `trials`), or
    /// `None` for a placement-only calibration (nothing to check). Runs the check on first use
    /// (GIL released; minutes on large sessions), then keeps it.
    fn do_no_harm<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match self.harm(py)? {
            Some((r, _)) => {
                let json = serde_json::to_string(r)
                    .map_err(|e| value_error(format!("serialising the do-no-harm verdict: {e}")))?;
                json_to_py(py, &json)
            }
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// The CLI's text report (with the verdict at the work site when `calibrate_cell` was asked
    /// for one).
    fn text(&self) -> String {
        let mut s = render_text(&self.calibrated.report);
        if let Some(w) = &self.work_site {
            s.push_str(&report::work_site_text(w));
        }
        s
    }

    /// The report as the CLI's JSON text (`calibrate --cell … --json`).
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The report as a dict, equal to `json.loads` of the CLI's `--json` output.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.json)
    }

    fn __repr__(&self) -> String {
        let r = &self.calibrated.report;
        let b = &r.b1_from_b2;
        format!(
            "CellResult(model={:?}, rows_used={}, parameters={}, xyz_mm={:?}, zyz_deg={:?})",
            r.model.name(),
            r.rows_used,
            r.parameters.len(),
            b.xyz_mm,
            b.zyz_deg
        )
    }
}

impl CellResult {
    /// The do-no-harm decision of this calibration, computed once (GIL released).
    fn harm(
        &self,
        py: Python<'_>,
    ) -> PyResult<&Option<(DoNoHarmReport, Option<SessionCalibration>)>> {
        if let Some(h) = self.harm.get() {
            return Ok(h);
        }
        let c = &self.calibrated;
        let h = py
            .detach(|| {
                cli_support::do_no_harm::check(
                    &self.cell,
                    &self.session,
                    c,
                    c.report.model,
                    ScreenMode::Auto,
                    None,
                    false,
                )
            })
            .map_err(|e| to_py(&e, "export", Otherwise::Calibration))?;
        Ok(self.harm.get_or_init(|| h))
    }

    /// The verdict at the work site of this calibration (`report::predict_work_site`, what
    /// `calibrate --cell` calls), GIL released.
    fn predict(&self, py: Python<'_>, site: &SiteInputs) -> PyResult<WorkSiteReport> {
        let c = &self.calibrated;
        py.detach(|| {
            predict_work_site(
                &self.cell,
                &c.problem,
                &c.calibration,
                &site.points,
                &site.source,
                site.acceptance,
                P95_SEED,
            )
        })
        .map_err(|e| to_py(&e, "the verdict at the work site", Otherwise::Calibration))
    }
}

/// Writes a report page to `path` (atomically, replacing a file of that name), as the CLI's
/// `--report`; returns the path. Errors: `OSError` subclasses.
fn write_page(path: &std::path::Path, html: &str) -> PyResult<String> {
    handclasp_cell::output::write_atomically(path, html.as_bytes()).map_err(|e| {
        to_py(
            &e,
            &format!(
                "report {}: cannot write the page (check that its folder exists and is writable)",
                path.display()
            ),
            Otherwise::Value,
        )
    })?;
    Ok(path.display().to_string())
}

/// Calibrates the whole cell from a session, as `handclasp calibrate --cell CELL --session
/// SESSION --model MODEL` does (the same fit, blunder screen, prediction and report).
///
/// `model`: `kinematic` (b1_from_b2 and every identifiable kinematic parameter of both robots,
/// MAP with the cell's tolerances as the prior), `placement` (b1_from_b2 alone) or
/// `kinematic+compliance` (kinematic plus gravity compliance as lumped coefficients, which need
/// no URDF masses). Runs with the
/// GIL released. The result check runs as in the CLI: a refused result raises
/// `CalibrationError` carrying `status`, `reason`, `result_check` (the check values) and
/// `refusal` (the CLI's `--json` refusal object), unless `force=True` (`--force`), which keeps
/// it; the check's findings are issued as `UserWarning`s (`kept by force=True: …` when kept).
///
/// The verdict at the work site (`--work-points F --accept-mm X --accept-deg Y`): given any of
/// `work_points` (an (n, 3) array of tool positions in base 1, mm, or a CSV path with header
/// `x_mm,y_mm,z_mm`; default the cell's `[teach]` centre), `accept_mm` (the largest cooperative
/// position error the job accepts there, mm) and `accept_deg` (the largest rotation error of
/// `b1_from_b2`, deg), the result's `work_site` and `to_dict()["work_site"]` hold the CLI's
/// verdict (PASS when each predicted p95's 95 % interval lies below its threshold). Work points
/// not reachable head-on are `UserWarning`s.
///
/// Errors: `ValueError` for a session of another cell, an unknown model or a bad verdict
/// argument, `CalibrationError` when the fit fails or is refused.
#[pyfunction]
#[pyo3(signature = (cell, session, model="kinematic", force=false, work_points=None, accept_mm=None, accept_deg=None))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate_cell(
    py: Python<'_>,
    cell: &Cell,
    session: &Session,
    model: &str,
    force: bool,
    work_points: Option<&Bound<'_, PyAny>>,
    accept_mm: Option<f64>,
    accept_deg: Option<f64>,
) -> PyResult<CellResult> {
    let Some(model) = CellModel::from_name(model) else {
        return Err(value_error(format!(
            "model={model:?}: use \"kinematic\", \"placement\" or \"kinematic+compliance\""
        )));
    };
    if !Arc::ptr_eq(&cell.cell, &session.cell) {
        return Err(value_error(
            "session: it was read for another Cell object; load it with this cell (Session.load(path, cell))",
        ));
    }
    let site = SiteInputs::read(&cell.cell, work_points, accept_mm, accept_deg)?;
    let c = Arc::clone(&cell.cell);
    let calibrated = py
        .detach(|| calibrate_session(&c, &session.session, model))
        .map_err(|e| {
            let context = match (&session.path, &cell.path) {
                (Some(s), Some(p)) => {
                    format!("calibrating {} with cell {}", s.display(), p.display())
                }
                _ => "calibrating the session".to_string(),
            };
            to_py(&e, &context, Otherwise::Calibration)
        })?;
    if let Some(check) = &calibrated.report.result_check {
        if check.refused() && !force {
            let mut refusal = cli_support::result_check::Refusal::new(
                "calibrate_cell",
                check.refusal_reason().replace("--force", "force=True"),
            );
            refusal.result_check = Some(check);
            return Err(crate::errors::refusal_error(py, &refusal));
        }
        let kept = if check.refused() {
            "kept by force=True: "
        } else {
            ""
        };
        for m in &check.messages {
            crate::errors::user_warning(py, &format!("{kept}{m}"))?;
        }
    }
    let mut result = CellResult {
        json: cell_json(&calibrated.report, None)?,
        calibrated,
        work_site: None,
        cell: c,
        session: session.session.clone(),
        harm: OnceLock::new(),
        cell_path: shown(cell.path.as_deref(), "(a Cell)"),
        session_path: shown(session.path.as_deref(), "(a Session from arrays)"),
    };
    if wants_site(work_points, accept_mm, accept_deg) {
        let w = result.predict(py, &site)?;
        warn_unreachable(py, &w)?;
        result.json = cell_json(&result.calibrated.report, Some(&w))?;
        result.work_site = Some(w);
    }
    Ok(result)
}

/// What a diagnosis found: the coincident-session report or the whole-cell one.
enum Diagnosis {
    /// A session of coincident handclasps only.
    Coincident(Box<::diagnose::DiagnoseReport>),
    /// A session with contact, tracker or plane rows.
    WholeCell(Box<::diagnose::CellDiagnoseReport>),
}

/// The result of [`diagnose`]: what the nominal models get wrong, and the CLI's report.
#[pyclass(module = "handclasp", frozen)]
pub struct DiagnoseResult {
    diagnosis: Diagnosis,
    /// The verdict at the work site and the model it is for, when `diagnose` was asked for it.
    work_site: Option<(WorkSiteReport, VerdictModel)>,
    /// `diagnose(force=True)` (`--force`): the verdict and the export are for the full model,
    /// the families the do-no-harm rule withholds included.
    force: bool,
    cell: Arc<handclasp_cell::Cell>,
    /// The cell's and the session's files as the page names them.
    cell_path: String,
    session_path: String,
    json: String,
}

/// The refusal of a verdict on a coincident-only session (the CLI's message, in Python's words).
const COINCIDENT_NO_VERDICT: &str = "work_points, accept_mm and accept_deg need a session with \
     contact, tracker or plane rows (the whole-cell diagnosis, whose exported model has a \
     posterior to predict from); this session has coincident rows only: drop them, or get the \
     verdict from handclasp.calibrate_cell(cell, session, work_points=…, accept_mm=…)";

impl DiagnoseResult {
    /// The verdict at the work site of the model a whole-cell diagnosis exports
    /// (`report::diagnosis_work_site`, what `diagnose` calls: the do-no-harm model, or the full
    /// model with `force=True`, as `--force`), GIL released. Errors: `ValueError` for a coincident diagnosis, `CalibrationError` when the
    /// prediction fails.
    fn predict(
        &self,
        py: Python<'_>,
        site: &SiteInputs,
    ) -> PyResult<(WorkSiteReport, VerdictModel)> {
        let Diagnosis::WholeCell(r) = &self.diagnosis else {
            return Err(value_error(COINCIDENT_NO_VERDICT));
        };
        let verdict = py
            .detach(|| {
                diagnosis_work_site(
                    &self.cell,
                    r,
                    self.force,
                    &site.points,
                    &site.source,
                    site.acceptance,
                    P95_SEED,
                )
            })
            .map_err(|e| to_py(&e, "the verdict at the work site", Otherwise::Calibration))?;
        warn_unreachable(py, &verdict.0)?;
        Ok(verdict)
    }

    /// The whole-cell diagnosis's JSON with the verdict, as `diagnose --json` prints it
    /// (compact).
    fn cell_json(
        r: &::diagnose::CellDiagnoseReport,
        verdict: Option<&(WorkSiteReport, VerdictModel)>,
    ) -> PyResult<String> {
        serde_json::to_string(&CellDiagnosisWithSite {
            report: r,
            work_site: verdict.map(|v| &v.0),
            work_site_model: verdict.map(|v| &v.1),
        })
        .map_err(|e| value_error(e.to_string()))
    }
}

#[pymethods]
impl DiagnoseResult {
    /// `"coincident"` or `"whole_cell"`: which diagnosis ran (by the session's kinds).
    #[getter]
    fn mode(&self) -> &'static str {
        match self.diagnosis {
            Diagnosis::Coincident(_) => "coincident",
            Diagnosis::WholeCell(_) => "whole_cell",
        }
    }

    /// The diagnosed `b1_from_b2`, 4×4, translation in mm.
    #[getter]
    fn b1_from_b2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        match &self.diagnosis {
            Diagnosis::Coincident(r) => pose_array(py, &r.b1_from_b2.to_isometry()),
            Diagnosis::WholeCell(r) => pose_array(py, &r.final_estimate.b1_from_b2),
        }
    }

    /// Writes the corrected model into `dir`, as `diagnose --export DIR`, under the same
    /// folder lock: a non-empty folder raises `FileExistsError` unless `overwrite`
    /// (`--overwrite`); `force=True` no longer overwrites (`ValueError`). Returns the files
    /// written.
    ///
    /// Whole-cell diagnoses: the do-no-harm rule's model, as the CLI writes it; when the rule
    /// withholds families, a `UserWarning` says which and why (the CLI's `warning: do no harm:
    /// …` line, then one line per withheld family with the held-out folds where the model
    /// with it is worse than nominal). `keep_withheld=True` writes the full model, the
    /// withheld families included (the CLI's `--export --force`), and warns that it did;
    /// its default (`None`) is `diagnose`'s `force`, so `diagnose(…, force=True).export(dir)`
    /// writes what `diagnose … --force --export DIR` writes. Coincident diagnoses have no such
    /// rule: `keep_withheld` changes nothing.
    #[pyo3(signature = (dir, overwrite=false, force=false, keep_withheld=None))]
    fn export(
        &self,
        py: Python<'_>,
        dir: PathBuf,
        overwrite: bool,
        force: bool,
        keep_withheld: Option<bool>,
    ) -> PyResult<Vec<String>> {
        let (keep_withheld, by) = match keep_withheld {
            Some(k) => (k, "keep_withheld=True"),
            None => (self.force, "diagnose(force=True)"),
        };
        let files = locked_export(py, &dir, overwrite, force, || match &self.diagnosis {
            Diagnosis::Coincident(r) => {
                ::diagnose::export_corrected(&self.cell, r, &r.b1_from_b2.to_isometry(), &dir)
            }
            Diagnosis::WholeCell(r) => {
                ::diagnose::export_cell_diagnosis_with(&self.cell, r, &dir, keep_withheld)
            }
        })?;
        if let Diagnosis::WholeCell(r) = &self.diagnosis {
            if let Some(warning) = r.do_no_harm_warning("keep_withheld=True") {
                let text = if keep_withheld {
                    format!(
                        "kept by {by}: {} holds the full model, families the do-no-harm \
                         rule withholds included ({warning})",
                        dir.display()
                    )
                } else {
                    let mut lines = vec![warning];
                    lines.extend(r.do_no_harm.withheld_lines());
                    lines.join("\n  ")
                };
                crate::errors::user_warning(py, &text)?;
            }
        }
        Ok(files)
    }

    /// The verdict at the work site (`diagnose --work-points F --accept-mm X --accept-deg Y`'s
    /// JSON `work_site`), or `None` when `diagnose` was given none of `work_points`,
    /// `accept_mm`, `accept_deg`. `to_dict()["work_site_model"]` says which model it is for.
    #[getter]
    fn work_site<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?
            .get_item("work_site")
            .or_else(|_| Ok(py.None().into_bound(py)))
    }

    /// Writes the HTML page `diagnose … --report PATH` writes, with the CLI's function: for a
    /// whole-cell diagnosis the verdict at the work site first (of the model `export` writes:
    /// the do-no-harm rule's), then the named causes with their held-out gain, the rejected
    /// families and the plots; for a coincident one the causes and the families.
    ///
    /// The verdict (whole-cell diagnoses only; `ValueError` on a coincident one): from
    /// `work_points` (an (n, 3) array of tool positions in base 1, mm, or a CSV path with header
    /// `x_mm,y_mm,z_mm`), `accept_mm` (mm) and `accept_deg` (deg) when any is given; else
    /// `diagnose`'s verdict when it was asked for one; else at the cell's `[teach]` centre with
    /// no acceptance. The page's last line names this call instead of a command line. Releases
    /// the GIL. Errors: `OSError` subclasses when the page cannot be written. Returns the path
    /// written.
    #[pyo3(signature = (path, work_points=None, accept_mm=None, accept_deg=None))]
    fn report(
        &self,
        py: Python<'_>,
        path: PathBuf,
        work_points: Option<&Bound<'_, PyAny>>,
        accept_mm: Option<f64>,
        accept_deg: Option<f64>,
    ) -> PyResult<String> {
        let inv = invocation("DiagnoseResult.report");
        let html = match &self.diagnosis {
            Diagnosis::Coincident(r) => {
                if wants_site(work_points, accept_mm, accept_deg) {
                    return Err(value_error(COINCIDENT_NO_VERDICT));
                }
                coincident_diagnosis_page(r, &self.cell_path, &self.session_path, &self.json, &inv)
            }
            Diagnosis::WholeCell(r) => {
                let fresh = if wants_site(work_points, accept_mm, accept_deg)
                    || self.work_site.is_none()
                {
                    let site = SiteInputs::read(&self.cell, work_points, accept_mm, accept_deg)?;
                    Some(self.predict(py, &site)?)
                } else {
                    None
                };
                let verdict = fresh.as_ref().or(self.work_site.as_ref());
                let json = Self::cell_json(r, verdict)?;
                cell_diagnosis_page(
                    r,
                    verdict.map(|(w, m)| (w, m)),
                    &self.cell_path,
                    &self.session_path,
                    &json,
                    &inv,
                )
            }
        };
        write_page(&path, &html)
    }

    /// The CLI's text report (with the verdict at the work site when `diagnose` was asked for
    /// one).
    fn text(&self) -> String {
        match &self.diagnosis {
            Diagnosis::Coincident(r) => ::diagnose::render_text(r),
            Diagnosis::WholeCell(r) => {
                let mut text = ::diagnose::render_cell_text(r);
                if let Some((w, model)) = &self.work_site {
                    text.push_str(&format!(
                        "work site: the verdict is for {}\n",
                        model.description
                    ));
                    text.push_str(&report::work_site_text(w));
                }
                text
            }
        }
    }

    /// The report as the CLI's JSON text (`diagnose … --json`).
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The report as a dict, equal to `json.loads` of the CLI's `--json` output.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.json)
    }

    fn __repr__(&self) -> String {
        format!("DiagnoseResult(mode={:?})", self.mode())
    }
}

/// The diagnosis's coverage report, as `handclasp diagnose` adds it (its warnings as Python
/// `UserWarning`s are not raised: the report carries them).
fn coverage(
    cell: &handclasp_cell::Cell,
    session: &handclasp_cell::Session,
) -> PyResult<calib_core::whole_cell::CoverageReport> {
    cli_support::cell_report::session_coverage_report(cell, session).map_err(|e| {
        to_py(
            &e,
            "the session's coverage of the robots' joint ranges and reach",
            Otherwise::Calibration,
        )
    })
}

/// Diagnoses what the nominal models get wrong in a measured session, as `handclasp diagnose
/// --cell CELL --session SESSION` does: a session with contact, tracker or plane rows gets the
/// whole-cell diagnosis (`prior_widening`), one of coincident handclasps the coincident one
/// (`seed`, `trials`, optional truth of `b1_from_b2`: `truth_xyz_mm` (3,) mm and
/// `truth_zyz_deg` (3,) ZYZ degrees). Runs with the GIL released.
///
/// The verdict at the work site (whole-cell diagnoses, as `diagnose --work-points F
/// --accept-mm X --accept-deg Y`): given any of `work_points` (an (n, 3) array of tool
/// positions in base 1, mm, or a CSV path with header `x_mm,y_mm,z_mm`; default the cell's
/// `[teach]` centre), `accept_mm` (mm) and `accept_deg` (deg), the result's `work_site` and
/// `to_dict()["work_site"]` / `["work_site_model"]` hold the CLI's verdict for the model
/// `export` writes (the do-no-harm rule's). On a coincident-only session they raise
/// `ValueError`, as the CLI refuses them.
///
/// `force=True` (`diagnose --force`): the verdict (and `.report(path)`'s, and `.export(dir)`'s
/// default) is for the full model, the families the do-no-harm rule withholds included, as the
/// CLI's `--force` makes it (`to_dict()["work_site_model"]["model"]` says `"full"`). Unlike the
/// CLI, `diagnose` runs no result check (a placement fit) before the diagnosis, so there is no
/// refusal for `force` to keep.
#[pyfunction]
#[pyo3(signature = (cell, session, seed=1, trials=400, prior_widening=10.0, truth_xyz_mm=None, truth_zyz_deg=None, work_points=None, accept_mm=None, accept_deg=None, force=false))]
#[allow(clippy::too_many_arguments)]
pub fn diagnose(
    py: Python<'_>,
    cell: &Cell,
    session: &Session,
    seed: u64,
    trials: usize,
    prior_widening: f64,
    truth_xyz_mm: Option<[f64; 3]>,
    truth_zyz_deg: Option<[f64; 3]>,
    work_points: Option<&Bound<'_, PyAny>>,
    accept_mm: Option<f64>,
    accept_deg: Option<f64>,
    force: bool,
) -> PyResult<DiagnoseResult> {
    let truth = match (truth_xyz_mm, truth_zyz_deg) {
        (Some(t), Some(z)) => {
            if !t.iter().chain(&z).all(|v| v.is_finite()) {
                return Err(value_error(
                    "truth_xyz_mm and truth_zyz_deg must be finite numbers",
                ));
            }
            let rot = kinematics::rotation_from_zyz(z.map(f64::to_radians));
            Some(Isometry3::from_parts(
                Translation3::from(Vector3::new(t[0], t[1], t[2]) / 1000.0),
                UnitQuaternion::from_rotation_matrix(&rot),
            ))
        }
        (None, None) => None,
        _ => return Err(value_error(
            "give both truth_xyz_mm (x, y, z in mm) and truth_zyz_deg (ZYZ degrees), or neither",
        )),
    };
    if trials < 20 {
        return Err(value_error(format!(
            "trials={trials} is too few for a residual distribution: use at least 20 (default 400)"
        )));
    }
    if !Arc::ptr_eq(&cell.cell, &session.cell) {
        return Err(value_error(
            "session: it was read for another Cell object; load it with this cell (Session.load(path, cell))",
        ));
    }
    let wants = wants_site(work_points, accept_mm, accept_deg);
    if wants && session.session.is_handclasp_only() {
        return Err(value_error(COINCIDENT_NO_VERDICT));
    }
    let site = SiteInputs::read(&cell.cell, work_points, accept_mm, accept_deg)?;
    let c = Arc::clone(&cell.cell);
    let context = match &session.path {
        Some(p) => format!("diagnosing {}", p.display()),
        None => "diagnosing the session".to_string(),
    };
    let s = &session.session;
    let (diagnosis, json) = if !s.is_handclasp_only() {
        if truth.is_some() {
            return Err(value_error(
                "truth_* applies to coincident-only sessions; this session has contact, tracker or plane rows (whole-cell diagnosis)",
            ));
        }
        let options = ::diagnose::CellDiagnoseOptions {
            prior_widening,
            ..::diagnose::CellDiagnoseOptions::default()
        };
        let mut report = py
            .detach(|| ::diagnose::diagnose_cell_session(&c, s, &options, &|_| {}))
            .map_err(|e| to_py(&e, &context, Otherwise::Calibration))?;
        report.coverage = Some(coverage(&c, s)?);
        // The CLI prints this report compact (`serde_json::to_string`).
        let json = DiagnoseResult::cell_json(&report, None)?;
        (Diagnosis::WholeCell(Box::new(report)), json)
    } else {
        let options = ::diagnose::DiagnoseOptions {
            seed,
            trials,
            truth,
            ..::diagnose::DiagnoseOptions::default()
        };
        let mut report = py
            .detach(|| {
                // The CLI reads a coincident session with diagnose's own loader (its unit
                // checks); a session from arrays is checked by the engine.
                let loaded = match &session.path {
                    Some(p) => Some(::diagnose::load_session(p, &c)?),
                    None => None,
                };
                ::diagnose::diagnose_session(&c, loaded.as_ref().unwrap_or(s), &options)
            })
            .map_err(|e| to_py(&e, &context, Otherwise::Calibration))?;
        report.coverage = Some(coverage(&c, s)?);
        let json = serde_json::to_string(&report).map_err(|e| value_error(e.to_string()))?;
        (Diagnosis::Coincident(Box::new(report)), json)
    };
    let mut result = DiagnoseResult {
        diagnosis,
        work_site: None,
        force,
        cell: c,
        cell_path: shown(cell.path.as_deref(), "(a Cell)"),
        session_path: shown(session.path.as_deref(), "(a Session from arrays)"),
        json,
    };
    if wants {
        let verdict = result.predict(py, &site)?;
        if let Diagnosis::WholeCell(r) = &result.diagnosis {
            result.json = DiagnoseResult::cell_json(r, Some(&verdict))?;
        }
        result.work_site = Some(verdict);
    }
    Ok(result)
}
