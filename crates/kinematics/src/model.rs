//! Serial-chain robot model loaded from a URDF.
//!
//! Frames: `base` is the URDF root link; the flange is the requested tool link (`tool0`).
//! `base_from_flange(q) = Π_k [fixed_prefix_k · Origin(xyz_k, rpy_k) · Rot(axis_k, q_k)] · last_from_flange`,
//! with `Origin` rotation `Rz(yaw)·Ry(pitch)·Rx(roll)` (URDF). Lengths in metres, angles in radians.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};

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

/// One actuated (revolute or continuous) joint of the chain.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// URDF joint name.
    pub name: String,
    /// URDF parent link.
    pub parent_link: String,
    /// URDF child link.
    pub child_link: String,
    /// Fixed joints between the previous actuated joint's frame and this joint's URDF parent link
    /// (identity if none; also holds any fixed joints before the first actuated joint).
    pub fixed_prefix: Isometry3<f64>,
    /// URDF `<origin xyz>`, m, in the parent link frame.
    pub origin_xyz: Vector3<f64>,
    /// URDF `<origin rpy>`, rad (`Rz(yaw)·Ry(pitch)·Rx(roll)`).
    pub origin_rpy: Vector3<f64>,
    /// Rotation axis, unit, in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Lower limit, rad (`-inf` for continuous joints).
    pub lower: f64,
    /// Upper limit, rad (`+inf` for continuous joints).
    pub upper: f64,
    /// Velocity limit, rad/s.
    pub velocity: f64,
    /// Effort limit, N·m.
    pub effort: f64,
}

/// Mass and centre of mass of everything rigidly carried by one actuated joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LumpedInertial {
    /// Mass, kg.
    pub mass: f64,
    /// Centre of mass, m, in the joint's frame after its rotation (zero if `mass == 0`).
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
        let nonzero: Vec<usize> = (0..3).filter(|&i| t[i] != 0.0).collect();
        let t_kind = match nonzero[..] {
            [] => 3,
            [k] => k as u8,
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
    /// 0, 1, 2 if the axis is ±x, ±y, ±z exactly; 3 otherwise.
    pub(crate) axis_kind: u8,
    /// Sign of the axis when `axis_kind < 3`.
    pub(crate) axis_sign: f64,
    /// `prev_from_joint = fixed_prefix · Origin(xyz, rpy)`.
    pub(crate) origin: FixedTransform,
    /// `3·t_kind + axis_kind` (0–8) when the origin has no rotation, its translation a single
    /// non-zero component and the axis is a coordinate axis: the FK loop's one-dispatch case;
    /// 9 otherwise.
    pub(crate) fast_kind: u8,
}

