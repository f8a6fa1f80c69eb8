//! The cell, its observations, the unknowns and their layout, and the residuals with their
//! analytic Jacobians (see the module documentation of [`crate::whole_cell`] for the maths).

use kinematics::{
    tip_error_jacobian, true_base_from_tip, Axis, ErrorParam, KinematicErrors, RobotModel,
};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Point3, Unit, Vector3};
use serde::Serialize;

use crate::registration::rigid_fit_fast;

/// Errors of the whole-cell calibration. Non-convergence is not an error (see
/// [`super::StopReason`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CellFitError {
    /// Invalid input: the message names the observation row or field and the fix.
    #[error("{0}")]
    InvalidInput(String),
    /// The kinematic model rejected an observation's joint angles or parameters.
    #[error("observation row {row}: {message}")]
    Kinematics {
        /// 1-based source row of the observation.
        row: usize,
        /// What the kinematics reported.
        message: String,
    },
    /// A residual or Jacobian is not finite at an observation (NaN input or a diverged iterate).
    #[error(
        "observation row {row}: non-finite residual or Jacobian; check the joint angles and group \
         values for NaN or huge numbers"
    )]
    NonFinite {
        /// 1-based source row.
        row: usize,
    },
    /// After rejecting blunders too few observation rows remain to fit the unknowns.
    #[error(
        "only {remaining} residual rows remain after rejecting blunders at rows {rejected_rows:?}, \
         but the fit needs at least {needed}; re-record rows {rejected_rows:?}"
    )]
    TooFewRows {
        /// Residual rows (scalars) left.
        remaining: usize,
        /// Residual rows needed.
        needed: usize,
        /// 1-based source rows rejected as blunders: the rows to re-record.
        rejected_rows: Vec<usize>,
    },
}

/// Which robot: 1 (its base frame `b1` is the frame of the result) or 2.
pub type RobotIndex = u8;

fn robot_slot(robot: RobotIndex) -> Option<usize> {
    match robot {
        1 => Some(0),
        2 => Some(1),
        _ => None,
    }
}

/// Manufacturing tolerances of one robot, the source of the prior. **Convention**: a tolerance
/// is the half-width of a uniform band, so the prior of each parameter is `N(0, (tol/√3)²)` and a
/// truth drawn from `U(±tol)` has exactly the prior's variance. A tolerance of `0` (or `None`)
/// means "not fitted": the parameter is held at zero.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tolerance {
    /// Joint zero offset, rad. Default 0.05° (8.73e-4 rad).
    pub joint_offset_rad: f64,
    /// Joint origin position, each axis, m (URDF `<origin xyz>`, parent link frame). Default 0.5 mm.
    pub origin_xyz_m: f64,
    /// Joint origin orientation, each of roll/pitch/yaw, rad. Default 0.05°.
    pub origin_rpy_rad: f64,
    /// Tool tip offset, each axis, m (flange axes), per tool. Default 0.5 mm.
    pub tip_m: f64,
    /// Joint scale (gear ratio) error, ratio. Default `None` (not fitted).
    pub joint_scale: Option<f64>,
    /// Joint compliance under gravity, rad/(N·m). Default `None` (not fitted).
    pub compliance_rad_per_nm: Option<f64>,
}

impl Default for Tolerance {
    fn default() -> Self {
        Self {
            joint_offset_rad: 0.05f64.to_radians(),
            origin_xyz_m: 0.5e-3,
            origin_rpy_rad: 0.05f64.to_radians(),
            tip_m: 0.5e-3,
            joint_scale: None,
            compliance_rad_per_nm: None,
        }
    }
}

impl Tolerance {
    /// All tolerances zero: nothing of the robot is fitted (a placement-only fit).
    pub fn none() -> Self {
        Self {
            joint_offset_rad: 0.0,
            origin_xyz_m: 0.0,
            origin_rpy_rad: 0.0,
            tip_m: 0.0,
            joint_scale: None,
            compliance_rad_per_nm: None,
        }
    }

    /// Prior standard deviation `tol/√3` of a kinematic parameter (0: not fitted). The mount
    /// parameters are never fitted (they are the base placement's job).
    pub fn prior_sigma(&self, p: ErrorParam) -> f64 {
        let tol = match p {
            ErrorParam::JointOffset { .. } => self.joint_offset_rad,
            ErrorParam::JointScale { .. } => self.joint_scale.unwrap_or(0.0),
            ErrorParam::OriginXyz { .. } => self.origin_xyz_m,
            ErrorParam::OriginRpy { .. } => self.origin_rpy_rad,
            ErrorParam::Tip { .. } => self.tip_m,
            ErrorParam::Compliance { .. } => self.compliance_rad_per_nm.unwrap_or(0.0),
            ErrorParam::MountXyz { .. } | ErrorParam::MountRpy { .. } => 0.0,
        };
        tol / 3f64.sqrt()
    }

    fn check(&self, robot: RobotIndex) -> Result<(), CellFitError> {
        let fields = [
            ("joint_offset_rad", self.joint_offset_rad),
            ("origin_xyz_m", self.origin_xyz_m),
            ("origin_rpy_rad", self.origin_rpy_rad),
            ("tip_m", self.tip_m),
            ("joint_scale", self.joint_scale.unwrap_or(0.0)),
            (
                "compliance_rad_per_nm",
                self.compliance_rad_per_nm.unwrap_or(0.0),
            ),
        ];
        for (field, v) in fields {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CellFitError::InvalidInput(format!(
                    "robot {robot} tolerance `{field}` is {v}; give a finite value ≥ 0 (0: not fitted)"
                )));
            }
        }
        Ok(())
    }
}

/// A named tool point on a robot's flange (the handclasp tip, a tracker reflector, …).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tool {
    /// Name, for messages and reports.
    pub name: String,
    /// Nominal tip offset in the flange (`tool0`) frame, m.
    pub flange_from_tip: Vector3<f64>,
}

/// One robot of the cell: its nominal model, its tools, gravity and tolerances.
#[derive(Debug, Clone)]
pub struct CellRobot {
    /// Nominal kinematic model.
    pub model: RobotModel,
    /// Tool points (at least one); observations name them by index.
    pub tools: Vec<Tool>,
    /// Gravity acceleration in this robot's nominal base frame, m/s² (used by compliance).
    pub g_base: Vector3<f64>,
    /// Tolerances: the prior, and which parameters are fitted.
    pub tolerance: Tolerance,
}

