//! What was observed: the observation kinds, the nuisance groups (tracker frames, planes,
//! contact distances), the [`CellProblem`] that holds them with both robots, and its checks.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Point3, Unit, Vector3};

use super::cell::{CellFitError, CellRobot, Noise3};
use super::PlacementPrior;
use crate::Robot;

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
    /// Two flat faces touching flush (e.g. faces of two marker polyhedra): the distance between
    /// the two tips ALONG the faces' common normal is `d`; a slide of one face on the other
    /// (the tangential part of the tip-to-tip vector) is not observed. 1 residual
    /// `n̄·(g2 − p1) − d`, m, with `p1` robot 1's tip in b1, `g2 = b1_from_b2·p2_b2`,
    /// `n̄ = (n1_b1 − n2_b1)/‖n1_b1 − n2_b1‖` the mean face normal (pointing from robot 1 to
    /// robot 2), `n1_b1 = R(b1_from_tip1)·n1_tip`, `n2_b1 = R(b1_from_b2)·R(b2_from_tip2)·n2_tip`
    /// (both rotate with every kinematic parameter and the placement). For flush faces
    /// `n2_b1 = −n1_b1`, `n̄ = n1_b1`, and `d` is the sum of the two faces' distances from their
    /// tip points. The tip frame's axes are the flange's ([`super::Tool`] is a translation).
    FaceContact {
        /// Robot 1's joints, rad.
        q1: Vec<f64>,
        /// Robot 2's joints, rad.
        q2: Vec<f64>,
        /// Robot 1's tool.
        tool1: usize,
        /// Robot 2's tool.
        tool2: usize,
        /// Unit outward normal of robot 1's touching face, in robot 1's TIP frame (rotation of
        /// base_from_tip = base_from_flange · flange_from_tip).
        n1_tip: Unit<Vector3<f64>>,
        /// Unit outward normal of robot 2's touching face, in robot 2's tip frame.
        n2_tip: Unit<Vector3<f64>>,
        /// Contact group: its distance d is known or fitted, as for `Contact`.
        group: usize,
        /// σ of the residual, m.
        sigma_m: f64,
    },
    /// One robot's tool measured by an external device in the unknown frame of its group:
    /// 3 residuals `tracker_from_anchor·p_anchor − p_tracker`, m.
    Tracker {
        /// The robot measured (1 or 2).
        robot: Robot,
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
        robot: Robot,
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

/// The observation kinds without their data: the one list of them. The session CSV's `kind`
/// names and column sets (handclasp-cell), the residual dispatch ([`ObservationKind`]) and the
/// per-kind reports (diagnose) are derived from it; a new kind is an arm here and in
/// [`ObservationKind`] with its residual, and its row's reader and writer in handclasp-cell's
/// `session/kinds.rs` (docs/ARCHITECTURE.md lists the files). Not `#[non_exhaustive]`, so that
/// every crate's `match` on it names the new kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    /// Two tool points coincide ([`ObservationKind::Coincident`]).
    Coincident,
    /// Two tool points a distance apart ([`ObservationKind::Contact`]).
    Contact,
    /// One robot's tool measured by a tracker ([`ObservationKind::Tracker`]).
    Tracker,
    /// One robot's tool touches a plane ([`ObservationKind::Plane`]).
    Plane,
    /// Two flat faces touching flush ([`ObservationKind::FaceContact`]).
    FaceContact,
}

impl Kind {
    /// Every kind, in the documented order: the session CSV's list of `kind` values (its
    /// messages name them in this order) and the order of per-kind counts.
    pub const ALL: [Kind; 5] = [
        Kind::Coincident,
        Kind::Contact,
        Kind::Tracker,
        Kind::Plane,
        Kind::FaceContact,
    ];

