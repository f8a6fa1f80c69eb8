//! Sessions for this crate's tests, built by forward kinematics alone (the simulator, which puts
//! both robots' true tips together by inverse kinematics, is sim-cell's and sits above this
//! crate): deterministic joint vectors inside the limits, tool points from the nominal models,
//! rows of every kind. Good for the file formats and the adapter, whose checks are the nominal
//! FK of each row; not for a fit that must recover a truth (sim-cell's tests do that).

use calib_core::Robot;
use kinematics::base_from_tip;
use nalgebra::{Point3, Unit, Vector3};

use crate::cell::{Cell, CellRobot};
use crate::session::{Session, SessionKind, SessionObservation, SessionPoint};

/// Joint vector `k` of `robot`, rad: each joint at `0.5 ± 0.3` of its range (continuous joints
/// taken as ±π), a different mix per `k`, so no two rows are alike and none is at a limit.
pub(crate) fn joints(robot: &CellRobot, k: usize) -> Vec<f64> {
    robot
        .model
        .joints()
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let (lo, hi) = (joint.lower.max(-3.1), joint.upper.min(3.1));
            let s = (1.7 * k as f64 + 1.1 * j as f64 + 0.3).sin();
            lo + (hi - lo) * (0.5 + 0.3 * s)
        })
        .collect()
}

/// Tool `tool`'s point of `robot` at `q` by its nominal model, m, its base frame.
pub(crate) fn tool_point(robot: &CellRobot, q: &[f64], tool: usize) -> Point3<f64> {
    let flange_from_tool = robot
        .flange_from_tool(tool)
        .expect("the robot has this tool");
    let base_from_tool = base_from_tip(&robot.model, q, &flange_from_tool).expect("FK");
    Point3::from(base_from_tool.translation.vector)
}

/// A handclasp-only session of `n` points (`point` 1…n): each point's tips are the nominal FK of
/// its joints (the tips do not meet: the formats never ask them to).
pub(crate) fn coincident_session(cell: &Cell, n: usize) -> Session {
    Session::from_points(
        (0..n)
            .map(|k| {
                let (q1, q2) = (joints(&cell.robot1, k), joints(&cell.robot2, k + 7));
                SessionPoint {
                    point: k + 1,
                    p_b1: tool_point(&cell.robot1, &q1, 0),
                    p_b2: tool_point(&cell.robot2, &q2, 0),
                    q1,
                    q2,
                }
            })
            .collect(),
    )
}

/// The robot of a one-robot row: robot 1 on even cycles, robot 2 on odd ones.
fn robot_of(cycle: usize) -> Robot {
    if cycle.is_multiple_of(2) {
        Robot::One
    } else {
        Robot::Two
    }
}

/// A mixed session of `n` rows with the kinds in turn as sim-cell's `SimKind::Mixed` writes them:
/// coincident (default tips), contact (group `contact`, distance fitted, σ 0.2 mm), tracker of
/// robot 1, plane of robot 1, tracker of robot 2, plane of robot 2, coincident, … Tracker rows
/// measure the robot's last tool (the `reflector` of the tests' cells, else the tip) in group
/// `tracker` at its base-frame point shifted by (1, 2, 3) m, σ 0.05 mm; plane rows touch group
/// `plane` with the tip, σ 0.1 mm.
pub(crate) fn mixed_session(cell: &Cell, n: usize) -> Session {
    let mut session = Session::default();
    for k in 0..n {
        let point = k + 1;
        let (q1, q2) = (joints(&cell.robot1, k), joints(&cell.robot2, k + 7));
        let kind = match k % 6 {
            0 => {
                session.points.push(SessionPoint {
                    point,
                    p_b1: tool_point(&cell.robot1, &q1, 0),
                    p_b2: tool_point(&cell.robot2, &q2, 0),
                    q1,
                    q2,
                });
                continue;
            }
            1 => SessionKind::Contact {
                q1,
                q2,
                tool1: 0,
                tool2: 0,
                group: "contact".into(),
                distance_m: None,
                sigma_m: 0.2e-3,
            },
            r => {
                let robot = robot_of((r - 2) / 2);
                let setup = cell.robot(robot);
                let q = if robot == Robot::One { q1 } else { q2 };
                if r.is_multiple_of(2) {
                    let tool = setup.tools.len();
                    SessionKind::Tracker {
                        robot,
                        p_tracker: tool_point(setup, &q, tool) + Vector3::new(1.0, 2.0, 3.0),
                        q,
                        tool,
                        group: "tracker".into(),
                        sigma_m: 0.05e-3,
                    }
                } else {
                    SessionKind::Plane {
                        robot,
                        q,
                        tool: 0,
                        group: "plane".into(),
                        sigma_m: 0.1e-3,
                    }
                }
            }
        };
        session
            .observations
            .push(SessionObservation { point, kind });
    }
    session
}

/// A session of `n` face contacts (group `faces`, distance 116 mm given, σ 0.05 mm) whose face
/// normals tilt from the tip frames' z by a different small angle on each row.
pub(crate) fn face_session(cell: &Cell, n: usize) -> Session {
    let observations = (0..n)
        .map(|k| {
            let t = 0.1 * (k as f64 + 1.0);
            SessionObservation {
                point: k + 1,
                kind: SessionKind::FaceContact {
                    q1: joints(&cell.robot1, k),
                    q2: joints(&cell.robot2, k + 7),
                    tool1: 0,
                    tool2: 0,
                    n1_tip: Unit::new_normalize(Vector3::new(t, -0.5 * t, 1.0)),
                    n2_tip: Unit::new_normalize(Vector3::new(-0.3 * t, t, 1.0)),
                    group: "faces".into(),
                    distance_m: Some(0.116),
                    sigma_m: 0.05e-3,
                },
            }
        })
        .collect();
    Session {
        points: Vec::new(),
        observations,
        ..Session::default()
    }
}
