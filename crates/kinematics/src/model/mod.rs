//! Serial-chain robot model loaded from a URDF.
//!
//! Frames: `base` is the URDF root link; the flange is the requested tool link (`tool0`).
//! `base_from_flange(q) = Π_k [fixed_prefix_k · Origin(xyz_k, rpy_k) · Motion_k(q_k)] · last_from_flange`,
//! with `Origin` rotation `Rz(yaw)·Ry(pitch)·Rx(roll)` (URDF) and `Motion_k` a rotation about the
//! joint axis by `q_k` rad (revolute, continuous) or a translation along it by `q_k` m
//! (prismatic). Lengths in metres, angles in radians.
//!
//! The product runs over the chain's moving joints ([`RobotModel::chain_joints`]); the joint
//! vector `q` that every function takes holds the independent ones ([`RobotModel::joints`]), and
//! the coupled joints' values are computed from it (see `coupling.rs`). A chain without coupled
//! joints has the same joints in both lists.
//!
//! Files: `mod.rs` the model's types and accessors, `urdf.rs` the loader (URDF → `RobotModel`).

mod urdf;

use nalgebra::{
    DMatrix, Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3,
};

use crate::coupling::{resolve, CouplingProblem, JointCoupling, LinearCoupling};
use crate::error::{KinematicsError, ModelError};

/// URDF rpy to a rotation: `R = Rz(yaw)·Ry(pitch)·Rx(roll)` with `rpy = (roll, pitch, yaw)`, rad.
pub fn rotation_from_rpy(rpy: &Vector3<f64>) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), rpy.z)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), rpy.y)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), rpy.x)
}

/// URDF `<origin xyz rpy>` (m, rad) as the isometry `parent_from_joint`.
pub fn origin_isometry(xyz: &Vector3<f64>, rpy: &Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(*xyz),
        UnitQuaternion::from_rotation_matrix(&rotation_from_rpy(rpy)),
    )
}

/// The kind of a moving joint, which fixes the unit of its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum JointKind {
    /// Rotary with limits (URDF `revolute`): the value is an angle, rad.
    Revolute,
    /// Rotary without limits (URDF `continuous`): the value is an angle, rad.
    Continuous,
    /// Linear (URDF `prismatic`: a track, a lift): the value is a travel along the axis, m.
    Prismatic,
}

impl JointKind {
    /// True for a prismatic (linear) joint.
    pub fn is_prismatic(self) -> bool {
        self == JointKind::Prismatic
    }

    /// The SI unit of the joint's value: `"rad"`, or `"m"` for a prismatic joint.
    pub fn unit_si(self) -> &'static str {
        if self.is_prismatic() {
            "m"
        } else {
            "rad"
        }
    }

    /// The URDF joint type: `"revolute"`, `"continuous"` or `"prismatic"`.
    pub fn urdf_name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
        }
    }
}

/// One moving (revolute, continuous or prismatic) joint of the chain.
///
/// Units follow [`Joint::kind`]: a revolute or continuous joint's value, limits and velocity are
/// in rad and rad/s and its effort in N·m; a prismatic joint's in m, m/s and N.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// URDF joint name.
    pub name: String,
    /// Revolute, continuous or prismatic: says the unit of the joint's value (rad or m).
    pub kind: JointKind,
    /// URDF parent link.
    pub parent_link: String,
    /// URDF child link.
    pub child_link: String,
    /// Fixed joints between the previous moving joint's frame and this joint's URDF parent link
    /// (identity if none; also holds any fixed joints before the first moving joint).
    pub fixed_prefix: Isometry3<f64>,
    /// URDF `<origin xyz>`, m, in the parent link frame.
    pub origin_xyz: Vector3<f64>,
    /// URDF `<origin rpy>`, rad (`Rz(yaw)·Ry(pitch)·Rx(roll)`).
    pub origin_rpy: Vector3<f64>,
    /// Rotation axis (revolute, continuous) or direction of travel (prismatic), unit, in the
    /// joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Lower limit: rad, or m for a prismatic joint (`-inf` for continuous joints). For a coupled
    /// joint, as written in the URDF and not checked.
    pub lower: f64,
    /// Upper limit: rad, or m for a prismatic joint (`+inf` for continuous joints). For a coupled
    /// joint, as written in the URDF and not checked.
    pub upper: f64,
    /// Velocity limit: rad/s, or m/s for a prismatic joint.
    pub velocity: f64,
    /// Effort limit: N·m, or N for a prismatic joint.
    pub effort: f64,
    /// `None` for an independent joint (a value of the joint vector `q`); for a coupled joint,
    /// its value in terms of `q` (a URDF `<mimic>` or [`RobotModel::with_couplings`]).
    pub coupling: Option<LinearCoupling>,
}