    /// The kind's name in files and reports: `"coincident"`, `"contact"`, `"tracker"`,
    /// `"plane"` or `"face_contact"`.
    pub const fn name(self) -> &'static str {
        match self {
            Kind::Coincident => "coincident",
            Kind::Contact => "contact",
            Kind::Tracker => "tracker",
            Kind::Plane => "plane",
            Kind::FaceContact => "face_contact",
        }
    }

    /// The kind named `name` (exactly, as [`Kind::name`] writes it); `None` for another text.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Number of residuals of one observation (1 or 3).
    pub const fn residual_rows(self) -> usize {
        match self {
            Kind::Coincident | Kind::Tracker => 3,
            Kind::Contact | Kind::FaceContact | Kind::Plane => 1,
        }
    }

    /// True when an observation of this kind takes both robots' joints (a pair of tool
    /// points); false when it takes one robot's (its `robot` field).
    pub const fn two_robot(self) -> bool {
        match self {
            Kind::Coincident | Kind::Contact | Kind::FaceContact => true,
            Kind::Tracker | Kind::Plane => false,
        }
    }

    /// The kind of nuisance group an observation of this kind belongs to (contacts and face
    /// contacts share the contact groups); `None` for a coincident handclasp.
    pub const fn group(self) -> Option<GroupKind> {
        match self {
            Kind::Coincident => None,
            Kind::Contact | Kind::FaceContact => Some(GroupKind::Contact),
            Kind::Tracker => Some(GroupKind::Tracker),
            Kind::Plane => Some(GroupKind::Plane),
        }
    }
}

/// The kinds of nuisance group of a [`CellProblem`]: its `contacts`, `trackers` and `planes`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GroupKind {
    /// A contact distance ([`ContactGroup`]).
    Contact,
    /// A tracker frame ([`TrackerGroup`]).
    Tracker,
    /// A plane ([`PlaneGroup`]).
    Plane,
}

impl GroupKind {
    /// Every group kind; [`GroupKind::index`] is the position in this list.
    pub const ALL: [GroupKind; 3] = [GroupKind::Contact, GroupKind::Tracker, GroupKind::Plane];

    /// Position in [`GroupKind::ALL`] (0 contact, 1 tracker, 2 plane), for per-group-kind arrays.
    pub const fn index(self) -> usize {
        match self {
            GroupKind::Contact => 0,
            GroupKind::Tracker => 1,
            GroupKind::Plane => 2,
        }
    }

    /// `"contact"`, `"tracker"` or `"plane"`.
    pub const fn name(self) -> &'static str {
        match self {
            GroupKind::Contact => "contact",
            GroupKind::Tracker => "tracker",
            GroupKind::Plane => "plane",
        }
    }
}

impl ObservationKind {
    /// The kind without its data.
    pub fn kind(&self) -> Kind {
        match self {
            ObservationKind::Coincident { .. } => Kind::Coincident,
            ObservationKind::Contact { .. } => Kind::Contact,
            ObservationKind::FaceContact { .. } => Kind::FaceContact,
            ObservationKind::Tracker { .. } => Kind::Tracker,
            ObservationKind::Plane { .. } => Kind::Plane,
        }
    }

    /// `"coincident"`, `"contact"`, `"face_contact"`, `"tracker"` or `"plane"` ([`Kind::name`]).
    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// Number of residuals (1 or 3, [`Kind::residual_rows`]).
    pub fn rows(&self) -> usize {
        self.kind().residual_rows()
    }

    /// The joint vectors the observation uses, with their robots (robot 1's first).
    pub fn joints(&self) -> Vec<(Robot, &[f64])> {
        match self {
            ObservationKind::Coincident { q1, q2, .. }
            | ObservationKind::Contact { q1, q2, .. }
            | ObservationKind::FaceContact { q1, q2, .. } => {
                vec![(Robot::One, q1.as_slice()), (Robot::Two, q2.as_slice())]
            }
            ObservationKind::Tracker { robot, q, .. } | ObservationKind::Plane { robot, q, .. } => {
                vec![(*robot, q.as_slice())]
            }
        }
    }

