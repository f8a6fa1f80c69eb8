//! Inverse kinematics to a tip position (m, base frame), optionally with the flange z axis along a
//! given direction, by damped least squares (Levenberg–Marquardt) within the joint limits.
//!
//! Task: the tip position error `e_p = p_target − p_tip` (3 rows, m) and, with a tool axis `a`,
//! the rotation that brings the flange z axis `z` onto `a`, `θ·n̂` with `θ = ∠(z, a)` and
//! `n̂ = z×a/|z×a|`, written in two directions `u, v ⟂ z` (2 rows, rad, weight 1 m/rad). Its
//! Jacobian rows are `u·ω_k, v·ω_k` (ω_k: joint k's angular-velocity column), so the axis task has
//! a single zero at `z = a` (the anti-parallel direction is not a spurious solution).
//!
//! Step: `dq = Jᵀ(JJᵀ + λI)⁻¹ e`, accepted when the cost `|e|²` decreases; λ follows Nielsen's
//! gain-ratio rule, and a seed is abandoned when λ exceeds 1e4 (a local minimum, typically on a
//! joint limit) or when, with the error above 0.1 mm, the cost fell by less than 1 % over 10
//! iterations (an unreachable target: the arm crawls along the workspace boundary).
//! Joint limits are an active set: a joint whose step would leave its range is moved onto the
//! limit, its column is removed, and the others are re-solved for what is left of the error.
//! For redundant problems the left-over freedom moves toward `preferred_q` by a null-space term
//! `(I − J⁺J)·0.5·(q_pref − q)` while the error is above 1e-6 (m or rad); the final steps are pure
//! Gauss–Newton so the solve reaches `tolerance_m` (default 1e-10 m).
//! Restarts come from a fixed, deterministic set of seeds (a Halton sequence over the joint
//! ranges; every other seed, except an `initial_q` the caller gave, first turns joint 1 toward
//! the target's azimuth); a target that no seed reaches is reported as [`IkStatus::Unreachable`] with the best
//! joint vector found. All work buffers are allocated once per call.
//!
//! Prismatic joints and coupled joints: `q` is the independent joints (rad, or m for a prismatic
//! joint) and the Jacobian columns are those of [`crate::geometric_jacobian`] (a prismatic
//! column in m/m, comparable with a rotary column in m/rad on an arm of about 1 m reach, so the
//! damping, in m², and the step rule are the same); a prismatic joint's limits are an active set
//! like any other, in m, and its Halton seeds span its whole travel (a rotary joint's at most
//! 2π). The azimuth aim turns the first rotary joint of the chain when only independent
//! prismatic joints come before it (a rail under an arm) and no coupled joint follows it; it is
//! skipped otherwise.

use nalgebra::{Matrix3, Point3, Unit, Vector3};

use crate::error::KinematicsError;
use crate::fk::{check_tip, joint_frames};
use crate::jacobian::joint_columns;
use crate::model::RobotModel;

/// Options of [`ik_tip_position`]. Every default is documented on its field.
#[derive(Debug, Clone, PartialEq)]
pub struct IkOptions {
    /// Desired direction of the flange z axis in the base frame (default None: position only).
    /// In a handclasp the two tips meet head-on, so each robot's flange z points at the other.
    pub tool_axis_base: Option<Unit<Vector3<f64>>>,
    /// Joint vector (rad, or m for a prismatic joint) the redundant freedom is pulled toward
    /// (default None).
    pub preferred_q: Option<Vec<f64>>,
    /// First seed (rad, or m for a prismatic joint); default None: `preferred_q`, else 0 clamped
    /// into each joint's range.
    pub initial_q: Option<Vec<f64>>,
    /// Position tolerance, m. Default 1e-10.
    pub tolerance_m: f64,
    /// Axis tolerance, rad (used with `tool_axis_base`). Default 1e-10.
    pub axis_tolerance_rad: f64,
    /// Iterations per seed. Default 300 (most solves need fewer than 20; near-singular
    /// targets converge only linearly).
    pub max_iterations: usize,
    /// Number of extra deterministic seeds tried after the first. Default 32.
    pub restarts: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            tool_axis_base: None,
            preferred_q: None,
            initial_q: None,
            tolerance_m: 1e-10,
            axis_tolerance_rad: 1e-10,
            max_iterations: 300,
            restarts: 32,
        }
    }
}

