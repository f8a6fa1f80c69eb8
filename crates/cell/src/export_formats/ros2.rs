//! ROS 2: a cell URDF with both robots under a `world` link at robot 1's base, the placement as
//! xacro properties, and a launch file for tf2's `static_transform_publisher`.
//!
//! Conventions, checked against:
//! - tf2 and `geometry_msgs/Transform`: translation in metres, unit quaternion (Hamilton) listed
//!   `x, y, z, w`; either sign is the same rotation, this export writes `w ≥ 0`
//!   ([`kinematics::quaternion_wxyz`]).
//! - `static_transform_publisher` (`ros2/geometry2`, `tf2_ros/src/static_transform_broadcaster_program.cpp`):
//!   the flag form `--x --y --z --qx --qy --qz --qw --frame-id --child-frame-id` (metres; the
//!   published transform is `frame_id_from_child`, here robot 1's base → robot 2's base). The
//!   flags arrived in Humble (ros2_documentation PR #2015, "release note for the
//!   static_transform_publisher args", 2021-10); Humble and Jazzy still take the positional
//!   `x y z qx qy qz qw frame child` with the warning "Old-style arguments are deprecated", and
//!   Rolling has dropped them (`ros2/geometry2` PR #790, cited by moveit2_tutorials PR #1122: the
//!   positional form now fails with "Frame id must not be empty"). So the launch file uses the
//!   flags; Foxy and Galactic (end of life) take only the positional form (the guide gives it).
//! - URDF `<origin xyz rpy>`: metres and radians, `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (URDF XML
//!   specification, joint `origin`; the golden test of [`kinematics::rotation_from_rpy`]), the
//!   same Z-Y-X decomposition as KUKA ([`kinematics::zyx_from_rotation`] gives `[yaw, pitch, roll]`).
//!   xacro properties are `<xacro:property name="…" value="…"/>` in a file with
//!   `xmlns:xacro="http://www.ros.org/wiki/xacro"`.
//!
//! The cell URDF (`cell.urdf`) holds each robot's URDF as the cell names it (a cell written by
//! `calibrate --cell --export` or `diagnose --export` names its corrected URDFs, so the calibrated
//! joint origins come along), every link, joint and material prefixed `robot1_` / `robot2_`, a
//! root link `world` (= robot 1's base), fixed joints `robot1_mount` (identity) and `robot2_mount`
//! (`b1_from_b2`), and a `robotN_tip` link at the cell's tip offset on the tool link. A robot URDF
//! rooted at its own `world` link loses that link (the cell's placement replaces it); other
//! children of it move to the robot's base link. Mesh files given by a relative path become
//! `file://` absolute paths. urdf-rs keeps links, joints and materials; `<transmission>` and
//! `<gazebo>` elements of the robot URDFs are not carried (named in the file's comment).

use std::path::Path;

use calib_core::Robot;
use kinematics::{base_from_flange, zyx_from_rotation, RobotModel, WORLD_LINK};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{metres, number, robots_in_world, unit, Deviation, Header, Ros2Transform};
use crate::cell::Cell;
use crate::error::FormatError;

/// The cell URDF's file name.
pub const URDF_FILE: &str = "cell.urdf";
/// The xacro properties' file name.
pub const XACRO_FILE: &str = "b1_from_b2.xacro";
/// The launch file's name (ROS 2 XML launch format).
pub const LAUNCH_FILE: &str = "b1_from_b2.launch.xml";

/// Prefix of robot `which`'s links, joints and materials in the cell URDF.
pub fn prefix(which: Robot) -> &'static str {
    match which {
        Robot::One => "robot1_",
        Robot::Two => "robot2_",
    }
}

/// The cell URDF's name of robot `which`'s base link (e.g. `robot2_base_link`): the launch
/// file's default frames.
pub fn base_frame(cell: &Cell, which: Robot) -> String {
    format!("{}{}", prefix(which), cell.robot(which).model.base_link())
}