    /// The (robot, tool) pairs the observation uses (robot 1's first).
    pub fn tools(&self) -> Vec<(Robot, usize)> {
        match self {
            ObservationKind::Coincident { tool1, tool2, .. }
            | ObservationKind::Contact { tool1, tool2, .. }
            | ObservationKind::FaceContact { tool1, tool2, .. } => {
                vec![(Robot::One, *tool1), (Robot::Two, *tool2)]
            }
            ObservationKind::Tracker { robot, tool, .. }
            | ObservationKind::Plane { robot, tool, .. } => vec![(*robot, *tool)],
        }
    }

    /// The nuisance group: its kind ([`Kind::group`]) and its index in the problem's list of
    /// that kind; `None` for a coincident handclasp.
    pub fn group(&self) -> Option<(GroupKind, usize)> {
        let kind = self.kind().group()?;
        match self {
            ObservationKind::Coincident { .. } => None,
            ObservationKind::Contact { group, .. }
            | ObservationKind::FaceContact { group, .. }
            | ObservationKind::Tracker { group, .. }
            | ObservationKind::Plane { group, .. } => Some((kind, *group)),
        }
    }

    /// The nuisance group's index, to renumber it (e.g. in a sub-problem); `None` for a
    /// coincident handclasp.
    pub fn group_mut(&mut self) -> Option<&mut usize> {
        match self {
            ObservationKind::Coincident { .. } => None,
            ObservationKind::Contact { group, .. }
            | ObservationKind::FaceContact { group, .. }
            | ObservationKind::Tracker { group, .. }
            | ObservationKind::Plane { group, .. } => Some(group),
        }
    }

    /// Scales the observation's stated noise by `s` (each σ times `s`, a covariance times `s²`).
    pub fn scale_noise(&mut self, s: f64) {
        match self {
            ObservationKind::Contact { sigma_m, .. }
            | ObservationKind::FaceContact { sigma_m, .. }
            | ObservationKind::Plane { sigma_m, .. } => *sigma_m *= s,
            ObservationKind::Coincident { noise, .. } | ObservationKind::Tracker { noise, .. } => {
                *noise = noise.scaled(s);
            }
        }
    }
}

/// Largest allowed `|‖n‖ − 1|` of a face normal of [`ObservationKind::FaceContact`] (a
/// `Unit` built with `new_normalize` is unit to ~1e-16; this catches zero, NaN and unnormalised
/// vectors wrapped with `new_unchecked`).
pub const UNIT_NORMAL_TOL: f64 = 1e-9;

/// Largest difference, rad (or m), between a one-robot row's trunk joints and the other arm's
/// trunk joints given for it ([`CellProblem::other_arm_q`]): 1e-9, round-off of one value
/// written twice.
pub const OTHER_ARM_TRUNK_TOL: f64 = 1e-9;

/// One observation with its 1-based source row (used in every message and report).
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// 1-based source row (e.g. the session CSV's data row).
    pub row: usize,
    /// What was observed.
    pub kind: ObservationKind,
}

/// A tracker (external measuring device) whose frame is unknown: `tracker_from_b{anchor}` is
/// fitted (unpenalised), optionally with a scale error and a linear drift of its translation.
///
/// With both on, a tool at `g` (anchor base frame) is predicted at
/// `p_tracker = (1 + s)·(tracker_from_anchor·g + u·δ)`: `s` the scale error (ratio), `δ` the
/// drift (m per unit of `u`, tracker axes) and `u = (row − first)/(last − first) − ½` the
/// observation's normalised recording order, `row` its 1-based source row and `first`/`last`
/// the smallest and largest row of the group's tracker observations (all of them, active or
/// not; `u = 0` for a single row). So `δ` is the translation drift over the whole recording and
/// `tracker_from_anchor` the frame at its middle. Both are unpenalised and start at 0.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerGroup {
    /// Name, for messages.
    pub name: String,
    /// The base frame the tracker frame is expressed against (1 or 2). Use the measured robot's
    /// base for a tracker that sees one robot only (then `b1_from_b2` does not enter).
    pub anchor: Robot,
    /// Starting value of `tracker_from_anchor`; `None`: a rigid fit of the group's measurements
    /// to the nominal tips (needs ≥ 3 non-collinear points).
    pub initial_tracker_from_anchor: Option<Isometry3<f64>>,
    /// Fit the scale error `s` (default off: `s = 0`). Confounded with the robots' link lengths
    /// when those are fitted without another length reference.
    pub fit_scale: bool,
    /// Fit the drift `δ` of the translation over the recording order (default off: `δ = 0`).
    pub fit_drift: bool,
}