impl Step {
    /// The step for a joint with axis `axis` and `prev_from_joint = (origin_r, origin_t)`.
    pub(crate) fn new(
        axis: Unit<Vector3<f64>>,
        origin_r: Matrix3<f64>,
        origin_t: Vector3<f64>,
    ) -> Step {
        let (axis_kind, axis_sign) = classify_axis(&axis);
        let origin = FixedTransform::new(origin_r, origin_t);
        let fast_kind = if origin.r_kind == 3 && origin.t_kind < 3 && axis_kind < 3 {
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

/// A serial robot arm from a URDF: the actuated joints from the root link to a tool link.
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
    joints: Vec<Joint>,
    last_from_flange: Isometry3<f64>,
    /// `last_from_flange` for the FK hot path.
    pub(crate) flange: FixedTransform,
    inertials: Vec<LumpedInertial>,
    pub(crate) steps: Vec<Step>,
    /// `(lower − CHECK_SLACK, upper + CHECK_SLACK)` per joint, rad: the fast path of `check_q`.
    limits: Vec<(f64, f64)>,
}

/// A joint value within this many radians outside a limit is accepted (round-off).
const CHECK_SLACK: f64 = 1e-9;

/// A chain whose joint origins add up to more than this many metres is refused as written in
/// millimetres ([`ModelError::LooksLikeMillimetres`]): the largest industrial arms reach about
/// 4 m, and a millimetre URDF of any arm sums to hundreds or thousands.
pub const MAX_CHAIN_LENGTH_M: f64 = 20.0;

/// The root link name that [`RobotModel::base_link`]'s world rule looks for.
pub const WORLD_LINK: &str = "world";

fn vec3(v: &urdf_rs::Vec3) -> Vector3<f64> {
    Vector3::new(v[0], v[1], v[2])
}

fn type_name(t: &urdf_rs::JointType) -> &'static str {
    match t {
        urdf_rs::JointType::Revolute => "revolute",
        urdf_rs::JointType::Continuous => "continuous",
        urdf_rs::JointType::Prismatic => "prismatic",
        urdf_rs::JointType::Fixed => "fixed",
        urdf_rs::JointType::Floating => "floating",
        urdf_rs::JointType::Planar => "planar",
        urdf_rs::JointType::Spherical => "spherical",
    }
}

impl RobotModel {
    /// Loads a URDF file; `tool_link` is the flange link (usually `tool0`).
    ///
    /// Errors: unreadable file, invalid URDF, missing link, branching tree, unsupported joint type,
    /// zero axis, bad limits ([`ModelError`]); messages name the file.
    pub fn from_urdf_file(path: &Path, tool_link: &str) -> Result<RobotModel, ModelError> {
        let is_xacro = path
            .file_name()
            .and_then(|f| f.to_str())
            .is_some_and(|f| f.to_ascii_lowercase().ends_with(".xacro"));
        if is_xacro {
            return Err(ModelError::Xacro {
                source_name: path.display().to_string(),
            });
        }
        let xml = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::build(&xml, tool_link, &path.display().to_string())
    }

    /// Loads a URDF from its XML text; see [`RobotModel::from_urdf_file`].
    pub fn from_urdf_str(xml: &str, tool_link: &str) -> Result<RobotModel, ModelError> {
        Self::build(xml, tool_link, "<string>")
    }

