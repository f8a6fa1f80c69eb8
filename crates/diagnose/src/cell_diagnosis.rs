//! The whole-cell diagnosis ([`diagnose_cell_session`]): what the nominal models get wrong in a
//! session with contact, tracker or plane rows (and any coincident ones), by forward selection
//! of parameter *families* on the whole-cell fit ([`calib_core::whole_cell`]) with a held-out
//! criterion that holds out whole nuisance groups.
//!
//! # Method
//! 1. **Problem.** [`sim_cell::whole_cell::cell_problem`] with every tolerance of the cell
//!    multiplied by [`CellDiagnoseOptions::prior_widening`] (the diagnosis looks for errors
//!    beyond the stated tolerances, so the prior only regularises what the data cannot see), and
//!    joint compliance added where the URDF has inertials: its tolerance is the (widened) joint
//!    offset tolerance divided by the largest gravity torque of the session's postures, so a
//!    compliance at its tolerance turns a joint by at most one offset tolerance; and
//!    joint-angle-periodic errors where the cell states no `periodic_rad`: each of the `sin`
//!    and `cos` amplitudes gets the (widened) joint offset tolerance, so a first harmonic at its
//!    tolerance is an angle error of the joint offset's size (×√2 at most).
//! 2. **Noise level.** Every family free, all rows: per kind, the robust scale of the whitened
//!    residuals `s_k = max(1, 1.4826·median|w|)`; each row's σ is multiplied by its kind's
//!    `s_k` for everything after (a laser tracker's logged σ of a few µm is far below any
//!    model's reach and would make every row a blunder and let one kind outweigh the rest).
//!    The report gives the residuals against the stated σ and `s_k`.
//! 3. **Screen.** The blunder screen of the whole-cell fit ([`fit_screened`]) with every family
//!    free (in a session too small for them, less the tracker drifts and scales:
//!    [`ScreenOptions::min_redundancy`]); rejected rows are left out of everything after.
//! 4. **Baseline.** Nominal kinematics with the nuisances fitted (tracker frames, planes, fitted
//!    contact distances, the placement); the residual rms of each kind against its stated σ.
//! 5. **Selection.** Candidates are [`Family`] entries (a robot's joint offsets, origin
//!    positions, origin angles, compliance, joint-periodic errors, each tool's tip; the contact
//!    distances of groups that state one; the tracker scales and the tracker drifts, one
//!    unpenalised scale or drift per tracker group, switched on like the contact distances).
//!    Each step fits every remaining candidate added to the current model in
//!    K folds and keeps, of those accepted (below), the one of lowest held-out χ²; it stops
//!    when none is accepted. **Folds** hold out whole units: each
//!    named group (tracker file, plane, contact group) is a unit, the coincident rows are cut
//!    into up to [`COINCIDENT_UNITS`] units in row order; units go to
//!    `min(units, max_folds)` folds round-robin; a group of fewer than its kind's
//!    [`MIN_SCORED_GROUP_ROWS`] rows is never held out (it trains every fold). With fewer than
//!    3 units (one tracker file),
//!    each unit is cut into up to 4 contiguous blocks (recording order) of at least
//!    [`MIN_GROUP_BLOCK_ROWS`] rows instead. **Held-out score** of a unit: its own nuisance
//!    (tracker frame, and its scale and drift when those families are in the model; plane;
//!    fitted contact distance) is unknown to the training fit, so it is
//!    fitted on one half of the unit's rows (alternate rows) with the training kinematics and
//!    placement held, and the other half is scored, then the halves swap: every scored residual
//!    is predicted by parameters that did not see it. Units without a nuisance (coincident,
//!    contacts of a stated distance) are scored directly. A candidate is **accepted** when it
//!    lowers the total held-out χ² by at least `min_relative_gain` (default 1 %) and the relative
//!    gains `g_u = 1 − χ²_u,after/χ²_u,before` of the units it is involved in
//!    ([`Family::involves`]: rows of its robot, or of its tool; relative, so that one unit of
//!    many rows or small σ does not decide alone; only those units, so that a tip family is not
//!    diluted by tracker files of another tool) have a t statistic
//!    `mean/(sd/√n) ≥ min_gain_t` (default 3); with fewer than 3 such units every one must gain
//!    `min_relative_gain`. An effect is thus named only when it helps the held-out groups
//!    consistently.
//! 6. **Effects.** Each accepted family: its parameters from the fit of the final model on all
//!    screened rows, with a 95 % interval `±1.96·σ` (posterior σ times the variance factor
//!    `max(1, sqrt(χ²/(rows − unknowns)))`, so that real data whose residuals exceed their
//!    stated σ get honest intervals); the held-out rms per kind before and after the step; the
//!    whitened residual rms against each joint (quartile bins) before and after.
//!
//! SI inside; [`crate::cell_report`] speaks mm, mrad, ppm and degrees (a tracker scale in ppm,
//! a drift in mm over the group's whole recording, a periodic amplitude in mrad).

use calib_core::whole_cell::{
    fit_cell_with, fit_screened, initial_estimate, CellEstimate, CellFit, CellFitError, CellParam,
    CellProblem, Evaluator, Noise3, ObservationKind, ParamLayout, PlacementPrior, ScreenOptions,
    SolveOptions, Tolerance,
};
use calib_core::Robot;
use kinematics::{gravity_torques, ErrorParam};
use nalgebra::DVector;
use rayon::prelude::*;
use serde::Serialize;
use sim_cell::whole_cell::{cell_problem, FitModel};
use sim_cell::{Cell, Session};
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::cell_report::{self, CellDiagnoseReport};
use crate::DiagnoseError;

/// At most this many held-out units are cut from the coincident rows (in row order, at least
/// [`MIN_UNIT_ROWS`] rows each).
pub const COINCIDENT_UNITS: usize = 4;
/// Fewest rows of a coincident unit.
pub const MIN_UNIT_ROWS: usize = 6;
/// Fewest rows of a group that is held out and scored, per kind (contact, tracker, plane): each
/// half must fit the group's nuisance (a distance from 1 row, a tracker frame or a plane from 3).
pub const MIN_SCORED_GROUP_ROWS: [usize; 3] = [2, 6, 6];
/// Fewest rows of a block cut from a group when the session has fewer than 3 units.
pub const MIN_GROUP_BLOCK_ROWS: usize = 12;
/// σ (m and rad) of the placement prior that holds the training placement while a held-out
/// unit's nuisance is fitted: far below any measurement, far above round-off.
const HOLD_SIGMA: f64 = 1e-7;
/// The 95 % two-sided normal quantile.
pub const Z95: f64 = 1.959_963_984_540_054;

