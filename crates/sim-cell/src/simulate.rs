//! Simulated handclasp sessions on a [`Cell`]: one teach point's model (`simulate_point`: both
//! robots' true tips meet up to the operator's alignment error, the reported joints carry the
//! repeatability and the encoder resolution, the tips are what the nominal models compute), the
//! session of a layout or of explicit points ([`generate_session`]), and the helpers the other
//! kinds' simulation (`session_kinds`) shares. The session CSV itself is
//! [`handclasp_cell::session`].

use crate::error::SimError;
use crate::layout::{teach_points, Layout};
use calib_core::Robot;
use handclasp_cell::cell::{Cell, CellRobot};
use handclasp_cell::{Session, SessionPoint};
use kinematics::{
    base_from_tip, ik_tip_position, tip_joint_jacobian_true, true_base_from_tip, IkOptions,
};
use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

/// Layout draws tried before a session is declared unreachable.
pub const MAX_LAYOUT_ATTEMPTS: usize = 20;
/// Tolerance of the true-robot Newton correction: the true tip is within this of its target, m.
pub const TRUE_TIP_TOL_M: f64 = 1e-9;
/// Newton iterations of the true-robot correction.
const TRUE_NEWTON_ITER: usize = 30;

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionSpec {
    /// Number of teach points (≥ 1).
    pub n: usize,
    /// Layout of the teach points.
    pub layout: Layout,
    /// Layout size, m (see [`crate::layout`]).
    pub spread_m: f64,
    /// Centre of the layout, m, b1 (None: the cell's `centre_b1`).
    pub centre_b1: Option<Point3<f64>>,
    /// Explicit teach points, m, b1 (overrides `n`/`layout`/`spread_m`; an unreachable one is an
    /// error naming it).
    pub points_b1: Option<Vec<Point3<f64>>>,
}

impl SessionSpec {
    /// `n` points of `layout` with `spread_m` around the cell's centre.
    pub fn new(n: usize, layout: Layout, spread_m: f64) -> Self {
        SessionSpec {
            n,
            layout,
            spread_m,
            centre_b1: None,
            points_b1: None,
        }
    }
}

/// Head-on approach directions (b1, unit) to try for a point, best first: along the line between
/// the shoulders, from robot 1's shoulder to the point, then those turned ±30°/±60° about the
/// vertical and tilted ±30°. Used by one-robot rows (tracker, plane); a meeting of both robots
/// takes [`meeting_directions`].
pub(crate) fn approach_directions(cell: &Cell, p: &Point3<f64>) -> Vec<Unit<Vector3<f64>>> {
    let first = |m: &kinematics::RobotModel| {
        m.joints()
            .first()
            .map_or(Vector3::zeros(), |j| j.origin_xyz)
    };
    directions_from(
        cell,
        p,
        first(&cell.robot1.model),
        cell.b1_from_b2 * Point3::from(first(&cell.robot2.model)),
    )
}

/// [`approach_directions`] for a meeting of both robots: on a shared-trunk cell the shoulders are
/// each arm's first joint after the trunk (its origin at q = 0: the fixed parts composed), whose
/// line runs from one hand's side to the other's; elsewhere the same directions.
pub(crate) fn meeting_directions(cell: &Cell, p: &Point3<f64>) -> Vec<Unit<Vector3<f64>>> {
    if cell.shared_joints == 0 {
        return approach_directions(cell, p);
    }
    let first_own = |m: &kinematics::RobotModel| {
        m.chain_joints()
            .iter()
            .take(cell.shared_joints + 1)
            .fold(nalgebra::Isometry3::identity(), |t, j| {
                t * j.fixed_prefix * kinematics::origin_isometry(&j.origin_xyz, &j.origin_rpy)
            })
            .translation
            .vector
    };
    directions_from(
        cell,
        p,
        first_own(&cell.robot1.model),
        cell.b1_from_b2 * Point3::from(first_own(&cell.robot2.model)),
    )
}