impl CellRobot {
    /// The kinematic parameters fitted for this robot (tolerance > 0), in catalogue order: per
    /// joint offset, scale, origin xyz, origin rpy, compliance. Tip offsets are per tool and not
    /// in this list; mounts are never fitted.
    pub fn fitted_params(&self) -> Vec<ErrorParam> {
        let mut out = Vec::new();
        for joint in 0..self.model.dof() {
            let mut cand = vec![
                ErrorParam::JointOffset { joint },
                ErrorParam::JointScale { joint },
            ];
            cand.extend(Axis::ALL.map(|axis| ErrorParam::OriginXyz { joint, axis }));
            cand.extend(Axis::ALL.map(|axis| ErrorParam::OriginRpy { joint, axis }));
            cand.push(ErrorParam::Compliance { joint });
            out.extend(
                cand.into_iter()
                    .filter(|&p| self.tolerance.prior_sigma(p) > 0.0),
            );
        }
        out
    }
}

/// Noise of a 3-row observation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[non_exhaustive]
pub enum Noise3 {
    /// Independent, equal σ on each axis, m.
    Isotropic {
        /// Standard deviation per axis, m.
        sigma_m: f64,
    },
    /// Full covariance of the 3 residuals, m², in the residual's frame (symmetric positive
    /// definite).
    Covariance {
        /// The covariance, m².
        cov_m2: Matrix3<f64>,
    },
}

impl Noise3 {
    /// The whitening matrix `W = L⁻¹` with `Σ = L·Lᵀ` (Cholesky), so `W·r` has unit covariance.
    fn whitening(&self, row: usize) -> Result<Matrix3<f64>, CellFitError> {
        match *self {
            Noise3::Isotropic { sigma_m } => {
                if sigma_m.is_finite() && sigma_m > 0.0 {
                    Ok(Matrix3::identity() / sigma_m)
                } else {
                    Err(CellFitError::InvalidInput(format!(
                        "observation row {row}: noise σ {sigma_m} m must be finite and > 0"
                    )))
                }
            }
            Noise3::Covariance { cov_m2 } => {
                let sym = (cov_m2 - cov_m2.transpose()).amax() <= 1e-12 * cov_m2.amax();
                let l = cov_m2
                    .cholesky()
                    .filter(|_| sym && cov_m2.iter().all(|v| v.is_finite()))
                    .and_then(|c| c.l().try_inverse());
                l.ok_or_else(|| {
                    CellFitError::InvalidInput(format!(
                        "observation row {row}: noise covariance is not symmetric positive \
                         definite ({cov_m2:?} m²)"
                    ))
                })
            }
        }
    }
}

/// What one observation saw. Joint vectors in rad, chain order; tools by index into
/// [`CellRobot::tools`]; groups by index into the problem's group lists.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum ObservationKind {
    /// The two tips coincide: 3 residuals `p1_b1 − b1_from_b2·p2_b2`, m.
    Coincident {
        /// Robot 1's joints, rad.
        q1: Vec<f64>,
        /// Robot 2's joints, rad.
        q2: Vec<f64>,
        /// Robot 1's tool.
        tool1: usize,
        /// Robot 2's tool.
        tool2: usize,
        /// Noise of the 3 residuals (b1 axes).
        noise: Noise3,
    },
    /// The tips are a distance `d` apart (e.g. two spheres touching): 1 residual
    /// `‖p1_b1 − b1_from_b2·p2_b2‖ − d`, m.
    Contact {
        /// Robot 1's joints, rad.
        q1: Vec<f64>,
        /// Robot 2's joints, rad.
        q2: Vec<f64>,
        /// Robot 1's tool.
        tool1: usize,
        /// Robot 2's tool.
        tool2: usize,
        /// Contact group (its distance is known or fitted).
        group: usize,
        /// σ of the residual, m.
        sigma_m: f64,
    },
    /// One robot's tool measured by an external device in the unknown frame of its group:
    /// 3 residuals `tracker_from_anchor·p_anchor − p_tracker`, m.
    Tracker {
        /// The robot measured (1 or 2).
        robot: RobotIndex,
        /// Its joints, rad.
        q: Vec<f64>,
        /// Its tool (e.g. the reflector).
        tool: usize,
        /// Tracker group.
        group: usize,
        /// The measured position in the tracker frame, m.
        p_tracker: Point3<f64>,
        /// Noise of the 3 residuals (tracker axes).
        noise: Noise3,
    },
    /// One robot's tool touches a plane of unknown position of its group: 1 residual
    /// `n·p_anchor − d`, m.
    Plane {
        /// The robot touching (1 or 2).
        robot: RobotIndex,
        /// Its joints, rad.
        q: Vec<f64>,
        /// Its tool.
        tool: usize,
        /// Plane group.
        group: usize,
        /// σ of the residual, m.
        sigma_m: f64,
    },
}

impl ObservationKind {
    /// `"coincident"`, `"contact"`, `"tracker"` or `"plane"`.
    pub fn name(&self) -> &'static str {
        match self {
            ObservationKind::Coincident { .. } => "coincident",
            ObservationKind::Contact { .. } => "contact",
            ObservationKind::Tracker { .. } => "tracker",
            ObservationKind::Plane { .. } => "plane",
        }
    }

    /// Number of residuals (1 or 3).
    pub fn rows(&self) -> usize {
        match self {
            ObservationKind::Coincident { .. } | ObservationKind::Tracker { .. } => 3,
            ObservationKind::Contact { .. } | ObservationKind::Plane { .. } => 1,
        }
    }
}

/// One observation with its 1-based source row (used in every message and report).
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// 1-based source row (e.g. the session CSV's data row).
    pub row: usize,
    /// What was observed.
    pub kind: ObservationKind,
}

/// A tracker (external measuring device) whose frame is unknown: `tracker_from_b{anchor}` is
/// fitted (unpenalised).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerGroup {
    /// Name, for messages.
    pub name: String,
    /// The base frame the tracker frame is expressed against (1 or 2). Use the measured robot's
    /// base for a tracker that sees one robot only (then `b1_from_b2` does not enter).
    pub anchor: RobotIndex,
    /// Starting value of `tracker_from_anchor`; `None`: a rigid fit of the group's measurements
    /// to the nominal tips (needs ≥ 3 non-collinear points).
    pub initial_tracker_from_anchor: Option<Isometry3<f64>>,
}