impl Joint {
    /// True if the joint's value follows other joints' (it is not part of `q`).
    pub fn is_coupled(&self) -> bool {
        self.coupling.is_some()
    }
}

/// Mass and centre of mass of everything rigidly carried by one moving joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LumpedInertial {
    /// Mass, kg.
    pub mass: f64,
    /// Centre of mass, m, in the joint's frame after its motion (zero if `mass == 0`).
    pub com: Vector3<f64>,
}

/// A fixed transform `(r, t)` of the chain, classified once for the FK hot path.
#[derive(Debug, Clone)]
pub(crate) struct FixedTransform {
    /// Rotation.
    pub(crate) r: Matrix3<f64>,
    /// Translation, m.
    pub(crate) t: Vector3<f64>,
    /// 0, 1, 2: `r` is exactly a rotation about x, y, z, i.e. the identity with the column pair
    /// (1,2), (2,0), (0,1) mixed by `r_sc = (sin, cos)`, so that `R·r` is that column mix of `R`
    /// (the same numbers as the full product); 3: `r` is exactly the identity; 4: general.
    pub(crate) r_kind: u8,
    /// `(sin, cos)` of the rotation when `r_kind < 3`.
    pub(crate) r_sc: (f64, f64),
    /// 0, 1, 2 if `t` is zero but for that component; 3 if it is all zero; 4 otherwise.
    pub(crate) t_kind: u8,
}

impl FixedTransform {
    /// Classifies `(r, t)`; see the fields.
    pub(crate) fn new(r: Matrix3<f64>, t: Vector3<f64>) -> FixedTransform {
        let (r_kind, r_sc) = classify_rotation(&r);
        // No allocation: the fits build a step per perturbed joint at every evaluation.
        let mut nonzero = (0..3).filter(|&i| t[i] != 0.0);
        let t_kind = match (nonzero.next(), nonzero.next()) {
            (None, _) => 3,
            (Some(k), None) => k as u8,
            _ => 4,
        };
        FixedTransform {
            r,
            t,
            r_kind,
            r_sc,
            t_kind,
        }
    }
}

/// See [`FixedTransform::r_kind`].
fn classify_rotation(r: &Matrix3<f64>) -> (u8, (f64, f64)) {
    if *r == Matrix3::identity() {
        return (3, (0.0, 1.0));
    }
    for (kind, (i, j)) in [(1, 2), (2, 0), (0, 1)].into_iter().enumerate() {
        let k = 3 - i - j;
        let (c, s) = (r[(i, i)], r[(j, i)]);
        let mut expected = Matrix3::zeros();
        expected[(k, k)] = 1.0;
        expected[(i, i)] = c;
        expected[(j, i)] = s;
        expected[(i, j)] = -s;
        expected[(j, j)] = c;
        if *r == expected {
            return (kind as u8, (s, c));
        }
    }
    (4, (0.0, 1.0))
}

/// Precomputed per-joint data for the hot path.
#[derive(Debug, Clone)]
pub(crate) struct Step {
    /// Axis in the joint frame.
    pub(crate) axis: Unit<Vector3<f64>>,
    /// 0, 1, 2 if the axis is ±x, ±y, ±z exactly; 3 otherwise; [`PRISMATIC`] for a prismatic
    /// joint (any axis).
    pub(crate) axis_kind: u8,
    /// Sign of the axis when `axis_kind < 3`.
    pub(crate) axis_sign: f64,
    /// `prev_from_joint = fixed_prefix · Origin(xyz, rpy)`.
    pub(crate) origin: FixedTransform,
    /// `3·t_kind + axis_kind` (0–8) when the origin has no rotation, its translation a single
    /// non-zero component and the axis is a coordinate axis: the FK loop's one-dispatch case;
    /// [`FAST_PRISMATIC`] for a prismatic joint; 9 otherwise.
    pub(crate) fast_kind: u8,
}

