//! `Cell` (the cell TOML) and `Session` (the session CSV, or arrays in its columns).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use kinematics::base_from_tip;
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{pose_array, rows, table, vector};
use crate::errors::{to_py, value_error, Otherwise};

/// A cell: two robots (URDFs, tips, mounts, tolerances), `b1_from_b2`, noise. Immutable.
#[pyclass(module = "handclasp", frozen)]
pub struct Cell {
    pub(crate) cell: Arc<handclasp_cell::Cell>,
    pub(crate) path: Option<PathBuf>,
}

#[pymethods]
impl Cell {
    /// Reads a cell TOML (URDF paths relative to its folder). Errors: `OSError` subclasses for an
    /// unreadable file or URDF, `ValueError` for invalid content (the message names the key and
    /// the fix, as the CLI's).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Cell> {
        let cell = py
            .detach(|| handclasp_cell::Cell::from_toml_file(&path))
            .map_err(|e| match std::fs::metadata(&path) {
                // The cell reader names the I/O error in its text only: an unreadable file is
                // still an `OSError`.
                Err(io) => crate::errors::os_error(io.kind(), cli_support::error_chain_text(&e)),
                Ok(_) => to_py(&e, "", Otherwise::Value),
            })?;
        Ok(Cell {
            cell: Arc::new(cell),
            path: Some(path),
        })
    }

    /// The cell's nominal `b1_from_b2` (base 2 in base 1), 4×4, translation in mm.
    #[getter]
    fn b1_from_b2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_array(py, &self.cell.b1_from_b2)
    }

    /// The file it was read from, or `None`.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.path.clone()
    }

    /// Whether the cell has a second robot (`[robot2]`); a one-robot cell (a robot measured by a
    /// tracker or against planes) has none, and its sessions hold tracker and plane rows only.
    #[getter]
    fn has_robot2(&self) -> bool {
        self.cell.has_robot2()
    }

    /// The joint counts `(dof1, dof2)` (the widths of `q1_deg`, `q2_deg`); a one-robot cell
    /// has no robot 2, so its `dof2` is `None` (`has_robot2` is false), as the other getters
    /// of what a cell lacks return `None`.
    #[getter]
    fn dof(&self) -> (usize, Option<usize>) {
        (
            self.cell.robot1.model.dof(),
            self.cell.has_robot2().then(|| self.cell.robot2.model.dof()),
        )
    }

    /// The cell as TOML text (what `export` writes as `cell.toml`).
    fn to_toml(&self) -> String {
        self.cell.to_toml_string()
    }

    fn __repr__(&self) -> String {
        format!(
            "Cell(path={:?}, robot1={:?}, robot2={})",
            self.path,
            self.cell.robot1.model.name(),
            if self.cell.has_robot2() {
                format!("{:?}", self.cell.robot2.model.name())
            } else {
                "None".to_string()
            }
        )
    }
}

/// A session: rows of joint angles and tips (coincident handclasps) and of the other kinds
/// (contact, face contact, tracker, plane), for one cell.
#[pyclass(module = "handclasp", frozen)]
pub struct Session {
    pub(crate) session: handclasp_cell::Session,
    pub(crate) cell: Arc<handclasp_cell::Cell>,
    /// The CSV it was read from (the CLI's diagnose reads coincident sessions from the file).
    pub(crate) path: Option<PathBuf>,
}

impl Session {
    /// The session CSV text.
    pub(crate) fn csv_text(&self) -> String {
        self.session.csv_text(&self.cell)
    }

    /// Writes the session CSV. Errors: `OSError` subclasses, `ValueError`.
    pub(crate) fn write_csv(&self, path: &Path) -> PyResult<()> {
        self.session
            .write_csv(path, &self.cell)
            .map_err(|e| to_py(&e, "", Otherwise::Value))
    }

    /// The session's columns by CSV name ([`Session::columns`]).
    pub(crate) fn columns_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        csv_columns(py, &self.csv_text())
    }
}

/// A CSV field: numbers in Rust's shortest round-trip form, text quoted when needed.
fn field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// One column of `from_arrays`: numbers (NaN = empty) or text (None = empty).
fn column_cells(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
    if let Ok(list) = obj.extract::<Vec<Option<String>>>() {
        return Ok(list
            .into_iter()
            .map(|s| field(&s.unwrap_or_default()))
            .collect());
    }
    let py = obj.py();
    let arr = py
        .import("numpy")?
        .call_method1("asarray", (obj, "float64"))
        .map_err(|e| value_error(format!("columns[{name:?}]: not numbers or strings ({e})")))?;
    let values: Vec<f64> = arr.call_method0("ravel")?.extract()?;
    Ok(values
        .into_iter()
        .map(|v| {
            if v.is_nan() {
                String::new()
            } else {
                format!("{v}")
            }
        })
        .collect())
}