/// The directions of [`approach_directions`] from shoulders `s1` (b1) and `s2` (b1).
fn directions_from(
    cell: &Cell,
    p: &Point3<f64>,
    s1: Vector3<f64>,
    s2: Point3<f64>,
) -> Vec<Unit<Vector3<f64>>> {
    let up = -cell.robot1.g_base.normalize();
    let mut base = Vec::new();
    for d in [s2.coords - s1, p.coords - s1] {
        if let Some(u) = Unit::try_new(d, 1e-9) {
            base.push(u);
        }
    }
    let mut out = base.clone();
    for b in &base {
        for deg in [30.0f64, -30.0, 60.0, -60.0] {
            out.push(Rotation3::from_axis_angle(&Unit::new_normalize(up), deg.to_radians()) * *b);
        }
        let side = b.cross(&up);
        if let Some(side) = Unit::try_new(side, 1e-9) {
            for deg in [30.0f64, -30.0] {
                out.push(Rotation3::from_axis_angle(&side, deg.to_radians()) * *b);
            }
        }
    }
    out
}

/// Reported joints (rad, continuous) that put the TRUE robot's tip at `target` (m, nominal base):
/// nominal IK with the flange z along `axis`, then Newton steps on the true model
/// (`∂p/∂q_rep` of the true robot, minimum-norm). `None` if unreachable or outside the limits.
fn solve_true(
    robot: &CellRobot,
    target: &Point3<f64>,
    axis: Option<Unit<Vector3<f64>>>,
) -> Option<Vec<f64>> {
    solve_true_tool(robot, 0, target, axis, None)
}

/// The true errors that move tool `tool`: the cell's `[robotN.errors]`, with the tip error for
/// tool 0 only (the extra tools are exact, as in [`handclasp_cell::problem::truth_estimate`]).
pub(crate) fn tool_errors(robot: &CellRobot, tool: usize) -> kinematics::KinematicErrors {
    let mut errors = robot.errors.clone();
    if tool != 0 {
        errors.tip = Vector3::zeros();
    }
    errors
}

/// [`solve_true`] for tool `tool` of `robot` ([`CellRobot::flange_from_tool`]), the IK seeded
/// with `seed` when given (rad).
pub(crate) fn solve_true_tool(
    robot: &CellRobot,
    tool: usize,
    target: &Point3<f64>,
    axis: Option<Unit<Vector3<f64>>>,
    seed: Option<&[f64]>,
) -> Option<Vec<f64>> {
    let flange_from_tool = robot.flange_from_tool(tool)?;
    let opts = IkOptions {
        tool_axis_base: axis,
        initial_q: seed.map(<[f64]>::to_vec),
        tolerance_m: 1e-9,
        axis_tolerance_rad: 1e-7,
        restarts: 8,
        ..IkOptions::default()
    };
    let sol = ik_tip_position(&robot.model, target, &flange_from_tool, &opts).ok()?;
    if !sol.reachable() {
        return None;
    }
    let mut q = sol.q;
    let errors = tool_errors(robot, tool);
    if errors.is_zero() {
        return Some(q);
    }
    for _ in 0..TRUE_NEWTON_ITER {
        let tip =
            true_base_from_tip(&robot.model, &errors, &q, &flange_from_tool, &robot.g_base).ok()?;
        let e = target.coords - tip.translation.vector;
        if e.norm() < TRUE_TIP_TOL_M {
            return Some(q);
        }
        let mut j =
            tip_joint_jacobian_true(&robot.model, &errors, &q, &flange_from_tool, &robot.g_base)
                .ok()?;
        // A held joint (limits equal: a shared trunk's, `RobotModel::with_joints_held`) does
        // not move: the step is taken by the others.
        for (k, jt) in robot.model.joints().iter().enumerate() {
            if jt.lower == jt.upper {
                j.column_mut(k).fill(0.0);
            }
        }
        let jjt: Matrix3<f64> = &j * j.transpose();
        let y = jjt.try_inverse()? * e;
        let dq = j.transpose() * y;
        for ((qi, d), jt) in q.iter_mut().zip(dq.iter()).zip(robot.model.joints()) {
            *qi = (*qi + d).clamp(jt.lower, jt.upper);
        }
    }
    None
}