/// Options of [`diagnose_cell_session`] (defaults in parentheses).
#[derive(Debug, Clone)]
pub struct CellDiagnoseOptions {
    /// Every tolerance of the cell is multiplied by this to form the diagnosis prior (default 10).
    pub prior_widening: f64,
    /// Most folds of the held-out criterion (default 6).
    pub max_folds: usize,
    /// Smallest relative decrease of the held-out χ² that accepts a family (default 0.01).
    pub min_relative_gain: f64,
    /// Smallest t statistic of the per-unit relative held-out gains that accepts a family (default 3).
    pub min_gain_t: f64,
    /// Most selection steps (default 8).
    pub max_steps: usize,
    /// Screen blunders first (default true).
    pub screen_blunders: bool,
    /// Solver settings (the starting placement is set from the cell when the session has fewer
    /// than 3 coincident rows).
    pub solve: SolveOptions,
}

impl Default for CellDiagnoseOptions {
    fn default() -> Self {
        Self {
            prior_widening: 10.0,
            max_folds: 6,
            min_relative_gain: 0.01,
            min_gain_t: 3.0,
            max_steps: 8,
            screen_blunders: true,
            solve: SolveOptions::default(),
        }
    }
}

/// What a candidate family is. One entry per family of parameters; a new error term of the
/// library (e.g. joint-periodic errors, tracker scale or drift) is one more variant here, with
/// its membership test in [`Family::contains`] and its availability in [`candidate_families`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "family", rename_all = "snake_case")]
#[non_exhaustive]
pub enum FamilyKind {
    /// Every joint zero offset of the robot.
    JointOffsets,
    /// Every joint origin position (link lengths and offsets) of the robot.
    OriginXyz,
    /// Every joint origin angle of the robot, except the one about the joint's own axis (that
    /// one is the joint offset: [`offset_alias`]).
    OriginRpy,
    /// Joint compliance under gravity, every joint of the robot.
    Compliance,
    /// One tool's tip offset (end-effector geometry), 3 components.
    ToolTip {
        /// Tool index (0 = the cell's tip, then `[robotN.tools]`).
        tool: usize,
    },
    /// The distances of the contact groups that state one (fitted instead of held).
    ContactDistance,
    /// Joint-angle-periodic errors of the robot: the first harmonic (`sin q`, `cos q`
    /// amplitudes) of every joint ([`ErrorParam::PeriodicSin`], [`ErrorParam::PeriodicCos`]).
    JointPeriodic,
    /// One scale error per tracker group of the session (unpenalised, like the tracker frame;
    /// [`calib_core::whole_cell::TrackerGroup::fit_scale`]).
    TrackerScale,
    /// One linear drift of the tracker-frame translation over the recording order per tracker
    /// group (unpenalised; [`calib_core::whole_cell::TrackerGroup::fit_drift`]).
    TrackerDrift,
}

/// A candidate family: a kind of parameter on one robot (or the cell's contact groups).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Family {
    /// The robot (1 or 2); `None` for the session-wide families ([`FamilyKind::ContactDistance`],
    /// [`FamilyKind::TrackerScale`], [`FamilyKind::TrackerDrift`]).
    pub robot: Option<u8>,
    /// The kind.
    #[serde(flatten)]
    pub kind: FamilyKind,
    /// A readable name, e.g. `robot 1 joint offsets`, `robot 2 tool tip tip`.
    pub name: String,
}

impl Family {
    fn new(robot: Option<Robot>, kind: FamilyKind, problem: &CellProblem) -> Self {
        let what = match kind {
            FamilyKind::JointOffsets => "joint offsets".to_string(),
            FamilyKind::OriginXyz => "joint origin positions".to_string(),
            FamilyKind::OriginRpy => "joint origin angles".to_string(),
            FamilyKind::Compliance => "joint compliance".to_string(),
            FamilyKind::ToolTip { tool } => {
                let r = robot.expect("a tool tip family has a robot");
                format!("tool `{}` tip", problem.robot(r).tools[tool].name)
            }
            FamilyKind::ContactDistance => "contact distances".to_string(),
            FamilyKind::JointPeriodic => "joint-periodic errors".to_string(),
            FamilyKind::TrackerScale => "tracker scales".to_string(),
            FamilyKind::TrackerDrift => "tracker drifts".to_string(),
        };
        let name = match robot {
            Some(r) => format!("{r} {what}"),
            None => what,
        };
        Self {
            robot: robot.map(Robot::number),
            kind,
            name,
        }
    }

    fn robot_is(&self, r: Robot) -> bool {
        self.robot == Some(r.number())
    }

    /// Whether an observation of this kind uses the family's parameters directly: its robot
    /// (and tool, for a tip), or, for the contact distances, a contact row, or, for the
    /// tracker scales and drifts, a tracker row.
    pub fn involves(&self, kind: &ObservationKind) -> bool {
        match self.kind {
            FamilyKind::ContactDistance => matches!(kind, ObservationKind::Contact { .. }),
            FamilyKind::TrackerScale | FamilyKind::TrackerDrift => {
                matches!(kind, ObservationKind::Tracker { .. })
            }
            FamilyKind::ToolTip { tool } => tools_of(kind)
                .iter()
                .any(|(r, t)| self.robot_is(*r) && *t == tool),
            _ => tools_of(kind).iter().any(|(r, _)| self.robot_is(*r)),
        }
    }

    /// Whether the unknown `p` belongs to this family.
    pub fn contains(&self, p: &CellParam) -> bool {
        match (self.kind, p) {
            (FamilyKind::ContactDistance, CellParam::ContactDistance { .. })
            | (FamilyKind::TrackerScale, CellParam::TrackerScale { .. })
            | (FamilyKind::TrackerDrift, CellParam::TrackerDrift { .. }) => true,
            (FamilyKind::ToolTip { tool }, CellParam::ToolTip { robot, tool: t, .. }) => {
                self.robot_is(*robot) && *t == tool
            }
            (kind, CellParam::Kinematic { robot, param }) => {
                self.robot_is(*robot)
                    && matches!(
                        (kind, param),
                        (FamilyKind::JointOffsets, ErrorParam::JointOffset { .. })
                            | (FamilyKind::OriginXyz, ErrorParam::OriginXyz { .. })
                            | (FamilyKind::OriginRpy, ErrorParam::OriginRpy { .. })
                            | (FamilyKind::Compliance, ErrorParam::Compliance { .. })
                            | (
                                FamilyKind::JointPeriodic,
                                ErrorParam::PeriodicSin { .. } | ErrorParam::PeriodicCos { .. }
                            )
                    )
            }
            _ => false,
        }
    }
}