/// A plane of unknown position, `{p_anchor : n·p_anchor = d}` (fitted, unpenalised).
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneGroup {
    /// Name, for messages.
    pub name: String,
    /// The base frame the plane is expressed in (1 or 2).
    pub anchor: RobotIndex,
    /// Starting `(unit normal, offset m)`; `None`: a least-squares plane through the group's
    /// nominal tips (needs ≥ 3 non-collinear points).
    pub initial: Option<(Unit<Vector3<f64>>, f64)>,
}

/// A contact distance shared by a group of [`ObservationKind::Contact`] rows.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactGroup {
    /// Name, for messages.
    pub name: String,
    /// The (starting) distance between the two tools, m.
    pub distance_m: f64,
    /// Fit the distance (unpenalised) instead of holding it known.
    pub fit_distance: bool,
}

/// The whole-cell calibration problem: two robots, observations, nuisance groups.
#[derive(Debug, Clone)]
pub struct CellProblem {
    /// Robot 1 (base frame `b1`).
    pub robot1: CellRobot,
    /// Robot 2 (base frame `b2`).
    pub robot2: CellRobot,
    /// The observations.
    pub observations: Vec<Observation>,
    /// Tracker groups.
    pub trackers: Vec<TrackerGroup>,
    /// Plane groups.
    pub planes: Vec<PlaneGroup>,
    /// Contact groups.
    pub contacts: Vec<ContactGroup>,
}

impl CellProblem {
    /// Robot 1 or 2.
    pub fn robot(&self, robot: RobotIndex) -> &CellRobot {
        if robot == 1 {
            &self.robot1
        } else {
            &self.robot2
        }
    }

    /// Checks the problem: robot indices, tools, groups, joint vector lengths, noise, and
    /// tolerances. Errors name the observation row and the field.
    pub fn check(&self) -> Result<(), CellFitError> {
        for r in [1u8, 2] {
            let rb = self.robot(r);
            rb.tolerance.check(r)?;
            if rb.tools.is_empty() {
                return Err(CellFitError::InvalidInput(format!(
                    "robot {r} has no tool; give at least one tool point"
                )));
            }
            if !rb.g_base.iter().all(|v| v.is_finite()) {
                return Err(CellFitError::InvalidInput(format!(
                    "robot {r}: gravity {:?} m/s² is not finite",
                    rb.g_base
                )));
            }
        }
        let tool_ok = |robot: RobotIndex, tool: usize, row: usize| {
            if robot_slot(robot).is_none() {
                return Err(CellFitError::InvalidInput(format!(
                    "observation row {row}: robot {robot} does not exist; use 1 or 2"
                )));
            }
            let n = self.robot(robot).tools.len();
            if tool >= n {
                return Err(CellFitError::InvalidInput(format!(
                    "observation row {row}: robot {robot} has {n} tool(s), tool index {tool} is out of range"
                )));
            }
            Ok(())
        };
        let group_ok = |what: &str, g: usize, n: usize, row: usize| {
            if g >= n {
                Err(CellFitError::InvalidInput(format!(
                    "observation row {row}: {what} group {g} does not exist ({n} defined)"
                )))
            } else {
                Ok(())
            }
        };
        let sigma_ok = |s: f64, row: usize| {
            if s.is_finite() && s > 0.0 {
                Ok(())
            } else {
                Err(CellFitError::InvalidInput(format!(
                    "observation row {row}: noise σ {s} m must be finite and > 0"
                )))
            }
        };
        for g in &self.trackers {
            if robot_slot(g.anchor).is_none() {
                return Err(CellFitError::InvalidInput(format!(
                    "tracker group `{}`: anchor robot {} does not exist; use 1 or 2",
                    g.name, g.anchor
                )));
            }
        }
        for g in &self.planes {
            if robot_slot(g.anchor).is_none() {
                return Err(CellFitError::InvalidInput(format!(
                    "plane group `{}`: anchor robot {} does not exist; use 1 or 2",
                    g.name, g.anchor
                )));
            }
        }
        for g in &self.contacts {
            if !(g.distance_m.is_finite() && g.distance_m >= 0.0) {
                return Err(CellFitError::InvalidInput(format!(
                    "contact group `{}`: distance {} m must be finite and ≥ 0",
                    g.name, g.distance_m
                )));
            }
        }
        for o in &self.observations {
            let row = o.row;
            match &o.kind {
                ObservationKind::Coincident {
                    tool1,
                    tool2,
                    noise,
                    ..
                } => {
                    tool_ok(1, *tool1, row)?;
                    tool_ok(2, *tool2, row)?;
                    noise.whitening(row)?;
                }
                ObservationKind::Contact {
                    tool1,
                    tool2,
                    group,
                    sigma_m,
                    ..
                } => {
                    tool_ok(1, *tool1, row)?;
                    tool_ok(2, *tool2, row)?;
                    group_ok("contact", *group, self.contacts.len(), row)?;
                    sigma_ok(*sigma_m, row)?;
                }
                ObservationKind::Tracker {
                    robot,
                    tool,
                    group,
                    p_tracker,
                    noise,
                    ..
                } => {
                    tool_ok(*robot, *tool, row)?;
                    group_ok("tracker", *group, self.trackers.len(), row)?;
                    noise.whitening(row)?;
                    if !p_tracker.iter().all(|v| v.is_finite()) {
                        return Err(CellFitError::InvalidInput(format!(
                            "observation row {row}: tracker position is not finite"
                        )));
                    }
                }
                ObservationKind::Plane {
                    robot,
                    tool,
                    group,
                    sigma_m,
                    ..
                } => {
                    tool_ok(*robot, *tool, row)?;
                    group_ok("plane", *group, self.planes.len(), row)?;
                    sigma_ok(*sigma_m, row)?;
                }
            }
            for (r, q) in joint_vectors(&o.kind) {
                self.robot(r)
                    .model
                    .check_q(q)
                    .map_err(|e| CellFitError::Kinematics {
                        row,
                        message: format!("robot {r}: {e}"),
                    })?;
            }
        }
        Ok(())
    }
}

/// The joint vectors an observation uses, with their robots.
fn joint_vectors(kind: &ObservationKind) -> Vec<(RobotIndex, &[f64])> {
    match kind {
        ObservationKind::Coincident { q1, q2, .. } | ObservationKind::Contact { q1, q2, .. } => {
            vec![(1, q1.as_slice()), (2, q2.as_slice())]
        }
        ObservationKind::Tracker { robot, q, .. } | ObservationKind::Plane { robot, q, .. } => {
            vec![(*robot, q.as_slice())]
        }
    }
}

