//! `calibrate_points`: `b1_from_b2` from handclasp points, as `handclasp calibrate POINTS.csv`
//! computes it ([`cli_support::points::points_report`]).

use std::path::PathBuf;

use calib_core::{read_points_csv, FitReport, Method, Mount, MountPair, PointPairs};
use cli_support::points::{
    all_methods, points_report, AllMethods, MethodOutcome, MisfitHints, PointsError, PointsFit,
    PointsOptions,
};
use nalgebra::{Isometry3, Point3};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::arrays::{json_to_py, pose_array, rows, table, vector};
use crate::errors::{to_py, value_error, Otherwise};

/// The Python names of the two ways out of a misfit.
const PY_HINTS: MisfitHints = MisfitHints {
    noise: "expected_noise_mm=",
    force: "force=True",
};

/// The result of [`calibrate_points`]: the fit and the CLI's report.
#[pyclass(module = "handclasp", frozen)]
pub struct PointsResult {
    report: FitReport,
    b1_from_b2: Isometry3<f64>,
    json: String,
    warnings: Vec<String>,
}

#[pymethods]
impl PointsResult {
    /// `b1_from_b2` as a 4×4 homogeneous matrix, translation in mm (`p_b1 = b1_from_b2 · p_b2`);
    /// full precision (the report's `xyz_mm` is rounded to 1e-6 mm).
    #[getter]
    fn b1_from_b2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_array(py, &self.b1_from_b2)
    }

    /// The method fitted (`lsq`, `constrained`, …).
    #[getter]
    fn method(&self) -> &'static str {
        self.report.method.name()
    }

    /// Residuals `p_b1 − b1_from_b2 · p_b2`, mm, shape (n, 3), b1 axes.
    #[getter]
    fn residuals_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let r: Vec<Vec<f64>> = self
            .report
            .residuals_mm
            .iter()
            .map(|r| r.to_vec())
            .collect();
        table(py, &r, 3)
    }

    /// The residual RMS, mm.
    #[getter]
    fn residual_rms_mm(&self) -> f64 {
        self.report.residual_rms_mm
    }

    /// The source rows of the points (CSV line numbers; 1..n for arrays).
    #[getter]
    fn rows(&self) -> Vec<usize> {
        self.report.rows.clone()
    }

    /// The predicted 1σ uncertainty (dict: `e_tran_1sigma_mm`, `e_rot_1sigma_deg`,
    /// `sigma_point_mm`, `covariance` (6×6, mm and deg), …), or `None` for a method without one.
    #[getter]
    fn uncertainty<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let dict = self.to_dict(py)?;
        dict.get_item("uncertainty")
    }

    /// The posterior covariance of `b1_from_b2` (6×6; order in `uncertainty["covariance_order"]`),
    /// or `None`.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.report.uncertainty.as_ref().map(|u| {
            let c: Vec<Vec<f64>> = u.covariance.iter().map(|r| r.to_vec()).collect();
            table(py, &c, 6)
        })
    }

    /// The residual norms, mm, shape (n,).
    #[getter]
    fn residual_norms_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vector(py, self.report.residual_norms_mm.clone())
    }

    /// Warnings (a misfit kept by `force=True`); `handclasp.calibrate_points` also issues them
    /// with `warnings.warn`.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The report as the CLI's JSON text (`handclasp calibrate POINTS.csv --json`).
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The report as a dict, equal to `json.loads` of the CLI's `--json` output.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.json)
    }

    fn __repr__(&self) -> String {
        let b = &self.report.b1_from_b2;
        format!(
            "PointsResult(method={:?}, points={}, xyz_mm={:?}, zyz_deg={:?}, residual_rms_mm={:.3})",
            self.report.method.name(),
            self.report.points,
            b.xyz_mm,
            b.zyz_deg,
            self.report.residual_rms_mm
        )
    }
}

