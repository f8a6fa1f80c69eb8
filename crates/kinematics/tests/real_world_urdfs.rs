//! URDFs as they come from vendors and ROS packages (issue 10), one regression test per input in
//! `fixtures/`, named after it.

use std::path::{Path, PathBuf};

use kinematics::{
    base_from_flange, JointKind, LinearCoupling, ModelError, RobotModel, MAX_CHAIN_LENGTH_M,
    WORLD_LINK,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Poses built from the same numbers through a different fixed-joint grouping: round-off only.
const SAME_NUMBERS_TOL: f64 = 1e-12;

fn fixture_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn hp20() -> RobotModel {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/hp20.urdf");
    RobotModel::from_urdf_file(&p, "tool0").unwrap()
}

/// The flanges of two models agree at random joint vectors within the limits.
fn assert_same_fk(a: &RobotModel, b: &RobotModel) {
    assert_eq!(a.dof(), b.dof());
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    for _ in 0..100 {
        let q: Vec<f64> = a
            .joints()
            .iter()
            .map(|j| rng.random_range(j.lower..j.upper))
            .collect();
        let fa = base_from_flange(a, &q).unwrap();
        let fb = base_from_flange(b, &q).unwrap();
        assert!(
            (fa.to_homogeneous() - fb.to_homogeneous()).amax() < SAME_NUMBERS_TOL,
            "{} vs {} at {q:?}",
            a.name(),
            b.name()
        );
    }
}

/// fixtures/ros_industrial_branches.urdf: the stock ROS-Industrial layout (`base_link-base`,
/// `flange` before `tool0`) with a camera on link 3 and a gripper (two prismatic fingers, one a
/// `<mimic>`) after tool0. Only the chain base_link → tool0 matters; the rest is listed.
#[test]
fn ros_industrial_branches() {
    let m =
        RobotModel::from_urdf_file(&fixture_path("ros_industrial_branches.urdf"), "tool0").unwrap();
    assert_eq!(
        (m.root_link(), m.base_link(), m.dof()),
        ("base_link", "base_link", 6)
    );
    assert_eq!(
        m.ignored_joints(),
        [
            "base_link-base",
            "camera_mount",
            "tool0-gripper",
            "finger_left_joint",
            "finger_right_joint"
        ]
    );
    assert_eq!(
        m.ignored_links(),
        [
            "base",
            "camera_link",
            "gripper_base",
            "finger_left",
            "finger_right"
        ]
    );
    assert_same_fk(&m, &hp20());
    // The shipped hp20 has no branch: nothing is ignored.
    assert!(hp20().ignored_joints().is_empty() && hp20().ignored_links().is_empty());
    // A tool link beyond the mimic finger puts the coupled joint on the chain, but the finger it
    // mimics is on another branch: refused, naming both.
    let e = RobotModel::from_urdf_file(
        &fixture_path("ros_industrial_branches.urdf"),
        "finger_right",
    )
    .unwrap_err();
    assert!(matches!(e, ModelError::MimicJoint { .. }), "{e}");
    assert!(
        e.to_string().contains("`finger_right_joint`")
            && e.to_string().contains("`finger_left_joint`")
            && e.to_string().contains("not a moving joint of that chain"),
        "{e}"
    );
    // The other finger (prismatic, independent) loads as a seventh joint, in metres.
    let m =
        RobotModel::from_urdf_file(&fixture_path("ros_industrial_branches.urdf"), "finger_left")
            .unwrap();
    assert_eq!(m.dof(), 7);
    assert_eq!(m.joints()[6].kind, JointKind::Prismatic);
    assert_eq!((m.joints()[6].lower, m.joints()[6].upper), (0.0, 0.04));
}

/// fixtures/world_root.urdf: hp20 fixed to a `world` root 2 m out and turned 90°. The world
/// rule: the base frame is base_link (FK identical to hp20's), and the placement is reported.
#[test]
fn world_root() {
    let m = RobotModel::from_urdf_file(&fixture_path("world_root.urdf"), "tool0").unwrap();
    assert_eq!((m.root_link(), m.base_link()), (WORLD_LINK, "base_link"));
    let expected = Isometry3::from_parts(
        Translation3::new(2.0, 1.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
    );
    let world_from_base = m.root_from_base().expect("the world rule applied");
    assert!((world_from_base.to_homogeneous() - expected.to_homogeneous()).amax() < 1e-15);
    assert!(m.ignored_joints().is_empty());
    assert_same_fk(&m, &hp20());
    // A root named otherwise, or a world joined by a moving joint, stays the base.
    let xml = std::fs::read_to_string(fixture_path("world_root.urdf")).unwrap();
    let m = RobotModel::from_urdf_str(&xml.replace("\"world\"", "\"cell\""), "tool0").unwrap();
    assert_eq!((m.root_link(), m.base_link()), ("cell", "cell"));
    assert!(m.root_from_base().is_none());
    assert_eq!(
        m.joints()[0].fixed_prefix.translation.vector,
        Vector3::new(2.0, 1.0, 0.0)
    );
}

/// fixtures/mimic_on_chain.urdf: joint_3 mimics joint_2 (multiplier −1). Refused until issue
/// 22; now a coupled joint: the user supplies joint_1 and joint_2, joint_3 = −joint_2, so the
/// flange keeps its pitch (both axes are y) and only joint_1 turns it.
#[test]
fn mimic_on_chain() {
    let m = RobotModel::from_urdf_file(&fixture_path("mimic_on_chain.urdf"), "tool0").unwrap();
    assert_eq!((m.dof(), m.chain_joints().len()), (2, 3));
    assert_eq!(
        m.chain_joints()[2].coupling,
        Some(LinearCoupling {
            terms: vec![(1, -1.0)],
            offset: 0.0
        })
    );
    let flange = base_from_flange(&m, &[0.4, 1.1]).unwrap();
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.4);
    assert!(flange.rotation.angle_to(&turn) < SAME_NUMBERS_TOL);
    // Three values (one for the coupled joint) are refused, naming it.
    let e = base_from_flange(&m, &[0.4, 1.1, -1.1]).unwrap_err();
    assert!(e.to_string().contains("2 independent joints") && e.to_string().contains("joint_3"));
    // The chain up to link_2 has no coupling and loads.
    let m = RobotModel::from_urdf_file(&fixture_path("mimic_on_chain.urdf"), "link_2").unwrap();
    assert_eq!(
        (m.dof(), m.ignored_joints()),
        (2, &["joint_3".to_string()][..])
    );
}

/// fixtures/linear_track.urdf: a prismatic track from `world` (not fixed, so `world` stays the
/// base). Refused until issue 22; now the track is joint 1, in metres: at 2 m along it with
/// joint_1 at 0 the flange is 2 + 0.8 m out and 0.5 m up.
#[test]
fn linear_track() {
    let m = RobotModel::from_urdf_file(&fixture_path("linear_track.urdf"), "tool0").unwrap();
    assert_eq!((m.base_link(), m.dof()), (WORLD_LINK, 2));
    assert_eq!(m.joints()[0].kind, JointKind::Prismatic);
    let flange = base_from_flange(&m, &[2.0, 0.0]).unwrap();
    assert!((flange.translation.vector - Vector3::new(2.8, 0.0, 0.5)).norm() < SAME_NUMBERS_TOL);
    // 2000 for 2 m is millimetres; 7 m is past the 6 m track.
    let e = base_from_flange(&m, &[2000.0, 0.0]).unwrap_err();
    assert!(e.to_string().contains("looks like millimetres"), "{e}");
    let e = base_from_flange(&m, &[7.0, 0.0]).unwrap_err();
    assert!(
        e.to_string()
            .contains("7000.000 mm, outside its limits 0.000..6000.000 mm"),
        "{e}"
    );
    // Loading from the carriage works: the arm alone.
    let xml = std::fs::read_to_string(fixture_path("linear_track.urdf")).unwrap();
    let arm_only = xml.replace("type=\"prismatic\"", "type=\"fixed\"");
    let m = RobotModel::from_urdf_str(&arm_only, "tool0").unwrap();
    assert_eq!((m.base_link(), m.dof()), ("carriage", 1));
}

/// fixtures/arm.urdf.xacro: refused by its extension, and by its `<xacro:…>` markup when given as text,
/// with the command to expand it.
#[test]
fn arm_urdf_xacro() {
    let path = fixture_path("arm.urdf.xacro");
    let e = RobotModel::from_urdf_file(&path, "tool0").unwrap_err();
    assert!(matches!(e, ModelError::Xacro { .. }), "{e}");
    assert!(e.to_string().contains("xacro") && e.to_string().contains("arm.urdf.xacro"));
    let xml = std::fs::read_to_string(&path).unwrap();
    let e = RobotModel::from_urdf_str(&xml, "tool0").unwrap_err();
    assert!(matches!(e, ModelError::Xacro { .. }), "{e}");
}

/// A URDF written by `xacro` keeps `xmlns:xacro` on `<robot>` with no xacro markup left: it is
/// plain URDF and loads. (Noticed at stop 28: the loader refused such files as xacro.) The same
/// text with a `${…}` substitution left in it is refused.
#[test]
fn expanded_xacro_output_with_leftover_namespace() {
    let xml = std::fs::read_to_string(fixture_path("comment_first.urdf")).unwrap();
    let expanded = xml.replacen(
        "<robot name=\"hp20\">",
        "<robot name=\"hp20\" xmlns:xacro=\"http://www.ros.org/wiki/xacro\">",
        1,
    );
    assert_ne!(expanded, xml, "the fixture's <robot> tag changed");
    let m = RobotModel::from_urdf_str(&expanded, "tool0").unwrap();
    assert_same_fk(&m, &hp20());
    let unexpanded = expanded.replacen(
        "<link name=\"base_link\"",
        "<link name=\"${prefix}base_link\"",
        1,
    );
    assert_ne!(unexpanded, expanded, "the fixture has no base_link");
    let e = RobotModel::from_urdf_str(&unexpanded, "tool0").unwrap_err();
    assert!(matches!(e, ModelError::Xacro { .. }), "{e}");
}

/// fixtures/hp20_millimetres.urdf: hp20 with every origin in millimetres (chain 2455 "m"); refused
/// naming the unit and the longest joint origin.
#[test]
fn hp20_millimetres() {
    let e =
        RobotModel::from_urdf_file(&fixture_path("hp20_millimetres.urdf"), "tool0").unwrap_err();
    match &e {
        ModelError::LooksLikeMillimetres {
            joint,
            origin,
            length,
            ..
        } => {
            assert_eq!(joint, "joint_5_b");
            assert!((origin - 795.0).abs() < 1e-9 && (length - 2455.0).abs() < 1e-9);
        }
        other => panic!("expected LooksLikeMillimetres, got {other}"),
    }
    assert!(e.to_string().contains("millimetres"), "{e}");
    // The shipped arms in metres are far below the threshold.
    let chain: f64 = hp20().joints().iter().map(|j| j.origin_xyz.norm()).sum();
    assert!(chain < MAX_CHAIN_LENGTH_M / 5.0, "{chain}");
}