/// The candidate families of `problem` (the widened diagnosis problem): per robot, each
/// family whose tolerance is > 0 (tool tips only for tools the session uses), then the contact
/// distances when a contact group states its distance, then the tracker scales and drifts when
/// the session has a tracker group.
pub fn candidate_families(problem: &CellProblem) -> Vec<Family> {
    let mut out = Vec::new();
    for r in [Robot::One, Robot::Two] {
        let rb = problem.robot(r);
        let tol = &rb.tolerance;
        let joint_families = [
            (FamilyKind::JointOffsets, tol.joint_offset_rad > 0.0),
            (FamilyKind::OriginXyz, tol.origin_xyz_m > 0.0),
            (FamilyKind::OriginRpy, tol.origin_rpy_rad > 0.0),
            (
                FamilyKind::Compliance,
                tol.compliance_rad_per_nm.unwrap_or(0.0) > 0.0,
            ),
            (
                FamilyKind::JointPeriodic,
                tol.periodic_rad.unwrap_or(0.0) > 0.0,
            ),
        ];
        let used = |o: &&calib_core::whole_cell::Observation| uses_robot(&o.kind, r);
        if !problem.observations.iter().any(|o| used(&o)) {
            continue;
        }
        for (kind, on) in joint_families {
            if on {
                out.push(Family::new(Some(r), kind, problem));
            }
        }
        if tol.tip_m > 0.0 {
            for tool in 0..rb.tools.len() {
                if problem
                    .observations
                    .iter()
                    .any(|o| tools_of(&o.kind).contains(&(r, tool)))
                {
                    out.push(Family::new(Some(r), FamilyKind::ToolTip { tool }, problem));
                }
            }
        }
    }
    if problem.contacts.iter().any(|c| !c.fit_distance) {
        out.push(Family::new(None, FamilyKind::ContactDistance, problem));
    }
    if !problem.trackers.is_empty() {
        out.push(Family::new(None, FamilyKind::TrackerScale, problem));
        out.push(Family::new(None, FamilyKind::TrackerDrift, problem));
    }
    out
}

fn uses_robot(kind: &ObservationKind, r: Robot) -> bool {
    tools_of(kind).iter().any(|(rr, _)| *rr == r)
}

/// The (robot, tool) pairs an observation uses.
fn tools_of(kind: &ObservationKind) -> Vec<(Robot, usize)> {
    match kind {
        ObservationKind::Coincident { tool1, tool2, .. }
        | ObservationKind::Contact { tool1, tool2, .. } => {
            vec![(Robot::One, *tool1), (Robot::Two, *tool2)]
        }
        ObservationKind::Tracker { robot, tool, .. }
        | ObservationKind::Plane { robot, tool, .. } => {
            vec![(*robot, *tool)]
        }
        _ => Vec::new(),
    }
}

/// The joint vectors of an observation with their robots.
pub(crate) fn joints_of(kind: &ObservationKind) -> Vec<(Robot, &[f64])> {
    match kind {
        ObservationKind::Coincident { q1, q2, .. } | ObservationKind::Contact { q1, q2, .. } => {
            vec![(Robot::One, q1.as_slice()), (Robot::Two, q2.as_slice())]
        }
        ObservationKind::Tracker { robot, q, .. } | ObservationKind::Plane { robot, q, .. } => {
            vec![(*robot, q.as_slice())]
        }
        _ => Vec::new(),
    }
}

/// The nuisance group of an observation: `(kind index, group)` (0 contact, 1 tracker, 2 plane);
/// `None` for coincident rows.
fn group_of(kind: &ObservationKind) -> Option<(usize, usize)> {
    match kind {
        ObservationKind::Contact { group, .. } => Some((0, *group)),
        ObservationKind::Tracker { group, .. } => Some((1, *group)),
        ObservationKind::Plane { group, .. } => Some((2, *group)),
        _ => None,
    }
}

/// The diagnosis problem: the cell's whole-cell problem with widened tolerances and compliance
/// where the URDF has inertials (see the module documentation).
pub fn diagnosis_problem(
    cell: &Cell,
    session: &Session,
    options: &CellDiagnoseOptions,
) -> Result<CellProblem, DiagnoseError> {
    let mut problem = cell_problem(cell, session, FitModel::Kinematic);
    let w = options.prior_widening;
    if !(w.is_finite() && w > 0.0) {
        return Err(DiagnoseError::Session {
            path: "<options>".into(),
            message: format!("prior widening {w} must be finite and > 0 (default 10)"),
        });
    }
    for r in [Robot::One, Robot::Two] {
        let max_tau = max_gravity_torque(&problem, r)?;
        let rb = if r == Robot::One {
            &mut problem.robot1
        } else {
            &mut problem.robot2
        };
        let t = rb.tolerance;
        let offset = t.joint_offset_rad * w;
        rb.tolerance = Tolerance {
            joint_offset_rad: offset,
            origin_xyz_m: t.origin_xyz_m * w,
            origin_rpy_rad: t.origin_rpy_rad * w,
            tip_m: t.tip_m * w,
            joint_scale: t.joint_scale.map(|s| s * w),
            compliance_rad_per_nm: match t.compliance_rad_per_nm {
                Some(c) => Some(c * w),
                None if max_tau > 0.0 && offset > 0.0 => Some(offset / max_tau),
                None => None,
            },
            periodic_rad: match t.periodic_rad {
                Some(p) => Some(p * w),
                None if offset > 0.0 => Some(offset),
                None => None,
            },
        };
    }
    Ok(problem)
}

/// Largest |gravity torque| (N·m) of robot `r` over the problem's postures; 0 without inertials.
fn max_gravity_torque(problem: &CellProblem, r: Robot) -> Result<f64, DiagnoseError> {
    let rb = problem.robot(r);
    if rb.model.inertials().is_empty() {
        return Ok(0.0);
    }
    let mut max = 0.0f64;
    for o in &problem.observations {
        for (rr, q) in joints_of(&o.kind) {
            if rr == r {
                let tau = gravity_torques(&rb.model, q, &rb.g_base).map_err(|source| {
                    DiagnoseError::Model {
                        robot: r.number(),
                        point: o.row,
                        source,
                    }
                })?;
                max = tau.iter().fold(max, |m, t| m.max(t.abs()));
            }
        }
    }
    Ok(max)
}

/// The problem of a model: with [`FamilyKind::ContactDistance`] selected, every contact
/// group's distance is fitted; with [`FamilyKind::TrackerScale`] (or
/// [`FamilyKind::TrackerDrift`]) every tracker group's scale (drift).
fn model_problem(problem: &CellProblem, model: &[Family]) -> CellProblem {
    let mut p = problem.clone();
    let has = |k: FamilyKind| model.iter().any(|f| f.kind == k);
    if has(FamilyKind::ContactDistance) {
        for c in &mut p.contacts {
            c.fit_distance = true;
        }
    }
    let (scale, drift) = (has(FamilyKind::TrackerScale), has(FamilyKind::TrackerDrift));
    for t in &mut p.trackers {
        t.fit_scale |= scale;
        t.fit_drift |= drift;
    }
    p
}