/// A plane of unknown position, `{p_anchor : n·p_anchor = d}` (fitted, unpenalised).
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneGroup {
    /// Name, for messages.
    pub name: String,
    /// The base frame the plane is expressed in (1 or 2).
    pub anchor: Robot,
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
    /// Optional prior on `b1_from_b2` around a known nominal (e.g. two arms on one base);
    /// `None`: the placement is fitted unpenalised.
    pub placement_prior: Option<PlacementPrior>,
    /// A shared-trunk cell ([`CellRobot::shared_joints`] > 0): the other arm's joints (its
    /// independent joints, rad or m, agreeing with the row's on the trunk) at the 1-based source
    /// row of each one-robot observation (tracker, plane) that gives them. The other arm's weight
    /// loads the trunk joints ([`kinematics::trunk`]): with its posture the trunk's gravity
    /// deflection carries both arms; without it, the measured arm's alone. Two-robot rows carry
    /// both arms' joints already. Empty otherwise.
    pub other_arm_q: BTreeMap<usize, Vec<f64>>,
}

impl CellProblem {
    /// Checks [`CellProblem::other_arm_q`]: only on a shared-trunk cell, each entry at the row of
    /// a one-robot observation (tracker or plane), as many values as the other arm's
    /// independent joints, all finite, and the trunk's independent joints equal to the row's
    /// (within [`OTHER_ARM_TRUNK_TOL`]: one trunk has one posture).
    fn check_other_arm_q(&self) -> Result<(), CellFitError> {
        if self.other_arm_q.is_empty() {
            return Ok(());
        }
        let k = self.robot2.shared_joints;
        if k == 0 {
            return Err(CellFitError::InvalidInput(
                "the other arm's joints are given for one-robot rows, but the cell has no shared \
                 trunk (robot 2's shared_joints is 0); give them only on a shared-trunk cell"
                    .into(),
            ));
        }
        let trunk_independent = self
            .robot1
            .model
            .chain_joints()
            .iter()
            .take(k)
            .filter(|j| !j.is_coupled())
            .count();
        for (&row, q_other) in &self.other_arm_q {
            let obs = self.observations.iter().find(|o| o.row == row);
            let (robot, q) = match obs.map(|o| &o.kind) {
                Some(ObservationKind::Tracker { robot, q, .. })
                | Some(ObservationKind::Plane { robot, q, .. }) => (*robot, q),
                _ => {
                    return Err(CellFitError::InvalidInput(format!(
                        "observation row {row}: the other arm's joints are given, but row {row} \
                         is not a tracker or plane row (two-robot rows carry both arms' joints); \
                         give them only for one-robot rows"
                    )))
                }
            };
            let other = robot.other();
            let dof = self.robot(other).model.dof();
            if q_other.len() != dof || !q_other.iter().all(|v| v.is_finite()) {
                return Err(CellFitError::InvalidInput(format!(
                    "observation row {row}: the other arm ({other}) has {dof} joints, but {} \
                     values are given (or some are not finite); give its {dof} joint values",
                    q_other.len()
                )));
            }
            for j in 0..trunk_independent.min(q.len()) {
                if (q[j] - q_other[j]).abs() > OTHER_ARM_TRUNK_TOL {
                    return Err(CellFitError::InvalidInput(format!(
                        "observation row {row}: trunk joint {} is {} rad for {robot} but {} rad \
                         in the other arm's joints; one trunk has one posture, give the row's \
                         value in both",
                        j + 1,
                        q[j],
                        q_other[j]
                    )));
                }
            }
        }
        Ok(())
    }

