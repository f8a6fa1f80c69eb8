//! The likely data mistakes a result check tries when a fit contradicts what the user stated,
//! each as an altered copy of the problem, fitted placement-only ([`try_problem`]) and judged
//! by its noise scale and its placement's distance from the stated one.
//!
//! 1. [`candidate_mistakes`] lists the mistakes that apply to a problem ([`Mistake`]: robot 2's
//!    rows shifted by ±1, the robots' columns swapped (identical robots), two joints swapped
//!    (adjacent pairs and 4↔6), a joint's sign flipped, radians read as degrees, a tip's sign
//!    flipped or the tip left out);
//! 2. [`Mistake::apply`] undoes the mistake on a copy of the problem (what the data would be
//!    had the user not made it);
//! 3. [`try_problem`] fits the copy with both robots nominal (the placement and the nuisances
//!    only, every row, no screen) and returns its robust noise scale
//!    ([`super::check::robust_noise_scale`]) and fitted placement.
//!
//! Another cell (a sibling cell file) is tried by the caller, who reads cells: it builds that
//! cell's problem and calls [`try_problem`] on it.

use nalgebra::Isometry3;

use super::check::{placement_distance, robust_noise_scale, PlacementDistance};
use super::solve::{fit_cell_with, SolveOptions};
use super::{CellFitError, CellProblem, ObservationKind, ParamLayout, Tolerance};
use crate::Robot;

/// One likely data mistake.
#[derive(Debug, Clone, PartialEq)]
pub enum Mistake {
    /// Robot 2's joints of the two-robot rows belong `by` rows later (`+1`) or earlier (`-1`).
    ShiftedRows {
        /// The shift, rows (±1).
        by: i32,
    },
    /// The two robots' joint columns were swapped (identical robots: the fit returns the
    /// inverse placement).
    SwappedRobots,
    /// Two joints of one robot in each other's columns (0-based joint indices).
    SwappedJoints {
        /// The robot.
        robot: Robot,
        /// The first joint, 0-based.
        a: usize,
        /// The second joint, 0-based.
        b: usize,
    },
    /// One joint's sign flipped (0-based joint index).
    FlippedJoint {
        /// The robot.
        robot: Robot,
        /// The joint, 0-based.
        joint: usize,
    },
    /// One robot's joints were radians read as degrees.
    RadiansAsDegrees {
        /// The robot.
        robot: Robot,
    },
    /// One robot's tip (`tip_mm`, tool 0) has the wrong sign.
    TipSign {
        /// The robot.
        robot: Robot,
    },
    /// One robot's tip (`tip_mm`, tool 0) should be zero (the tool point is the flange).
    TipLeftOut {
        /// The robot.
        robot: Robot,
    },
}

impl Mistake {
    /// What the user did, in words (`"robot 2's joints 4 and 6 swapped"`; joints 1-based).
    pub fn describe(&self) -> String {
        match self {
            Mistake::ShiftedRows { by } => format!(
                "robot 2's joint columns shifted by {} row{} against robot 1's",
                by.abs(),
                if by.abs() == 1 { "" } else { "s" }
            ),
            Mistake::SwappedRobots => {
                "the two robots' columns swapped (robot 1's joints under robot 2's headers)".into()
            }
            Mistake::SwappedJoints { robot, a, b } => format!(
                "robot {}'s joints {} and {} swapped",
                robot.number(),
                a + 1,
                b + 1
            ),
            Mistake::FlippedJoint { robot, joint } => format!(
                "robot {}'s joint {} with the wrong sign",
                robot.number(),
                joint + 1
            ),
            Mistake::RadiansAsDegrees { robot } => format!(
                "robot {}'s joints in radians, read as degrees",
                robot.number()
            ),
            Mistake::TipSign { robot } => {
                format!("robot {}'s tip_mm with the wrong sign", robot.number())
            }
            Mistake::TipLeftOut { robot } => format!(
                "robot {}'s tip_mm should be zero (tool point at the flange)",
                robot.number()
            ),
        }
    }

