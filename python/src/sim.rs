//! The simulator: `simulate_session` (a simulated measured session) and `plan` (the poses that
//! calibrate the cell best), as `sim-cell session` and `handclasp plan` compute them.

use std::sync::Arc;

use nalgebra::Point3;
use pyo3::prelude::*;
use sim_cell::plan::report::{render_text, Criterion, PlanInputs, PlanReport};
use sim_cell::plan::{plan_session, PlanSpec, DEFAULT_RANDOM_DRAWS};
use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

use crate::cell::{Cell, Session};
use crate::errors::{to_py, value_error, Otherwise};

/// `centre_mm` (3 numbers, mm, b1) in m.
fn centre(centre_mm: Option<[f64; 3]>) -> PyResult<Option<Point3<f64>>> {
    match centre_mm {
        None => Ok(None),
        Some(c) if c.iter().all(|v| v.is_finite()) => {
            Ok(Some(Point3::new(c[0], c[1], c[2]) * 1e-3))
        }
        Some(c) => Err(value_error(format!(
            "centre_mm takes three finite numbers x, y, z in mm (e.g. (475, -50, 995)); got {c:?}"
        ))),
    }
}

/// Simulates a measured session of `cell` (its `[robotN.errors]` are the hidden truth, its
/// `[noise]` the measurement noise), as `sim-cell session --cell CELL --n N --seed SEED` does.
///
/// `n`: teach points; `layout`: tetrahedron, random, planar or clustered; `spread_mm`: the
/// layout's size, mm; `centre_mm`: its centre in b1, mm (default: the cell's teach centre);
/// `kind`: coincident, contact, face_contact, tracker, plane or mixed (the other kinds' settings
/// are sim-cell's defaults). Seeded: the same seed gives the same session. Returns a `Session`.
#[pyfunction]
#[pyo3(signature = (cell, n=6, seed=1, layout="tetrahedron", spread_mm=1000.0, centre_mm=None, kind="coincident"))]
#[allow(clippy::too_many_arguments)]
pub fn simulate_session(
    py: Python<'_>,
    cell: &Cell,
    n: usize,
    seed: u64,
    layout: &str,
    spread_mm: f64,
    centre_mm: Option<[f64; 3]>,
    kind: &str,
) -> PyResult<Session> {
    let Some(layout) = Layout::from_name(layout) else {
        return Err(value_error(format!(
            "layout={layout:?}: use tetrahedron, random, planar or clustered"
        )));
    };
    let kind = match kind {
        "coincident" => SimKind::Coincident,
        "contact" => SimKind::Contact,
        "face_contact" => SimKind::FaceContact,
        "tracker" => SimKind::Tracker,
        "plane" => SimKind::Plane,
        "mixed" => SimKind::Mixed,
        other => {
            return Err(value_error(format!(
                "kind={other:?}: use coincident, contact, face_contact, tracker, plane or mixed"
            )))
        }
    };
    let mut spec = SessionSpec::new(n, layout, spread_mm * 1e-3);
    spec.centre_b1 = centre(centre_mm)?;
    let kinds = KindSpec {
        kind,
        ..KindSpec::default()
    };
    let c = Arc::clone(&cell.cell);
    let (session, _truth) = py
        .detach(|| generate_kind_session(&c, &spec, &kinds, None, &mut trial_rng(seed, 0)))
        .map_err(|e| to_py(&e, "", Otherwise::Value))?;
    Ok(Session {
        session,
        cell: c,
        path: None,
    })
}

/// The result of [`plan`]: the planned poses (a `Session`) and `handclasp plan`'s report.
#[pyclass(module = "handclasp", frozen)]
pub struct PlanResult {
    session: Py<Session>,
    report: PlanReport,
    json: String,
}

#[pymethods]
impl PlanResult {
    /// The planned poses as a `Session` (joints and nominal tips), to teach from.
    #[getter]
    fn session(&self, py: Python<'_>) -> Py<Session> {
        self.session.clone_ref(py)
    }

