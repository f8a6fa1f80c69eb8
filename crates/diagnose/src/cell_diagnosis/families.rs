//! The candidate families of the selection ([`Family`], [`candidate_families`]) and what a
//! model of them frees: its problem (fitted contact distances, tracker scales and drifts) and
//! its unknowns (less each origin angle that is a joint offset: [`offset_alias`]).
//!
//! On a shared-trunk cell (`[robot2] shares`: a positive
//! [`calib_core::whole_cell::CellRobot::shared_joints`]) the trunk's parameters are one set, robot 1's columns of the whole-cell layout
//! ([`ParamLayout::new`] ties robot 2's copies to them, as `calibrate --cell` does), so each
//! joint family is cut in two: a *trunk* family (the trunk joints' parameters, once: "trunk
//! joint offsets") and each robot's *arm* family (its joints after the trunk, and its arm links'
//! lumped coefficients on the trunk joints: each arm's weight on the trunk is its own).

use calib_core::whole_cell::{CellParam, CellProblem, GroupKind, ObservationKind, ParamLayout};
use calib_core::Robot;
use kinematics::ErrorParam;
use serde::Serialize;

use super::problem::uses_robot;

/// What a candidate family is. One entry per family of parameters; a new error term of the
/// library (e.g. joint-periodic errors, tracker scale or drift) is one more variant here, with
/// its membership test in [`Family::contains`] and its availability in [`candidate_families`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "family", rename_all = "snake_case")]
#[non_exhaustive]
pub enum FamilyKind {
    /// Every joint zero offset of the robot.
    JointOffsets,
    /// Every joint's encoder scale of the robot ([`ErrorParam::JointScale`]: a revolute
    /// joint's gear ratio, a prismatic joint's reading scale): a candidate when the cell's
    /// `[robotN.tolerance] joint_scale` is given.
    JointScales,
    /// Every joint origin position (link lengths and offsets) of the robot.
    OriginXyz,
    /// Every joint origin angle of the robot, except the one about the joint's own axis (that
    /// one is the joint offset: [`offset_alias`]).
    OriginRpy,
    /// Joint compliance under gravity, every joint of the robot.
    Compliance,
    /// Joint compliance under gravity as lumped coefficients (compliance × mass moment,
    /// [`ErrorParam::LumpedCompliance`]): the candidate when the URDF has no inertials.
    LumpedCompliance,
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

/// A candidate family: a kind of parameter on one robot, on a shared trunk, or on the
/// session's groups.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Family {
    /// The robot (1 or 2); `None` for the session-wide families ([`FamilyKind::ContactDistance`],
    /// [`FamilyKind::TrackerScale`], [`FamilyKind::TrackerDrift`]) and the trunk's.
    pub robot: Option<u8>,
    /// The kind.
    #[serde(flatten)]
    pub kind: FamilyKind,
    /// A readable name, e.g. `robot 1 joint offsets`, `robot 2 tool tip tip`, `trunk joint
    /// offsets`.
    pub name: String,
    /// A shared trunk's family (JSON `"trunk": true`, absent otherwise): the parameters of the
    /// first [`Family::trunk_joints`] chain joints, which both arms share (module docs).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub trunk: bool,
    /// The cell's shared trunk joints (robot 2's `shared_joints`; 0: no shared trunk). A robot
    /// family of a shared-trunk cell leaves the trunk's parameters to the trunk family.
    #[serde(skip)]
    pub trunk_joints: usize,
}

impl Family {
    fn new(robot: Option<Robot>, kind: FamilyKind, problem: &CellProblem) -> Self {
        Self::scoped(robot, false, kind, problem)
    }

    /// The trunk family of `kind` on a shared-trunk cell.
    fn trunk(kind: FamilyKind, problem: &CellProblem) -> Self {
        Self::scoped(None, true, kind, problem)
    }