impl Step {
    /// The step for a joint with axis `axis` and `prev_from_joint = (origin_r, origin_t)`,
    /// rotary or, if `prismatic`, linear.
    pub(crate) fn new(
        axis: Unit<Vector3<f64>>,
        origin_r: Matrix3<f64>,
        origin_t: Vector3<f64>,
        prismatic: bool,
    ) -> Step {
        let (axis_kind, axis_sign) = if prismatic {
            (PRISMATIC, 1.0)
        } else {
            classify_axis(&axis)
        };
        let origin = FixedTransform::new(origin_r, origin_t);
        let fast_kind = if prismatic {
            FAST_PRISMATIC
        } else if origin.r_kind == 3 && origin.t_kind < 3 && axis_kind < 3 {
            3 * origin.t_kind + axis_kind
        } else {
            9
        };
        Step {
            axis,
            axis_kind,
            axis_sign,
            origin,
            fast_kind,
        }
    }
}

/// [`Step::axis_kind`] of a prismatic joint.
pub(crate) const PRISMATIC: u8 = 4;

/// [`Step::fast_kind`] of a prismatic joint.
pub(crate) const FAST_PRISMATIC: u8 = 10;

/// Chains up to this many moving joints are handled on the stack (no allocation) by the
/// internal hot paths; longer chains (and the chain values of coupled chains) allocate.
pub(crate) const STACK_DOF: usize = 16;

/// Where the value of one chain joint comes from.
#[derive(Debug, Clone)]
pub(crate) enum ChainSource {
    /// `q[i]`.
    Independent(usize),
    /// A linear combination of `q`.
    Coupled(LinearCoupling),
}

/// A serial robot arm from a URDF: the moving joints from the root link to a tool link.
/// Immutable once built.
#[derive(Debug, Clone)]
pub struct RobotModel {
    name: String,
    root_link: String,
    base_link: String,
    /// The fixed `world` joint's transform when the world rule applied (see `base_link`).
    root_from_base: Option<Isometry3<f64>>,
    tool_link: String,
    /// Joints not on the chain from the root to the tool link, in file order.
    ignored_joints: Vec<String>,
    /// Links not on that chain, in file order.
    ignored_links: Vec<String>,
    /// The file the model was loaded from, or `"<string>"` (for messages).
    source_name: String,
    /// Every moving joint of the chain, in chain order.
    chain: Vec<Joint>,
    /// The independent ones (the joint vector `q`), in chain order.
    joints: Vec<Joint>,
    /// `None` without coupled joints (then `q` is the chain's values); else one entry per chain
    /// joint.
    pub(crate) sources: Option<Vec<ChainSource>>,
    /// The couplings from the URDF's `<mimic>` elements on the chain.
    urdf_couplings: Vec<JointCoupling>,
    /// The couplings added with [`RobotModel::with_couplings`].
    added_couplings: Vec<JointCoupling>,
    last_from_flange: Isometry3<f64>,
    /// `last_from_flange` for the FK hot path.
    pub(crate) flange: FixedTransform,
    inertials: Vec<LumpedInertial>,
    /// One per chain joint.
    pub(crate) steps: Vec<Step>,
    /// Some chain joint is prismatic (the hot loops take their prismatic-free variant if not).
    pub(crate) prismatic: bool,
    /// `(lower − slack, upper + slack)` ([`check_slack`]) per independent joint, rad or m: the fast
    /// path of `check_q`.
    limits: Vec<(f64, f64)>,
}