/// Outcome of an IK solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum IkStatus {
    /// Tolerances met.
    Converged,
    /// No seed met the tolerances: the target is out of reach (or too close to a limit/singularity).
    Unreachable,
}

/// Why the solver stopped on the joint vector it returns (for an [`IkStatus::Unreachable`]
/// result: why the search from the seed that came closest ended; every other seed ended for one
/// of the same reasons).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum IkStopReason {
    /// The tolerances were met.
    Converged,
    /// The seed used all [`IkOptions::max_iterations`] iterations while still making progress
    /// (slow, linear convergence: typically a solution at or next to a singularity; more
    /// iterations may reach it).
    IterationCap,
    /// With the task error above 0.1 mm (or 1e-4 rad), the cost fell by less than 1 % over 10
    /// iterations: the arm crawls along its workspace boundary, typically because the target is
    /// out of reach.
    Stalled,
    /// No damped step lowered the cost even with the damping raised to 1e4 m²: a local minimum
    /// of the least-squares cost, typically with joints on their limits or at a singular
    /// configuration whose Jacobian cannot reduce the remaining error.
    DampingLimit,
}

impl IkStopReason {
    /// `"converged"`, `"iteration_cap"`, `"stalled"` or `"damping_limit"`.
    pub fn name(self) -> &'static str {
        match self {
            IkStopReason::Converged => "converged",
            IkStopReason::IterationCap => "iteration_cap",
            IkStopReason::Stalled => "stalled",
            IkStopReason::DampingLimit => "damping_limit",
        }
    }
}

/// Result of [`ik_tip_position`].
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// Joint vector (the independent joints: rad, or m for a prismatic joint), within the
    /// limits (best found if unreachable).
    pub q: Vec<f64>,
    /// Whether the tolerances were met.
    pub status: IkStatus,
    /// Remaining tip position error, m.
    pub position_error_m: f64,
    /// Remaining angle between the flange z axis and the requested axis, rad (0 if none requested).
    pub axis_error_rad: f64,
    /// Iterations used, over all seeds.
    pub iterations: usize,
    /// Why the search that produced `q` stopped ([`IkStopReason::Converged`] exactly when
    /// `status` is [`IkStatus::Converged`]).
    pub stop_reason: IkStopReason,
    /// Seeds tried (1 to `1 + restarts`).
    pub seeds_tried: usize,
}

impl IkSolution {
    /// True when the solve converged.
    pub fn reachable(&self) -> bool {
        self.status == IkStatus::Converged
    }
}

/// Largest task: 3 position rows + 2 axis rows.
const MAX_ROWS: usize = 5;
/// Null-space gain toward `preferred_q` per iteration (fraction of the remaining difference).
const NULL_GAIN: f64 = 0.5;
/// The null-space pull stops below this task error (m or rad), so the last steps are pure
/// Gauss–Newton and converge quadratically.
const NULL_STOP: f64 = 1e-6;
/// Damping bounds, in m² (rows are m and rad at 1 m/rad).
const LAMBDA_INIT: f64 = 1e-3;
const LAMBDA_MIN: f64 = 1e-16;
const LAMBDA_GIVE_UP: f64 = 1e4;

/// A seed is abandoned when, with its error above `STALL_MIN_ERROR` (m or rad), the cost fell by
/// less than 1 % over `STALL_WINDOW` iterations.
const STALL_WINDOW: usize = 10;
const STALL_MIN_ERROR: f64 = 1e-4;

type Col = [f64; MAX_ROWS];

/// The task at one q: residual, Jacobian columns, errors.
struct Lin {
    e: Col,
    cols: Vec<Col>,
    pos_err: f64,
    axis_err: f64,
    cost: f64,
}

impl Lin {
    fn new(n: usize) -> Self {
        Lin {
            e: [0.0; MAX_ROWS],
            cols: vec![[0.0; MAX_ROWS]; n],
            pos_err: f64::INFINITY,
            axis_err: f64::INFINITY,
            cost: f64::INFINITY,
        }
    }
}

struct Problem<'a> {
    model: &'a RobotModel,
    target: Point3<f64>,
    tip: Vector3<f64>,
    axis: Option<Vector3<f64>>,
    rows: usize,
}