/// The mounts from `mounts` (a paper cell) or `mount1` and `mount2`.
fn mount_pair(
    mounts: Option<&str>,
    mount1: Option<&str>,
    mount2: Option<&str>,
) -> PyResult<Option<MountPair>> {
    let parse_err = |what: &str, e: calib_core::CalibError| value_error(format!("{what}: {e}"));
    match (mounts, mount1, mount2) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            Err(value_error("give mounts= or mount1= and mount2=, not both"))
        }
        (Some(m), None, None) => MountPair::parse_paper(m)
            .map(Some)
            .map_err(|e| parse_err("mounts (or give mount1= and mount2=)", e)),
        (None, Some(a), Some(b)) => Ok(Some(MountPair {
            robot1: Mount::parse(a).map_err(|e| parse_err("mount1", e))?,
            robot2: Mount::parse(b).map_err(|e| parse_err("mount2", e))?,
        })),
        (None, None, None) => Ok(None),
        _ => Err(value_error(
            "mount1= and mount2= go together: give both (floor, ceiling, wall or tilt:RX,RY)",
        )),
    }
}

/// Point pairs from two (n, 3) arrays in mm, rows numbered 1..n, with the reader's checks
/// (duplicates, unit mismatch, coordinates that look like metres).
fn pairs_from_arrays(p1: &Bound<'_, PyAny>, p2: &Bound<'_, PyAny>) -> PyResult<PointPairs> {
    let (r1, _) = rows(p1, "p1_mm", 3, "robot 1's tips in base 1, mm")?;
    let (r2, _) = rows(p2, "p2_mm", 3, "robot 2's tips in base 2, mm")?;
    if r1.len() != r2.len() {
        return Err(value_error(format!(
            "p1_mm has {} points and p2_mm {}: give one row per handclasp in both",
            r1.len(),
            r2.len()
        )));
    }
    let point = |r: &Vec<f64>| Point3::new(r[0], r[1], r[2]) * 1e-3;
    for (name, rs) in [("p1_mm", &r1), ("p2_mm", &r2)] {
        if !rs.is_empty()
            && rs
                .iter()
                .all(|r| r.iter().all(|c| c.abs() < calib_core::METRES_LIMIT_MM))
        {
            return Err(value_error(format!(
                "{name}: every coordinate is below {} mm: the points look like metres; give millimetres (× 1000)",
                calib_core::METRES_LIMIT_MM
            )));
        }
    }
    let pairs = PointPairs::new(
        r1.iter().map(point).collect(),
        r2.iter().map(point).collect(),
    )
    .map_err(|e| to_py(&e, "", Otherwise::Value))?;
    pairs
        .check_consistency("p1_mm/p2_mm")
        .map_err(|e| to_py(&e, "", Otherwise::Value))?;
    Ok(pairs)
}