/// The kinematic corrections of one robot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobotCorrection {
    /// Kinematic errors (the `tip` field is unused: tips are per tool).
    pub errors: KinematicErrors,
    /// Tip offset error of each tool, m, flange axes (added to [`Tool::flange_from_tip`]).
    pub tool_tip_m: Vec<Vector3<f64>>,
}

impl RobotCorrection {
    /// No corrections for `robot`.
    pub fn zero(robot: &CellRobot) -> Self {
        Self {
            errors: KinematicErrors::zero(robot.model.dof()),
            tool_tip_m: vec![Vector3::zeros(); robot.tools.len()],
        }
    }

    /// The errors with tool `tool`'s tip error in the `tip` field.
    pub fn errors_for_tool(&self, tool: usize) -> KinematicErrors {
        let mut e = self.errors.clone();
        e.tip = self.tool_tip_m[tool];
        e
    }
}

/// A plane `{p : n·p = d}` in its anchor's base frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlaneEstimate {
    /// Unit normal, anchor base axes.
    pub normal_anchor: Unit<Vector3<f64>>,
    /// Offset `d`, m.
    pub offset_m: f64,
}

/// Values of every unknown of the cell: the placement, both robots' corrections and the
/// nuisance unknowns. Used as the fit's state and result, and as the truth in studies.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellEstimate {
    /// Base 2 in base 1.
    pub b1_from_b2: Isometry3<f64>,
    /// Robot 1's corrections.
    pub robot1: RobotCorrection,
    /// Robot 2's corrections.
    pub robot2: RobotCorrection,
    /// `tracker_from_b{anchor}` of each tracker group.
    pub tracker_from_anchor: Vec<Isometry3<f64>>,
    /// Each plane group's plane.
    pub planes: Vec<PlaneEstimate>,
    /// Each contact group's distance, m.
    pub contact_distance_m: Vec<f64>,
}

impl CellEstimate {
    /// Nominal robots (no corrections), the given placement and groups at identity / unit z /
    /// their given distance.
    pub fn nominal(problem: &CellProblem, b1_from_b2: Isometry3<f64>) -> Self {
        Self {
            b1_from_b2,
            robot1: RobotCorrection::zero(&problem.robot1),
            robot2: RobotCorrection::zero(&problem.robot2),
            tracker_from_anchor: vec![Isometry3::identity(); problem.trackers.len()],
            planes: vec![
                PlaneEstimate {
                    normal_anchor: Vector3::z_axis(),
                    offset_m: 0.0
                };
                problem.planes.len()
            ],
            contact_distance_m: problem.contacts.iter().map(|c| c.distance_m).collect(),
        }
    }

    /// Checks that the estimate fits `problem`: one correction per joint and tool of each robot,
    /// one value per group, all finite. Errors name the field.
    pub fn check(&self, problem: &CellProblem) -> Result<(), CellFitError> {
        self.check_robots(problem)?;
        if self.tracker_from_anchor.len() != problem.trackers.len()
            || self.planes.len() != problem.planes.len()
            || self.contact_distance_m.len() != problem.contacts.len()
        {
            return Err(CellFitError::InvalidInput(format!(
                "cell estimate: {} tracker frame(s), {} plane(s), {} contact distance(s) for {}, \
                 {} and {} group(s); build it with CellEstimate::nominal for this problem",
                self.tracker_from_anchor.len(),
                self.planes.len(),
                self.contact_distance_m.len(),
                problem.trackers.len(),
                problem.planes.len(),
                problem.contacts.len()
            )));
        }
        Ok(())
    }

    /// The robot part of [`CellEstimate::check`] (what the cooperative vector needs).
    pub fn check_robots(&self, problem: &CellProblem) -> Result<(), CellFitError> {
        let bad = |what: String| {
            Err(CellFitError::InvalidInput(format!(
                "cell estimate: {what}; build it with CellEstimate::nominal for this problem"
            )))
        };
        for r in [1u8, 2] {
            let rb = problem.robot(r);
            let c = self.robot(r);
            if let Err(e) = c.errors.check(&rb.model) {
                return bad(format!("robot {r}: {e}"));
            }
            if c.tool_tip_m.len() != rb.tools.len() {
                return bad(format!(
                    "robot {r} has {} tool tip error(s) for {} tool(s)",
                    c.tool_tip_m.len(),
                    rb.tools.len()
                ));
            }
            if !c.tool_tip_m.iter().all(|t| t.iter().all(|v| v.is_finite())) {
                return bad(format!("robot {r} has a non-finite tool tip error"));
            }
        }
        if !self
            .b1_from_b2
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite())
            || !self
                .b1_from_b2
                .rotation
                .coords
                .iter()
                .all(|v| v.is_finite())
        {
            return bad("b1_from_b2 is not finite".into());
        }
        Ok(())
    }

    /// Robot 1's or 2's corrections.
    pub fn robot(&self, robot: RobotIndex) -> &RobotCorrection {
        if robot == 1 {
            &self.robot1
        } else {
            &self.robot2
        }
    }

    fn robot_mut(&mut self, robot: RobotIndex) -> &mut RobotCorrection {
        if robot == 1 {
            &mut self.robot1
        } else {
            &mut self.robot2
        }
    }
}

/// One scalar unknown of the fit.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum CellParam {
    /// Left translation perturbation of `b1_from_b2`, m, b1 axes.
    PlacementTranslation {
        /// Axis.
        axis: Axis,
    },
    /// Left rotation perturbation of `b1_from_b2`, rad, b1 axes.
    PlacementRotation {
        /// Axis.
        axis: Axis,
    },
    /// A kinematic parameter of a robot (its own unit).
    Kinematic {
        /// 1 or 2.
        robot: RobotIndex,
        /// The parameter.
        param: ErrorParam,
    },
    /// A tool's tip offset error, m, flange axes.
    ToolTip {
        /// 1 or 2.
        robot: RobotIndex,
        /// Tool index.
        tool: usize,
        /// Axis.
        axis: Axis,
    },
    /// Left translation perturbation of a tracker frame, m.
    TrackerTranslation {
        /// Group index.
        group: usize,
        /// Axis.
        axis: Axis,
    },
    /// Left rotation perturbation of a tracker frame, rad.
    TrackerRotation {
        /// Group index.
        group: usize,
        /// Axis.
        axis: Axis,
    },
    /// A plane normal's tangent perturbation (direction 0 or 1 of its tangent basis), rad.
    PlaneNormal {
        /// Group index.
        group: usize,
        /// 0 or 1.
        direction: usize,
    },
    /// A plane's offset, m.
    PlaneOffset {
        /// Group index.
        group: usize,
    },
    /// A contact group's distance, m.
    ContactDistance {
        /// Group index.
        group: usize,
    },
}