/// A joint value within this many radians (or metres) outside a limit is accepted (round-off):
/// above the 8.7e-9 rad by which a joint at its limit, written as degrees with 6 decimals (as the
/// session files are: ±5e-7°), reads back outside it. `handclasp plan` picks poses at joint limits,
/// and with 1e-9 its plans were refused by the session reader (regression test
/// `check_q_accepts_a_limit_written_with_six_decimals_of_a_degree`).
const CHECK_SLACK: f64 = 1e-8;

/// A prismatic joint's reading within this many metres past a limit is accepted as a reading
/// (encoder overshoot at a soft limit), not refused as out of range: FIGAROH's TIAGo reports its
/// torso lift at up to 0.350181 m against the URDF's upper limit of 0.35 m, in every one of its
/// four recordings. Half a millimetre is far below any unit mistake (mm read as m is ×1000).
pub const PRISMATIC_READING_SLACK_M: f64 = 0.5e-3;

/// The slack past joint `j`'s limits that [`RobotModel::check_q`] accepts: [`CHECK_SLACK`], or
/// [`PRISMATIC_READING_SLACK_M`] for a prismatic joint.
fn check_slack(j: &Joint) -> f64 {
    if j.kind.is_prismatic() {
        PRISMATIC_READING_SLACK_M
    } else {
        CHECK_SLACK
    }
}

/// A prismatic joint whose limits reach beyond this many metres is refused as written in
/// millimetres ([`ModelError::LimitsLookLikeMillimetres`]): the longest robot tracks are tens of
/// metres.
pub const MAX_PRISMATIC_TRAVEL_M: f64 = 100.0;

/// A prismatic joint value outside the limits is reported as millimetres written as metres
/// ([`KinematicsError::LooksLikeMillimetres`]) when it lies within the limits once divided by
/// 1000 and exceeds this many times the larger limit's magnitude.
const MM_FOR_M_RATIO: f64 = 10.0;

/// A chain whose joint origins add up to more than this many metres is refused as written in
/// millimetres ([`ModelError::LooksLikeMillimetres`]): the largest industrial arms reach about
/// 4 m, and a millimetre URDF of any arm sums to hundreds or thousands.
pub const MAX_CHAIN_LENGTH_M: f64 = 20.0;

/// The root link name that [`RobotModel::base_link`]'s world rule looks for.
pub const WORLD_LINK: &str = "world";

impl RobotModel {
    /// The same robot with `couplings` declared on top of the URDF's `<mimic>` elements (e.g. the
    /// couplings of a cell file): each named joint's value then follows the others', and it
    /// leaves the joint vector `q` ([`RobotModel::joints`], [`RobotModel::dof`]). Couplings
    /// added before are kept.
    ///
    /// ```
    /// # use kinematics::{base_from_flange, JointCoupling, RobotModel};
    /// let urdf = r#"<robot name="torso">
    ///   <link name="base"/><link name="l1"/><link name="l2"/><link name="tool0"/>
    ///   <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    ///     <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    ///   <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    ///     <origin xyz="0 0 0.5"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    ///   <joint name="j3" type="revolute"><parent link="l2"/><child link="tool0"/>
    ///     <origin xyz="0 0 0.5"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
    /// </robot>"#;
    /// let model = RobotModel::from_urdf_str(urdf, "tool0")?
    ///     .with_couplings(&[JointCoupling {
    ///         joint: "j3".into(),
    ///         terms: vec![("j1".into(), -1.0), ("j2".into(), -1.0)],
    ///         offset: 0.0,
    ///     }])?;
    /// assert_eq!((model.dof(), model.chain_joints().len()), (2, 3));
    /// // j3 = −(j1 + j2) keeps the flange level whatever j1 and j2.
    /// let flange = base_from_flange(&model, &[0.3, -0.7])?;
    /// assert!(flange.rotation.angle() < 1e-15);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// Errors ([`ModelError::BadCoupling`]): a named joint that is not a moving joint of the
    /// chain, a joint coupled twice (also by a URDF `<mimic>`), a non-finite coefficient or
    /// offset, couplings that refer to each other in a loop, or every joint coupled.
    pub fn with_couplings(self, couplings: &[JointCoupling]) -> Result<RobotModel, ModelError> {
        let mut model = self;
        let urdf = std::mem::take(&mut model.urdf_couplings);
        let mut added = std::mem::take(&mut model.added_couplings);
        added.extend_from_slice(couplings);
        model.set_couplings(urdf, added)?;
        Ok(model)
    }