/// Rounds each rotary joint of `q` (rad) to a multiple of the encoder `resolution` (rad) within
/// its limits; a prismatic joint (m) is left as it is (an angular resolution has no length).
pub(crate) fn quantise(robot: &CellRobot, q: &mut [f64], resolution: f64) {
    if resolution > 0.0 {
        for (qi, jt) in q.iter_mut().zip(robot.model.joints()) {
            if jt.kind.is_prismatic() {
                continue;
            }
            let mut v = (*qi / resolution).round() * resolution;
            if v > jt.upper {
                v -= resolution;
            }
            if v < jt.lower {
                v += resolution;
            }
            *qi = v;
        }
    }
}

pub(crate) fn gauss3(rng: &mut impl Rng, sigma: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        sigma.x * rng.sample::<f64, _>(StandardNormal),
        sigma.y * rng.sample::<f64, _>(StandardNormal),
        sigma.z * rng.sample::<f64, _>(StandardNormal),
    )
}

/// Why one point failed: (the robot that failed, message).
pub(crate) type PointFailure = (Robot, String);

/// Simulates one teach point `p` (true meeting point, m, b1). Robot 1's true tip is at `p`,
/// robot 2's at `p + ε` (alignment); the reported joints put the true tips there up to
/// repeatability `δ` (unseen by the encoders), quantised to the encoder resolution; the tips are
/// what the nominal models compute from the reported joints. On a shared-trunk cell both arms
/// stand on one trunk posture (`trunk::meet_on_trunk`).
fn simulate_point(
    cell: &Cell,
    p: &Point3<f64>,
    label: usize,
    rng: &mut impl Rng,
) -> Result<SessionPoint, PointFailure> {
    let eps = gauss3(rng, &cell.noise.alignment_m);
    let rep = Vector3::repeat(cell.noise.repeatability_m);
    let d1 = gauss3(rng, &rep);
    let d2 = gauss3(rng, &rep);
    let b2_from_b1 = cell.b1_from_b2.inverse();
    let target1 = p + d1;
    let target2 = b2_from_b1 * (p + eps) + d2;
    let (q1, q2) = if cell.shared_joints > 0 {
        let dirs = meeting_directions(cell, p);
        let target2 = |_: &Vector3<f64>| target2;
        let (q1, q2, _) = crate::trunk::meet_on_trunk(cell, &target1, &target2, &dirs, None, rng)?;
        (q1, q2)
    } else {
        meet_apart(cell, p, &target1, &target2)?
    };
    let t1 = base_from_tip(&cell.robot1.model, &q1, &cell.robot1.flange_from_tip)
        .map_err(|e| (Robot::One, e.to_string()))?;
    let t2 = base_from_tip(&cell.robot2.model, &q2, &cell.robot2.flange_from_tip)
        .map_err(|e| (Robot::Two, e.to_string()))?;
    Ok(SessionPoint {
        point: label,
        q1,
        q2,
        p_b1: Point3::from(t1.translation.vector),
        p_b2: Point3::from(t2.translation.vector),
    })
}

/// Both robots' reported joints (two separate robots) with robot 1's true tip at `target1` (b1)
/// and robot 2's at `target2` (b2), head-on along the first of [`approach_directions`] both reach.
fn meet_apart(
    cell: &Cell,
    p: &Point3<f64>,
    target1: &Point3<f64>,
    target2: &Point3<f64>,
) -> Result<(Vec<f64>, Vec<f64>), PointFailure> {
    let b2_from_b1 = cell.b1_from_b2.inverse();
    let mut last = (Robot::One, String::new());
    for d in approach_directions(cell, p) {
        let Some(mut q1) = solve_true(&cell.robot1, target1, Some(d)) else {
            last = (Robot::One, "robot 1 cannot reach it head-on".into());
            continue;
        };
        let axis2 = Unit::new_normalize(b2_from_b1.rotation * -d.into_inner());
        let Some(mut q2) = solve_true(&cell.robot2, target2, Some(axis2)) else {
            last = (Robot::Two, "robot 2 cannot reach it head-on".into());
            continue;
        };
        quantise(&cell.robot1, &mut q1, cell.noise.encoder_resolution_rad);
        quantise(&cell.robot2, &mut q2, cell.noise.encoder_resolution_rad);
        return Ok((q1, q2));
    }
    Err(last)
}