fn pose(iso: &Isometry3<f64>) -> urdf_rs::Pose {
    let t = iso.translation.vector;
    let [yaw, pitch, roll] = zyx_from_rotation(&iso.rotation.to_rotation_matrix());
    // `+ 0.0` turns −0.0 into 0.0 (printed `-0` otherwise).
    urdf_rs::Pose {
        xyz: urdf_rs::Vec3([t.x + 0.0, t.y + 0.0, t.z + 0.0]),
        rpy: urdf_rs::Vec3([roll + 0.0, pitch + 0.0, yaw + 0.0]),
    }
}

fn iso(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    kinematics::origin_isometry(&Vector3::from(pose.xyz.0), &Vector3::from(pose.rpy.0))
}

fn fixed_joint(
    name: String,
    parent: String,
    child: String,
    origin: urdf_rs::Pose,
) -> urdf_rs::Joint {
    urdf_rs::Joint {
        name,
        joint_type: urdf_rs::JointType::Fixed,
        origin,
        parent: urdf_rs::LinkName { link: parent },
        child: urdf_rs::LinkName { link: child },
        axis: urdf_rs::Axis::default(),
        limit: urdf_rs::JointLimit::default(),
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    }
}

fn empty_link(name: String) -> urdf_rs::Link {
    urdf_rs::Link {
        name,
        inertial: urdf_rs::Inertial::default(),
        visual: Vec::new(),
        collision: Vec::new(),
    }
}

/// A mesh file name as the cell URDF writes it: `package://`, `file://` and other URLs unchanged,
/// a relative path made absolute against the robot URDF's folder (`file://`).
fn mesh_filename(name: &str, urdf_dir: &Path) -> String {
    if name.contains("://") || Path::new(name).is_absolute() {
        name.to_string()
    } else {
        format!("file://{}", urdf_dir.join(name).display())
    }
}

fn prefix_geometry(g: &mut urdf_rs::Geometry, urdf_dir: &Path) {
    if let urdf_rs::Geometry::Mesh { filename, .. } = g {
        *filename = mesh_filename(filename, urdf_dir);
    }
}