    /// Resolves the URDF's and the added couplings and sets the chain's coupled joints, the
    /// independent joints and the value sources.
    fn set_couplings(
        &mut self,
        urdf: Vec<JointCoupling>,
        added: Vec<JointCoupling>,
    ) -> Result<(), ModelError> {
        let all: Vec<JointCoupling> = urdf.iter().chain(&added).cloned().collect();
        let names: Vec<&str> = self.chain.iter().map(|j| j.name.as_str()).collect();
        let resolved = resolve(&names, &all).map_err(|problem| {
            let source_name = self.source_name.clone();
            let chain = names.join(", ");
            match problem {
                CouplingProblem::NotOnChain { index, missing } if index < urdf.len() => {
                    ModelError::MimicJoint {
                        source_name,
                        joint: urdf[index].joint.clone(),
                        mimicked: missing,
                    }
                }
                CouplingProblem::NotOnChain { index, missing } => ModelError::BadCoupling {
                    source_name,
                    joint: all[index].joint.clone(),
                    problem: format!(
                        "`{missing}` is not a moving joint of the chain to `{}` (the chain's \
                         moving joints: {chain}); name joints of that chain",
                        self.tool_link
                    ),
                },
                CouplingProblem::Duplicate { joint } => ModelError::BadCoupling {
                    source_name,
                    problem: if urdf.iter().any(|c| c.joint == joint) {
                        "the joint already has a <mimic> in the URDF; remove the <mimic> or the \
                         declared coupling"
                            .into()
                    } else {
                        "the joint is coupled twice; declare one coupling per joint".into()
                    },
                    joint,
                },
                CouplingProblem::NotFinite { joint } => ModelError::BadCoupling {
                    source_name,
                    joint,
                    problem: "a coefficient or the offset is not a finite number".into(),
                },
                CouplingProblem::Cycle { joints } => ModelError::BadCoupling {
                    source_name,
                    joint: joints[0].clone(),
                    problem: format!(
                        "the couplings refer to each other in a loop ({}); each coupled joint \
                         must follow joints that do not follow it",
                        joints.join(" → ")
                    ),
                },
                CouplingProblem::AllCoupled => ModelError::BadCoupling {
                    source_name,
                    joint: names.last().copied().unwrap_or_default().to_string(),
                    problem: format!(
                        "every moving joint of the chain ({chain}) would be coupled; leave at \
                         least one independent"
                    ),
                },
            }
        })?;
        let coupled = resolved.iter().any(Option::is_some);
        let mut sources = Vec::with_capacity(self.chain.len());
        let mut joints = Vec::new();
        for (joint, coupling) in self.chain.iter_mut().zip(resolved) {
            match &coupling {
                None => sources.push(ChainSource::Independent(joints.len())),
                Some(c) => sources.push(ChainSource::Coupled(c.clone())),
            }
            joint.coupling = coupling;
            if !joint.is_coupled() {
                joints.push(joint.clone());
            }
        }
        self.limits = joints
            .iter()
            .map(|j| (j.lower - check_slack(j), j.upper + check_slack(j)))
            .collect();
        self.joints = joints;
        self.sources = coupled.then_some(sources);
        self.urdf_couplings = urdf;
        self.added_couplings = added;
        Ok(())
    }