impl Problem<'_> {
    /// Evaluates the task at `q` into `lin`; `frames` is scratch.
    fn linearize(&self, q: &[f64], frames: &mut Vec<(Matrix3<f64>, Vector3<f64>)>, lin: &mut Lin) {
        let (r_flange, t_flange) = joint_frames(self.model, q, frames);
        let p_tip = t_flange + r_flange * self.tip;
        let ep = self.target.coords - p_tip;
        lin.e[..3].copy_from_slice(ep.as_slice());
        lin.pos_err = ep.norm();
        let mut basis = None;
        lin.axis_err = 0.0;
        if let Some(a) = &self.axis {
            let z: Vector3<f64> = r_flange.column(2).into_owned();
            let c = z.cross(a);
            let s = c.norm();
            let theta = s.atan2(z.dot(a));
            // u, v ⟂ z.
            let helper = if z.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let u = z.cross(&helper).normalize();
            let v = z.cross(&u);
            let n_hat = if s > 1e-300 { c / s } else { u };
            let ea = theta * n_hat;
            lin.e[3] = u.dot(&ea);
            lin.e[4] = v.dot(&ea);
            lin.axis_err = theta;
            basis = Some((u, v));
        }
        if self.model.has_coupled_joints() {
            // Chain rule: column i = Σ_k (∂q_k/∂q_i)·(chain column k).
            lin.cols.iter_mut().for_each(|c| *c = [0.0; MAX_ROWS]);
            for (k, ((r, t), step)) in frames.iter().zip(self.model.steps.iter()).enumerate() {
                let (vel, w) = joint_columns::<true>(step, r, t, &p_tip);
                let mut chain_col = [0.0; MAX_ROWS];
                chain_col[..3].copy_from_slice(vel.as_slice());
                if let Some((u, v)) = &basis {
                    chain_col[3] = u.dot(&w);
                    chain_col[4] = v.dot(&w);
                }
                self.model.for_each_dependence(k, |i, c| {
                    for (x, y) in lin.cols[i].iter_mut().zip(&chain_col) {
                        *x += c * y;
                    }
                });
            }
        } else if self.model.prismatic {
            self.fill_columns::<true>(frames, &p_tip, &basis, lin);
        } else {
            self.fill_columns::<false>(frames, &p_tip, &basis, lin);
        }
        lin.cost = lin.e[..self.rows].iter().map(|x| x * x).sum();
    }

    /// The columns of `lin` for a chain without coupled joints (one column per chain joint) that
    /// may (or, `false`, does not) hold prismatic joints.
    #[inline(always)]
    fn fill_columns<const MAY_BE_PRISMATIC: bool>(
        &self,
        frames: &[(Matrix3<f64>, Vector3<f64>)],
        p_tip: &Vector3<f64>,
        basis: &Option<(Vector3<f64>, Vector3<f64>)>,
        lin: &mut Lin,
    ) {
        for (((r, t), step), col) in frames
            .iter()
            .zip(self.model.steps.iter())
            .zip(&mut lin.cols)
        {
            let (vel, w) = joint_columns::<MAY_BE_PRISMATIC>(step, r, t, p_tip);
            col[..3].copy_from_slice(vel.as_slice());
            if let Some((u, v)) = basis {
                col[3] = u.dot(&w);
                col[4] = v.dot(&w);
            }
        }
    }
}

impl Problem<'_> {
    /// The joint [`Problem::aim_first_joint`] turns: `(chain index, index in q)` of the first
    /// rotary chain joint when every joint before it is an independent prismatic joint and it
    /// drives no coupled joint; `None` otherwise.
    fn aim_joint(&self) -> Option<(usize, usize)> {
        let chain = self.model.chain_joints();
        let k = chain.iter().position(|j| !j.kind.is_prismatic())?;
        if chain[..=k].iter().any(|j| j.is_coupled()) {
            return None;
        }
        // Independent joints before k are all prismatic and uncoupled: k is q index k.
        let drives_coupled = chain.iter().any(|j| {
            j.coupling
                .as_ref()
                .is_some_and(|c| c.terms.iter().any(|&(i, _)| i == k))
        });
        (!drives_coupled).then_some((k, k))
    }

    /// Seed improvement: turns the first joint (the first rotary one after a rail, see
    /// [`Problem::aim_joint`]) so that the tip has the target's azimuth about that joint's axis
    /// (one cyclic-coordinate-descent step, clamped to the limits). For the usual arm with a
    /// vertical first axis this points the arm at the target, which removes most joint-limit
    /// local minima of the least-squares cost.
    fn aim_first_joint(&self, q: &mut [f64], frames: &mut Vec<(Matrix3<f64>, Vector3<f64>)>) {
        let Some((k, qi)) = self.aim_joint() else {
            return;
        };
        let (r_flange, t_flange) = joint_frames(self.model, q, frames);
        let (Some((r1, t1)), Some(step), Some(jt)) = (
            frames.get(k),
            self.model.steps.get(k),
            self.model.joints().get(qi),
        ) else {
            return;
        };
        let w = r1 * step.axis.into_inner();
        let flat = |p: Vector3<f64>| p - w * w.dot(&p);
        let from = flat(t_flange + r_flange * self.tip - t1);
        let to = flat(self.target.coords - t1);
        if from.norm() < 1e-6 || to.norm() < 1e-6 {
            return;
        }
        let angle = from.cross(&to).dot(&w).atan2(from.dot(&to));
        q[qi] = (q[qi] + angle).clamp(jt.lower, jt.upper);
    }
}