impl CellParam {
    /// True for the kinematic parameters (the ones with a prior).
    pub fn is_kinematic(&self) -> bool {
        matches!(
            self,
            CellParam::Kinematic { .. } | CellParam::ToolTip { .. }
        )
    }

    /// A readable name, e.g. `robot 2 origin_xyz joint 3 x`.
    pub fn describe(&self, problem: &CellProblem) -> String {
        match self {
            CellParam::PlacementTranslation { axis } => format!("b1_from_b2 translation {axis}"),
            CellParam::PlacementRotation { axis } => format!("b1_from_b2 rotation {axis}"),
            CellParam::Kinematic { robot, param } => format!("robot {robot} {param}"),
            CellParam::ToolTip { robot, tool, axis } => format!(
                "robot {robot} tool `{}` tip {axis}",
                problem.robot(*robot).tools[*tool].name
            ),
            CellParam::TrackerTranslation { group, axis } => {
                format!(
                    "tracker `{}` translation {axis}",
                    problem.trackers[*group].name
                )
            }
            CellParam::TrackerRotation { group, axis } => {
                format!(
                    "tracker `{}` rotation {axis}",
                    problem.trackers[*group].name
                )
            }
            CellParam::PlaneNormal { group, direction } => {
                format!("plane `{}` normal {direction}", problem.planes[*group].name)
            }
            CellParam::PlaneOffset { group } => {
                format!("plane `{}` offset", problem.planes[*group].name)
            }
            CellParam::ContactDistance { group } => {
                format!("contact `{}` distance", problem.contacts[*group].name)
            }
        }
    }
}

#[derive(Debug, Clone)]
struct RobotLayout {
    /// Fitted kinematic parameters (tips excluded) and their columns.
    kin: Vec<(ErrorParam, usize)>,
    /// Column of tool t's tip x (y, z follow), if that tool's tip is fitted.
    /// Column of each axis of each tool's tip error, if fitted.
    tip_col: Vec<[Option<usize>; 3]>,
}

/// The unknowns of a fit and their prior: column `j` of every Jacobian is `params[j]`.
#[derive(Debug, Clone)]
pub struct ParamLayout {
    /// The unknowns, in column order: placement (6), robot 1, robot 2, trackers (6 each),
    /// planes (3 each), fitted contact distances.
    pub params: Vec<CellParam>,
    /// Square-root prior information `R_p` (rows × `params.len()`): the prior cost is
    /// `‖R_p·θ‖²` with `θ` the parameter values (zero on unpenalised columns).
    pub prior_sqrt_info: DMatrix<f64>,
    robots: [RobotLayout; 2],
    tracker_col: Vec<usize>,
    plane_col: Vec<usize>,
    contact_col: Vec<Option<usize>>,
}

impl ParamLayout {
    /// The layout of `problem` with every parameter its tolerances select, except those in
    /// `fixed` (held at their current value, normally 0), and a diagonal prior `1/σ` with
    /// `σ = tol/√3`.
    pub fn new(problem: &CellProblem, fixed: &[CellParam]) -> Self {
        let mut params: Vec<CellParam> = Vec::new();
        for axis in Axis::ALL {
            params.push(CellParam::PlacementTranslation { axis });
        }
        for axis in Axis::ALL {
            params.push(CellParam::PlacementRotation { axis });
        }
        let mut sigmas: Vec<f64> = vec![0.0; 6];
        let mut robots = Vec::new();
        for r in [1u8, 2] {
            let rb = problem.robot(r);
            let mut kin = Vec::new();
            for p in rb.fitted_params() {
                let cp = CellParam::Kinematic { robot: r, param: p };
                if fixed.contains(&cp) {
                    continue;
                }
                kin.push((p, params.len()));
                params.push(cp);
                sigmas.push(rb.tolerance.prior_sigma(p));
            }
            let mut tip_col = Vec::new();
            for tool in 0..rb.tools.len() {
                let mut cols = [None; 3];
                if rb.tolerance.tip_m > 0.0 {
                    for (a, &axis) in Axis::ALL.iter().enumerate() {
                        let p = CellParam::ToolTip {
                            robot: r,
                            tool,
                            axis,
                        };
                        if fixed.contains(&p) {
                            continue;
                        }
                        cols[a] = Some(params.len());
                        params.push(p);
                        sigmas.push(rb.tolerance.tip_m / 3f64.sqrt());
                    }
                }
                tip_col.push(cols);
            }
            robots.push(RobotLayout { kin, tip_col });
        }
        let mut tracker_col = Vec::new();
        for group in 0..problem.trackers.len() {
            tracker_col.push(params.len());
            for axis in Axis::ALL {
                params.push(CellParam::TrackerTranslation { group, axis });
            }
            for axis in Axis::ALL {
                params.push(CellParam::TrackerRotation { group, axis });
            }
            sigmas.extend([0.0; 6]);
        }
        let mut plane_col = Vec::new();
        for group in 0..problem.planes.len() {
            plane_col.push(params.len());
            params.push(CellParam::PlaneNormal {
                group,
                direction: 0,
            });
            params.push(CellParam::PlaneNormal {
                group,
                direction: 1,
            });
            params.push(CellParam::PlaneOffset { group });
            sigmas.extend([0.0; 3]);
        }
        let mut contact_col = Vec::new();
        for (group, c) in problem.contacts.iter().enumerate() {
            if c.fit_distance {
                contact_col.push(Some(params.len()));
                params.push(CellParam::ContactDistance { group });
                sigmas.push(0.0);
            } else {
                contact_col.push(None);
            }
        }
        let penal: Vec<usize> = (0..params.len()).filter(|&j| sigmas[j] > 0.0).collect();
        let mut prior_sqrt_info = DMatrix::zeros(penal.len(), params.len());
        for (i, &j) in penal.iter().enumerate() {
            prior_sqrt_info[(i, j)] = 1.0 / sigmas[j];
        }
        let [r1, r2]: [RobotLayout; 2] = robots.try_into().expect("two robots");
        Self {
            params,
            prior_sqrt_info,
            robots: [r1, r2],
            tracker_col,
            plane_col,
            contact_col,
        }
    }

    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// True if there are no unknowns (never: the placement is always fitted).
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// Column of a parameter, if fitted.
    pub fn column(&self, p: &CellParam) -> Option<usize> {
        self.params.iter().position(|q| q == p)
    }