    /// This model with its first `values.len()` independent joints held at `values` (rad, or m
    /// for a prismatic joint): each one's lower and upper limits become its value, so inverse
    /// kinematics ([`crate::ik_tip_position`], which keeps every joint within its limits) moves
    /// only the others. For an arm on a shared trunk: the trunk's joints are drawn once and each
    /// arm is solved with them held. The kinematics are unchanged.
    ///
    /// Errors ([`KinematicsError::InvalidInput`]): more values than independent joints, or a
    /// value that is not finite or lies outside its joint's limits (naming the joint).
    pub fn with_joints_held(&self, values: &[f64]) -> Result<RobotModel, KinematicsError> {
        if values.len() > self.joints.len() {
            return Err(KinematicsError::InvalidInput(format!(
                "cannot hold {} joints of {}: it has {} independent joints",
                values.len(),
                self.name,
                self.joints.len()
            )));
        }
        let mut out = self.clone();
        for (k, &v) in values.iter().enumerate() {
            let j = &out.joints[k];
            if !(v.is_finite() && v >= j.lower && v <= j.upper) {
                return Err(KinematicsError::InvalidInput(format!(
                    "cannot hold joint {} ({}) of {} at {v}: give a finite value within its limits [{}, {}] ({})",
                    k + 1,
                    j.name,
                    self.name,
                    j.lower,
                    j.upper,
                    j.kind.unit_si()
                )));
            }
            let name = j.name.clone();
            for joint in out.joints.iter_mut().chain(out.chain.iter_mut()) {
                if joint.name == name {
                    joint.lower = v;
                    joint.upper = v;
                }
            }
            let slack = check_slack(&out.joints[k]);
            out.limits[k] = (v - slack, v + slack);
        }
        Ok(out)
    }

    /// The URDF robot name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The URDF's root link (the root of the chain to the tool link). It is the base frame
    /// unless the world rule applies (see [`RobotModel::base_link`]).
    pub fn root_link(&self) -> &str {
        &self.root_link
    }

    /// The link whose frame is the robot's base frame: every pose, Jacobian and gravity vector of
    /// this crate is expressed in it.
    ///
    /// The world rule: if the root link is named `world` ([`WORLD_LINK`]) and the first joint
    /// from it toward the tool link is fixed, that joint places the robot in a world frame, and
    /// the base frame is its child link (`base_link` in ROS-Industrial URDFs), not `world`: the
    /// robot's controller reports poses in its own base, and handclasp calibrates where that base
    /// is. The dropped placement is [`RobotModel::root_from_base`]. Otherwise the base is the
    /// root link.
    pub fn base_link(&self) -> &str {
        &self.base_link
    }

    /// `world_from_base`, m and rad, when the world rule of [`RobotModel::base_link`] applied:
    /// the fixed joint's `<origin>` between `world` and the base link. It is reported, not
    /// applied. `None` when the base is the root link.
    pub fn root_from_base(&self) -> Option<&Isometry3<f64>> {
        self.root_from_base.as_ref()
    }

    /// The URDF joints that are not on the chain from the root to the tool link (other branches:
    /// a gripper, a camera mount, ROS-Industrial's `base_link-base`, anything after the tool
    /// link), in file order. They do not enter any computation, and neither do their links'
    /// masses.
    pub fn ignored_joints(&self) -> &[String] {
        &self.ignored_joints
    }

    /// The URDF links that are not on the chain from the root to the tool link, in file order
    /// (see [`RobotModel::ignored_joints`]).
    pub fn ignored_links(&self) -> &[String] {
        &self.ignored_links
    }

    /// The tool (flange) link the model ends at.
    pub fn tool_link(&self) -> &str {
        &self.tool_link
    }