#[pymethods]
impl Session {
    /// Reads a session CSV of `cell` (every kind; tips FK-checked against the cell). Errors:
    /// `OSError` subclasses for an unreadable file, `ValueError` naming the line and column.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf, cell: &Cell) -> PyResult<Session> {
        let c = Arc::clone(&cell.cell);
        let session = py
            .detach(|| handclasp_cell::Session::read_csv(&path, &c))
            .map_err(|e| to_py(&e, "", Otherwise::Value))?;
        Ok(Session {
            session,
            cell: c,
            path: Some(path),
        })
    }

    /// A session from arrays, read exactly as the session CSV with these columns would be
    /// (same checks, same messages; "line k" is array row k − 2).
    ///
    /// `q1_deg` (n, dof1), `q2_deg` (n, dof2): the joint angles, degrees (mm for a prismatic
    /// joint); `p1_mm`, `p2_mm` (n, 3): the controllers' nominal tips in each base, mm (default:
    /// computed by the cell's nominal FK); `point`: the point numbers (default 1..n). `columns`:
    /// any other session CSV columns by name (`kind`, `group`, `distance_mm`, `tracker_x_mm`, …;
    /// numbers with NaN for an empty cell, or lists of strings), or every column for a mixed
    /// session (then omit `q1_deg`/`q2_deg`).
    #[staticmethod]
    #[pyo3(signature = (cell, q1_deg=None, q2_deg=None, p1_mm=None, p2_mm=None, point=None, columns=None))]
    #[allow(clippy::too_many_arguments)]
    fn from_arrays(
        py: Python<'_>,
        cell: &Cell,
        q1_deg: Option<&Bound<'_, PyAny>>,
        q2_deg: Option<&Bound<'_, PyAny>>,
        p1_mm: Option<&Bound<'_, PyAny>>,
        p2_mm: Option<&Bound<'_, PyAny>>,
        point: Option<Vec<usize>>,
        columns: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Session> {
        let c = Arc::clone(&cell.cell);
        let (d1, d2) = (c.robot1.model.dof(), c.robot2.model.dof());
        // Column name → cells, in header order.
        let mut cols: Vec<(String, Vec<String>)> = Vec::new();
        let num = |v: f64| format!("{v}");
        match (q1_deg, q2_deg) {
            (Some(q1), Some(q2)) => {
                let (q1, _) = rows(q1, "q1_deg", d1, "robot 1's joints, deg")?;
                let (q2, _) = rows(q2, "q2_deg", d2, "robot 2's joints, deg")?;
                if q1.len() != q2.len() {
                    return Err(value_error(format!(
                        "q1_deg has {} rows and q2_deg {}: give one row per teach point in both",
                        q1.len(),
                        q2.len()
                    )));
                }
                let n = q1.len();
                let points = point.unwrap_or_else(|| (1..=n).collect());
                if points.len() != n {
                    return Err(value_error(format!(
                        "point has {} entries for {n} rows",
                        points.len()
                    )));
                }
                cols.push((
                    "point".into(),
                    points.iter().map(|p| p.to_string()).collect(),
                ));
                for (r, q, robot) in [(1, &q1, &c.robot1), (2, &q2, &c.robot2)] {
                    // `rN_qK_mm` for a prismatic joint (its values are mm), as the CSV's header.
                    for (k, joint) in robot.model.joints().iter().enumerate() {
                        cols.push((
                            handclasp_cell::joint_column(r, k + 1, joint.kind.is_prismatic()),
                            q.iter().map(|row| num(row[k])).collect(),
                        ));
                    }
                }
                let tips = |name: &str,
                            given: Option<&Bound<'_, PyAny>>,
                            robot: &handclasp_cell::CellRobot,
                            q: &[Vec<f64>]|
                 -> PyResult<Vec<Vec<f64>>> {
                    if let Some(p) = given {
                        let (p, _) = rows(p, name, 3, "tips, mm")?;
                        if p.len() != n {
                            return Err(value_error(format!(
                                "{name} has {} rows for {n} joint rows",
                                p.len()
                            )));
                        }
                        return Ok(p);
                    }
                    q.iter()
                        .enumerate()
                        .map(|(i, row)| {
                            let q_si: Vec<f64> = row
                                .iter()
                                .zip(robot.model.joints())
                                .map(|(&v, j)| {
                                    if j.kind.is_prismatic() {
                                        v * 1e-3
                                    } else {
                                        v.to_radians()
                                    }
                                })
                                .collect();
                            base_from_tip(&robot.model, &q_si, &robot.flange_from_tip)
                                .map(|t| (t.translation.vector * 1e3).iter().copied().collect())
                                .map_err(|e| {
                                    value_error(format!(
                                        "{name}: row {i}: {}",
                                        cli_support::error_chain_text(&e)
                                    ))
                                })
                        })
                        .collect()
                };
                let t1 = tips("p1_mm", p1_mm, &c.robot1, &q1)?;
                let t2 = tips("p2_mm", p2_mm, &c.robot2, &q2)?;
                for (r, t) in [(1, &t1), (2, &t2)] {
                    for (a, axis) in ["x", "y", "z"].iter().enumerate() {
                        cols.push((
                            format!("r{r}_{axis}_mm"),
                            t.iter().map(|row| num(row[a])).collect(),
                        ));
                    }
                }
            }
            (None, None) => {
                if columns.is_none() {
                    return Err(value_error(
                        "give q1_deg and q2_deg (and optionally p1_mm, p2_mm), or every column in columns=",
                    ));
                }
            }
            _ => return Err(value_error("q1_deg and q2_deg go together: give both")),
        }
        if let Some(extra) = columns {
            for (k, v) in extra.iter() {
                let name: String = k.extract()?;
                if cols.iter().any(|(c, _)| *c == name) {
                    return Err(value_error(format!(
                        "columns[{name:?}] is also given as an array argument"
                    )));
                }
                cols.push((name.clone(), column_cells(&name, &v)?));
            }
        }
        let n = cols.first().map_or(0, |c| c.1.len());
        if let Some((name, c)) = cols.iter().find(|(_, c)| c.len() != n) {
            return Err(value_error(format!(
                "column {name:?} has {} rows, the others {n}",
                c.len()
            )));
        }
        let mut text = cols
            .iter()
            .map(|(name, _)| field(name))
            .collect::<Vec<_>>()
            .join(",");
        text.push('\n');
        for i in 0..n {
            text.push_str(
                &cols
                    .iter()
                    .map(|(_, c)| c[i].as_str())
                    .collect::<Vec<_>>()
                    .join(","),
            );
            text.push('\n');
        }
        let session = py
            .detach(|| handclasp_cell::Session::parse_csv(&text, Path::new("<arrays>"), &c))
            .map_err(|e| to_py(&e, "", Otherwise::Value))?;
        Ok(Session {
            session,
            cell: c,
            path: None,
        })
    }

    /// Writes the session CSV (mm, degrees; the CLI reads it back as it stands).
    fn to_csv(&self, path: PathBuf) -> PyResult<()> {
        self.write_csv(&path)
    }

    /// The session CSV text.
    fn to_csv_string(&self) -> String {
        self.csv_text()
    }

    /// The session's columns by CSV name: numbers as float64 arrays (NaN for an empty cell),
    /// text columns (`kind`, `group`, tools) as lists of str. `handclasp.Session.to_frame()`
    /// makes a pandas DataFrame of them.
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.columns_dict(py)
    }

    /// [`Session::columns`] as a pandas DataFrame when pandas is installed, else the dict.
    fn to_frame<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let columns = self.columns(py)?;
        py.import("handclasp")?.getattr("frame")?.call1((columns,))
    }

    /// The number of rows of all kinds.
    fn __len__(&self) -> usize {
        self.session.len()
    }

    /// Rows per observation kind (`coincident`, `contact`, `face_contact`, `tracker`, `plane`).
    #[getter]
    fn rows_by_kind(&self) -> BTreeMap<&'static str, usize> {
        calib_core::whole_cell::Kind::ALL
            .iter()
            .zip(self.session.kind_counts())
            .map(|(k, n)| (k.name(), n))
            .collect()
    }

    /// The coincident handclasps' joint angles of robot 1, degrees (mm for a prismatic joint),
    /// shape (n, dof1).
    #[getter]
    fn q1_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.joints(py, 1)
    }

    /// The coincident handclasps' joint angles of robot 2, shape (n, dof2).
    #[getter]
    fn q2_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.joints(py, 2)
    }

    /// The coincident handclasps' nominal tips of robot 1 in base 1, mm, shape (n, 3).
    #[getter]
    fn p1_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let t: Vec<Vec<f64>> = self
            .session
            .points
            .iter()
            .map(|p| (p.p_b1.coords * 1e3).iter().copied().collect())
            .collect();
        table(py, &t, 3)
    }

    /// The coincident handclasps' nominal tips of robot 2 in base 2, mm, shape (n, 3).
    #[getter]
    fn p2_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let t: Vec<Vec<f64>> = self
            .session
            .points
            .iter()
            .map(|p| (p.p_b2.coords * 1e3).iter().copied().collect())
            .collect();
        table(py, &t, 3)
    }

    fn __repr__(&self) -> String {
        format!("Session(rows={}, path={:?})", self.session.len(), self.path)
    }
}