/// Solves `a·x = b` for a symmetric positive definite `n×n` block of `a` (in place, Cholesky).
/// Returns false if `a` is not positive definite.
// Index loops read as the textbook algorithm.
#[allow(clippy::needless_range_loop)]
fn solve_spd(a: &mut [[f64; MAX_ROWS]; MAX_ROWS], b: &mut Col, n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j][j];
        for k in 0..j {
            d -= a[j][k] * a[j][k];
        }
        if d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..n {
            let mut s = a[i][j];
            for k in 0..j {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i][k] * b[k];
        }
        b[i] = s / a[i][i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k][i] * b[k];
        }
        b[i] = s / a[i][i];
    }
    true
}

fn dot(a: &Col, b: &Col, n: usize) -> f64 {
    a[..n].iter().zip(&b[..n]).map(|(x, y)| x * y).sum()
}

/// Scratch for [`lm_step`].
struct StepWork {
    free: Vec<bool>,
    dq: Vec<f64>,
}

/// One damped step with the joint limits as an active set; writes the new q into `q_new`.
/// Returns false if the damped normal matrix is not positive definite.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
fn lm_step(
    model: &RobotModel,
    q: &[f64],
    lin: &Lin,
    rows: usize,
    lambda: f64,
    pull: Option<&[f64]>,
    sw: &mut StepWork,
    q_new: &mut [f64],
) -> bool {
    let n = q.len();
    sw.free.iter_mut().for_each(|f| *f = true);
    sw.dq.iter_mut().for_each(|d| *d = 0.0);
    // At most n passes: each pass fixes at least one more joint or ends.
    for _ in 0..=n {
        // Normal matrix over the free columns and the error left after the fixed joints' moves.
        let mut a = [[0.0; MAX_ROWS]; MAX_ROWS];
        let mut rhs = lin.e;
        for k in 0..n {
            let c = &lin.cols[k];
            if sw.free[k] {
                for r in 0..rows {
                    for s in 0..=r {
                        a[r][s] += c[r] * c[s];
                    }
                }
            } else {
                for r in 0..rows {
                    rhs[r] -= c[r] * sw.dq[k];
                }
            }
        }
        for r in 0..rows {
            a[r][r] += lambda;
            for s in 0..r {
                a[s][r] = a[r][s];
            }
        }
        let a_copy = a;
        if !solve_spd(&mut a, &mut rhs, rows) {
            return false;
        }
        // Null-space pull: d − Jᵀ(JJᵀ+λI)⁻¹J d over the free joints.
        let mut jd = [0.0; MAX_ROWS];
        if let Some(pref) = pull {
            for k in 0..n {
                if sw.free[k] {
                    let d = NULL_GAIN * (pref[k] - q[k]);
                    for r in 0..rows {
                        jd[r] += lin.cols[k][r] * d;
                    }
                }
            }
            let mut a2 = a_copy;
            if !solve_spd(&mut a2, &mut jd, rows) {
                return false;
            }
        }
        let mut violated = false;
        for k in 0..n {
            if !sw.free[k] {
                continue;
            }
            let c = &lin.cols[k];
            let mut d = dot(c, &rhs, rows);
            if let Some(pref) = pull {
                d += NULL_GAIN * (pref[k] - q[k]) - dot(c, &jd, rows);
            }
            sw.dq[k] = d;
        }
        for (k, jt) in model.joints().iter().enumerate() {
            if !sw.free[k] {
                continue;
            }
            let target = q[k] + sw.dq[k];
            if target < jt.lower || target > jt.upper {
                sw.dq[k] = target.clamp(jt.lower, jt.upper) - q[k];
                sw.free[k] = false;
                violated = true;
            }
        }
        if !violated {
            break;
        }
    }
    for (k, jt) in model.joints().iter().enumerate() {
        q_new[k] = (q[k] + sw.dq[k]).clamp(jt.lower, jt.upper);
    }
    true
}

