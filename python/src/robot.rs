//! `Robot` (a URDF model) and `fk`: tip poses for many joint vectors at once.

use std::path::PathBuf;

use calib_core::Robot as Which;
use kinematics::{base_from_tip, true_base_from_flange, KinematicErrors, RobotModel};
use nalgebra::{Translation3, Vector3};
use pyo3::prelude::*;

use crate::arrays::{f64_array, matrix_mm, poses_array};
use crate::cell::Cell;
use crate::errors::{to_py, value_error, Otherwise};

/// A robot model loaded from a URDF: the chain from the base link to the flange link
/// (`tool_link`, default `tool0`). Immutable.
#[pyclass(module = "handclasp", frozen)]
pub struct Robot {
    pub(crate) model: RobotModel,
}

#[pymethods]
impl Robot {
    /// Loads the URDF at `path`, the chain ending at link `tool_link`. Errors: `OSError` for an
    /// unreadable file, `ValueError` for an invalid URDF or a missing link.
    #[staticmethod]
    #[pyo3(signature = (path, tool_link="tool0"))]
    fn load(path: PathBuf, tool_link: &str) -> PyResult<Robot> {
        RobotModel::from_urdf_file(&path, tool_link)
            .map(|model| Robot { model })
            .map_err(|e| to_py(&e, "cannot load the robot model", Otherwise::Value))
    }

    /// The robot's name (the URDF's).
    #[getter]
    fn name(&self) -> String {
        self.model.name().to_string()
    }

    /// The number of independent joints (the width of `q_deg`).
    #[getter]
    fn dof(&self) -> usize {
        self.model.dof()
    }

    /// The independent joints' names, chain order from the base.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.model.joints().iter().map(|j| j.name.clone()).collect()
    }

    /// The joints' limits in file units (deg; mm for a prismatic joint), shape (dof, 2).
    #[getter]
    fn limits(&self) -> Vec<[f64; 2]> {
        self.model
            .joints()
            .iter()
            .map(|j| {
                let f = |v: f64| {
                    if j.kind.is_prismatic() {
                        v * 1e3
                    } else {
                        v.to_degrees()
                    }
                };
                [f(j.lower), f(j.upper)]
            })
            .collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(name={:?}, dof={})",
            self.model.name(),
            self.model.dof()
        )
    }
}

/// What `fk` evaluates: a model, its errors (zero for a bare URDF), gravity and the tip.
struct FkRobot {
    model: RobotModel,
    /// `Some` for a cell's robot: the cell's true FK (`[robotN.errors]`).
    errors: Option<(KinematicErrors, Vector3<f64>)>,
    flange_from_tip: Vector3<f64>,
}

/// The tip offset from `tip` (None: the flange; an (3,) array in mm; "cell": the cell's
/// calibrated tip).
fn tip_offset(
    tip: Option<&Bound<'_, PyAny>>,
    cell_tip: Option<Vector3<f64>>,
) -> PyResult<Vector3<f64>> {
    let Some(tip) = tip else {
        return Ok(Vector3::zeros());
    };
    if let Ok(text) = tip.extract::<String>() {
        return match (text.as_str(), cell_tip) {
            ("cell", Some(t)) => Ok(t),
            ("cell", None) => Err(value_error(
                "tip=\"cell\" needs robot=(cell, 1|2): a bare URDF has no tip",
            )),
            _ => Err(value_error(format!(
                "tip={text:?}: give the tip offset in the flange frame as 3 numbers in mm, or \"cell\""
            ))),
        };
    }
    let (v, shape) = f64_array(tip, "tip")?;
    if shape != [3] {
        return Err(value_error(format!(
            "tip: shape {shape:?}, expected (3,): x, y, z in mm in the flange frame"
        )));
    }
    Ok(Vector3::new(v[0], v[1], v[2]) * 1e-3)
}