impl Session {
    /// Robot `r`'s joints of the coincident handclasps in file units.
    fn joints<'py>(&self, py: Python<'py>, r: u8) -> Bound<'py, PyArray2<f64>> {
        let robot = if r == 1 {
            &self.cell.robot1
        } else {
            &self.cell.robot2
        };
        let joints = robot.model.joints();
        let q: Vec<Vec<f64>> = self
            .session
            .points
            .iter()
            .map(|p| {
                let q = if r == 1 { &p.q1 } else { &p.q2 };
                q.iter()
                    .zip(joints)
                    .map(|(&v, j)| {
                        if j.kind.is_prismatic() {
                            v * 1e3
                        } else {
                            v.to_degrees()
                        }
                    })
                    .collect()
            })
            .collect();
        table(py, &q, joints.len())
    }
}

/// CSV text's columns by header name: numbers as float64 arrays (NaN for an empty cell), text
/// columns (any cell not a number, or `kind`, `group`, `tool*`, `method`, `mounts`) as lists of
/// str.
pub fn csv_columns<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyDict>> {
    let mut all = csv_rows(text);
    let header = if all.is_empty() {
        Vec::new()
    } else {
        all.remove(0)
    };
    let mut cells: BTreeMap<usize, Vec<String>> = BTreeMap::new();
    for row in &all {
        for (k, v) in row.iter().enumerate() {
            cells.entry(k).or_default().push(v.clone());
        }
    }
    let text_column = |name: &str| {
        matches!(name, "kind" | "group" | "method" | "mounts" | "layout")
            || name.starts_with("tool")
    };
    let out = PyDict::new(py);
    for (k, name) in header.iter().enumerate() {
        let col = cells.remove(&k).unwrap_or_default();
        let numbers: Option<Vec<f64>> = col
            .iter()
            .map(|c| {
                if c.is_empty() {
                    Some(f64::NAN)
                } else {
                    c.parse().ok()
                }
            })
            .collect();
        match numbers {
            Some(v) if !text_column(name) => out.set_item(name, vector(py, v))?,
            _ => out.set_item(name, PyList::new(py, col)?)?,
        }
    }
    Ok(out)
}