/// The deterministic seeds after the first: a Halton sequence over the joint ranges (90 % of the
/// span around its middle; a rotary joint's span capped at 2π, a prismatic joint's whole travel).
pub(crate) fn halton_seed(model: &RobotModel, s: usize, out: &mut [f64]) {
    const PRIMES: [usize; 10] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29];
    for (i, (j, o)) in model.joints().iter().zip(out.iter_mut()).enumerate() {
        let b = PRIMES[i % PRIMES.len()];
        let (mut f, mut k, mut inv) = (0.0, s, 1.0 / b as f64);
        while k > 0 {
            f += (k % b) as f64 * inv;
            k /= b;
            inv /= b as f64;
        }
        let (lo, hi) = finite_range(j.lower, j.upper);
        let span = if j.kind.is_prismatic() {
            hi - lo
        } else {
            (hi - lo).min(std::f64::consts::TAU)
        };
        let c = 0.5 * (lo + hi);
        *o = (c + (f - 0.5) * span * 0.9).clamp(lo, hi);
    }
}

fn finite_range(lower: f64, upper: f64) -> (f64, f64) {
    if lower.is_finite() && upper.is_finite() {
        (lower, upper)
    } else {
        (-std::f64::consts::PI, std::f64::consts::PI)
    }
}

fn check_vec(model: &RobotModel, v: &Option<Vec<f64>>, what: &str) -> Result<(), KinematicsError> {
    if let Some(v) = v {
        if v.len() != model.dof() || v.iter().any(|x| !x.is_finite()) {
            return Err(KinematicsError::InvalidInput(format!(
                "IkOptions::{what} must hold {} finite values (rad, or m for a prismatic joint; one per independent joint of {}), got {:?}",
                model.dof(),
                model.name(),
                v
            )));
        }
    }
    Ok(())
}