/// The unknowns of a model: placement, nuisances and the families' parameters (the other
/// kinematic parameters held at zero).
fn model_layout(problem: &CellProblem, model: &[Family]) -> ParamLayout {
    let all = ParamLayout::new(problem, &[]);
    let fixed: Vec<CellParam> = all
        .params
        .iter()
        .filter(|p| {
            p.is_kinematic() && (offset_alias(problem, p) || !model.iter().any(|f| f.contains(p)))
        })
        .cloned()
        .collect();
    ParamLayout::new(problem, &fixed)
}

/// Whether `p` is an origin angle whose small rotation is about its joint's own axis: it then
/// commutes with the joint rotation and equals a joint offset, so [`FamilyKind::OriginRpy`]
/// leaves it out (the offset family holds it). With `R(rpy)` the nominal origin rotation, the
/// perturbation `δ` of component `k` turns the child frame by `ω = log(R(rpy)ᵀ·R(rpy + δ·e_k))/δ`
/// (child axes); aliased when `ω` is parallel to the joint axis within [`ALIAS_TOL`].
pub fn offset_alias(problem: &CellProblem, p: &CellParam) -> bool {
    let CellParam::Kinematic {
        robot,
        param: ErrorParam::OriginRpy { joint, axis },
    } = p
    else {
        return false;
    };
    let Some(j) = problem.robot(*robot).model.joints().get(*joint) else {
        return false;
    };
    // A step small enough for the linearisation, large enough for round-off (1e-6 rad).
    let h = 1e-6;
    let mut rpy = j.origin_rpy;
    let r0 = kinematics::rotation_from_rpy(&rpy);
    rpy[axis.index()] += h;
    let r1 = kinematics::rotation_from_rpy(&rpy);
    let omega = (r0.transpose() * r1).scaled_axis() / h;
    omega.cross(j.axis.as_ref()).norm() <= ALIAS_TOL * omega.norm()
}

/// Relative tolerance of [`offset_alias`] (sine of the angle between `ω` and the axis).
pub const ALIAS_TOL: f64 = 1e-4;

/// The sub-problem of the observations `rows` (indices into `problem.observations`), its groups
/// renumbered to the ones these rows use.
fn sub_problem(problem: &CellProblem, rows: &[usize]) -> CellProblem {
    let mut maps: [Vec<Option<usize>>; 3] = [
        vec![None; problem.contacts.len()],
        vec![None; problem.trackers.len()],
        vec![None; problem.planes.len()],
    ];
    let mut p = CellProblem {
        observations: Vec::with_capacity(rows.len()),
        trackers: Vec::new(),
        planes: Vec::new(),
        contacts: Vec::new(),
        ..problem.clone()
    };
    for &i in rows {
        let mut o = problem.observations[i].clone();
        if let Some((k, g)) = group_of(&o.kind) {
            let new = match maps[k][g] {
                Some(n) => n,
                None => {
                    let n = match k {
                        0 => {
                            p.contacts.push(problem.contacts[g].clone());
                            p.contacts.len() - 1
                        }
                        1 => {
                            p.trackers.push(problem.trackers[g].clone());
                            p.trackers.len() - 1
                        }
                        _ => {
                            p.planes.push(problem.planes[g].clone());
                            p.planes.len() - 1
                        }
                    };
                    maps[k][g] = Some(n);
                    n
                }
            };
            match &mut o.kind {
                ObservationKind::Contact { group, .. }
                | ObservationKind::Tracker { group, .. }
                | ObservationKind::Plane { group, .. } => *group = new,
                _ => {}
            }
        }
        p.observations.push(o);
    }
    p
}

fn coincident_count(problem: &CellProblem, rows: &[usize]) -> usize {
    rows.iter()
        .filter(|&&i| {
            matches!(
                problem.observations[i].kind,
                ObservationKind::Coincident { .. }
            )
        })
        .count()
}

/// Fits `model` on the observations `rows` of `problem` (a sub-problem of them), starting from
/// the robot corrections and placement of `start` when given. Returns the sub-problem and fit.
fn fit_model(
    problem: &CellProblem,
    model: &[Family],
    rows: &[usize],
    start: Option<&CellEstimate>,
    options: &CellDiagnoseOptions,
    cell_b1_from_b2: nalgebra::Isometry3<f64>,
) -> Result<(CellProblem, CellFit), CellFitError> {
    let sub = sub_problem(&model_problem(problem, model), rows);
    let layout = model_layout(&sub, model);
    let all: Vec<usize> = (0..sub.observations.len()).collect();
    let placement = match start {
        Some(s) => Some(s.b1_from_b2),
        None if coincident_count(&sub, &all) < 3 => Some(cell_b1_from_b2),
        None => options.solve.initial_b1_from_b2,
    };
    let mut est = initial_estimate(&sub, placement, &all)?;
    if let Some(s) = start {
        est.robot1 = s.robot1.clone();
        est.robot2 = s.robot2.clone();
    }
    let fit = fit_cell_with(&sub, layout, &all, None, Some(&est), &options.solve)?;
    Ok((sub, fit))
}

/// One scored residual block: the observation's kind, its raw residual (m) and its whitened
/// residual.
#[derive(Debug, Clone)]
pub(crate) struct ScoredRow {
    pub(crate) kind: &'static str,
    pub(crate) raw_m: DVector<f64>,
    pub(crate) whitened: DVector<f64>,
    /// Stated σ of each residual, m (`sqrt diag (WᵀW)⁻¹`).
    pub(crate) sigma_m: DVector<f64>,
    /// Index of the observation in its problem.
    pub(crate) index: usize,
}

/// Residuals of `rows` of `problem` at `est` under `layout`.
pub(crate) fn residuals_at(
    problem: &CellProblem,
    layout: &ParamLayout,
    est: &CellEstimate,
    rows: &[usize],
) -> Result<Vec<ScoredRow>, CellFitError> {
    let ev = Evaluator::new(problem, layout);
    rows.iter()
        .map(|&i| {
            let o = &problem.observations[i];
            let l = ev.linearise(o, est, false)?;
            let w = &l.whitening;
            let sigma_m = match (w.transpose() * w).try_inverse() {
                Some(cov) => cov.diagonal().map(|v| v.max(0.0).sqrt()),
                None => DVector::from_element(w.nrows(), f64::NAN),
            };
            Ok(ScoredRow {
                kind: o.kind.name(),
                whitened: w * &l.residual,
                raw_m: l.residual,
                sigma_m,
                index: i,
            })
        })
        .collect()
}