/// The cell URDF text (see the module documentation), with an opening comment.
///
/// Errors: a robot URDF that cannot be read or parsed ([`FormatError::Cell`] naming the robot and
/// file), or whose cell-URDF form cannot be written.
pub(crate) fn cell_urdf(cell: &Cell, header: &Header<'_>) -> Result<String, FormatError> {
    let mut out = urdf_rs::Robot {
        name: "handclasp_cell".to_string(),
        links: vec![empty_link(WORLD_LINK.to_string())],
        joints: Vec::new(),
        materials: Vec::new(),
    };
    for (which, world_from_base) in robots_in_world(cell) {
        let setup = cell.robot(which);
        let p = prefix(which);
        let bad = |message: String| FormatError::Cell {
            path: setup.urdf_path.clone(),
            message: format!("{which}: building the cell URDF: {message}"),
        };
        let xml = kinematics::input::read_input_text(&setup.urdf_path, "URDF")
            .map_err(FormatError::input)?;
        let mut robot = urdf_rs::read_from_string(&xml).map_err(|e| bad(e.to_string()))?;
        let urdf_dir = setup
            .urdf_path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        let model = &setup.model;
        let base = model.base_link().to_string();
        // The world rule: drop the robot's own `world` root; its other children move to the base.
        if let Some(root_from_base) = model.root_from_base() {
            let root = model.root_link().to_string();
            let base_from_root = root_from_base.inverse();
            robot.links.retain(|l| l.name != root);
            robot
                .joints
                .retain(|j| !(j.parent.link == root && j.child.link == base));
            for j in &mut robot.joints {
                if j.parent.link == root {
                    j.parent.link = base.clone();
                    j.origin = pose(&(base_from_root * iso(&j.origin)));
                }
            }
        }
        let material_names: Vec<String> = robot.materials.iter().map(|m| m.name.clone()).collect();
        let rename_material = |m: &mut urdf_rs::Material| {
            // A visual's material that names a top-level material refers to it; an inline one
            // is renamed too so two robots never define one name twice.
            if !m.name.is_empty() && (material_names.contains(&m.name) || m.color.is_some()) {
                m.name = format!("{p}{}", m.name);
            }
        };
        for m in &mut robot.materials {
            m.name = format!("{p}{}", m.name);
        }
        for l in &mut robot.links {
            l.name = format!("{p}{}", l.name);
            for v in &mut l.visual {
                prefix_geometry(&mut v.geometry, &urdf_dir);
                if let Some(m) = &mut v.material {
                    rename_material(m);
                }
            }
            for c in &mut l.collision {
                prefix_geometry(&mut c.geometry, &urdf_dir);
            }
        }
        for j in &mut robot.joints {
            j.name = format!("{p}{}", j.name);
            j.parent.link = format!("{p}{}", j.parent.link);
            j.child.link = format!("{p}{}", j.child.link);
            if let Some(m) = &mut j.mimic {
                m.joint = format!("{p}{}", m.joint);
            }
        }
        out.joints.push(fixed_joint(
            format!("{p}mount"),
            WORLD_LINK.to_string(),
            format!("{p}{base}"),
            pose(&world_from_base),
        ));
        out.links.append(&mut robot.links);
        out.joints.append(&mut robot.joints);
        out.materials.append(&mut robot.materials);
        // The tip (the cell's tool 0) on the flange.
        let tip = Isometry3::from_parts(
            Translation3::from(setup.flange_from_tip),
            UnitQuaternion::identity(),
        );
        out.links.push(empty_link(format!("{p}tip")));
        out.joints.push(fixed_joint(
            format!("{p}tip_joint"),
            format!("{p}{}", setup.tool_link),
            format!("{p}tip"),
            pose(&tip),
        ));
    }
    let body = urdf_rs::write_to_string(&out).map_err(|e| FormatError::Cell {
        path: cell.base_dir.clone(),
        message: format!("cannot write the cell URDF: {e}"),
    })?;
    let body = tidy_urdf(&body);
    let comment = header
        .lines(
            "",
            &[
                "Convention: URDF, metres and radians, <origin rpy> R = Rz(yaw)*Ry(pitch)*Rx(roll). Root link `world` = robot 1's",
                "base; fixed joints robot1_mount (identity) and robot2_mount (b1_from_b2) carry each robot's URDF as the cell",
                "names it, every link/joint/material prefixed robot1_ / robot2_; robotN_tip is the cell's tip on the flange.",
                "Only links, joints and materials of the robot URDFs are carried (no transmission or gazebo elements).",
            ],
        )
        .replace("--", "- -");
    Ok(format!(
        "<?xml version=\"1.0\"?>\n<!--\n{comment}-->\n{body}\n"
    ))
}

/// What urdf-rs writes for an absent `<inertial>` (a zero one) and for an absent `<axis>` and
/// `<limit>` (the URDF defaults `1 0 0` and a zero limit, which only fixed and continuous joints
/// may have): removed, so a link without mass stays without an inertial (KDL warns about an
/// inertial on the root) and fixed joints carry no axis.
fn tidy_urdf(body: &str) -> String {
    const ZERO_INERTIAL: &str = "\n    <inertial>\n      <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n      \
        <mass value=\"0\"/>\n      <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/>\n    </inertial>";
    const DEFAULT_AXIS_LIMIT: &str = "\n    <axis xyz=\"1 0 0\"/>\n    \
        <limit lower=\"0\" upper=\"0\" effort=\"0\" velocity=\"0\"/>";
    body.replace(ZERO_INERTIAL, "")
        .replace(DEFAULT_AXIS_LIMIT, "")
}

