//! `validate`: a calibrated cell scored on a session it was not fitted to, beside the nominal
//! cell, as `handclasp validate` computes it ([`cli_support::validate`], the CLI's function).

use std::path::PathBuf;
use std::sync::Arc;

use cli_support::validate::{
    read_session, render_text, validate as score, warnings, NamedCell, Nuisance, NuisanceSource,
    ValidateReport,
};
use pyo3::prelude::*;

use crate::arrays::json_to_py;
use crate::cell::{Cell, Session};
use crate::errors::{to_py, user_warning, value_error, Otherwise};
use crate::work_site::shown;

/// How a session read with the wrong cell is told to name the nominal cell.
const NOMINAL_HINT: &str = "nominal=Cell.load(NOMINAL.toml)";

/// The result of [`validate`]: per kind, per nuisance group and over all rows, each cell's rms,
/// largest and whitened residual, and the calibrated-over-nominal rms ratio.
#[pyclass(module = "handclasp", frozen)]
pub struct ValidateResult {
    report: ValidateReport,
    json: String,
}

#[pymethods]
impl ValidateResult {
    /// The report as a dict, equal to `json.loads` of `handclasp validate … --json`.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.json)
    }

    /// The report as the CLI's JSON text (`validate … --json`, pretty).
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The CLI's text report (`validate` without `--json`).
    fn text(&self) -> String {
        render_text(&self.report)
    }

    /// The CLI's `warning:` lines without the prefix (also issued as `UserWarning`s by
    /// `validate`): the calibrated cell fits worse than nominal, or its whitened rms is far
    /// above the stated noise.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        warnings(&self.report)
    }

    /// Over every row: `to_dict()["all"]` (`rows`, `calibrated` and `nominal` scores with
    /// `rms_mm`, `max_mm`, `whitened_rms`, and `rms_ratio`).
    #[getter]
    fn all<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.to_dict(py)?.get_item("all")
    }

    fn __repr__(&self) -> String {
        let a = &self.report.all;
        format!(
            "ValidateResult(rows={}, calibrated_rms_mm={:.4}, nominal_rms_mm={}, rms_ratio={})",
            a.rows,
            a.calibrated.rms_mm,
            a.nominal
                .map_or("None".to_string(), |n| format!("{:.4}", n.rms_mm)),
            a.rms_ratio
                .map_or("None".to_string(), |r| format!("{r:.4}"))
        )
    }
}

/// A session argument: a `Session` read with one of the two cells, or a CSV path read as the
/// CLI reads it (with the nominal cell first, then the calibrated cell). Returns the session
/// and the name the report gives it.
fn session_of(
    py: Python<'_>,
    arg: &Bound<'_, PyAny>,
    what: &str,
    calibrated: &Cell,
    nominal: Option<&Cell>,
) -> PyResult<(handclasp_cell::Session, String)> {
    if let Ok(s) = arg.cast::<Session>() {
        let s = s.get();
        let ours = Arc::ptr_eq(&s.cell, &calibrated.cell)
            || nominal.is_some_and(|n| Arc::ptr_eq(&s.cell, &n.cell));
        if !ours {
            return Err(value_error(format!(
                "{what}: it was read for another Cell object; load it with the nominal cell \
                 (Session.load(path, nominal)) or the calibrated one, or pass its path"
            )));
        }
        return Ok((
            s.session.clone(),
            shown(s.path.as_deref(), "(a Session from arrays)"),
        ));
    }
    let path: PathBuf = arg.extract().map_err(|_| {
        value_error(format!(
            "{what}: give a handclasp.Session or a session CSV path"
        ))
    })?;
    let label = |arg: &str, c: &Cell| format!("{arg}={}", shown(c.path.as_deref(), "(a Cell)"));
    let mut readers: Vec<(String, &handclasp_cell::Cell)> = Vec::new();
    if let Some(n) = nominal {
        readers.push((label("nominal", n), &n.cell));
    }
    readers.push((label("calibrated_cell", calibrated), &calibrated.cell));
    let session = py
        .detach(|| read_session(&path, &readers, NOMINAL_HINT))
        .map_err(|e| to_py(&e, "", Otherwise::Value))?;
    Ok((session, path.display().to_string()))
}