/// Held-out residuals of one unit (rows of `problem`, all of one nuisance group or none) given a
/// training estimate: the unit's nuisance fitted on one half with the training kinematics and
/// placement held, the other half scored, and back.
fn score_unit(
    problem: &CellProblem,
    unit: &[usize],
    train: &CellEstimate,
    options: &CellDiagnoseOptions,
) -> Result<Vec<ScoredRow>, CellFitError> {
    let mut sub = sub_problem(problem, unit);
    for rb in [&mut sub.robot1, &mut sub.robot2] {
        rb.tolerance = Tolerance::none();
    }
    sub.placement_prior = Some(PlacementPrior {
        nominal_b1_from_b2: train.b1_from_b2,
        sigma_m: HOLD_SIGMA,
        sigma_rad: HOLD_SIGMA,
    });
    let layout = ParamLayout::new(&sub, &[]);
    let n = sub.observations.len();
    let with_train = |mut e: CellEstimate| {
        e.b1_from_b2 = train.b1_from_b2;
        e.robot1 = train.robot1.clone();
        e.robot2 = train.robot2.clone();
        e
    };
    let has_nuisance = layout.len() > 6;
    if !has_nuisance {
        let mut e = CellEstimate::nominal(&sub, train.b1_from_b2);
        for (g, c) in sub.contacts.iter().enumerate() {
            e.contact_distance_m[g] = c.distance_m;
        }
        let all: Vec<usize> = (0..n).collect();
        return residuals_at(&sub, &layout, &with_train(e), &all);
    }
    let halves: [Vec<usize>; 2] = [
        (0..n).filter(|i| i % 2 == 0).collect(),
        (0..n).filter(|i| i % 2 == 1).collect(),
    ];
    let mut out = Vec::with_capacity(n);
    for h in 0..2 {
        let (fit_rows, test_rows) = (&halves[h], &halves[1 - h]);
        let start = with_train(initial_estimate(&sub, Some(train.b1_from_b2), fit_rows)?);
        let fit = fit_cell_with(
            &sub,
            layout.clone(),
            fit_rows,
            None,
            Some(&start),
            &options.solve,
        )?;
        out.extend(residuals_at(&sub, &layout, &fit.estimate, test_rows)?);
    }
    Ok(out)
}

/// The held-out units of the rows `rows`: one per named group of at least
/// [`MIN_SCORED_GROUP_ROWS`] rows (in order of first appearance; smaller groups are never held
/// out), the coincident rows cut into up to [`COINCIDENT_UNITS`] units in row order.
pub(crate) fn held_out_units(problem: &CellProblem, rows: &[usize]) -> Vec<Vec<usize>> {
    let mut keys: Vec<(usize, usize)> = Vec::new();
    let mut units: Vec<Vec<usize>> = Vec::new();
    let mut coincident = Vec::new();
    for &i in rows {
        match group_of(&problem.observations[i].kind) {
            Some(key) => match keys.iter().position(|k| *k == key) {
                Some(u) => units[u].push(i),
                None => {
                    keys.push(key);
                    units.push(vec![i]);
                }
            },
            None => coincident.push(i),
        }
    }
    // A group too small to fit its nuisance on half its rows is never held out (it trains
    // every fold and is not scored).
    let mut units: Vec<Vec<usize>> = units
        .into_iter()
        .zip(&keys)
        .filter(|(u, (kind, _))| u.len() >= MIN_SCORED_GROUP_ROWS[*kind])
        .map(|(u, _)| u)
        .collect();
    if !coincident.is_empty() {
        let parts = (coincident.len() / MIN_UNIT_ROWS).clamp(1, COINCIDENT_UNITS);
        let size = coincident.len().div_ceil(parts);
        units.extend(coincident.chunks(size).map(<[usize]>::to_vec));
    }
    if units.len() < 3 {
        // Too few units to hold any out: cut each into contiguous blocks (recording order) of
        // at least 2·MIN_GROUP_BLOCK_ROWS rows; each block's nuisance is refitted when it is
        // scored, so no held-out row is predicted by a nuisance fitted on it.
        units = units
            .into_iter()
            .flat_map(|u| {
                let parts = (u.len() / MIN_GROUP_BLOCK_ROWS).clamp(1, COINCIDENT_UNITS);
                let size = u.len().div_ceil(parts);
                u.chunks(size).map(<[usize]>::to_vec).collect::<Vec<_>>()
            })
            .collect();
    }
    units
}

/// The held-out result of one model.
#[derive(Debug, Clone)]
pub(crate) struct HeldOut {
    /// Held-out χ² of each unit (whitened residual sum of squares).
    pub(crate) unit_chi2: Vec<f64>,
    /// Scored residual blocks.
    pub(crate) rows: Vec<ScoredRow>,
}

impl HeldOut {
    pub(crate) fn total(&self) -> f64 {
        self.unit_chi2.iter().sum()
    }
}

/// The held-out design: the rows used and their units, grouped into folds.
#[derive(Debug, Clone)]
pub(crate) struct Folds {
    /// Rows (observation indices) used, after the blunder screen.
    pub(crate) used: Vec<usize>,
    /// Each fold's units (each a list of rows).
    pub(crate) folds: Vec<Vec<Vec<usize>>>,
    /// Number of units over all folds.
    pub(crate) n_units: usize,
}

/// Each unit's held-out χ² and scored rows, of one fold, in the fold's unit order.
type FoldHeldOut = Vec<(f64, Vec<ScoredRow>)>;

/// One fold of the held-out criterion: `model` fitted on the used rows outside fold `fold` of
/// `design` (starting from `start`), then each of the fold's units scored on `scoring_problem`
/// (`problem` under `model`). Returns each unit's held-out χ² and scored rows, in the fold's
/// unit order.
#[allow(clippy::too_many_arguments)]
fn fold_held_out(
    problem: &CellProblem,
    scoring_problem: &CellProblem,
    model: &[Family],
    design: &Folds,
    fold: usize,
    start: &CellEstimate,
    options: &CellDiagnoseOptions,
    cell_b1_from_b2: nalgebra::Isometry3<f64>,
) -> Result<FoldHeldOut, CellFitError> {
    let units = &design.folds[fold];
    let held: Vec<usize> = units.iter().flatten().copied().collect();
    let train: Vec<usize> = design
        .used
        .iter()
        .copied()
        .filter(|i| !held.contains(i))
        .collect();
    let (_, fit) = fit_model(
        problem,
        model,
        &train,
        Some(start),
        options,
        cell_b1_from_b2,
    )?;
    units
        .iter()
        .map(|unit| {
            let scored = score_unit(scoring_problem, unit, &fit.estimate, options)?;
            let chi2 = scored.iter().map(|s| s.whitened.norm_squared()).sum();
            Ok((chi2, scored))
        })
        .collect()
}