/// Reads a cell URDF back with the project's loader: robot 1's and robot 2's chains from `world`
/// (tool links `robotN_<tool_link>`), their placement (the world rule's `root_from_base`) against
/// the identity and `b1_from_b2`, their flange poses against the cell's models at six
/// configurations per robot, and the tip link's offset against the cell's tip.
pub(crate) fn check_cell_urdf(text: &str, cell: &Cell) -> Result<Deviation, String> {
    let mut dev = Deviation {
        translation_m: 0.0,
        rotation_rad: 0.0,
    };
    for (which, world_from_base) in robots_in_world(cell) {
        let setup = cell.robot(which);
        let p = prefix(which);
        let tool = format!("{p}{}", setup.tool_link);
        // The couplings the cell declares (not in the URDF) hold for the cell URDF too, its
        // joints named with the robot's prefix.
        let couplings: Vec<kinematics::JointCoupling> = setup
            .model
            .added_couplings()
            .iter()
            .map(|c| kinematics::JointCoupling {
                joint: format!("{p}{}", c.joint),
                terms: c
                    .terms
                    .iter()
                    .map(|(j, k)| (format!("{p}{j}"), *k))
                    .collect(),
                offset: c.offset,
            })
            .collect();
        let loaded = RobotModel::from_urdf_str(text, &tool)
            .and_then(|m| m.with_couplings(&couplings))
            .map_err(|e| format!("{which}'s chain to {tool}: {e}"))?;
        if loaded.root_link() != WORLD_LINK {
            return Err(format!(
                "{which}'s chain starts at `{}`, not at `{WORLD_LINK}`",
                loaded.root_link()
            ));
        }
        let placed = loaded
            .root_from_base()
            .ok_or_else(|| format!("{which}: no fixed joint from `{WORLD_LINK}` to its base"))?;
        dev = dev.max(Deviation::between(&world_from_base, placed));
        if loaded.dof() != setup.model.dof() {
            return Err(format!(
                "{which}: {} joints in the cell URDF, {} in the cell's model",
                loaded.dof(),
                setup.model.dof()
            ));
        }
        for q in check_configurations(&setup.model) {
            let want = base_from_flange(&setup.model, &q).map_err(|e| e.to_string())?;
            let got = base_from_flange(&loaded, &q).map_err(|e| e.to_string())?;
            dev = dev.max(Deviation::between(&want, &got));
        }
        let tip = RobotModel::from_urdf_str(text, &format!("{p}tip"))
            .map_err(|e| format!("{which}'s chain to {p}tip: {e}"))?;
        let flange_from_tip = tip.last_from_flange().translation.vector
            - loaded.last_from_flange().translation.vector;
        let rotated = loaded.last_from_flange().rotation.inverse() * flange_from_tip;
        dev = dev.max(Deviation {
            translation_m: (rotated - setup.flange_from_tip).norm(),
            rotation_rad: 0.0,
        });
    }
    Ok(dev)
}

/// Six joint vectors within `model`'s limits: zero (clamped into the limits), and 10 %, 30 %,
/// 50 %, 70 %, 90 % of each joint's range (a continuous joint: of ±π).
fn check_configurations(model: &RobotModel) -> Vec<Vec<f64>> {
    let range = |j: &kinematics::Joint| {
        let lo = if j.lower.is_finite() {
            j.lower
        } else {
            -std::f64::consts::PI
        };
        let hi = if j.upper.is_finite() {
            j.upper
        } else {
            std::f64::consts::PI
        };
        (lo, hi)
    };
    let mut out = vec![model
        .joints()
        .iter()
        .map(|j| {
            let (lo, hi) = range(j);
            0.0_f64.clamp(lo, hi)
        })
        .collect()];
    for f in [0.1, 0.3, 0.5, 0.7, 0.9] {
        out.push(
            model
                .joints()
                .iter()
                .map(|j| {
                    let (lo, hi) = range(j);
                    lo + f * (hi - lo)
                })
                .collect(),
        );
    }
    out
}