/// Simulates a handclasp session on `cell` (see `simulate_point` in this module's source for one point's model): teach
/// points from `spec` (a layout draw, redrawn up to [`MAX_LAYOUT_ATTEMPTS`] times until both robots
/// reach every point head-on, or the explicit points). Seeded by `rng` alone.
///
/// Errors: an invalid spec, or a teach point outside the common workspace (naming the point, the
/// robot and what would work).
pub fn generate_session(
    cell: &Cell,
    spec: &SessionSpec,
    rng: &mut impl Rng,
) -> Result<Session, SimError> {
    if !(spec.spread_m.is_finite() && spec.spread_m > 0.0) && spec.points_b1.is_none() {
        return Err(SimError::InvalidInput(format!(
            "spread {} mm must be a positive length (e.g. 1000)",
            spec.spread_m * 1e3
        )));
    }
    let centre = spec.centre_b1.unwrap_or(cell.centre_b1);
    if let Some(points) = &spec.points_b1 {
        let mut out = Vec::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            if !p.iter().all(|x| x.is_finite()) {
                return Err(SimError::InvalidInput(format!(
                    "teach point {} is not finite",
                    i + 1
                )));
            }
            match simulate_point(cell, p, i + 1, rng) {
                Ok(sp) => out.push(sp),
                Err((robot, why)) => return Err(unreachable(cell, i + 1, p, robot, &why, None)),
            }
        }
        return Ok(Session::from_points(out));
    }
    if spec.n == 0 {
        return Err(SimError::InvalidInput(
            "a session needs at least 1 point (4 for every method)".into(),
        ));
    }
    let mut last_fail = None;
    'draw: for _ in 0..MAX_LAYOUT_ATTEMPTS {
        let pts = teach_points(spec.layout, spec.n, spec.spread_m, &centre, rng);
        let mut out = Vec::with_capacity(spec.n);
        for (i, p) in pts.iter().enumerate() {
            match simulate_point(cell, p, i + 1, rng) {
                Ok(sp) => out.push(sp),
                Err((robot, why)) => {
                    last_fail = Some((i + 1, *p, robot, why));
                    continue 'draw;
                }
            }
        }
        return Ok(Session::from_points(out));
    }
    let (i, p, robot, why) = last_fail.unwrap_or((1, centre, Robot::One, String::new()));
    Err(unreachable(cell, i, &p, robot, &why, Some(spec)))
}

pub(crate) fn unreachable(
    cell: &Cell,
    point: usize,
    p: &Point3<f64>,
    robot: Robot,
    why: &str,
    spec: Option<&SessionSpec>,
) -> SimError {
    let c = cell.centre_b1 * 1e3;
    let hint = match spec {
        Some(s) => format!(
            "no draw of {MAX_LAYOUT_ATTEMPTS} {} layouts with spread {:.0} mm fitted; reduce the spread or move the centre toward ({:.0}, {:.0}, {:.0}) mm",
            s.layout, s.spread_m * 1e3, c.x, c.y, c.z
        ),
        None => format!("move it toward the common workspace centre ({:.0}, {:.0}, {:.0}) mm", c.x, c.y, c.z),
    };
    SimError::Unreachable {
        point,
        p_b1_mm: [p.x * 1e3, p.y * 1e3, p.z * 1e3],
        message: format!("{why} ({}); {hint}", cell.robot(robot).model.name()),
    }
}