/// Fits `b1_from_b2` (base 2 in base 1) from handclasp points, as `handclasp calibrate
/// POINTS.csv` does: the same fit, plausibility check and report.
///
/// `p1_mm`, `p2_mm`: (n, 3) arrays of the tips in base 1 and base 2, mm (row i of both is the
/// same physical point); or `p1_mm` a points CSV path and `p2_mm` None (then the report's rows are
/// the file's line numbers, as the CLI's). `method`: generic, generic-affine, paper, lsq or
/// constrained (default: constrained with mounts, else lsq), or `all` (`--method all`: every
/// method, paper and constrained only with mounts; returns a `PointsMethods`). `mounts`: floor-floor, floor-wall or
/// floor-ceiling; or `mount1`, `mount2`: floor, ceiling, wall or tilt:RX,RY (deg).
/// `tilt_sigma_deg`, `point_sigma_mm`: the soft mount of `constrained`. `expected_noise_mm`: a fit
/// whose median residual norm exceeds it raises `CalibrationError` naming the likely data
/// mistake, unless `force`.
#[pyfunction]
#[pyo3(signature = (p1_mm, p2_mm=None, method=None, mounts=None, mount1=None, mount2=None,
                    tilt_sigma_deg=None, point_sigma_mm=0.5, expected_noise_mm=5.0, force=false))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate_points(
    py: Python<'_>,
    p1_mm: &Bound<'_, PyAny>,
    p2_mm: Option<&Bound<'_, PyAny>>,
    method: Option<&str>,
    mounts: Option<&str>,
    mount1: Option<&str>,
    mount2: Option<&str>,
    tilt_sigma_deg: Option<f64>,
    point_sigma_mm: f64,
    expected_noise_mm: f64,
    force: bool,
) -> PyResult<Py<PyAny>> {
    let mounts = mount_pair(mounts, mount1, mount2)?;
    let method_text = method.unwrap_or(if mounts.is_some() {
        "constrained"
    } else {
        "lsq"
    });
    let all = method_text == "all";
    let method = match Method::from_name(method_text) {
        Some(m) => m,
        // `all` checks its options as its last method would (constrained with mounts, else lsq).
        None if all && mounts.is_some() => Method::Constrained,
        None if all => Method::Lsq,
        None => {
            return Err(value_error(format!(
                "method={method_text:?}: unknown method; use generic, generic-affine, paper, lsq, constrained or all"
            )))
        }
    };
    if mounts.is_none() && matches!(method, Method::Paper | Method::Constrained) {
        return Err(value_error(format!(
            "method={method_text:?} needs the installation: give mounts=\"floor-floor\"|\"floor-wall\"|\"floor-ceiling\", or mount1= and mount2="
        )));
    }
    let valid = |v: f64| v.is_finite() && v > 0.0;
    let soft = match tilt_sigma_deg {
        None => None,
        Some(t) => {
            if method != Method::Constrained {
                return Err(value_error(
                    "tilt_sigma_deg applies to method=\"constrained\" (or \"all\" with mounts)",
                ));
            }
            if !valid(t) || !valid(point_sigma_mm) {
                return Err(value_error(
                    "tilt_sigma_deg and point_sigma_mm must be finite and > 0",
                ));
            }
            Some((t.to_radians(), point_sigma_mm * 1e-3))
        }
    };
    if !valid(expected_noise_mm) {
        return Err(value_error(format!(
            "expected_noise_mm={expected_noise_mm}: must be finite and > 0 (the handclasp alignment noise, mm)"
        )));
    }
    let (pairs, source) = match p2_mm {
        Some(p2) => (pairs_from_arrays(p1_mm, p2)?, None),
        None => {
            let path: PathBuf = p1_mm.extract().map_err(|_| {
                value_error(
                    "give p1_mm and p2_mm as (n, 3) arrays in mm, or p1_mm as a points CSV path",
                )
            })?;
            let pairs = py
                .detach(|| read_points_csv(&path))
                .map_err(|e| to_py(&e, "", Otherwise::Value))?;
            (pairs, Some(path))
        }
    };
    let options = PointsOptions {
        method,
        mounts,
        soft,
        expected_noise_m: expected_noise_mm * 1e-3,
        force,
    };
    if all {
        return Ok(Py::new(py, all_methods_result(py, &pairs, options)?)?.into_any());
    }
    let fitted = py.detach(|| points_report(&pairs, &options, PY_HINTS));
    let fitted = fitted.map_err(|e| {
        let context = match &source {
            Some(p) => format!("{}: method {}", p.display(), method.name()),
            None => format!("method {}", method.name()),
        };
        match e {
            PointsError::Fit(calib_core::CalibError::InvalidOption { .. }) => {
                to_py(&e, &context, Otherwise::Value)
            }
            PointsError::Misfit(ref m) => {
                let mut refusal = cli_support::result_check::Refusal::new(
                    "calibrate_points",
                    format!("{context}: {}", m.message),
                );
                refusal.misfit = Some(m);
                crate::errors::refusal_error(py, &refusal)
            }
            e => to_py(&e, &context, Otherwise::Calibration),
        }
    })?;
    Ok(Py::new(py, PointsResult::new(fitted)?)?.into_any())
}

impl PointsResult {
    /// The result of one fit, its JSON the CLI's.
    fn new(fitted: PointsFit) -> PyResult<PointsResult> {
        let json = serde_json::to_string_pretty(&fitted.report)
            .map_err(|e| value_error(format!("serialising the report: {e}")))?;
        Ok(PointsResult {
            b1_from_b2: fitted.b1_from_b2,
            report: fitted.report,
            json,
            warnings: fitted.warnings,
        })
    }
}