/// The xacro file: `b1_from_b2_x/_y/_z` (m), `b1_from_b2_roll/_pitch/_yaw` (rad, URDF rpy), and
/// `b1_from_b2_xyz` / `b1_from_b2_rpy` (the same, as `<origin>` strings).
pub(crate) fn render_xacro(b1_from_b2: &Isometry3<f64>, header: &Header<'_>) -> String {
    let p = pose(b1_from_b2);
    let [x, y, z] = p.xyz.0.map(metres);
    let [roll, pitch, yaw] = p.rpy.0.map(unit);
    let comment = header
        .lines(
            "  ",
            &[
                "Convention: xacro properties of the placement for a URDF <origin xyz rpy>: metres; radians with",
                "R = Rz(yaw)*Ry(pitch)*Rx(roll). Use: <xacro:include filename=\"b1_from_b2.xacro\"/> then",
                "<origin xyz=\"${b1_from_b2_xyz}\" rpy=\"${b1_from_b2_rpy}\"/> on the joint from robot 1's base to robot 2's.",
            ],
        )
        .replace("--", "- -");
    format!(
        "<?xml version=\"1.0\"?>\n<robot xmlns:xacro=\"http://www.ros.org/wiki/xacro\">\n<!--\n{comment}-->\n  \
         <xacro:property name=\"b1_from_b2_x\" value=\"{x}\"/>\n  \
         <xacro:property name=\"b1_from_b2_y\" value=\"{y}\"/>\n  \
         <xacro:property name=\"b1_from_b2_z\" value=\"{z}\"/>\n  \
         <xacro:property name=\"b1_from_b2_roll\" value=\"{roll}\"/>\n  \
         <xacro:property name=\"b1_from_b2_pitch\" value=\"{pitch}\"/>\n  \
         <xacro:property name=\"b1_from_b2_yaw\" value=\"{yaw}\"/>\n  \
         <xacro:property name=\"b1_from_b2_xyz\" value=\"{x} {y} {z}\"/>\n  \
         <xacro:property name=\"b1_from_b2_rpy\" value=\"{roll} {pitch} {yaw}\"/>\n</robot>\n"
    )
}

/// The placement of a xacro file written by [`render_xacro`] (the `_xyz`/`_rpy` strings must
/// agree with the single properties).
pub(crate) fn parse_xacro(text: &str) -> Result<Isometry3<f64>, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| e.to_string())?;
    let prop = |name: &str| -> Result<String, String> {
        doc.descendants()
            .find(|n| n.tag_name().name() == "property" && n.attribute("name") == Some(name))
            .and_then(|n| n.attribute("value"))
            .map(str::to_string)
            .ok_or_else(|| format!("no xacro:property `{name}`"))
    };
    let mut v = [0.0; 6];
    for (k, name) in ["x", "y", "z", "roll", "pitch", "yaw"].iter().enumerate() {
        let key = format!("b1_from_b2_{name}");
        v[k] = number(&prop(&key)?, &key)?;
    }
    for (key, want) in [("b1_from_b2_xyz", &v[..3]), ("b1_from_b2_rpy", &v[3..])] {
        let got: Vec<f64> = prop(key)?
            .split_whitespace()
            .map(|t| number(t, key))
            .collect::<Result<_, _>>()?;
        if got != want {
            return Err(format!(
                "{key} = {got:?} disagrees with the single properties {want:?}"
            ));
        }
    }
    Ok(kinematics::origin_isometry(
        &Vector3::new(v[0], v[1], v[2]),
        &Vector3::new(v[3], v[4], v[5]),
    ))
}