    /// Prior standard deviation of column `j` from the diagonal of the prior information (0 for
    /// unpenalised columns).
    pub fn prior_sigma(&self, j: usize) -> f64 {
        let info: f64 = self.prior_sqrt_info.column(j).norm_squared();
        if info > 0.0 {
            1.0 / info.sqrt()
        } else {
            0.0
        }
    }

    /// The values of the parameters in `estimate` (0 on the manifold perturbation columns of the
    /// placement, trackers and plane normals, which are relative to the current value).
    pub fn values(&self, estimate: &CellEstimate) -> DVector<f64> {
        let mut v = DVector::zeros(self.len());
        for (slot, r) in [1u8, 2].into_iter().enumerate() {
            let corr = estimate.robot(r);
            for &(p, c) in &self.robots[slot].kin {
                v[c] = corr.errors.get(p);
            }
            for (tool, cols) in self.robots[slot].tip_col.iter().enumerate() {
                for (a, c) in cols.iter().enumerate() {
                    if let Some(c) = c {
                        v[*c] = corr.tool_tip_m[tool][a];
                    }
                }
            }
        }
        for (g, c) in self.plane_col.iter().enumerate() {
            v[c + 2] = estimate.planes[g].offset_m;
        }
        for (g, c) in self.contact_col.iter().enumerate() {
            if let Some(c) = c {
                v[*c] = estimate.contact_distance_m[g];
            }
        }
        v
    }

    /// Applies a step `delta` (one entry per column) to `estimate`: placement and tracker frames
    /// by left perturbation `X ← Translation(ρ)·Rotation(φ)·X`, plane normals by
    /// `n ← normalise(n + a·u + b·v)` with `(u, v)` [`tangent_basis`]`(n)`, everything else
    /// additively.
    pub fn apply(&self, estimate: &CellEstimate, delta: &DVector<f64>) -> CellEstimate {
        let mut e = estimate.clone();
        let left = |x: &Isometry3<f64>, c: usize| {
            let rho = Vector3::new(delta[c], delta[c + 1], delta[c + 2]);
            let phi = Vector3::new(delta[c + 3], delta[c + 4], delta[c + 5]);
            Isometry3::new(rho, phi) * x
        };
        e.b1_from_b2 = left(&estimate.b1_from_b2, 0);
        for (slot, r) in [1u8, 2].into_iter().enumerate() {
            let corr = e.robot_mut(r);
            for &(p, c) in &self.robots[slot].kin {
                corr.errors.add(p, delta[c]);
            }
            for (tool, cols) in self.robots[slot].tip_col.iter().enumerate() {
                for (a, c) in cols.iter().enumerate() {
                    if let Some(c) = c {
                        corr.tool_tip_m[tool][a] += delta[*c];
                    }
                }
            }
        }
        for (g, &c) in self.tracker_col.iter().enumerate() {
            e.tracker_from_anchor[g] = left(&estimate.tracker_from_anchor[g], c);
        }
        for (g, &c) in self.plane_col.iter().enumerate() {
            let n = estimate.planes[g].normal_anchor;
            let (u, v) = tangent_basis(&n);
            e.planes[g].normal_anchor =
                Unit::new_normalize(n.into_inner() + u * delta[c] + v * delta[c + 1]);
            e.planes[g].offset_m += delta[c + 2];
        }
        for (g, c) in self.contact_col.iter().enumerate() {
            if let Some(c) = c {
                e.contact_distance_m[g] += delta[*c];
            }
        }
        e
    }
}

/// A deterministic orthonormal basis `(u, v)` of the plane orthogonal to `n`.
pub fn tangent_basis(n: &Unit<Vector3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    let a = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = n.cross(&a).normalize();
    let v = n.cross(&u);
    (u, v)
}

/// Sparse 3-row Jacobian: (column, ∂/∂column).
type Cols3 = Vec<(usize, Vector3<f64>)>;

/// A linearised observation: residuals and Jacobian rows (unwhitened and the whitening).
#[derive(Debug, Clone)]
pub struct ObservationLinearisation {
    /// Residuals (1 or 3), m, unwhitened.
    pub residual: DVector<f64>,
    /// Jacobian rows (1 or 3) × layout columns, unwhitened.
    pub jacobian: DMatrix<f64>,
    /// Whitening matrix (1×1 or 3×3): `W·r` has unit covariance.
    pub whitening: DMatrix<f64>,
}

/// Evaluates residuals and analytic Jacobians of observations at an estimate.
pub struct Evaluator<'a> {
    problem: &'a CellProblem,
    layout: &'a ParamLayout,
    /// Jacobian parameter lists per robot: fitted kin params then tip x, y, z.
    jac_params: [Vec<ErrorParam>; 2],
}

impl<'a> Evaluator<'a> {
    /// An evaluator of `problem` with unknowns `layout`.
    pub fn new(problem: &'a CellProblem, layout: &'a ParamLayout) -> Self {
        let jp = |slot: usize| {
            let mut v: Vec<ErrorParam> = layout.robots[slot].kin.iter().map(|k| k.0).collect();
            v.extend(Axis::ALL.map(|axis| ErrorParam::Tip { axis }));
            v
        };
        Self {
            problem,
            layout,
            jac_params: [jp(0), jp(1)],
        }
    }