    fn build(xml: &str, tool_link: &str, src: &str) -> Result<RobotModel, ModelError> {
        if xml.contains("xmlns:xacro") {
            return Err(ModelError::Xacro {
                source_name: src.to_string(),
            });
        }
        let robot = urdf_rs::read_from_string(xml).map_err(|e| ModelError::Parse {
            source_name: src.to_string(),
            message: e.to_string(),
        })?;
        let s = || src.to_string();
        let links: HashMap<&str, &urdf_rs::Link> =
            robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
        let known = || {
            let mut v: Vec<&str> = robot.links.iter().map(|l| l.name.as_str()).collect();
            v.sort_unstable();
            v.join(", ")
        };
        // Parent joint of each link, children of each link.
        let mut parent_of: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
        for j in &robot.joints {
            for l in [&j.parent.link, &j.child.link] {
                if !links.contains_key(l.as_str()) {
                    return Err(ModelError::MissingLink {
                        source_name: s(),
                        link: l.clone(),
                        known: known(),
                    });
                }
            }
            if parent_of.insert(j.child.link.as_str(), j).is_some() {
                return Err(ModelError::NotATree {
                    source_name: s(),
                    link: j.child.link.clone(),
                });
            }
        }
        if !links.contains_key(tool_link) {
            return Err(ModelError::MissingLink {
                source_name: s(),
                link: tool_link.to_string(),
                known: known(),
            });
        }
        // Walk from the tool link up to the root.
        let mut path: Vec<&urdf_rs::Joint> = Vec::new();
        let mut cur = tool_link;
        while let Some(j) = parent_of.get(cur) {
            if path.len() > robot.joints.len() {
                return Err(ModelError::NotATree {
                    source_name: s(),
                    link: cur.to_string(),
                });
            }
            path.push(j);
            cur = j.parent.link.as_str();
        }
        let root_link = cur.to_string();
        path.reverse();
        // The world rule: a `world` root fixed to the arm is not the arm's base frame.
        let mut world_joint = None;
        if root_link == WORLD_LINK
            && path
                .first()
                .is_some_and(|j| matches!(j.joint_type, urdf_rs::JointType::Fixed))
        {
            world_joint = Some(path.remove(0));
        }
        let base_link = world_joint.map_or_else(|| root_link.clone(), |j| j.child.link.clone());
        let root_from_base =
            world_joint.map(|j| origin_isometry(&vec3(&j.origin.xyz), &vec3(&j.origin.rpy)));
        let on_chain: HashSet<&str> = path
            .iter()
            .chain(world_joint.iter())
            .map(|j| j.name.as_str())
            .collect();
        let chain_links: HashSet<&str> = std::iter::once(root_link.as_str())
            .chain(path.iter().map(|j| j.child.link.as_str()))
            .chain(std::iter::once(base_link.as_str()))
            .collect();
        let ignored_joints: Vec<String> = robot
            .joints
            .iter()
            .filter(|j| !on_chain.contains(j.name.as_str()))
            .map(|j| j.name.clone())
            .collect();
        let ignored_links: Vec<String> = robot
            .links
            .iter()
            .filter(|l| !chain_links.contains(l.name.as_str()))
            .map(|l| l.name.clone())
            .collect();
        for j in &path {
            if let Some(m) = &j.mimic {
                return Err(ModelError::MimicJoint {
                    source_name: s(),
                    joint: j.name.clone(),
                    mimicked: m.joint.clone(),
                });
            }
        }

        let mut joints = Vec::new();
        let mut steps = Vec::new();
        // For the inertials: the links carried by each actuated joint, with joint_from_link.
        let mut carried: Vec<Vec<(Isometry3<f64>, &urdf_rs::Link)>> = Vec::new();
        let mut pending = Isometry3::identity();
        for j in &path {
            let xyz = vec3(&j.origin.xyz);
            let rpy = vec3(&j.origin.rpy);
            if !(xyz.iter().chain(rpy.iter()).all(|v| v.is_finite())) {
                return Err(ModelError::BadOrigin {
                    source_name: s(),
                    joint: j.name.clone(),
                });
            }
            let origin = origin_isometry(&xyz, &rpy);
            let child = links[j.child.link.as_str()];
            match j.joint_type {
                urdf_rs::JointType::Fixed => {
                    pending *= origin;
                    if let Some(c) = carried.last_mut() {
                        c.push((pending, child));
                    }
                }
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                    let a = vec3(&j.axis.xyz);
                    let n = a.norm();
                    if !n.is_finite() || n < 1e-12 {
                        return Err(ModelError::ZeroAxis {
                            source_name: s(),
                            joint: j.name.clone(),
                            axis: [a.x, a.y, a.z],
                        });
                    }
                    let axis = Unit::new_normalize(a);
                    let (lower, upper) = if matches!(j.joint_type, urdf_rs::JointType::Continuous) {
                        (f64::NEG_INFINITY, f64::INFINITY)
                    } else {
                        (j.limit.lower, j.limit.upper)
                    };
                    let revolute = matches!(j.joint_type, urdf_rs::JointType::Revolute);
                    // A revolute joint needs a real range: lower == upper is what urdf-rs gives
                    // for a missing <limit>.
                    if lower.is_nan()
                        || upper.is_nan()
                        || lower > upper
                        || (revolute
                            && (!(lower.is_finite() && upper.is_finite()) || lower == upper))
                    {
                        return Err(ModelError::BadLimits {
                            source_name: s(),
                            joint: j.name.clone(),
                            lower,
                            upper,
                        });
                    }
                    // Beyond ±2 turns the numbers are almost surely degrees.
                    if revolute && lower.abs().max(upper.abs()) > 2.0 * std::f64::consts::TAU {
                        return Err(ModelError::LimitsLookLikeDegrees {
                            source_name: s(),
                            joint: j.name.clone(),
                            lower,
                            upper,
                        });
                    }
                    let prev_from_joint = pending * origin;
                    let origin_r = if rpy == Vector3::zeros() && pending.rotation.w == 1.0 {
                        Matrix3::identity()
                    } else {
                        *prev_from_joint.rotation.to_rotation_matrix().matrix()
                    };
                    steps.push(Step::new(
                        axis,
                        origin_r,
                        prev_from_joint.translation.vector,
                    ));
                    joints.push(Joint {
                        name: j.name.clone(),
                        parent_link: j.parent.link.clone(),
                        child_link: j.child.link.clone(),
                        fixed_prefix: pending,
                        origin_xyz: xyz,
                        origin_rpy: rpy,
                        axis,
                        lower,
                        upper,
                        velocity: j.limit.velocity,
                        effort: j.limit.effort,
                    });
                    pending = Isometry3::identity();
                    carried.push(vec![(pending, child)]);
                }
                urdf_rs::JointType::Prismatic => {
                    return Err(ModelError::PrismaticJoint {
                        source_name: s(),
                        joint: j.name.clone(),
                    })
                }
                ref other => {
                    return Err(ModelError::UnsupportedJoint {
                        source_name: s(),
                        joint: j.name.clone(),
                        kind: type_name(other).to_string(),
                    })
                }
            }
        }
        if joints.is_empty() {
            return Err(ModelError::NoActuatedJoints {
                source_name: s(),
                tool_link: tool_link.to_string(),
            });
        }
        // Millimetres: the joint origins of any arm in metres sum to a few metres.
        let length: f64 = path.iter().map(|j| vec3(&j.origin.xyz).norm()).sum();
        if length > MAX_CHAIN_LENGTH_M {
            let longest = path
                .iter()
                .max_by(|a, b| {
                    vec3(&a.origin.xyz)
                        .norm()
                        .total_cmp(&vec3(&b.origin.xyz).norm())
                })
                .expect("a chain longer than 20 m has joints");
            return Err(ModelError::LooksLikeMillimetres {
                source_name: s(),
                joint: longest.name.clone(),
                origin: vec3(&longest.origin.xyz).norm(),
                length,
            });
        }
        let inertials = carried
            .iter()
            .map(|c| {
                let mut mass = 0.0;
                let mut moment = Vector3::zeros();
                for (joint_from_link, link) in c {
                    let m = link.inertial.mass.value;
                    if m > 0.0 && m.is_finite() {
                        let com_link = vec3(&link.inertial.origin.xyz);
                        mass += m;
                        moment += m * (joint_from_link * nalgebra::Point3::from(com_link)).coords;
                    }
                }
                LumpedInertial {
                    mass,
                    com: if mass > 0.0 {
                        moment / mass
                    } else {
                        Vector3::zeros()
                    },
                }
            })
            .collect();
        Ok(RobotModel {
            name: robot.name.clone(),
            root_link,
            base_link,
            root_from_base,
            tool_link: tool_link.to_string(),
            ignored_joints,
            ignored_links,
            last_from_flange: pending,
            flange: FixedTransform::new(
                *pending.rotation.to_rotation_matrix().matrix(),
                pending.translation.vector,
            ),
            inertials,
            steps,
            limits: joints
                .iter()
                .map(|j| (j.lower - CHECK_SLACK, j.upper + CHECK_SLACK))
                .collect(),
            joints,
        })
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

    /// Number of actuated joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Actuated joints in chain order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Fixed joints after the last actuated joint's frame up to the tool link: `last_from_flange`.
    pub fn last_from_flange(&self) -> &Isometry3<f64> {
        &self.last_from_flange
    }

    /// One lumped inertial per actuated joint k: mass (kg) and COM (m, in joint k's frame after its
    /// rotation) of the links rigidly carried by joint k up to joint k+1; the last one includes
    /// everything up to the tool link.
    pub fn inertials(&self) -> &[LumpedInertial] {
        &self.inertials
    }

    /// Checks a joint vector (rad): length, finiteness, plainly-degrees values, joint limits.
    /// A value within 1e-9 rad outside a limit is accepted (round-off).
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
            if v < j.lower - CHECK_SLACK || v > j.upper + CHECK_SLACK {
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