    /// Number of independent joints: the length of the joint vector `q` every function takes
    /// (the moving joints of the chain that are not coupled).
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The independent joints in chain order: `q[i]` is the value of `joints()[i]` (rad, or m
    /// for a prismatic joint, see [`Joint::kind`]). Without coupled joints these are all the
    /// chain's moving joints.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Every moving joint of the chain in chain order, the coupled ones included (each with its
    /// [`Joint::coupling`]). The kinematic-error model ([`crate::KinematicErrors`]) and the
    /// gravity torques ([`crate::gravity_torques`]) have one entry per chain joint.
    pub fn chain_joints(&self) -> &[Joint] {
        &self.chain
    }

    /// True if some chain joint is coupled ([`RobotModel::dof`] is then less than the number of
    /// chain joints).
    pub fn has_coupled_joints(&self) -> bool {
        self.sources.is_some()
    }

    /// True if some chain joint is prismatic (its value in m, not rad).
    pub fn has_prismatic_joints(&self) -> bool {
        self.prismatic
    }

    /// The couplings that hold: the URDF's `<mimic>` elements on the chain, then those added
    /// with [`RobotModel::with_couplings`], as declared.
    pub fn couplings(&self) -> Vec<JointCoupling> {
        self.urdf_couplings
            .iter()
            .chain(&self.added_couplings)
            .cloned()
            .collect()
    }

    /// The couplings added with [`RobotModel::with_couplings`] (not in the URDF), as declared.
    pub fn added_couplings(&self) -> &[JointCoupling] {
        &self.added_couplings
    }

    /// The chain joints' values at the independent joint vector `q` (rad, or m for prismatic
    /// joints): one per [`RobotModel::chain_joints`] entry, the coupled ones computed.
    ///
    /// Errors: a bad `q` ([`RobotModel::check_q`]).
    pub fn chain_values(&self, q: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        self.check_q(q)?;
        let mut out = vec![0.0; self.chain.len()];
        self.chain_values_into(q, &mut out);
        Ok(out)
    }

    /// `∂q_chain/∂q`, the constant (chain joints × [`RobotModel::dof`]) matrix of the couplings:
    /// row k is the unit row of joint k's index in `q` for an independent joint, the coupling's
    /// coefficients for a coupled one. The Jacobians of this crate with respect to `q` are the
    /// chain Jacobians times this matrix.
    pub fn coupling_matrix(&self) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(self.chain.len(), self.dof());
        for k in 0..self.chain.len() {
            self.for_each_dependence(k, |i, c| a[(k, i)] += c);
        }
        a
    }

    /// Calls `f(i, ∂q_chain_k/∂q_i)` for every independent joint `i` that chain joint `k`
    /// depends on.
    #[inline]
    pub(crate) fn for_each_dependence(&self, k: usize, mut f: impl FnMut(usize, f64)) {
        match &self.sources {
            None => f(k, 1.0),
            Some(sources) => match &sources[k] {
                ChainSource::Independent(i) => f(*i, 1.0),
                ChainSource::Coupled(c) => c.terms.iter().for_each(|&(i, x)| f(i, x)),
            },
        }
    }

    /// The chain values at `q` into `out` (len = chain joints); no checks (a missing `q` entry
    /// counts as 0).
    pub(crate) fn chain_values_into(&self, q: &[f64], out: &mut [f64]) {
        match &self.sources {
            None => {
                for (o, k) in out.iter_mut().zip(0..) {
                    *o = q.get(k).copied().unwrap_or(0.0);
                }
            }
            Some(sources) => {
                for (o, source) in out.iter_mut().zip(sources) {
                    *o = match source {
                        ChainSource::Independent(i) => q.get(*i).copied().unwrap_or(0.0),
                        ChainSource::Coupled(c) => c.value(q),
                    };
                }
            }
        }
    }

    /// The chain values at `q`: `q` itself without coupled joints (no copy), else computed into
    /// `buf` (which then allocates). No checks. Used as
    /// `let mut buf = Vec::new(); let q_chain = model.chain_q(q, &mut buf);`, so the hot paths of
    /// chains without couplings stay as they were (no closure, no copy).
    #[inline(always)]
    pub(crate) fn chain_q<'a>(&self, q: &'a [f64], buf: &'a mut Vec<f64>) -> &'a [f64] {
        if self.sources.is_none() {
            return q;
        }
        self.chain_q_coupled(q, buf)
    }