    /// Tip of `robot`'s `tool` at `q` in its own base frame, m, and its Jacobian columns.
    fn robot_tip(
        &self,
        est: &CellEstimate,
        robot: RobotIndex,
        tool: usize,
        q: &[f64],
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError> {
        let slot = robot_slot(robot).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "observation row {row}: robot {robot} is not 1 or 2"
            ))
        })?;
        let rb = self.problem.robot(robot);
        let tool_def = rb.tools.get(tool).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "observation row {row}: robot {robot} has no tool {tool}"
            ))
        })?;
        let errors = est.robot(robot).errors_for_tool(tool);
        let kin_err = |e: kinematics::KinematicsError| CellFitError::Kinematics {
            row,
            message: format!("robot {robot}: {e}"),
        };
        let p = true_base_from_tip(&rb.model, &errors, q, &tool_def.flange_from_tip, &rb.g_base)
            .map_err(kin_err)?
            .translation
            .vector;
        let mut cols = Cols3::new();
        if want_jac {
            let lay = &self.layout.robots[slot];
            let tip_col = lay.tip_col[tool];
            if !lay.kin.is_empty() || tip_col.iter().any(Option::is_some) {
                // Always the kinematic columns and all three tip axes; unfitted axes are skipped.
                let j = tip_error_jacobian(
                    &rb.model,
                    &errors,
                    q,
                    &tool_def.flange_from_tip,
                    &rb.g_base,
                    &self.jac_params[slot],
                )
                .map_err(kin_err)?;
                for (k, &(_, c)) in lay.kin.iter().enumerate() {
                    cols.push((c, j.column(k).into_owned()));
                }
                let k0 = lay.kin.len();
                for (a, c) in tip_col.iter().enumerate() {
                    if let Some(c) = c {
                        cols.push((*c, j.column(k0 + a).into_owned()));
                    }
                }
            }
        }
        Ok((p, cols))
    }

    /// Tip of `robot`'s tool in base `anchor`'s frame and its Jacobian columns (including the
    /// placement's when the frames differ).
    #[allow(clippy::too_many_arguments)]
    fn tip_in_anchor(
        &self,
        est: &CellEstimate,
        robot: RobotIndex,
        tool: usize,
        q: &[f64],
        anchor: RobotIndex,
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError> {
        let (f, cols) = self.robot_tip(est, robot, tool, q, want_jac, row)?;
        if robot == anchor {
            return Ok((f, cols));
        }
        let x = &est.b1_from_b2;
        let r_x = x.rotation.to_rotation_matrix().into_inner();
        if robot == 2 {
            // g = X·f2; ∂g/∂ρ = I, ∂g/∂φ_i = e_i × g, ∂g/∂θ2 = R_X·J2.
            let g = (x * Point3::from(f)).coords;
            let mut out: Cols3 = cols.into_iter().map(|(c, v)| (c, r_x * v)).collect();
            if want_jac {
                for (i, axis) in Axis::ALL.iter().enumerate() {
                    out.push((i, axis.unit()));
                    out.push((3 + i, axis.unit().cross(&g)));
                }
            }
            Ok((g, out))
        } else {
            // g = X⁻¹·f1; with X' = exp(ξ)·X, X'⁻¹·f1 = X⁻¹·(f1 − ρ − φ×f1) to first order.
            let g = (x.inverse() * Point3::from(f)).coords;
            let r_t = r_x.transpose();
            let mut out: Cols3 = cols.into_iter().map(|(c, v)| (c, r_t * v)).collect();
            if want_jac {
                for (i, axis) in Axis::ALL.iter().enumerate() {
                    out.push((i, -(r_t * axis.unit())));
                    out.push((3 + i, -(r_t * axis.unit().cross(&f))));
                }
            }
            Ok((g, out))
        }
    }

    /// Residuals, Jacobian rows (layout columns) and whitening of one observation at `est`.
    pub fn linearise(
        &self,
        obs: &Observation,
        est: &CellEstimate,
        want_jac: bool,
    ) -> Result<ObservationLinearisation, CellFitError> {
        let row = obs.row;
        let n = self.layout.len();
        let rows = obs.kind.rows();
        let mut jac = DMatrix::zeros(if want_jac { rows } else { 0 }, n);
        let put3 = |jac: &mut DMatrix<f64>, cols: &Cols3, sign: f64| {
            for (c, v) in cols {
                for a in 0..3 {
                    jac[(a, *c)] += sign * v[a];
                }
            }
        };
        let put1 = |jac: &mut DMatrix<f64>, cols: &Cols3, w: &Vector3<f64>| {
            for (c, v) in cols {
                jac[(0, *c)] += w.dot(v);
            }
        };
        let (residual, whitening) = match &obs.kind {
            ObservationKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                noise,
            } => {
                let (p1, c1) = self.tip_in_anchor(est, 1, *tool1, q1, 1, want_jac, row)?;
                let (g2, c2) = self.tip_in_anchor(est, 2, *tool2, q2, 1, want_jac, row)?;
                if want_jac {
                    put3(&mut jac, &c1, 1.0);
                    put3(&mut jac, &c2, -1.0);
                }
                let w = noise.whitening(row)?;
                (
                    DVector::from_column_slice((p1 - g2).as_slice()),
                    DMatrix::from_column_slice(3, 3, w.as_slice()),
                )
            }
            ObservationKind::Contact {
                q1,
                q2,
                tool1,
                tool2,
                group,
                sigma_m,
            } => {
                let (p1, c1) = self.tip_in_anchor(est, 1, *tool1, q1, 1, want_jac, row)?;
                let (g2, c2) = self.tip_in_anchor(est, 2, *tool2, q2, 1, want_jac, row)?;
                let e = p1 - g2;
                let dist = e.norm();
                let u = if dist > 0.0 { e / dist } else { Vector3::x() };
                if want_jac {
                    put1(&mut jac, &c1, &u);
                    put1(&mut jac, &c2, &(-u));
                    if let Some(c) = self.layout.contact_col[*group] {
                        jac[(0, c)] -= 1.0;
                    }
                }
                (
                    DVector::from_element(1, dist - est.contact_distance_m[*group]),
                    DMatrix::from_element(1, 1, 1.0 / sigma_m),
                )
            }
            ObservationKind::Tracker {
                robot,
                q,
                tool,
                group,
                p_tracker,
                noise,
            } => {
                let anchor = self.problem.trackers[*group].anchor;
                let (g, cols) = self.tip_in_anchor(est, *robot, *tool, q, anchor, want_jac, row)?;
                let t = &est.tracker_from_anchor[*group];
                let m = (t * Point3::from(g)).coords;
                if want_jac {
                    let r_t = t.rotation.to_rotation_matrix().into_inner();
                    let moved: Cols3 = cols.into_iter().map(|(c, v)| (c, r_t * v)).collect();
                    put3(&mut jac, &moved, 1.0);
                    let c0 = self.layout.tracker_col[*group];
                    for (i, axis) in Axis::ALL.iter().enumerate() {
                        for a in 0..3 {
                            jac[(a, c0 + i)] += axis.unit()[a];
                            jac[(a, c0 + 3 + i)] += axis.unit().cross(&m)[a];
                        }
                    }
                }
                let w = noise.whitening(row)?;
                (
                    DVector::from_column_slice((m - p_tracker.coords).as_slice()),
                    DMatrix::from_column_slice(3, 3, w.as_slice()),
                )
            }
            ObservationKind::Plane {
                robot,
                q,
                tool,
                group,
                sigma_m,
            } => {
                let anchor = self.problem.planes[*group].anchor;
                let (g, cols) = self.tip_in_anchor(est, *robot, *tool, q, anchor, want_jac, row)?;
                let plane = &est.planes[*group];
                let nrm = plane.normal_anchor.into_inner();
                if want_jac {
                    put1(&mut jac, &cols, &nrm);
                    let (u, v) = tangent_basis(&plane.normal_anchor);
                    let c0 = self.layout.plane_col[*group];
                    jac[(0, c0)] += u.dot(&g);
                    jac[(0, c0 + 1)] += v.dot(&g);
                    jac[(0, c0 + 2)] -= 1.0;
                }
                (
                    DVector::from_element(1, nrm.dot(&g) - plane.offset_m),
                    DMatrix::from_element(1, 1, 1.0 / sigma_m),
                )
            }
        };
        if !residual.iter().chain(jac.iter()).all(|v| v.is_finite()) {
            return Err(CellFitError::NonFinite { row });
        }
        Ok(ObservationLinearisation {
            residual,
            jacobian: jac,
            whitening,
        })
    }

    /// The cooperative vector `v = f1(q1) − b1_from_b2·f2(q2)` (m, b1 axes) and its Jacobian
    /// (3 × layout columns) at `est`.
    pub fn cooperative_vector(
        &self,
        est: &CellEstimate,
        pair: &super::ConfigPair,
        want_jac: bool,
    ) -> Result<(Vector3<f64>, DMatrix<f64>), CellFitError> {
        let (p1, c1) = self.tip_in_anchor(est, 1, pair.tool1, &pair.q1, 1, want_jac, 0)?;
        let (g2, c2) = self.tip_in_anchor(est, 2, pair.tool2, &pair.q2, 1, want_jac, 0)?;
        let mut jac = DMatrix::zeros(3, if want_jac { self.layout.len() } else { 0 });
        if want_jac {
            for (c, v) in &c1 {
                for a in 0..3 {
                    jac[(a, *c)] += v[a];
                }
            }
            for (c, v) in &c2 {
                for a in 0..3 {
                    jac[(a, *c)] -= v[a];
                }
            }
        }
        Ok((p1 - g2, jac))
    }
}