/// The robot of `robot`: a URDF path, a `Robot`, or `(cell, 1|2)`.
fn fk_robot(robot: &Bound<'_, PyAny>, tip: Option<&Bound<'_, PyAny>>) -> PyResult<FkRobot> {
    if let Ok(r) = robot.cast::<Robot>() {
        return Ok(FkRobot {
            model: r.get().model.clone(),
            errors: None,
            flange_from_tip: tip_offset(tip, None)?,
        });
    }
    if let Ok((cell, which)) = robot.extract::<(Bound<'_, Cell>, i64)>() {
        let which = match which {
            1 => Which::One,
            2 => Which::Two,
            other => {
                return Err(value_error(format!(
                    "robot=(cell, {other}): the cell's robot is 1 or 2"
                )))
            }
        };
        let cell = cell.get();
        let r = cell.cell.robot(which);
        return Ok(FkRobot {
            model: r.model.clone(),
            errors: Some((r.errors.clone(), r.g_base)),
            flange_from_tip: tip_offset(tip, Some(r.flange_from_tip + r.errors.tip))?,
        });
    }
    if let Ok(path) = robot.extract::<PathBuf>() {
        let model = RobotModel::from_urdf_file(&path, "tool0")
            .map_err(|e| to_py(&e, "cannot load the robot model", Otherwise::Value))?;
        return Ok(FkRobot {
            model,
            errors: None,
            flange_from_tip: tip_offset(tip, None)?,
        });
    }
    Err(value_error(
        "robot: give a URDF path, a handclasp.Robot, or (cell, 1|2)",
    ))
}

/// Forward kinematics: `base_from_tip` (4×4, mm) for each joint vector, vectorised in Rust with
/// the GIL released.
///
/// `robot`: a URDF path (chain to `tool0`), a `Robot`, or `(cell, 1|2)` for the cell's robot
/// with everything the cell models (`[robotN.errors]`: joint offsets and scales, origin errors,
/// the mount error, compliance under the cell's gravity), as `handclasp fk --cell` computes it;
/// the pose is then in that robot's nominal base frame. `q_deg`: shape (n, dof) or (dof,),
/// degrees (mm for a prismatic joint), URDF chain order. `tip`: the tip offset in the flange
/// frame, mm, shape (3,) (default: the flange), or `"cell"` for the cell's calibrated tip.
/// Returns shape (n, 4, 4) (or (4, 4) for one joint vector), float64, translation in mm.
/// Errors: `ValueError` for a wrong width, NaN, or a joint outside its limits.
#[pyfunction]
#[pyo3(signature = (robot, q_deg, tip=None))]
pub fn fk<'py>(
    py: Python<'py>,
    robot: &Bound<'py, PyAny>,
    q_deg: &Bound<'py, PyAny>,
    tip: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let robot = fk_robot(robot, tip)?;
    let dof = robot.model.dof();
    let (values, shape) = f64_array(q_deg, "q_deg")?;
    let single = match shape.as_slice() {
        [w] if *w == dof => true,
        [_, w] if *w == dof => false,
        _ => {
            return Err(value_error(format!(
                "q_deg: shape {shape:?}, expected (n, {dof}) or ({dof},): {} has {dof} joints",
                robot.model.name()
            )))
        }
    };
    let joints = robot.model.joints();
    let poses = py.detach(|| -> Result<Vec<[[f64; 4]; 4]>, String> {
        values
            .chunks(dof.max(1))
            .enumerate()
            .map(|(i, row)| {
                let q: Vec<f64> = row
                    .iter()
                    .zip(joints)
                    .map(|(&v, j)| {
                        if j.kind.is_prismatic() {
                            v * 1e-3
                        } else {
                            v.to_radians()
                        }
                    })
                    .collect();
                let pose = match &robot.errors {
                    None => base_from_tip(&robot.model, &q, &robot.flange_from_tip),
                    Some((errors, g_base)) => {
                        true_base_from_flange(&robot.model, errors, &q, g_base)
                            .map(|f| f * Translation3::from(robot.flange_from_tip))
                    }
                };
                pose.map(|p| matrix_mm(&p))
                    .map_err(|e| format!("q_deg[{i}]: {}", cli_support::error_chain_text(&e)))
            })
            .collect()
    });
    let poses = poses.map_err(value_error)?;
    let out = poses_array(py, &poses);
    if single {
        Ok(out.get_item(0)?)
    } else {
        Ok(out.into_any())
    }
}
