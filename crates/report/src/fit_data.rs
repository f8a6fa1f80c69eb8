//! The data behind the calibration page's plots, from the same fit as its report: every
//! session row's residual against the final fit ([`row_residuals`]) and the range of each
//! joint the session covers against its limits ([`joint_coverage`]).

use calib_core::whole_cell::{CellCalibration, CellProblem, Evaluator, ObservationKind};
use calib_core::Robot;
use handclasp_cell::Cell;
use kinematics::JointKind;
use serde::Serialize;

use crate::ReportError;

/// One session row's residual against the final fit.
#[derive(Debug, Clone, Serialize)]
pub struct RowResidual {
    /// The row's kind (`coincident`, `contact`, `face_contact`, `tracker`, `plane`).
    pub kind: &'static str,
    /// Robot 1's joints of the row, degrees (`None` for a row of robot 2 alone).
    pub q1_deg: Option<Vec<f64>>,
    /// Robot 2's joints of the row, degrees (`None` for a row of robot 1 alone).
    pub q2_deg: Option<Vec<f64>>,
    /// Rejected as a blunder (not used by the final fit).
    pub rejected: bool,
    /// Norm of the residual vector (1 or 3 components), mm.
    pub residual_mm: f64,
    /// The 1-based session row (the CSV's `point`).
    pub row: usize,
    /// Norm of the whitened residual: the residual in the row's stated σ.
    pub size_sigma: f64,
}

/// Every row's residual at `cal`'s final estimate (`problem`'s observations, one per session
/// row in row order), rejected rows included and marked.
///
/// Errors: a row the models cannot evaluate at the estimate (named).
pub fn row_residuals(
    problem: &CellProblem,
    cal: &CellCalibration,
) -> Result<Vec<RowResidual>, ReportError> {
    let ev = Evaluator::new(problem, &cal.fit.layout);
    let deg = |q: &[f64]| q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>();
    problem
        .observations
        .iter()
        .enumerate()
        .map(|(i, obs)| {
            let lin = ev
                .linearise(obs, &cal.fit.estimate, false)
                .map_err(|source| ReportError::Residual {
                    row: obs.row,
                    source,
                })?;
            let (q1_deg, q2_deg) = match &obs.kind {
                ObservationKind::Coincident { q1, q2, .. }
                | ObservationKind::Contact { q1, q2, .. }
                | ObservationKind::FaceContact { q1, q2, .. } => (Some(deg(q1)), Some(deg(q2))),
                ObservationKind::Tracker { robot, q, .. }
                | ObservationKind::Plane { robot, q, .. } => match robot {
                    Robot::One => (Some(deg(q)), None),
                    Robot::Two => (None, Some(deg(q))),
                },
                _ => (None, None),
            };
            Ok(RowResidual {
                kind: obs.kind.name(),
                q1_deg,
                q2_deg,
                rejected: !cal.fit.active.contains(&i),
                residual_mm: lin.residual.norm() * 1e3,
                row: obs.row,
                size_sigma: (&lin.whitening * &lin.residual).norm(),
            })
        })
        .collect()
}

/// The range of one joint the session covers, against the joint's limits.
#[derive(Debug, Clone, Serialize)]
pub struct JointCoverage {
    /// `(session max − min)/(upper − lower)`, in [0, 1] (0 when the session has no row of the
    /// robot).
    pub fraction: f64,
    /// 1-based joint.
    pub joint: usize,
    /// Lower limit, in `unit` (−180° for a continuous joint).
    pub lower: f64,
    /// The URDF joint name.
    pub name: String,
    /// The robot.
    pub robot: Robot,
    /// Smallest and largest value over the session's rows of the robot, in `unit`; `None`
    /// without such rows.
    pub session: Option<[f64; 2]>,
    /// `deg` (revolute and continuous joints) or `mm` (prismatic).
    pub unit: &'static str,
    /// Upper limit, in `unit`.
    pub upper: f64,
}

/// Each joint's coverage by `rows` (their joint vectors in degrees, rejected rows included:
/// they are still where the robots went), robot 1's joints then robot 2's.
pub fn joint_coverage(cell: &Cell, rows: &[RowResidual]) -> Vec<JointCoverage> {
    let mut out = Vec::new();
    for robot in [Robot::One, Robot::Two] {
        let model = &cell.robot(robot).model;
        for (j, joint) in model.joints().iter().enumerate() {
            let (unit, scale, lower, upper) = match joint.kind {
                JointKind::Prismatic => ("mm", 1e3, joint.lower * 1e3, joint.upper * 1e3),
                JointKind::Continuous => ("deg", 1.0, -180.0, 180.0),
                _ => (
                    "deg",
                    1.0,
                    joint.lower.to_degrees(),
                    joint.upper.to_degrees(),
                ),
            };
            // Rows carry degrees; a prismatic joint's value (m) became "degrees" of m·180/π.
            let to_unit = |v: f64| {
                if joint.kind == JointKind::Prismatic {
                    v.to_radians() * scale
                } else {
                    v
                }
            };
            let values: Vec<f64> = rows
                .iter()
                .filter_map(|r| match robot {
                    Robot::One => r.q1_deg.as_ref(),
                    Robot::Two => r.q2_deg.as_ref(),
                })
                .filter_map(|q| q.get(j).copied().map(to_unit))
                .collect();
            let session = (!values.is_empty()).then(|| {
                values
                    .iter()
                    .fold([f64::INFINITY, f64::NEG_INFINITY], |[a, b], v| {
                        [a.min(*v), b.max(*v)]
                    })
            });
            let travel = upper - lower;
            let fraction = match session {
                Some([a, b]) if travel > 0.0 => ((b - a) / travel).clamp(0.0, 1.0),
                _ => 0.0,
            };
            out.push(JointCoverage {
                fraction,
                joint: j + 1,
                lower,
                name: joint.name.clone(),
                robot,
                session,
                unit,
                upper,
            });
        }
    }
    out
}