    /// The plan's session CSV text (what `handclasp plan --out` writes).
    fn to_csv_string(&self, py: Python<'_>) -> String {
        self.session.borrow(py).csv_text()
    }

    /// Writes the plan's session CSV (`--out`). Errors: `OSError` subclasses.
    fn to_csv(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        self.session.borrow(py).write_csv(&path)
    }

    /// The session's columns (`Session.columns`).
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        self.session.borrow(py).columns_dict(py)
    }

    /// The number of planned poses.
    fn __len__(&self, py: Python<'_>) -> usize {
        self.session.borrow(py).session.len()
    }

    /// The CLI's text report.
    fn text(&self) -> String {
        render_text(&self.report)
    }

    /// The report as the CLI's JSON text (`plan --json`).
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The report as a dict, equal to `json.loads` of `handclasp plan … --json`: the poses, the
    /// plan's predicted cooperative error beside the random picks' mean (mm, deg), its parts.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        crate::arrays::json_to_py(py, &self.json)
    }

    fn __repr__(&self) -> String {
        format!(
            "PlanResult(n={}, criterion={:?}, cooperative_rms_mm={:.3}, random_mean_mm={:.3})",
            self.report.n,
            self.report.criterion,
            self.report.predicted.plan.cooperative_rms_mm,
            self.report.predicted.random.cooperative_rms_mm
        )
    }
}

/// Plans a session: the `n` handclasp poses (of `candidates` seeded candidates both robots reach)
/// that minimise the predicted cooperative error of the whole-cell calibration (`criterion="a"`)
/// or maximise its information volume (`"d"`), as `handclasp plan` does. `spread_mm`: the side of
/// the candidates' cube, mm; `centre_mm`: its centre in b1, mm (default: the cell's teach
/// centre); `out`: where to write the plan's session CSV (`--out`; `None`: not written, and the
/// report says `(not written)`).
///
/// Returns a `PlanResult`: `.session` (the poses as a `Session`; `.to_csv`, `.to_csv_string`,
/// `.columns`, `len()` as the session's), `.to_dict()` (the CLI's `plan --json`: the poses,
/// the plan's predicted cooperative error beside the random picks' mean, mm and deg), `.text()`.
/// The layout checks `calibrate --cell` runs on a session are `UserWarning`s. Runs with the GIL
/// released. Errors: `ValueError` (a bad option, a one-robot cell), `OSError` subclasses (`out`).
#[pyfunction]
#[pyo3(signature = (cell, n=40, candidates=400, criterion="a", seed=1, spread_mm=1000.0, centre_mm=None, random_draws=DEFAULT_RANDOM_DRAWS, out=None))]
#[allow(clippy::too_many_arguments)]
pub fn plan(
    py: Python<'_>,
    cell: &Cell,
    n: usize,
    candidates: usize,
    criterion: &str,
    seed: u64,
    spread_mm: f64,
    centre_mm: Option<[f64; 3]>,
    random_draws: usize,
    out: Option<std::path::PathBuf>,
) -> PyResult<PlanResult> {
    let Some(criterion) = Criterion::from_name(criterion) else {
        return Err(value_error(format!(
            "criterion={criterion:?}: use \"a\" (smallest predicted cooperative error) or \"d\" (largest information volume)"
        )));
    };
    let spec = PlanSpec {
        n,
        candidates,
        criterion: criterion.design(),
        seed,
        spread_m: spread_mm * 1e-3,
        centre_b1: centre(centre_mm)?,
        random_draws,
    };
    let c = Arc::clone(&cell.cell);
    let planned = py
        .detach(|| plan_session(&c, &spec, &mut |_, _| {}))
        .map_err(|e| to_py(&e, "planning", Otherwise::Value))?;
    // The degeneracy check calibrate --cell runs on a session, in its words (as the CLI).
    let problem = handclasp_cell::problem::cell_problem(
        &c,
        &planned.session,
        handclasp_cell::problem::FitModel::Kinematic,
    );
    for w in cli_support::result_check::layout_warnings(&problem) {
        crate::errors::user_warning(py, &w)?;
    }
    let cell_name = crate::work_site::shown(cell.path.as_deref(), "(a Cell)");
    let out_name = crate::work_site::shown(out.as_deref(), "(not written)");
    let report = PlanReport::new(
        &PlanInputs {
            cell: &cell_name,
            out: &out_name,
            n,
            candidates,
            criterion,
            seed,
            spread_mm,
            centre_mm,
        },
        &c,
        &planned,
    );
    let json = serde_json::to_string_pretty(&report)
        .map_err(|e| value_error(format!("serialising the report: {e}")))?;
    let session = Session {
        session: planned.session,
        cell: c,
        path: None,
    };
    if let Some(path) = &out {
        session.write_csv(path)?;
    }
    Ok(PlanResult {
        session: Py::new(py, session)?,
        report,
        json,
    })
}