/// The rows of CSV text (header included), by the `csv` crate.
fn csv_rows(text: &str) -> Vec<Vec<String>> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(text.as_bytes())
        .records()
        .filter_map(Result::ok)
        .map(|r| r.iter().map(str::to_string).collect())
        .collect()
}

/// Converts a controller's or dataset's CSV files into a session of `cell`, as a mapping file
/// says (`handclasp import --cell CELL --map MAP --input FILE…`; the CTU maps are in
/// tools/ctu-motoman/maps/). Errors: `OSError` subclasses for unreadable files, `ValueError`
/// naming the file, line and column.
#[pyfunction]
pub fn import_session(
    py: Python<'_>,
    cell: &Cell,
    map: PathBuf,
    inputs: Vec<PathBuf>,
) -> PyResult<Session> {
    let c = Arc::clone(&cell.cell);
    let session = py.detach(|| -> PyResult<handclasp_cell::Session> {
        let read = |p: &Path, flag: &str| {
            kinematics::input::read_input_text(p, flag).map_err(|e| match e {
                kinematics::input::InputError::Io { source, .. } => crate::errors::os_error(
                    source.kind(),
                    format!("{flag} {}: {source}", p.display()),
                ),
                other => value_error(format!("{flag} {other}")),
            })
        };
        let text = read(&map, "map")?;
        let import = handclasp_cell::ImportMap::from_toml_str(&text, &map, &c)
            .map_err(|e| to_py(&e, "map", Otherwise::Value))?;
        let mut session = handclasp_cell::Session::default();
        for input in &inputs {
            let text = read(input, "input")?;
            import
                .read_rows(&text, input, &c, &mut session)
                .map_err(|e| to_py(&e, "input", Otherwise::Value))?;
        }
        if session.is_empty() {
            return Err(value_error(format!(
                "no row imported from {} file(s)",
                inputs.len()
            )));
        }
        // The input checks every command shares, with `import`'s message (the session in
        // memory named `<session>` where the CLI names its --out file).
        handclasp_cell::check_session_inputs(&session).map_err(|source| {
            let e = handclasp_cell::FormatError::SessionCheck {
                path: PathBuf::from("<session>"),
                source,
            };
            to_py(&e, "", Otherwise::Value)
        })?;
        Ok(session)
    })?;
    Ok(Session {
        session,
        cell: c,
        path: None,
    })
}
