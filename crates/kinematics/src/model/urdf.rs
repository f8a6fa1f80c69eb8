//! URDF → [`RobotModel`]: reading the file or text with urdf-rs, finding the chain from the root
//! to the tool link, checking joint types, axes, limits and units, lumping fixed joints and
//! inertials, and the URDF's `<mimic>` couplings. Errors ([`ModelError`]) name the file (or
//! `<string>`), the joint or link, and the fix.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Unit, Vector3};

use super::{
    origin_isometry, FixedTransform, Joint, JointKind, LumpedInertial, RobotModel, Step,
    MAX_CHAIN_LENGTH_M, MAX_PRISMATIC_TRAVEL_M, PRISMATIC, WORLD_LINK,
};
use crate::coupling::JointCoupling;
use crate::error::ModelError;

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

/// Checks a moving joint's limits as read from the URDF.
fn check_limits(
    kind: JointKind,
    lower: f64,
    upper: f64,
    joint: &str,
    src: &str,
) -> Result<(), ModelError> {
    if kind == JointKind::Prismatic {
        if !(lower.is_finite() && upper.is_finite() && lower < upper) {
            return Err(ModelError::BadLinearLimits {
                source_name: src.to_string(),
                joint: joint.to_string(),
                lower,
                upper,
            });
        }
        if lower.abs().max(upper.abs()) > MAX_PRISMATIC_TRAVEL_M {
            return Err(ModelError::LimitsLookLikeMillimetres {
                source_name: src.to_string(),
                joint: joint.to_string(),
                lower,
                upper,
            });
        }
        return Ok(());
    }
    let revolute = kind == JointKind::Revolute;
    // A revolute joint needs a real range: lower == upper is what urdf-rs gives for a missing
    // <limit>.
    if lower.is_nan()
        || upper.is_nan()
        || lower > upper
        || (revolute && (!(lower.is_finite() && upper.is_finite()) || lower == upper))
    {
        return Err(ModelError::BadLimits {
            source_name: src.to_string(),
            joint: joint.to_string(),
            lower,
            upper,
        });
    }
    // Beyond ±2 turns the numbers are almost surely degrees.
    if revolute && lower.abs().max(upper.abs()) > 2.0 * std::f64::consts::TAU {
        return Err(ModelError::LimitsLookLikeDegrees {
            source_name: src.to_string(),
            joint: joint.to_string(),
            lower,
            upper,
        });
    }
    Ok(())
}

/// True when `xml` still holds xacro markup: a `<xacro:…>` element, or `${…}` / `$(…)`
/// substitutions in a file that declares the xacro namespace. A leftover `xmlns:xacro`
/// attribute alone is not xacro: `xacro` keeps it on `<robot>` in the URDFs it writes, and those
/// are plain URDF.
fn is_unexpanded_xacro(xml: &str) -> bool {
    xml.contains("<xacro:")
        || (xml.contains("xmlns:xacro") && (xml.contains("${") || xml.contains("$(")))
}

impl RobotModel {
    /// Loads a URDF file; `tool_link` is the flange link (usually `tool0`). The chain's moving
    /// joints may be revolute, continuous or prismatic; a `<mimic>` joint on the chain is a
    /// coupled joint (its mimicked joint must be on the chain too). More couplings can be added
    /// with [`RobotModel::with_couplings`].
    ///
    /// Errors: unreadable file, invalid URDF, missing link, branching tree, unsupported joint type,
    /// zero axis, bad limits, a `<mimic>` of a joint off the chain ([`ModelError`]); messages name
    /// the file.
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
        let xml = crate::input::read_input_text(path, "URDF").map_err(|e| match e {
            crate::input::InputError::Io { path, source } => ModelError::Io { path, source },
            other => ModelError::Input(other),
        })?;
        Self::build(&xml, tool_link, &path.display().to_string())
    }

    /// Loads a URDF from its XML text; see [`RobotModel::from_urdf_file`].
    pub fn from_urdf_str(xml: &str, tool_link: &str) -> Result<RobotModel, ModelError> {
        Self::build(xml, tool_link, "<string>")
    }

    fn build(xml: &str, tool_link: &str, src: &str) -> Result<RobotModel, ModelError> {
        if is_unexpanded_xacro(xml) {
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
        // The URDF's <mimic> elements on the chain (resolved after the joints are read).
        let urdf_couplings: Vec<JointCoupling> = path
            .iter()
            .filter_map(|j| {
                j.mimic.as_ref().map(|m| {
                    JointCoupling::mimic(
                        &j.name,
                        &m.joint,
                        m.multiplier.unwrap_or(1.0),
                        m.offset.unwrap_or(0.0),
                    )
                })
            })
            .collect();

        let mut chain = Vec::new();
        let mut steps = Vec::new();
        // For the inertials: the links carried by each moving joint, with joint_from_link.
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
            let kind = match j.joint_type {
                urdf_rs::JointType::Fixed => {
                    pending *= origin;
                    if let Some(c) = carried.last_mut() {
                        c.push((pending, child));
                    }
                    continue;
                }
                urdf_rs::JointType::Revolute => JointKind::Revolute,
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                ref other => {
                    return Err(ModelError::UnsupportedJoint {
                        source_name: s(),
                        joint: j.name.clone(),
                        kind: type_name(other).to_string(),
                    })
                }
            };
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
            let (lower, upper) = if kind == JointKind::Continuous {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                (j.limit.lower, j.limit.upper)
            };
            // A coupled joint's limits are not used (its value follows the others').
            if j.mimic.is_none() {
                check_limits(kind, lower, upper, &j.name, src)?;
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
                kind.is_prismatic(),
            ));
            chain.push(Joint {
                name: j.name.clone(),
                kind,
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
                coupling: None,
            });
            pending = Isometry3::identity();
            carried.push(vec![(pending, child)]);
        }
        if chain.is_empty() {
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
        let mut model = RobotModel {
            name: robot.name.clone(),
            root_link,
            base_link,
            root_from_base,
            tool_link: tool_link.to_string(),
            ignored_joints,
            ignored_links,
            source_name: s(),
            joints: Vec::new(),
            chain,
            sources: None,
            urdf_couplings: Vec::new(),
            added_couplings: Vec::new(),
            last_from_flange: pending,
            flange: FixedTransform::new(
                *pending.rotation.to_rotation_matrix().matrix(),
                pending.translation.vector,
            ),
            inertials,
            prismatic: steps.iter().any(|s| s.axis_kind == PRISMATIC),
            steps,
            limits: Vec::new(),
        };
        model.set_couplings(urdf_couplings, Vec::new())?;
        Ok(model)
    }
}