/// Starting values: `b1_from_b2` (given, or a rigid fit of the coincident rows at nominal),
/// tracker frames (given, or a rigid fit) and planes (given, or a least-squares plane).
pub fn initial_estimate(
    problem: &CellProblem,
    initial_b1_from_b2: Option<Isometry3<f64>>,
    active: &[usize],
) -> Result<CellEstimate, CellFitError> {
    let layout = ParamLayout::new(problem, &[]);
    let ev = Evaluator::new(problem, &layout);
    let mut est = CellEstimate::nominal(problem, Isometry3::identity());
    let x = match initial_b1_from_b2 {
        Some(x) => x,
        None => {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for &i in active {
                let o = &problem.observations[i];
                if let ObservationKind::Coincident {
                    q1,
                    q2,
                    tool1,
                    tool2,
                    ..
                } = &o.kind
                {
                    a.push(Point3::from(
                        ev.robot_tip(&est, 1, *tool1, q1, false, o.row)?.0,
                    ));
                    b.push(Point3::from(
                        ev.robot_tip(&est, 2, *tool2, q2, false, o.row)?.0,
                    ));
                }
            }
            rigid_fit_fast(&a, &b).ok_or_else(|| {
                CellFitError::InvalidInput(format!(
                    "no starting b1_from_b2: {} coincident row(s) (need ≥ 3 not on a line); \
                     give an initial b1_from_b2",
                    a.len()
                ))
            })?
        }
    };
    est.b1_from_b2 = x;
    for (g, grp) in problem.trackers.iter().enumerate() {
        if let Some(t) = grp.initial_tracker_from_anchor {
            est.tracker_from_anchor[g] = t;
            continue;
        }
        let (mut meas, mut model) = (Vec::new(), Vec::new());
        for &i in active {
            let o = &problem.observations[i];
            if let ObservationKind::Tracker {
                robot,
                q,
                tool,
                group,
                p_tracker,
                ..
            } = &o.kind
            {
                if *group == g {
                    let (p, _) =
                        ev.tip_in_anchor(&est, *robot, *tool, q, grp.anchor, false, o.row)?;
                    meas.push(*p_tracker);
                    model.push(Point3::from(p));
                }
            }
        }
        est.tracker_from_anchor[g] = rigid_fit_fast(&meas, &model).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "tracker group `{}`: {} row(s), need ≥ 3 not on a line for a starting frame; \
                 add rows or give initial_tracker_from_anchor",
                grp.name,
                meas.len()
            ))
        })?;
    }
    for (g, grp) in problem.planes.iter().enumerate() {
        if let Some((n, d)) = grp.initial {
            est.planes[g] = PlaneEstimate {
                normal_anchor: n,
                offset_m: d,
            };
            continue;
        }
        let mut pts = Vec::new();
        for &i in active {
            let o = &problem.observations[i];
            if let ObservationKind::Plane {
                robot,
                q,
                tool,
                group,
                ..
            } = &o.kind
            {
                if *group == g {
                    pts.push(
                        ev.tip_in_anchor(&est, *robot, *tool, q, grp.anchor, false, o.row)?
                            .0,
                    );
                }
            }
        }
        est.planes[g] = fit_plane(&pts).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "plane group `{}`: {} row(s), need ≥ 3 not on a line for a starting plane; add \
                 rows or give an initial plane",
                grp.name,
                pts.len()
            ))
        })?;
    }
    Ok(est)
}

/// Least-squares plane through points (normal = smallest principal axis).
fn fit_plane(pts: &[Vector3<f64>]) -> Option<PlaneEstimate> {
    if pts.len() < 3 {
        return None;
    }
    let c = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let mut m = Matrix3::zeros();
    for p in pts {
        m += (p - c) * (p - c).transpose();
    }
    let eig = m.symmetric_eigen();
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    if eig.eigenvalues[idx[1]] <= 1e-12 * eig.eigenvalues[idx[2]].max(1e-300) {
        return None;
    }
    let n = Unit::new_normalize(eig.eigenvectors.column(idx[0]).into_owned());
    Some(PlaneEstimate {
        normal_anchor: n,
        offset_m: n.dot(&c),
    })
}