/// Cross-validates each of `models` over `design`'s folds, every training fit starting from
/// `start`. The (model, fold) fits run in parallel (rayon's current pool) and are assembled in
/// model order, then fold order, then unit order; each fit depends only on its own inputs, so
/// the results, and the error returned (the first in that order), are those of running the fits
/// one after another, whatever the thread count. `on_fit(m)` is called (from any thread) after
/// each finished fit of model `m`.
#[allow(clippy::too_many_arguments)]
fn cross_validate_all(
    problem: &CellProblem,
    models: &[Vec<Family>],
    design: &Folds,
    start: &CellEstimate,
    options: &CellDiagnoseOptions,
    cell_b1_from_b2: nalgebra::Isometry3<f64>,
    on_fit: &(dyn Fn(usize) + Sync),
) -> Result<Vec<HeldOut>, CellFitError> {
    let scoring: Vec<CellProblem> = models.iter().map(|m| model_problem(problem, m)).collect();
    let n_folds = design.folds.len();
    let jobs: Vec<(usize, usize)> = (0..models.len())
        .flat_map(|m| (0..n_folds).map(move |f| (m, f)))
        .collect();
    let results: Vec<Result<FoldHeldOut, CellFitError>> = jobs
        .par_iter()
        .map(|&(m, f)| {
            let r = fold_held_out(
                problem,
                &scoring[m],
                &models[m],
                design,
                f,
                start,
                options,
                cell_b1_from_b2,
            );
            on_fit(m);
            r
        })
        .collect();
    let mut results = results.into_iter();
    let mut out = Vec::with_capacity(models.len());
    for _ in models {
        let mut unit_chi2 = Vec::with_capacity(design.n_units);
        let mut rows = Vec::new();
        for fold in results.by_ref().take(n_folds) {
            for (chi2, scored) in fold? {
                unit_chi2.push(chi2);
                rows.extend(scored);
            }
        }
        out.push(HeldOut { unit_chi2, rows });
    }
    Ok(out)
}

/// Whether `after` gains enough over `before` (see the module documentation); returns the t
/// statistic of the relative gains of the units the family is `involved` in (∞ or 0 with fewer
/// than 3 such units).
fn significant(
    before: &HeldOut,
    after: &HeldOut,
    involved: &[bool],
    options: &CellDiagnoseOptions,
) -> (bool, f64) {
    let rel: Vec<f64> = before
        .unit_chi2
        .iter()
        .zip(&after.unit_chi2)
        .zip(involved)
        .filter(|(_, inv)| **inv)
        .map(|((b, a), _)| if *b > 0.0 { (b - a) / b } else { 0.0 })
        .collect();
    let total_before = before.total();
    let relative = if total_before > 0.0 {
        (total_before - after.total()) / total_before
    } else {
        0.0
    };
    let n = rel.len() as f64;
    let t = if rel.len() < 3 {
        if rel.iter().all(|r| *r >= options.min_relative_gain) {
            f64::INFINITY
        } else {
            0.0
        }
    } else {
        let mean = rel.iter().sum::<f64>() / n;
        let var = rel.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        if var > 0.0 {
            mean / (var / n).sqrt()
        } else if mean > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    };
    (
        relative >= options.min_relative_gain && t >= options.min_gain_t,
        t,
    )
}

/// One selection step's record, in SI.
#[derive(Debug, Clone)]
pub(crate) struct StepRecord {
    pub(crate) family: Family,
    pub(crate) before: HeldOut,
    pub(crate) after: HeldOut,
    pub(crate) t: f64,
    pub(crate) accepted: bool,
    /// Full fits (all screened rows) before and after the step.
    pub(crate) fit_before: (CellProblem, CellFit),
    pub(crate) fit_after: Option<(CellProblem, CellFit)>,
    /// Held-out χ² of every candidate tried at this step.
    pub(crate) tried: Vec<(String, f64)>,
}

/// Everything [`crate::cell_report`] needs, in SI.
#[derive(Debug, Clone)]
pub(crate) struct CellDiagnosis {
    pub(crate) problem: CellProblem,
    pub(crate) candidates: Vec<Family>,
    pub(crate) rejected: Vec<calib_core::whole_cell::RejectedRow>,
    pub(crate) used: Vec<usize>,
    pub(crate) n_units: usize,
    pub(crate) n_folds: usize,
    /// Noise scale per kind, in [`KINDS`] order.
    pub(crate) noise_scale: [f64; 4],
    pub(crate) baseline: (CellProblem, CellFit),
    pub(crate) baseline_held_out: HeldOut,
    pub(crate) steps: Vec<StepRecord>,
    pub(crate) final_fit: (CellProblem, CellFit),
}

/// Observation kinds in report order.
pub const KINDS: [&str; 4] = ["contact", "tracker", "plane", "coincident"];

/// Per kind ([`KINDS`] order), `max(1, 1.4826·median|w|)` of the whitened residuals of the fit
/// with every family free on `rows`.
fn noise_scales(
    problem: &CellProblem,
    families: &[Family],
    rows: &[usize],
    options: &CellDiagnoseOptions,
    x0: nalgebra::Isometry3<f64>,
) -> Result<[f64; 4], CellFitError> {
    let (sub, fit) = fit_model(problem, families, rows, None, options, x0)?;
    let scored = residuals_at(&sub, &fit.layout, &fit.estimate, &fit.active)?;
    let mut out = [1.0; 4];
    for (k, kind) in KINDS.iter().enumerate() {
        let mut w: Vec<f64> = scored
            .iter()
            .filter(|r| r.kind == *kind)
            .flat_map(|r| r.whitened.iter().map(|v| v.abs()).collect::<Vec<_>>())
            .collect();
        if w.is_empty() {
            continue;
        }
        w.sort_by(f64::total_cmp);
        let median = if w.len() % 2 == 1 {
            w[w.len() / 2]
        } else {
            0.5 * (w[w.len() / 2 - 1] + w[w.len() / 2])
        };
        out[k] = (1.4826 * median).max(1.0);
    }
    Ok(out)
}