    fn scoped(robot: Option<Robot>, trunk: bool, kind: FamilyKind, problem: &CellProblem) -> Self {
        let what = match kind {
            FamilyKind::JointOffsets => "joint offsets".to_string(),
            FamilyKind::JointScales => "joint scales".to_string(),
            FamilyKind::OriginXyz => "joint origin positions".to_string(),
            FamilyKind::OriginRpy => "joint origin angles".to_string(),
            FamilyKind::Compliance => "joint compliance".to_string(),
            FamilyKind::LumpedCompliance => "joint compliance (lumped, no masses)".to_string(),
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
            None if trunk => format!("trunk {what}"),
            None => what,
        };
        Self {
            robot: robot.map(Robot::number),
            kind,
            name,
            trunk,
            trunk_joints: problem.robot2.shared_joints,
        }
    }

    /// Whether `p` (robot `robot`'s kinematic parameter) is a parameter of the shared trunk:
    /// robot 1's (the layout's one copy) at a trunk joint, other than an arm link's lumped
    /// coefficient on it ([`kinematics::is_branch_param`]).
    fn is_trunk_param(&self, robot: Robot, p: &ErrorParam) -> bool {
        let k = self.trunk_joints;
        robot == Robot::One
            && p.joint().is_some_and(|j| j < k)
            && !kinematics::is_branch_param(p, k)
    }

    fn robot_is(&self, r: Robot) -> bool {
        self.robot == Some(r.number())
    }

    /// Whether an observation of this kind uses the family's parameters directly: its robot
    /// (and tool, for a tip), or, for the contact distances, a contact row, or, for the
    /// tracker scales and drifts, a tracker row.
    pub fn involves(&self, kind: &ObservationKind) -> bool {
        match self.kind {
            FamilyKind::ContactDistance => kind.kind().group() == Some(GroupKind::Contact),
            FamilyKind::TrackerScale | FamilyKind::TrackerDrift => {
                kind.kind().group() == Some(GroupKind::Tracker)
            }
            FamilyKind::ToolTip { tool } => kind
                .tools()
                .iter()
                .any(|(r, t)| self.robot_is(*r) && *t == tool),
            // Both arms ride on the trunk.
            _ if self.trunk => !kind.tools().is_empty(),
            _ => kind.tools().iter().any(|(r, _)| self.robot_is(*r)),
        }
    }