/// The launch file (ROS 2 XML launch format): one `static_transform_publisher` node with the flag
/// form, frames as launch arguments defaulting to the cell URDF's base links.
pub(crate) fn render_launch(
    v: &Ros2Transform,
    parent: &str,
    child: &str,
    header: &Header<'_>,
) -> String {
    let comment = header
        .lines(
            "  ",
            &[
                "Convention: tf2 static transform, metres, unit quaternion x y z w (w >= 0): the pose of robot 2's base",
                "frame (child) in robot 1's base frame (parent). Flag form (ROS 2 Humble and later; Rolling accepts only it).",
                "Use it when each robot's description is published separately; the cell URDF already holds this joint",
                "(robot2_mount), so do not run both. Run: ros2 launch b1_from_b2.launch.xml [parent_frame:=...] [child_frame:=...]",
            ],
        )
        .replace("--", "- -");
    format!(
        "<?xml version=\"1.0\"?>\n<launch>\n<!--\n{comment}-->\n  \
         <arg name=\"parent_frame\" default=\"{parent}\"/>\n  \
         <arg name=\"child_frame\" default=\"{child}\"/>\n  \
         <node pkg=\"tf2_ros\" exec=\"static_transform_publisher\" name=\"b1_from_b2_publisher\"\n        \
         args=\"--x {x} --y {y} --z {z} --qx {qx} --qy {qy} --qz {qz} --qw {qw} --frame-id $(var parent_frame) --child-frame-id $(var child_frame)\"/>\n\
         </launch>\n",
        x = metres(v.x_m),
        y = metres(v.y_m),
        z = metres(v.z_m),
        qx = unit(v.qx),
        qy = unit(v.qy),
        qz = unit(v.qz),
        qw = unit(v.qw),
    )
}

/// The transform numbers of a launch file written by this module (`--x … --qw` flags).
pub fn parse_launch_transform(text: &str) -> Result<Ros2Transform, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| e.to_string())?;
    let node = doc
        .descendants()
        .find(|n| {
            n.tag_name().name() == "node"
                && n.attribute("exec") == Some("static_transform_publisher")
        })
        .ok_or("no <node exec=\"static_transform_publisher\">")?;
    let args: Vec<&str> = node
        .attribute("args")
        .ok_or("the node has no args")?
        .split_whitespace()
        .collect();
    let flag = |name: &str| -> Result<f64, String> {
        let i = args
            .iter()
            .position(|a| *a == name)
            .ok_or_else(|| format!("no {name} argument"))?;
        number(args.get(i + 1).copied().unwrap_or(""), name)
    };
    Ok(Ros2Transform {
        x_m: flag("--x")?,
        y_m: flag("--y")?,
        z_m: flag("--z")?,
        qx: flag("--qx")?,
        qy: flag("--qy")?,
        qz: flag("--qz")?,
        qw: flag("--qw")?,
    })
}

pub(crate) fn parse_launch(text: &str) -> Result<Isometry3<f64>, String> {
    let v = parse_launch_transform(text)?;
    v.placement().ok_or_else(|| {
        format!(
            "qx qy qz qw = {} {} {} {} is not a unit quaternion",
            v.qx, v.qy, v.qz, v.qw
        )
    })
}

/// One sentence per robot whose `[robotN.errors]` hold terms the cell URDF does not carry (the
/// URDF is written as the cell names it; a simulated cell's errors are its truth, an exported
/// cell's are what a URDF cannot express: joint scale, compliance).
pub(crate) fn unexpressed_errors(cell: &Cell) -> Vec<String> {
    [Robot::One, Robot::Two]
        .into_iter()
        .filter_map(|which| {
            let errors = &cell.robot(which).errors;
            let mut kinds: Vec<&str> = Vec::new();
            for p in kinematics::all_params(errors.dof()) {
                if errors.get(p) != 0.0 && !kinds.contains(&p.kind_name()) {
                    kinds.push(p.kind_name());
                }
            }
            (!kinds.is_empty()).then(|| {
                format!(
                    "{which}: the cell's [robot{n}.errors] ({}) are not in {URDF_FILE}, which carries the robot's URDF as the \
                     cell names it (a calibrated cell from `calibrate --cell --export` puts what a URDF can hold into its URDFs)",
                    kinds.join(", "),
                    n = if which == Robot::One { 1 } else { 2 }
                )
            })
        })
        .collect()
}