/// Joint values (the independent joints: rad, or m for a prismatic joint) that put the tip at
/// `p_base_tip` (m, base frame), with the tip at
/// `flange_from_tip` (m, flange frame), within the joint limits; with
/// `options.tool_axis_base`, the flange z axis also points along that direction (base frame).
///
/// Non-convergence is [`IkStatus::Unreachable`], not an error. Errors: non-finite target, tip or
/// tool axis, option vectors of the wrong length or non-finite, non-positive tolerances, zero
/// `max_iterations`.
///
/// # Examples
/// ```
/// use kinematics::{base_from_tip, ik_tip_position, IkOptions, RobotModel};
/// use nalgebra::{Point3, Vector3};
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/hp20.urdf");
/// let model = RobotModel::from_urdf_file(std::path::Path::new(path), "tool0").unwrap();
/// let tip = Vector3::new(0.0, 0.0, 0.15);
/// let target = Point3::new(1.0, 0.3, 0.8);
/// let sol = ik_tip_position(&model, &target, &tip, &IkOptions::default()).unwrap();
/// assert!(sol.reachable());
/// let p = base_from_tip(&model, &sol.q, &tip).unwrap().translation.vector;
/// assert!((p - target.coords).norm() < 1e-9);
/// ```
pub fn ik_tip_position(
    model: &RobotModel,
    p_base_tip: &Point3<f64>,
    flange_from_tip: &Vector3<f64>,
    options: &IkOptions,
) -> Result<IkSolution, KinematicsError> {
    check_tip(flange_from_tip)?;
    if p_base_tip.iter().any(|v| !v.is_finite()) {
        return Err(KinematicsError::InvalidInput(format!(
            "IK target {:?} m is not finite; give a finite tip position",
            p_base_tip.coords.as_slice()
        )));
    }
    if !(options.tolerance_m > 0.0 && options.axis_tolerance_rad > 0.0) {
        return Err(KinematicsError::InvalidInput(format!(
            "IK tolerances must be positive, got tolerance_m = {} and axis_tolerance_rad = {}",
            options.tolerance_m, options.axis_tolerance_rad
        )));
    }
    if options.max_iterations == 0 {
        return Err(KinematicsError::InvalidInput(
            "IkOptions::max_iterations is 0; give at least 1 (default 300)".into(),
        ));
    }
    check_vec(model, &options.preferred_q, "preferred_q")?;
    check_vec(model, &options.initial_q, "initial_q")?;
    let axis = match options.tool_axis_base {
        Some(a) if a.iter().all(|x| x.is_finite()) => Some(a.into_inner()),
        Some(a) => {
            return Err(KinematicsError::InvalidInput(format!(
                "tool axis {:?} is not finite; give a finite direction",
                a.as_slice()
            )))
        }
        None => None,
    };
    let n = model.dof();
    let problem = Problem {
        model,
        target: *p_base_tip,
        tip: *flange_from_tip,
        axis,
        rows: if axis.is_some() { 5 } else { 3 },
    };
    let rows = problem.rows;
    let tol_ok = |l: &Lin| {
        l.pos_err <= options.tolerance_m
            && (axis.is_none() || l.axis_err <= options.axis_tolerance_rad)
    };
    let redundant = n > rows;
    let pull = options.preferred_q.as_deref().filter(|_| redundant);

    let mut frames = Vec::with_capacity(n);
    let mut lin = Lin::new(n);
    let mut lin_try = Lin::new(n);
    let mut sw = StepWork {
        free: vec![true; n],
        dq: vec![0.0; n],
    };
    let mut q = vec![0.0; n];
    let mut q_try = vec![0.0; n];
    let mut best_q = vec![0.0; n];
    let (mut best_pe, mut best_ae, mut best_score) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut best_reason = IkStopReason::IterationCap;
    let mut total_iters = 0;

    let user_seed = options.initial_q.as_ref().or(options.preferred_q.as_ref());
    for s in 0..=options.restarts {
        if s == 0 {
            match user_seed {
                Some(first) => q.copy_from_slice(first),
                None => q.iter_mut().for_each(|x| *x = 0.0),
            }
        } else {
            halton_seed(model, s, &mut q);
        }
        for (qi, jt) in q.iter_mut().zip(model.joints()) {
            *qi = qi.clamp(jt.lower, jt.upper);
        }
        // Aim every other seed (not an `initial_q` the caller gave): aiming misleads when the
        // target lies near joint 1's axis.
        if s % 2 == 0 && !(s == 0 && options.initial_q.is_some()) {
            problem.aim_first_joint(&mut q, &mut frames);
        }
        problem.linearize(&q, &mut frames, &mut lin);
        let mut lambda = LAMBDA_INIT;
        let mut nu = 2.0;
        let mut converged = tol_ok(&lin);
        let mut it = 0;
        let mut checkpoint_cost = lin.cost;
        let mut reason = IkStopReason::IterationCap;
        while !converged && it < options.max_iterations {
            it += 1;
            // Stall: far from any solution and under 1 % progress in the last STALL_WINDOW
            // iterations (typically an unreachable target, the arm crawling along its boundary).
            if it % STALL_WINDOW == 0 {
                if lin.cost.sqrt() > STALL_MIN_ERROR && lin.cost > 0.99 * checkpoint_cost {
                    reason = IkStopReason::Stalled;
                    break;
                }
                checkpoint_cost = lin.cost;
            }
            let use_pull = pull.filter(|_| lin.cost.sqrt() > NULL_STOP);
            let mut gain_ratio = None;
            for p in [use_pull, None] {
                if !lm_step(model, &q, &lin, rows, lambda, p, &mut sw, &mut q_try) {
                    break;
                }
                problem.linearize(&q_try, &mut frames, &mut lin_try);
                if tol_ok(&lin_try) {
                    gain_ratio = Some(1.0);
                    break;
                }
                if lin_try.cost < lin.cost {
                    // Gain ratio: actual over predicted decrease, the prediction being
                    // |e − J·dq|² of the linear model.
                    let mut predicted = 0.0;
                    for r in 0..rows {
                        let mut x = lin.e[r];
                        for (k, c) in lin.cols.iter().enumerate() {
                            x -= c[r] * (q_try[k] - q[k]);
                        }
                        predicted += x * x;
                    }
                    let drop = lin.cost - predicted;
                    let rho = if drop > 0.0 {
                        (lin.cost - lin_try.cost) / drop
                    } else {
                        1.0
                    };
                    gain_ratio = Some(rho);
                    break;
                }
                if p.is_none() {
                    break;
                }
            }
            if let Some(rho) = gain_ratio {
                std::mem::swap(&mut q, &mut q_try);
                std::mem::swap(&mut lin, &mut lin_try);
                // Nielsen's update (Madsen, Nielsen & Tingleff, "Methods for non-linear least
                // squares problems", 2004, eq. 2.21).
                let t = 2.0 * rho.min(1.0) - 1.0;
                lambda = (lambda * (1.0 / 3.0f64).max(1.0 - t * t * t)).max(LAMBDA_MIN);
                nu = 2.0;
                converged = tol_ok(&lin);
            } else {
                lambda *= nu;
                nu *= 2.0;
                if lambda > LAMBDA_GIVE_UP {
                    reason = IkStopReason::DampingLimit;
                    break;
                }
            }
        }
        total_iters += it;
        if converged {
            return Ok(IkSolution {
                q,
                status: IkStatus::Converged,
                position_error_m: lin.pos_err,
                axis_error_rad: lin.axis_err,
                iterations: total_iters,
                stop_reason: IkStopReason::Converged,
                seeds_tried: s + 1,
            });
        }
        let score = lin.pos_err + lin.axis_err;
        if score < best_score {
            best_score = score;
            best_reason = reason;
            best_pe = lin.pos_err;
            best_ae = lin.axis_err;
            best_q.copy_from_slice(&q);
        }
    }
    Ok(IkSolution {
        q: best_q,
        status: IkStatus::Unreachable,
        position_error_m: best_pe,
        axis_error_rad: best_ae,
        iterations: total_iters,
        stop_reason: best_reason,
        seeds_tried: options.restarts + 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_fixtures::TWO_JOINT;

    #[test]
    fn solve_spd_matches_direct_solution() {
        // A = [[4, 2], [2, 3]], b = [2, 1] → x = [0.5, 0].
        let mut a = [[0.0; MAX_ROWS]; MAX_ROWS];
        a[0][0] = 4.0;
        a[1][0] = 2.0;
        a[0][1] = 2.0;
        a[1][1] = 3.0;
        let mut b = [2.0, 1.0, 0.0, 0.0, 0.0];
        assert!(solve_spd(&mut a, &mut b, 2));
        assert!((b[0] - 0.5).abs() < 1e-15 && b[1].abs() < 1e-15);
        let mut not_pd = [[0.0; MAX_ROWS]; MAX_ROWS];
        not_pd[0][0] = -1.0;
        assert!(!solve_spd(&mut not_pd, &mut b, 1));
    }

    /// `with_joints_held`: the inverse kinematics of the held model reaches a target the free
    /// arm reaches, without moving the held joints (a shared trunk's), and a value outside a
    /// held joint's limits (or too many values) is refused naming the joint.
    #[test]
    fn held_joints_do_not_move_in_the_inverse_kinematics() {
        let free = crate::test_fixtures::mixed_coupled();
        let q = [0.05, 0.3, -0.4, 0.1];
        let tip = Vector3::new(0.0, 0.0, 0.1);
        let target = Point3::from(
            crate::base_from_tip(&free, &q, &tip)
                .unwrap()
                .translation
                .vector,
        );
        let held = free.with_joints_held(&q[..2]).unwrap();
        let start = IkOptions {
            initial_q: Some(vec![0.0; 4]),
            ..IkOptions::default()
        };
        let sol = ik_tip_position(&held, &target, &tip, &start).unwrap();
        assert!(sol.reachable(), "{sol:?}");
        assert_eq!(sol.q[..2], q[..2]);
        let reached = crate::base_from_tip(&free, &sol.q, &tip).unwrap();
        assert!((reached.translation.vector - target.coords).norm() < 1e-9);
        let j = &free.joints()[1];
        let e = free
            .with_joints_held(&[0.0, j.upper + 0.1])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&j.name) && e.contains("within its limits"),
            "{e}"
        );
        assert!(free.with_joints_held(&[0.0; 5]).is_err());
    }

    #[test]
    fn halton_seeds_stay_in_limits_and_differ() {
        let xml = TWO_JOINT;
        let m = RobotModel::from_urdf_str(xml, "tool0").unwrap();
        let mut prev = vec![f64::NAN; 2];
        for s in 1..20 {
            let mut q = vec![0.0; 2];
            halton_seed(&m, s, &mut q);
            assert!((-1.0..=2.0).contains(&q[0]));
            assert!(q[1].abs() <= std::f64::consts::PI);
            assert_ne!(q, prev);
            prev = q;
        }
    }
}