    /// The report's name of the family's unknown `p`: [`CellParam::describe`], except that a
    /// trunk family names its parameters once as the trunk's (`trunk joint_offset joint 2`, not
    /// robot 1's copy).
    pub fn param_name(&self, problem: &CellProblem, p: &CellParam) -> String {
        match p {
            CellParam::Kinematic { param, .. } if self.trunk => format!("trunk {param}"),
            _ => p.describe(problem),
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
                let scope = if self.trunk {
                    self.is_trunk_param(*robot, param)
                } else {
                    self.robot_is(*robot) && !self.is_trunk_param(*robot, param)
                };
                scope
                    && matches!(
                        (kind, param),
                        (FamilyKind::JointOffsets, ErrorParam::JointOffset { .. })
                            | (FamilyKind::JointScales, ErrorParam::JointScale { .. })
                            | (FamilyKind::OriginXyz, ErrorParam::OriginXyz { .. })
                            | (FamilyKind::OriginRpy, ErrorParam::OriginRpy { .. })
                            | (FamilyKind::Compliance, ErrorParam::Compliance { .. })
                            | (
                                FamilyKind::LumpedCompliance,
                                ErrorParam::LumpedCompliance { .. }
                            )
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

/// The candidate families of `problem` (the widened diagnosis problem): on a shared-trunk cell
/// first the trunk's families (robot 1's tolerances, which the layout gives the trunk's one
/// set of parameters); per robot, each family whose tolerance is > 0 (tool tips only for tools
/// the session uses), then the contact distances when a contact group states its distance, then
/// the tracker scales and drifts when the session has a tracker group. A joint family with no
/// fitted parameter (an arm of trunk joints only, a trunk without lumped coefficients of its
/// own) is left out.
pub fn candidate_families(problem: &CellProblem) -> Vec<Family> {
    let mut out = Vec::new();
    let shared = problem.robot2.shared_joints > 0;
    let layout = ParamLayout::new(problem, &[]);
    let has_params = |f: &Family| {
        layout
            .params
            .iter()
            .any(|p| f.contains(p) && !offset_alias(problem, p))
    };
    for r in [Robot::One, Robot::Two] {
        let rb = problem.robot(r);
        let tol = &rb.tolerance;
        let joint_families = [
            (FamilyKind::JointOffsets, tol.joint_offset_rad > 0.0),
            (
                FamilyKind::JointScales,
                tol.joint_scale.unwrap_or(0.0) > 0.0,
            ),
            (FamilyKind::OriginXyz, tol.origin_xyz_m > 0.0),
            (FamilyKind::OriginRpy, tol.origin_rpy_rad > 0.0),
            (
                FamilyKind::Compliance,
                tol.compliance_rad_per_nm.unwrap_or(0.0) > 0.0,
            ),
            (
                FamilyKind::LumpedCompliance,
                tol.lumped_compliance_rad.unwrap_or(0.0) > 0.0,
            ),
            (
                FamilyKind::JointPeriodic,
                tol.periodic_rad.unwrap_or(0.0) > 0.0,
            ),
        ];
        // The trunk's families (robot 1's tolerances), whichever arm the rows measure.
        if shared && r == Robot::One && !problem.observations.is_empty() {
            for (kind, on) in joint_families {
                let f = Family::trunk(kind, problem);
                if on && has_params(&f) {
                    out.push(f);
                }
            }
        }
        let used = |o: &&calib_core::whole_cell::Observation| uses_robot(&o.kind, r);
        if !problem.observations.iter().any(|o| used(&o)) {
            continue;
        }
        for (kind, on) in joint_families {
            let f = Family::new(Some(r), kind, problem);
            if on && (!shared || has_params(&f)) {
                out.push(f);
            }
        }
        if tol.tip_m > 0.0 {
            for tool in 0..rb.tools.len() {
                if problem
                    .observations
                    .iter()
                    .any(|o| o.kind.tools().contains(&(r, tool)))
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

/// The problem of a model: with [`FamilyKind::ContactDistance`] selected, every contact
/// group's distance is fitted; with [`FamilyKind::TrackerScale`] (or
/// [`FamilyKind::TrackerDrift`]) every tracker group's scale (drift).
pub(super) fn model_problem(problem: &CellProblem, model: &[Family]) -> CellProblem {
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
pub(super) fn model_layout(problem: &CellProblem, model: &[Family]) -> ParamLayout {
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
    let Some(j) = problem.robot(*robot).model.chain_joints().get(*joint) else {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell_diagnosis::tests::mixed_session;
    use crate::cell_diagnosis::{diagnosis_problem, CellDiagnoseOptions};
    use handclasp_cell::Cell;

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

    /// With `[robot1.tolerance] joint_scale` given, robot 1's joint scales are a candidate
    /// family of their own, and every fitted parameter is still in exactly one family.
    #[test]
    fn joint_scales_are_a_family_when_their_tolerance_is_given() {
        let mut cell = Cell::default_floor_wall();
        cell.robot1.tolerance.joint_scale = Some(1e-3);
        let session = mixed_session(&cell, 24, 4);
        let p = diagnosis_problem(&cell, &session, &CellDiagnoseOptions::default()).unwrap();
        let fams = candidate_families(&p);
        let scales: Vec<&Family> = fams
            .iter()
            .filter(|f| f.kind == FamilyKind::JointScales)
            .collect();
        assert_eq!(scales.len(), 1, "{fams:?}");
        assert_eq!(scales[0].name, "robot 1 joint scales");
        let layout = ParamLayout::new(&p, &[]);
        let mut n_scales = 0;
        for param in layout.params.iter().filter(|c| c.is_kinematic()) {
            let n = fams.iter().filter(|f| f.contains(param)).count();
            let is_scale = matches!(
                param,
                CellParam::Kinematic {
                    param: ErrorParam::JointScale { .. },
                    ..
                }
            );
            n_scales += usize::from(is_scale);
            if is_scale {
                assert_eq!(n, 1, "{param:?} in {n} families");
                assert!(scales[0].contains(param));
            }
        }
        assert_eq!(n_scales, p.robot1.model.dof());
    }

    /// On a shared-trunk cell (the humanoid of `cells/humanoid-trunk.toml`, robot 1's and robot
    /// 2's first 4 chain joints one trunk) the trunk's parameters are tested once: a trunk
    /// family per joint kind holds robot 1's columns at the trunk joints and names them
    /// `trunk …`; each arm's family holds its joints after the trunk only; every fitted unknown
    /// is in exactly one family; a one-arm sub-problem keeps only its rows' other-arm postures.
    #[test]
    fn a_shared_trunk_is_one_family_per_kind_beside_each_arm() {
        use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../cells/humanoid-trunk.toml"
        );
        let cell = Cell::from_toml_file(std::path::Path::new(path)).unwrap();
        let k = cell.shared_joints;
        assert_eq!(k, 4);
        let kinds = KindSpec {
            kind: SimKind::Tracker,
            tracker_sigma_m: 1e-4,
            ..KindSpec::default()
        };
        let spec = SessionSpec::new(12, Layout::Random, 0.4);
        let session = generate_kind_session(&cell, &spec, &kinds, None, &mut trial_rng(5, 0))
            .unwrap()
            .0;
        let p = diagnosis_problem(&cell, &session, &CellDiagnoseOptions::default()).unwrap();
        assert_eq!(
            p.other_arm_q.len(),
            12,
            "every tracker row gives the other arm"
        );
        let fams = candidate_families(&p);
        let trunk: Vec<&Family> = fams.iter().filter(|f| f.trunk).collect();
        let names: Vec<&str> = trunk.iter().map(|f| f.name.as_str()).collect();
        assert!(
            names.contains(&"trunk joint offsets")
                && names.contains(&"trunk joint origin positions"),
            "{names:?}"
        );
        assert!(trunk.iter().all(|f| f.robot.is_none()));
        let layout = ParamLayout::new(&p, &[]);
        for param in layout.params.iter().filter(|c| c.is_kinematic()) {
            let n = fams.iter().filter(|f| f.contains(param)).count();
            assert_eq!(n, 1, "{param:?} in {n} families");
            let CellParam::Kinematic { robot, param: e } = param else {
                continue;
            };
            let at_trunk = e.joint().is_some_and(|j| j < k) && !kinematics::is_branch_param(e, k);
            // Robot 2's trunk parameters are robot 1's columns: none of its own.
            assert!(!(at_trunk && *robot == Robot::Two), "{param:?}");
            let owner = fams.iter().find(|f| f.contains(param)).unwrap();
            assert_eq!(owner.trunk, at_trunk, "{param:?} in {}", owner.name);
            if owner.trunk {
                assert!(
                    owner.param_name(&p, param).starts_with("trunk "),
                    "{param:?}"
                );
            } else {
                assert_eq!(owner.param_name(&p, param), param.describe(&p));
            }
        }
        // Both arms' rows involve the trunk; robot 2's families involve its rows only.
        let r2_offsets = fams
            .iter()
            .find(|f| f.robot == Some(2) && f.kind == FamilyKind::JointOffsets)
            .unwrap();
        for o in &p.observations {
            assert!(trunk[0].involves(&o.kind));
            assert_eq!(
                r2_offsets.involves(&o.kind),
                o.kind.tools().iter().any(|(r, _)| *r == Robot::Two)
            );
        }
        let sub = crate::cell_diagnosis::held_out::sub_problem(&p, &[0, 1, 2]);
        let rows: Vec<usize> = sub.observations.iter().map(|o| o.row).collect();
        assert_eq!(sub.other_arm_q.keys().copied().collect::<Vec<_>>(), rows);
    }
}