/// Scores a calibrated cell on a session it was not fitted to, beside the nominal cell, as
/// `handclasp validate --cell CALIBRATED --session NEW [--nominal NOMINAL] [--nuisance
/// split|fixed --calibration-session OLD]` does (the same function).
///
/// `calibrated_cell`: a `Cell`, e.g. `Cell.load` of `CellResult.export(dir)`'s `cell.toml` (its
/// placement, URDFs, tips and `[robotN.errors]` are scored; nothing of it is fitted).
/// `session`: a `Session` read with either cell, or a CSV path (read with `nominal` first, then
/// the calibrated cell: a session's tip columns are the models that recorded it). `nominal`: a
/// `Cell` to compare with (its `[robotN.errors]` ignored). `nuisance`: where the session's
/// tracker frames, planes and fitted contact distances come from: `"split"` (default) fits each
/// group's on alternate rows and scores the other rows, and back; `"fixed"` fits them on
/// `calibration_session` (a `Session` or path, the one the cell was calibrated on, its groups
/// named as the new session's) with each cell held and carries them over by group name.
///
/// Returns a `ValidateResult` (`.to_dict()` equal to the CLI's `--json`, `.text()`, `.all`,
/// `.warnings`); the CLI's `warning:` lines are issued as `UserWarning`s. Releases the GIL.
/// Errors: `ValueError` for bad arguments or a session that does not fit the cells, `OSError`
/// subclasses for unreadable files, `CalibrationError` when a cell cannot be scored (a nuisance
/// fit fails).
#[pyfunction]
#[pyo3(signature = (calibrated_cell, session, nominal=None, nuisance="split", calibration_session=None))]
pub fn validate(
    py: Python<'_>,
    calibrated_cell: &Cell,
    session: &Bound<'_, PyAny>,
    nominal: Option<&Cell>,
    nuisance: &str,
    calibration_session: Option<&Bound<'_, PyAny>>,
) -> PyResult<ValidateResult> {
    let mode = match nuisance {
        "split" => Nuisance::Split,
        "fixed" => Nuisance::Fixed,
        other => {
            return Err(value_error(format!(
                "nuisance={other:?}: use \"split\" (refit on alternate rows of each group) or \
                 \"fixed\" (fitted on calibration_session)"
            )))
        }
    };
    match (mode, calibration_session.is_some()) {
        (Nuisance::Split, true) => {
            return Err(value_error(
                "calibration_session is used with nuisance=\"fixed\" only: add \
                 nuisance=\"fixed\", or drop it",
            ))
        }
        (Nuisance::Fixed, false) => {
            return Err(value_error(
                "nuisance=\"fixed\" needs calibration_session (the session the cell was \
                 calibrated on)",
            ))
        }
        _ => {}
    }
    let (new, session_name) = session_of(py, session, "session", calibrated_cell, nominal)?;
    let old = calibration_session
        .map(|s| session_of(py, s, "calibration_session", calibrated_cell, nominal))
        .transpose()?;
    let source = match &old {
        Some((calibration, _)) => NuisanceSource::Fixed { calibration },
        None => NuisanceSource::Split,
    };
    let cal_name = shown(calibrated_cell.path.as_deref(), "(a Cell)");
    let nom_name = nominal.map(|n| shown(n.path.as_deref(), "(a Cell)"));
    let report = py
        .detach(|| {
            score(
                NamedCell {
                    cell: &calibrated_cell.cell,
                    name: &cal_name,
                },
                nominal.zip(nom_name.as_deref()).map(|(n, name)| NamedCell {
                    cell: &n.cell,
                    name,
                }),
                &new,
                &session_name,
                source,
            )
        })
        .map_err(|e| to_py(&e, "", Otherwise::Calibration))?;
    for w in warnings(&report) {
        user_warning(py, &w)?;
    }
    let json = serde_json::to_string_pretty(&report)
        .map_err(|e| value_error(format!("serialising the report: {e}")))?;
    Ok(ValidateResult { report, json })
}