    /// The normalised recording order `u ∈ [−½, ½]` of a tracker observation of `group` at
    /// source row `row` (see [`TrackerGroup`]): `(row − first)/(last − first) − ½` over the
    /// group's tracker observations, 0 when the group has one row (or none).
    pub fn tracker_order(&self, group: usize, row: usize) -> f64 {
        let (first, last) = self.tracker_row_span(group);
        if last > first {
            (row as f64 - first as f64) / (last - first) as f64 - 0.5
        } else {
            0.0
        }
    }

    /// Smallest and largest source row of `group`'s tracker observations (`(0, 0)` if none).
    pub(super) fn tracker_row_span(&self, group: usize) -> (usize, usize) {
        let mut span: Option<(usize, usize)> = None;
        for o in &self.observations {
            if let ObservationKind::Tracker { group: g, .. } = o.kind {
                if g == group {
                    span = Some(span.map_or((o.row, o.row), |(a, b)| (a.min(o.row), b.max(o.row))));
                }
            }
        }
        span.unwrap_or((0, 0))
    }

    /// Robot 1 or 2.
    pub fn robot(&self, robot: Robot) -> &CellRobot {
        if robot == Robot::One {
            &self.robot1
        } else {
            &self.robot2
        }
    }

    /// Checks the problem: robot indices, tools, groups, joint vector lengths, noise, and
    /// tolerances. Errors name the observation row and the field.
    pub fn check(&self) -> Result<(), CellFitError> {
        if let Some(p) = &self.placement_prior {
            p.check()?;
        }
        for r in [Robot::One, Robot::Two] {
            let rb = self.robot(r);
            rb.tolerance.check(r)?;
            if rb.tools.is_empty() {
                return Err(CellFitError::InvalidInput(format!(
                    "{r} has no tool; give at least one tool point"
                )));
            }
            if !rb.g_base.iter().all(|v| v.is_finite()) {
                return Err(CellFitError::InvalidInput(format!(
                    "{r}: gravity {:?} m/s² is not finite",
                    rb.g_base
                )));
            }
        }
        self.check_other_arm_q()?;
        let tool_ok = |robot: Robot, tool: usize, row: usize| {
            let n = self.robot(robot).tools.len();
            if tool >= n {
                return Err(CellFitError::InvalidInput(format!(
                    "observation row {row}: {robot} has {n} tool(s), tool index {tool} is out of range"
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
                    tool_ok(Robot::One, *tool1, row)?;
                    tool_ok(Robot::Two, *tool2, row)?;
                    noise.whitening(row)?;
                }
                ObservationKind::Contact {
                    tool1,
                    tool2,
                    group,
                    sigma_m,
                    ..
                }
                | ObservationKind::FaceContact {
                    tool1,
                    tool2,
                    group,
                    sigma_m,
                    ..
                } => {
                    tool_ok(Robot::One, *tool1, row)?;
                    tool_ok(Robot::Two, *tool2, row)?;
                    group_ok("contact", *group, self.contacts.len(), row)?;
                    sigma_ok(*sigma_m, row)?;
                    if let ObservationKind::FaceContact { n1_tip, n2_tip, .. } = &o.kind {
                        for (name, robot, n) in [
                            ("n1_tip", Robot::One, n1_tip),
                            ("n2_tip", Robot::Two, n2_tip),
                        ] {
                            let norm = n.norm();
                            if !(n.iter().all(|v| v.is_finite())
                                && (norm - 1.0).abs() <= UNIT_NORMAL_TOL)
                            {
                                return Err(CellFitError::InvalidInput(format!(
                                    "observation row {row}: face normal {name} {:?} is not a unit \
                                     vector (norm {norm}); give the outward normal of {robot}'s \
                                     touching face in its tip frame, non-zero and finite, \
                                     normalised (Unit::new_normalize)",
                                    n.as_slice()
                                )));
                            }
                        }
                    }
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
            for (r, q) in o.kind.joints() {
                self.robot(r)
                    .model
                    .check_q(q)
                    .map_err(|e| CellFitError::Kinematics {
                        row,
                        message: format!("{r}: {e}"),
                    })?;
            }
        }
        Ok(())
    }
}