    /// A copy of `problem` with the mistake undone; `None` when it cannot apply (e.g. robots
    /// of different joint counts for [`Mistake::SwappedRobots`]).
    pub fn apply(&self, problem: &CellProblem) -> Option<CellProblem> {
        let mut p = problem.clone();
        match *self {
            Mistake::ShiftedRows { by } => {
                let two: Vec<usize> = (0..p.observations.len())
                    .filter(|&i| q_pair(&p.observations[i].kind).is_some())
                    .collect();
                if two.len() < 4 {
                    return None;
                }
                let q2s: Vec<Vec<f64>> = two
                    .iter()
                    .filter_map(|&i| q_pair(&problem.observations[i].kind).map(|(_, q2)| q2))
                    .collect();
                let mut keep = vec![true; p.observations.len()];
                for (k, &i) in two.iter().enumerate() {
                    let from = k as i64 - i64::from(by);
                    match usize::try_from(from).ok().and_then(|f| q2s.get(f)) {
                        Some(q2) => set_q2(&mut p.observations[i].kind, q2.clone()),
                        None => keep[i] = false,
                    }
                }
                let mut k = 0;
                p.observations.retain(|_| {
                    k += 1;
                    keep[k - 1]
                });
            }
            Mistake::SwappedRobots => {
                if problem.robot1.model.dof() != problem.robot2.model.dof() {
                    return None;
                }
                for o in &mut p.observations {
                    if let Some((q1, q2)) = q_pair(&o.kind) {
                        set_q1(&mut o.kind, q2);
                        set_q2(&mut o.kind, q1);
                    }
                }
            }
            Mistake::SwappedJoints { robot, a, b } => map_q(&mut p, robot, |q| {
                if a < q.len() && b < q.len() {
                    q.swap(a, b);
                }
            }),
            Mistake::FlippedJoint { robot, joint } => map_q(&mut p, robot, |q| {
                if let Some(v) = q.get_mut(joint) {
                    *v = -*v;
                }
            }),
            Mistake::RadiansAsDegrees { robot } => map_q(&mut p, robot, |q| {
                // Read as degrees and converted: q = x·π/180 for the radian figure x.
                for v in q.iter_mut() {
                    *v = v.to_degrees();
                }
            }),
            Mistake::TipSign { robot } => {
                let r = robot_mut(&mut p, robot);
                let t = r.tools.first_mut()?;
                if t.flange_from_tip.norm() == 0.0 {
                    return None;
                }
                t.flange_from_tip = -t.flange_from_tip;
            }
            Mistake::TipLeftOut { robot } => {
                let r = robot_mut(&mut p, robot);
                let t = r.tools.first_mut()?;
                if t.flange_from_tip.norm() == 0.0 {
                    return None;
                }
                t.flange_from_tip = nalgebra::Vector3::zeros();
            }
        }
        Some(p)
    }
}

fn robot_mut(p: &mut CellProblem, robot: Robot) -> &mut super::CellRobot {
    match robot {
        Robot::One => &mut p.robot1,
        Robot::Two => &mut p.robot2,
    }
}

/// `(q1, q2)` of a two-robot observation.
fn q_pair(kind: &ObservationKind) -> Option<(Vec<f64>, Vec<f64>)> {
    match kind {
        ObservationKind::Coincident { q1, q2, .. }
        | ObservationKind::Contact { q1, q2, .. }
        | ObservationKind::FaceContact { q1, q2, .. } => Some((q1.clone(), q2.clone())),
        _ => None,
    }
}

fn set_q1(kind: &mut ObservationKind, v: Vec<f64>) {
    if let ObservationKind::Coincident { q1, .. }
    | ObservationKind::Contact { q1, .. }
    | ObservationKind::FaceContact { q1, .. } = kind
    {
        *q1 = v;
    }
}