/// A seeded Monte Carlo sweep over the paper's cells, as `sim-cell sweep` runs it: for each grid
/// cell (mounts × noise × spread × points) `trials` simulated sessions, each fitted by every
/// method. Returns the summary table (`sim-cell sweep`'s `summary.csv`: one row per grid cell
/// and method, errors in mm and deg) as a dict of columns, or with `trials_table=True` the
/// per-trial table (`trials.csv`). Runs with the GIL released; the result is identical whatever
/// the thread count.
///
/// `mode`: `"geometry"` (points and noise only, fast; default) or `"robot"` (`--mode robot`:
/// full sessions on the cells' robots: IK, reach limits, encoder quantisation, repeatability;
/// methods also `paper-spread4`, `placement`, `kinematic`). Robot mode only: `layout`
/// (`tetrahedron`, `random`, `planar`, `clustered`, `planned`; `--layout`), `kinematic_errors`
/// (`"none"`: the cells' `[robotN.errors]`; `"tolerance"`: drawn per trial from
/// `[robotN.tolerance]`) and `cells` (a list of `Cell`s instead of the paper's three; their
/// mounts replace `mounts`, `--cell`). `trials` defaults to 200 (geometry) or 5 (robot).
#[pyfunction]
#[pyo3(signature = (mounts=None, noise_mm=None, spread_mm=None, n_points=None, methods=None, trials=None, seed=1, trials_table=false, mode="geometry", layout=None, kinematic_errors="none", cells=None))]
#[allow(clippy::too_many_arguments)]
pub fn sweep<'py>(
    py: Python<'py>,
    mounts: Option<Vec<String>>,
    noise_mm: Option<Vec<f64>>,
    spread_mm: Option<Vec<f64>>,
    n_points: Option<Vec<usize>>,
    methods: Option<Vec<String>>,
    trials: Option<usize>,
    seed: u64,
    trials_table: bool,
    mode: &str,
    layout: Option<&str>,
    kinematic_errors: &str,
    cells: Option<Vec<PyRef<'_, crate::cell::Cell>>>,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    use sim_cell::sweep::{
        run_sweep, summarize_cells, write_summary_csv, write_trials_csv, KinematicErrorDraw, Mode,
        SweepConfig, SweepLayout, SweepMethod,
    };
    let defaults = SweepConfig::default();
    let mode = match mode {
        "geometry" => Mode::Geometry,
        "robot" => Mode::Robot,
        other => {
            return Err(value_error(format!(
                "mode={other:?}: use \"geometry\" (points and noise only) or \"robot\" \
                 (full sessions)"
            )))
        }
    };
    let robot_only = |given: bool, what: &str| {
        if given && mode == Mode::Geometry {
            Err(value_error(format!(
                "{what} is for mode=\"robot\" (geometry mode uses the paper's placements and layouts only)"
            )))
        } else {
            Ok(())
        }
    };
    robot_only(cells.is_some(), "cells")?;
    robot_only(kinematic_errors != "none", "kinematic_errors")?;
    let layout = match layout {
        None => defaults.layout,
        Some("planned") => SweepLayout::Planned,
        Some(name) => sim_cell::layout::Layout::ALL
            .into_iter()
            .find(|l| l.name() == name)
            .map(SweepLayout::from)
            .ok_or_else(|| {
                value_error(format!(
                    "layout={name:?}: use tetrahedron, random, planar, clustered or (robot mode) planned"
                ))
            })?,
    };
    let kinematic_errors = match kinematic_errors {
        "none" => KinematicErrorDraw::None,
        "tolerance" => KinematicErrorDraw::Tolerance,
        other => {
            return Err(value_error(format!(
                "kinematic_errors={other:?}: use \"none\" (the cells' [robotN.errors]) or \"tolerance\" (drawn per trial)"
            )))
        }
    };
    let mut mounts = match mounts {
        None => defaults.mounts.clone(),
        Some(m) => m
            .iter()
            .map(|m| {
                calib_core::MountPair::parse_paper(m)
                    .map_err(|e| value_error(format!("mounts: {e}")))
            })
            .collect::<PyResult<Vec<_>>>()?,
    };
    let methods = match methods {
        None => defaults.methods.clone(),
        Some(m) => m
            .iter()
            .map(|m| {
                SweepMethod::from_name(m).ok_or_else(|| {
                    value_error(format!(
                        "methods: unknown method `{m}`; use generic, generic-affine, paper, lsq, constrained, or in robot mode paper-spread4, placement, kinematic"
                    ))
                })
            })
            .collect::<PyResult<Vec<_>>>()?,
    };
    // Robot mode: one cell per mount pair, the given cells (their mounts replace `mounts`) or
    // the paper's.
    let robot_cells: Vec<handclasp_cell::Cell> = match (mode, cells) {
        (Mode::Geometry, _) => Vec::new(),
        (Mode::Robot, Some(given)) => {
            let given: Vec<handclasp_cell::Cell> =
                given.iter().map(|c| (*c.cell).clone()).collect();
            mounts = given.iter().map(handclasp_cell::Cell::mounts).collect();
            given
        }
        (Mode::Robot, None) => mounts
            .iter()
            .map(|m| {
                handclasp_cell::Cell::shipped(*m).ok_or_else(|| {
                    value_error("robot mode without cells knows the paper's three cells only")
                })
            })
            .collect::<PyResult<_>>()?,
    };
    let config = SweepConfig {
        mode,
        mounts,
        noise_mm: noise_mm.unwrap_or(defaults.noise_mm.clone()),
        spread_m: spread_mm.map_or(defaults.spread_m.clone(), |s| {
            s.iter().map(|v| v * 1e-3).collect()
        }),
        n_points: n_points.unwrap_or(defaults.n_points.clone()),
        methods,
        layout,
        kinematic_errors,
        trials: trials.unwrap_or(match mode {
            Mode::Geometry => 200,
            Mode::Robot => 5,
        }),
        seed,
    };
    let text = py
        .detach(|| -> Result<Vec<u8>, sim_cell::SimError> {
            let result = run_sweep(&config, &robot_cells, &|_| {})?;
            let mut out = Vec::new();
            let written = if trials_table {
                write_trials_csv(&result, &mut out)
            } else {
                write_summary_csv(&summarize_cells(&result), &mut out)
            };
            written.map_err(|source| sim_cell::SimError::Io {
                path: "<memory>".into(),
                source,
            })?;
            Ok(out)
        })
        .map_err(|e| to_py(&e, "sweep", Otherwise::Value))?;
    crate::cell::csv_columns(py, &String::from_utf8_lossy(&text))
}