/// The result of `calibrate_points(..., method="all")`, as `handclasp calibrate POINTS.csv
/// --method all`: each method's fit, or why it does not apply.
#[pyclass(module = "handclasp", frozen)]
pub struct PointsMethods {
    /// The fits, by method name (alphabetical).
    fits: Vec<(&'static str, Py<PointsResult>)>,
    /// Why each other method does not apply, by method name.
    errors: Vec<(&'static str, String)>,
    json: String,
}

#[pymethods]
impl PointsMethods {
    /// The fitted methods' results, by method name: each a `PointsResult` (its `.to_dict()` the
    /// CLI's `--method NAME --json`).
    #[getter]
    fn results<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let out = pyo3::types::PyDict::new(py);
        for (name, r) in &self.fits {
            out.set_item(name, r.clone_ref(py))?;
        }
        Ok(out)
    }

    /// Why each method that does not apply to these points does not (too few points, a misfit),
    /// by method name.
    #[getter]
    fn errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let out = pyo3::types::PyDict::new(py);
        for (name, e) in &self.errors {
            out.set_item(name, e)?;
        }
        Ok(out)
    }

    /// Every method's result, fitted or not, by name; `None` for one that does not apply.
    fn __getitem__(&self, py: Python<'_>, name: &str) -> PyResult<Option<Py<PointsResult>>> {
        if let Some((_, r)) = self.fits.iter().find(|(n, _)| *n == name) {
            return Ok(Some(r.clone_ref(py)));
        }
        if self.errors.iter().any(|(n, _)| *n == name) {
            return Ok(None);
        }
        Err(pyo3::exceptions::PyKeyError::new_err(format!(
            "{name:?}: not a method fitted here"
        )))
    }

    /// The report as the CLI's JSON text (`calibrate POINTS.csv --method all --json`).
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The report as a dict, equal to `json.loads` of the CLI's `--method all --json` output.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_to_py(py, &self.json)
    }

    fn __repr__(&self) -> String {
        format!(
            "PointsMethods(fitted={:?}, not_applicable={:?})",
            self.fits.iter().map(|f| f.0).collect::<Vec<_>>(),
            self.errors.iter().map(|e| e.0).collect::<Vec<_>>()
        )
    }
}

/// Fits every method `--method all` fits ([`all_methods`]) with `options` (its method
/// replaced), GIL released; each fit's warnings are `UserWarning`s.
fn all_methods_result(
    py: Python<'_>,
    pairs: &PointPairs,
    options: PointsOptions,
) -> PyResult<PointsMethods> {
    let methods = all_methods(options.mounts.is_some());
    let outcomes: Vec<(Method, Result<PointsFit, PointsError>)> = py.detach(|| {
        methods
            .iter()
            .map(|&method| {
                let o = PointsOptions {
                    method,
                    ..options.clone()
                };
                (method, points_report(pairs, &o, PY_HINTS))
            })
            .collect()
    });
    let mut report = AllMethods::default();
    let mut fits = Vec::new();
    let mut errors = Vec::new();
    for (method, outcome) in outcomes {
        match outcome {
            Ok(fitted) => {
                for w in &fitted.warnings {
                    crate::errors::user_warning(py, w)?;
                }
                report.insert(method, Ok(fitted.report.clone()));
                fits.push((method.name(), Py::new(py, PointsResult::new(fitted)?)?));
            }
            Err(e) => {
                report.insert(method, Err(e));
                if let Some(MethodOutcome::NotApplicable { error, .. }) =
                    report.methods.get(method.name())
                {
                    errors.push((method.name(), error.clone()));
                }
            }
        }
    }
    fits.sort_by_key(|f| f.0);
    errors.sort_by_key(|e| e.0);
    let json = serde_json::to_string_pretty(&report)
        .map_err(|e| value_error(format!("serialising the report: {e}")))?;
    Ok(PointsMethods { fits, errors, json })
}