    /// [`RobotModel::chain_q`] of a chain with coupled joints.
    #[cold]
    #[inline(never)]
    fn chain_q_coupled<'a>(&self, q: &[f64], buf: &'a mut Vec<f64>) -> &'a [f64] {
        buf.clear();
        buf.resize(self.chain.len(), 0.0);
        self.chain_values_into(q, buf);
        buf
    }

    /// Fixed joints after the last actuated joint's frame up to the tool link: `last_from_flange`.
    pub fn last_from_flange(&self) -> &Isometry3<f64> {
        &self.last_from_flange
    }

    /// One lumped inertial per chain joint k ([`RobotModel::chain_joints`]): mass (kg) and COM
    /// (m, in joint k's frame after its motion) of the links rigidly carried by joint k up to
    /// joint k+1; the last one includes everything up to the tool link.
    pub fn inertials(&self) -> &[LumpedInertial] {
        &self.inertials
    }

    /// Checks a joint vector (the independent joints, rad or m for prismatic ones): length,
    /// finiteness, plainly-degrees values (revolute joints), plainly-millimetre values (prismatic
    /// joints), joint limits. A value within 1e-8 rad (or m) outside a limit is accepted
    /// (round-off, including 6 decimals of a degree in a file). A coupled joint's value is not limit-checked.
    pub fn check_q(&self, q: &[f64]) -> Result<(), KinematicsError> {
        // One branch-free pass for the common case; the error is worked out only on failure.
        let ok = q.len() == self.limits.len()
            && q.iter()
                .zip(&self.limits)
                .fold(true, |ok, (&v, &(lo, hi))| {
                    ok & v.is_finite() & (v >= lo) & (v <= hi)
                });
        if ok {
            return Ok(());
        }
        self.check_q_error(q)
    }

    /// The error for a joint vector that failed the fast check (`Ok` if there is none).
    #[cold]
    pub(crate) fn check_q_error(&self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() != self.joints.len() {
            if self.has_coupled_joints() {
                return Err(KinematicsError::WrongLengthCoupled {
                    robot: self.name.clone(),
                    expected: self.joints.len(),
                    got: q.len(),
                    coupled: self
                        .chain
                        .iter()
                        .filter(|j| j.is_coupled())
                        .map(|j| j.name.clone())
                        .collect::<Vec<_>>()
                        .join(", "),
                });
            }
            return Err(KinematicsError::WrongLength {
                robot: self.name.clone(),
                expected: self.joints.len(),
                got: q.len(),
            });
        }
        for (i, (j, &v)) in self.joints.iter().zip(q).enumerate() {
            if !v.is_finite() {
                return Err(KinematicsError::NotFinite {
                    index: i + 1,
                    joint: j.name.clone(),
                    value: v,
                });
            }
            let outside = v < j.lower - check_slack(j) || v > j.upper + check_slack(j);
            if outside && j.kind.is_prismatic() {
                let (lower_mm, upper_mm) = (j.lower * 1e3, j.upper * 1e3);
                let as_m = v * 1e-3;
                if as_m >= j.lower - CHECK_SLACK
                    && as_m <= j.upper + CHECK_SLACK
                    && v.abs() > MM_FOR_M_RATIO * j.lower.abs().max(j.upper.abs())
                {
                    return Err(KinematicsError::LooksLikeMillimetres {
                        index: i + 1,
                        joint: j.name.clone(),
                        value: v,
                        lower_mm,
                        upper_mm,
                    });
                }
                return Err(KinematicsError::OutOfLinearLimits {
                    index: i + 1,
                    joint: j.name.clone(),
                    value_mm: v * 1e3,
                    lower_mm,
                    upper_mm,
                });
            }
            if outside {
                let lower_deg = j.lower.to_degrees();
                let upper_deg = j.upper.to_degrees();
                if v.abs() > std::f64::consts::TAU && v >= lower_deg && v <= upper_deg {
                    return Err(KinematicsError::LooksLikeDegrees {
                        index: i + 1,
                        joint: j.name.clone(),
                        value: v,
                        lower_deg,
                        upper_deg,
                    });
                }
                return Err(KinematicsError::OutOfLimits {
                    index: i + 1,
                    joint: j.name.clone(),
                    value_deg: v.to_degrees(),
                    lower_deg,
                    upper_deg,
                });
            }
        }
        Ok(())
    }
}

fn classify_axis(axis: &Unit<Vector3<f64>>) -> (u8, f64) {
    for k in 0..3 {
        let others_zero = (0..3).filter(|&i| i != k).all(|i| axis[i] == 0.0);
        if others_zero && axis[k].abs() == 1.0 {
            return (k as u8, axis[k].signum());
        }
    }
    (3, 1.0)
}