fn set_q2(kind: &mut ObservationKind, v: Vec<f64>) {
    if let ObservationKind::Coincident { q2, .. }
    | ObservationKind::Contact { q2, .. }
    | ObservationKind::FaceContact { q2, .. } = kind
    {
        *q2 = v;
    }
}

/// Applies `f` to every joint vector of `robot` in `p`.
fn map_q(p: &mut CellProblem, robot: Robot, f: impl Fn(&mut Vec<f64>)) {
    for o in &mut p.observations {
        match &mut o.kind {
            ObservationKind::Coincident { q1, q2, .. }
            | ObservationKind::Contact { q1, q2, .. }
            | ObservationKind::FaceContact { q1, q2, .. } => match robot {
                Robot::One => f(q1),
                Robot::Two => f(q2),
            },
            ObservationKind::Tracker { robot: r, q, .. }
            | ObservationKind::Plane { robot: r, q, .. } => {
                if *r == robot {
                    f(q)
                }
            }
        }
    }
}

/// The mistakes that apply to `problem`, in the order they are reported: shifted rows,
/// swapped robots, swapped joints (adjacent pairs, then 4↔6), flipped joints, radians read as
/// degrees, tip sign, tip left out.
pub fn candidate_mistakes(problem: &CellProblem) -> Vec<Mistake> {
    let mut out = vec![
        Mistake::ShiftedRows { by: 1 },
        Mistake::ShiftedRows { by: -1 },
        Mistake::SwappedRobots,
    ];
    for robot in Robot::BOTH {
        let dof = problem.robot(robot).model.dof();
        for a in 0..dof.saturating_sub(1) {
            out.push(Mistake::SwappedJoints { robot, a, b: a + 1 });
        }
        if dof >= 6 {
            out.push(Mistake::SwappedJoints { robot, a: 3, b: 5 });
        }
    }
    for robot in Robot::BOTH {
        for joint in 0..problem.robot(robot).model.dof() {
            out.push(Mistake::FlippedJoint { robot, joint });
        }
    }
    for robot in Robot::BOTH {
        out.push(Mistake::RadiansAsDegrees { robot });
    }
    for robot in Robot::BOTH {
        out.push(Mistake::TipSign { robot });
        out.push(Mistake::TipLeftOut { robot });
    }
    out
}

/// What one altered problem gives, fitted placement-only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trial {
    /// Its robust noise scale (relative to the stated noise).
    pub noise_scale: f64,
    /// Its fitted `b1_from_b2`.
    pub b1_from_b2: Isometry3<f64>,
}

impl Trial {
    /// Its placement's distance from `stated`.
    pub fn distance(&self, stated: &Isometry3<f64>) -> PlacementDistance {
        placement_distance(&self.b1_from_b2, stated)
    }
}

/// Fits `problem` with both robots nominal (placement and nuisances, every row, no screen),
/// starting from a rigid fit of its coincident rows, or from `start` when it has fewer than 3.
///
/// # Errors
/// As [`fit_cell_with`].
pub fn try_problem(problem: &CellProblem, start: &Isometry3<f64>) -> Result<Trial, CellFitError> {
    let mut p = problem.clone();
    p.robot1.tolerance = Tolerance::none();
    p.robot2.tolerance = Tolerance::none();
    let coincident = p
        .observations
        .iter()
        .filter(|o| matches!(o.kind, ObservationKind::Coincident { .. }))
        .count();
    let solve = SolveOptions {
        initial_b1_from_b2: (coincident < 3).then_some(*start),
        ..SolveOptions::default()
    };
    let all: Vec<usize> = (0..p.observations.len()).collect();
    let layout = ParamLayout::new(&p, &[]);
    let fit = fit_cell_with(&p, layout, &all, None, &solve)?;
    Ok(Trial {
        noise_scale: robust_noise_scale(&p, &fit, 1.0)?,
        b1_from_b2: fit.estimate.b1_from_b2,
    })
}