/// `problem` with every row's σ multiplied by its kind's scale ([`KINDS`] order).
fn scaled_noise(problem: &CellProblem, scale: &[f64; 4]) -> CellProblem {
    let mut p = problem.clone();
    for o in &mut p.observations {
        let k = KINDS.iter().position(|k| *k == o.kind.name()).unwrap_or(0);
        let s = scale[k];
        match &mut o.kind {
            ObservationKind::Contact { sigma_m, .. } | ObservationKind::Plane { sigma_m, .. } => {
                *sigma_m *= s;
            }
            ObservationKind::Coincident { noise, .. } | ObservationKind::Tracker { noise, .. } => {
                *noise = match *noise {
                    Noise3::Isotropic { sigma_m } => Noise3::Isotropic {
                        sigma_m: sigma_m * s,
                    },
                    Noise3::Covariance { cov_m2 } => Noise3::Covariance {
                        cov_m2: cov_m2 * (s * s),
                    },
                    other => other,
                };
            }
            _ => {}
        }
    }
    p
}

/// Diagnoses a session with non-coincident rows on its cell (see the module documentation).
/// `progress` receives one line per phase and per candidate held out (for a progress display;
/// called from any of rayon's threads, as the candidates' fits run in parallel). The report is
/// the same whatever the thread count (`RAYON_NUM_THREADS`, or the pool it runs in).
///
/// Errors: invalid problem (naming the row and field), a model failure, or too few rows after
/// the blunder screen (naming the rows to re-record).
pub fn diagnose_cell_session(
    cell: &Cell,
    session: &Session,
    options: &CellDiagnoseOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<CellDiagnoseReport, DiagnoseError> {
    let problem = diagnosis_problem(cell, session, options)?;
    problem.check().map_err(cell_error)?;
    let d = run(cell, problem, options, progress).map_err(cell_error)?;
    Ok(cell_report::build(&d, options))
}

fn cell_error(e: CellFitError) -> DiagnoseError {
    DiagnoseError::Session {
        path: "<session>".into(),
        message: e.to_string(),
    }
}

/// The model "every family free" of the noise level and the blunder screen: every candidate,
/// less the tracker drifts and then the tracker scales (unpenalised, 3 and 1 unknowns per
/// tracker group) while the unpenalised unknowns plus the screen's
/// [`ScreenOptions::min_redundancy`] exceed the session's residual rows (a small session).
fn every_family_free(problem: &CellProblem, candidates: &[Family]) -> Vec<Family> {
    let rows: usize = problem.observations.iter().map(|o| o.kind.rows()).sum();
    let needed = ScreenOptions::default().min_redundancy;
    let mut free = candidates.to_vec();
    for kind in [FamilyKind::TrackerDrift, FamilyKind::TrackerScale] {
        let layout = model_layout(&model_problem(problem, &free), &free);
        let unpenalised = (0..layout.len())
            .filter(|&j| layout.prior_sigma(j) == 0.0)
            .count();
        if unpenalised + needed <= rows {
            break;
        }
        free.retain(|f| f.kind != kind);
    }
    free
}

fn run(
    cell: &Cell,
    problem: CellProblem,
    options: &CellDiagnoseOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<CellDiagnosis, CellFitError> {
    let x0 = cell.b1_from_b2;
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let candidates = candidate_families(&problem);
    let mut solve = options.solve.clone();
    if coincident_count(&problem, &all) < 3 {
        solve.initial_b1_from_b2 = Some(x0);
    }
    let options = &CellDiagnoseOptions {
        solve,
        ..options.clone()
    };
    let free = every_family_free(&problem, &candidates);
    progress("noise level per kind (every family free)");
    let noise_scale = noise_scales(&problem, &free, &all, options, x0)?;
    let problem = scaled_noise(&problem, &noise_scale);
    let (used, rejected) = if options.screen_blunders {
        progress("screening blunders (every family free)");
        let p = model_problem(&problem, &free);
        let layout = model_layout(&p, &free);
        let screened = fit_screened(&p, Some(layout), &options.solve, &ScreenOptions::default())?;
        (screened.fit.active.clone(), screened.rejected)
    } else {
        (all.clone(), Vec::new())
    };
    let units = held_out_units(&problem, &used);
    let n_units = units.len();
    let n_folds = n_units.min(options.max_folds.max(2));
    let mut folds: Vec<Vec<Vec<usize>>> = vec![Vec::new(); n_folds];
    for (u, unit) in units.into_iter().enumerate() {
        folds[u % n_folds].push(unit);
    }
    // Units in fold order (the order `cross_validate_all` scores them).
    progress("baseline: nominal kinematics, nuisances fitted");
    let baseline = fit_model(&problem, &[], &used, None, options, x0)?;
    let design = Folds {
        used: used.clone(),
        folds,
        n_units,
    };
    let baseline_held_out = cross_validate_all(
        &problem,
        &[Vec::new()],
        &design,
        &baseline.1.estimate,
        options,
        x0,
        &|_| {},
    )?
    .remove(0);
    let mut model: Vec<Family> = Vec::new();
    let mut current = baseline.clone();
    let mut current_held = baseline_held_out.clone();
    let mut steps = Vec::new();
    for step in 0..options.max_steps {
        let remaining: Vec<&Family> = candidates.iter().filter(|c| !model.contains(c)).collect();
        if remaining.is_empty() {
            break;
        }
        // Every candidate's held-out result; the step keeps the lowest held-out χ² among the
        // significant ones (a candidate that gains more in total but not consistently over the
        // units does not hide a consistent one), else records the lowest as the stop.
        // The candidates' (candidate, fold) fits run in parallel; the results come back in
        // candidate order, as if run one after another.
        let models: Vec<Vec<Family>> = remaining
            .iter()
            .map(|cand| {
                let mut m = model.clone();
                m.push((*cand).clone());
                m
            })
            .collect();
        progress(&format!(
            "step {}: {} candidates × {} folds",
            step + 1,
            remaining.len(),
            n_folds
        ));
        let fits_done: Vec<AtomicUsize> = remaining.iter().map(|_| AtomicUsize::new(0)).collect();
        let candidates_done = AtomicUsize::new(0);
        let on_fit = |m: usize| {
            if fits_done[m].fetch_add(1, Ordering::Relaxed) + 1 == n_folds {
                let k = candidates_done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(&format!(
                    "step {}: candidate {}/{} held out: {}",
                    step + 1,
                    k,
                    remaining.len(),
                    remaining[m].name
                ));
            }
        };
        let held_out = cross_validate_all(
            &problem,
            &models,
            &design,
            &current.1.estimate,
            options,
            x0,
            &on_fit,
        )?;
        let mut results: Vec<(Family, HeldOut, bool, f64)> = Vec::new();
        let mut tried = Vec::new();
        for (cand, held) in remaining.iter().zip(held_out) {
            tried.push((cand.name.clone(), held.total()));
            let involved: Vec<bool> = design
                .folds
                .iter()
                .flatten()
                .map(|unit| {
                    unit.iter()
                        .any(|&i| cand.involves(&problem.observations[i].kind))
                })
                .collect();
            let (ok, t) = significant(&current_held, &held, &involved, options);
            results.push(((*cand).clone(), held, ok, t));
        }
        let lowest = |only_significant: bool| {
            results
                .iter()
                .filter(|r| r.2 || !only_significant)
                .min_by(|a, b| a.1.total().total_cmp(&b.1.total()))
                .cloned()
        };
        let Some((family, held, accepted, t)) = lowest(true).or_else(|| lowest(false)) else {
            break;
        };
        let mut record = StepRecord {
            family: family.clone(),
            before: current_held.clone(),
            after: held.clone(),
            t,
            accepted,
            fit_before: current.clone(),
            fit_after: None,
            tried,
        };
        if !accepted {
            steps.push(record);
            break;
        }
        model.push(family);
        let next = fit_model(
            &problem,
            &model,
            &used,
            Some(&current.1.estimate),
            options,
            x0,
        )?;
        record.fit_after = Some(next.clone());
        steps.push(record);
        current = next;
        current_held = held;
    }
    Ok(CellDiagnosis {
        problem,
        candidates,
        rejected,
        used,
        n_units,
        n_folds,
        noise_scale,
        baseline,
        baseline_held_out,
        steps,
        final_fit: current,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

    fn mixed_session(cell: &Cell, n: usize, seed: u64) -> Session {
        let spec = SessionSpec::new(n, Layout::Random, 0.7);
        let kinds = KindSpec {
            kind: SimKind::Mixed,
            ..KindSpec::default()
        };
        generate_kind_session(cell, &spec, &kinds, None, &mut trial_rng(seed, 0))
            .expect("session")
            .0
    }

    #[test]
    fn sub_problem_renumbers_groups_and_units_cover_every_row_once() {
        let cell = Cell::default_floor_wall();
        let session = mixed_session(&cell, 36, 3);
        let p = diagnosis_problem(&cell, &session, &CellDiagnoseOptions::default()).unwrap();
        p.check().unwrap();
        let all: Vec<usize> = (0..p.observations.len()).collect();
        let units = held_out_units(&p, &all);
        let mut seen: Vec<usize> = units.iter().flatten().copied().collect();
        seen.sort_unstable();
        assert_eq!(seen, all);
        for unit in &units {
            let groups: Vec<_> = unit
                .iter()
                .map(|&i| group_of(&p.observations[i].kind))
                .collect();
            assert!(
                groups.windows(2).all(|w| w[0] == w[1]),
                "one group per unit"
            );
            let sub = sub_problem(&p, unit);
            sub.check().unwrap();
            assert_eq!(
                sub.contacts.len() + sub.trackers.len() + sub.planes.len(),
                usize::from(groups[0].is_some())
            );
        }
    }

    #[test]
    fn small_groups_are_never_held_out_and_a_small_session_is_diagnosed() {
        let cell = Cell::default_floor_wall();
        // 12 rows: 2 coincident, 2 contact, 4 tracker, 4 plane (too few to hold out a tracker
        // or plane group).
        let session = mixed_session(&cell, 12, 2);
        let options = CellDiagnoseOptions::default();
        let p = diagnosis_problem(&cell, &session, &options).unwrap();
        let all: Vec<usize> = (0..p.observations.len()).collect();
        let units = held_out_units(&p, &all);
        assert!(units
            .iter()
            .flatten()
            .all(|&i| !matches!(group_of(&p.observations[i].kind), Some((1 | 2, _)))));
        let r = diagnose_cell_session(&cell, &session, &options, &|_| {}).unwrap();
        assert_eq!(r.rows_used + r.rejected_points.len(), 12);
    }

    /// Regression guard for the parallel (candidate, fold) fits: a mixed session with a hidden
    /// joint offset (so a family is named and the next step runs too) gives the byte-identical
    /// JSON report in a 1-thread and a 2-thread pool, and the same progress lines.
    #[test]
    fn the_report_is_identical_whatever_the_thread_count() {
        let mut truth = Cell::default_floor_wall();
        truth
            .robot1
            .errors
            .set(ErrorParam::JointOffset { joint: 1 }, 2e-3);
        let session = mixed_session(&truth, 36, 5);
        let nominal = Cell::default_floor_wall();
        let run_with = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let lines = std::sync::Mutex::new(Vec::new());
            let report = pool.install(|| {
                diagnose_cell_session(
                    &nominal,
                    &session,
                    &CellDiagnoseOptions::default(),
                    &|line| lines.lock().expect("progress lines").push(line.to_owned()),
                )
                .expect("diagnosis")
            });
            // Candidates finish in thread order, so the count in "step s: candidate k/n held
            // out: NAME" is dropped; the set of (step, name) lines is what must agree.
            let mut lines: Vec<String> = lines
                .into_inner()
                .expect("progress lines")
                .into_iter()
                .map(|l| match l.split_once(" held out: ") {
                    Some((head, name)) => {
                        format!(
                            "{} {name}",
                            head.split(" candidate ").next().unwrap_or(head)
                        )
                    }
                    None => l,
                })
                .collect();
            lines.sort();
            (serde_json::to_string(&report).expect("json"), report, lines)
        };
        let (json1, report1, lines1) = run_with(1);
        let (json2, _, lines2) = run_with(2);
        assert!(
            !report1.effects.is_empty() && report1.stopped_at.is_some(),
            "the session must name a family and then stop: {}",
            crate::render_cell_text(&report1)
        );
        assert_eq!(json1, json2);
        assert_eq!(lines1, lines2);
    }

    #[test]
    fn families_partition_the_kinematic_unknowns() {
        let cell = Cell::default_floor_wall();
        let session = mixed_session(&cell, 24, 4);
        let p = diagnosis_problem(&cell, &session, &CellDiagnoseOptions::default()).unwrap();
        let fams = candidate_families(&p);
        let layout = ParamLayout::new(&p, &[]);
        let mut aliases = 0;
        for param in layout.params.iter().filter(|c| c.is_kinematic()) {
            let n = fams.iter().filter(|f| f.contains(param)).count();
            // Scale parameters are off by default; every other fitted parameter is in exactly
            // one family.
            assert_eq!(n, 1, "{param:?} in {n} families");
            aliases += usize::from(offset_alias(&p, param));
        }
        // Every revolute joint has exactly one origin angle about its own axis when the
        // nominal angles are multiples of 90° (the shipped URDFs).
        assert_eq!(aliases, p.robot1.model.dof() + p.robot2.model.dof());
        let all = fams.clone();
        let full = model_layout(&p, &all);
        assert_eq!(
            full.params.iter().filter(|c| c.is_kinematic()).count(),
            layout.params.iter().filter(|c| c.is_kinematic()).count() - aliases
        );
        assert!(model_layout(&p, &[])
            .params
            .iter()
            .all(|c| !c.is_kinematic()));
    }
}
