//! Integration tests of the kinematics crate on the shipped URDFs.

use std::f64::consts::FRAC_PI_2;
use std::path::Path;

mod common;

use common::random_q;
use kinematics::*;
use nalgebra::{Point3, Rotation3, Unit, Vector3};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Exact-arithmetic comparisons (a few ulps of metre-scale sums).
const EXACT_TOL: f64 = 1e-12;
/// IK round trip: FK(IK(p)) within 1e-9 m of p.
const ROUND_TRIP_TOL_M: f64 = 1e-9;

fn robot(name: &str) -> RobotModel {
    let p = format!("{}/../../robots/{name}.urdf", env!("CARGO_MANIFEST_DIR"));
    RobotModel::from_urdf_file(Path::new(&p), "tool0").unwrap()
}

#[test]
fn rpy_order_is_rz_ry_rx() {
    // Golden: roll 0.1, pitch 0.2, yaw 0.3 must equal Rz(0.3)·Ry(0.2)·Rx(0.1).
    let r = rotation_from_rpy(&Vector3::new(0.1, 0.2, 0.3));
    let expected = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), 0.2)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), 0.1);
    assert!((r.matrix() - expected.matrix()).norm() < EXACT_TOL);
    // And not the other order.
    let other = Rotation3::from_axis_angle(&Vector3::x_axis(), 0.1)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), 0.2)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3);
    assert!((r.matrix() - other.matrix()).norm() > 1e-3);
}

#[test]
fn loads_both_robots() {
    let hp = robot("hp20");
    assert_eq!((hp.name(), hp.dof()), ("hp20", 6));
    let va = robot("va1400");
    assert_eq!((va.name(), va.dof()), ("va1400", 7));
    let total: f64 = hp.inertials().iter().map(|i| i.mass).sum();
    // base_link (60 kg) is not carried by any joint.
    assert!((total - 208.0).abs() < EXACT_TOL, "{total}");
    let total: f64 = va.inertials().iter().map(|i| i.mass).sum();
    assert!((total - 100.0).abs() < EXACT_TOL, "{total}");
}

#[test]
fn fk_zero_pose_hp20() {
    let m = robot("hp20");
    let t = base_from_flange(&m, &[0.0; 6]).unwrap();
    // 0.150 + 0.795 + 0.105 out, 0.505 + 0.760 + 0.140 up; flange z along base x.
    assert!((t.translation.vector - Vector3::new(1.050, 0.0, 1.405)).norm() < EXACT_TOL);
    assert!((t.rotation * Vector3::z() - Vector3::x()).norm() < EXACT_TOL);
    // ROS-Industrial tool0: x points down at the zero pose.
    assert!((t.rotation * Vector3::x() + Vector3::z()).norm() < EXACT_TOL);
    let tip = base_from_tip(&m, &[0.0; 6], &Vector3::new(0.0, 0.0, 0.1)).unwrap();
    assert!((tip.translation.vector - Vector3::new(1.150, 0.0, 1.405)).norm() < EXACT_TOL);
}

#[test]
fn fk_zero_pose_va1400() {
    let m = robot("va1400");
    let t = base_from_flange(&m, &[0.0; 7]).unwrap();
    // 0.150 + 0.640 + 0.100 out, 0.450 + 0.300 + 0.314 + 0.200 up.
    assert!((t.translation.vector - Vector3::new(0.890, 0.0, 1.264)).norm() < EXACT_TOL);
}

#[test]
fn fk_hand_computed_poses() {
    let m = robot("hp20");
    // S = 90°: the zero-pose flange rotates to +y.
    let t = base_from_flange(&m, &[FRAC_PI_2, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
    assert!((t.translation.vector - Vector3::new(0.0, 1.050, 1.405)).norm() < EXACT_TOL);
    // L = 90° (axis +y): upper arm lies along +x; U offset 0.140 then along +x, forearm points down.
    let t = base_from_flange(&m, &[0.0, FRAC_PI_2, 0.0, 0.0, 0.0, 0.0]).unwrap();
    let expected = Vector3::new(0.150 + 0.760 + 0.140, 0.0, 0.505 - 0.795 - 0.105);
    assert!(
        (t.translation.vector - expected).norm() < EXACT_TOL,
        "{}",
        t.translation.vector
    );
    // U = 90° (axis −y): the forearm points up and the 0.140 U offset now points to −x.
    let t = base_from_flange(&m, &[0.0, 0.0, FRAC_PI_2, 0.0, 0.0, 0.0]).unwrap();
    let expected = Vector3::new(0.150 - 0.140, 0.0, 0.505 + 0.760 + 0.795 + 0.105);
    assert!(
        (t.translation.vector - expected).norm() < EXACT_TOL,
        "{}",
        t.translation.vector
    );
    // VA1400 E = 90° with the arm upright moves the forearm to +y.
    let v = robot("va1400");
    let t = base_from_flange(&v, &[0.0, 0.0, FRAC_PI_2, 0.0, 0.0, 0.0, 0.0]).unwrap();
    assert!((t.translation.vector - Vector3::new(0.150, 0.740, 1.264)).norm() < EXACT_TOL);
}

/// Central-difference step, rad, and tolerance (per column, m/rad or rad/rad): truncation
/// h²/6·|p'''| ≲ 2e-11 with lever arms under 2 m, round-off ≈ eps·|p|/h ≈ 4e-11; 1e-9 leaves a
/// margin of ~15× over their sum. (The check of every column on the shipped arms and the
/// prismatic and coupled chains is the unit test `jacobians_match_central_differences_on_every_chain`
/// in `src/jacobian.rs`.)
const FD_STEP: f64 = 1e-5;
const FD_TOL: f64 = 1e-9;

fn round_trip(name: &str, n: usize, with_axis: bool) {
    let m = robot(name);
    let tip = Vector3::new(0.0, 0.0, 0.15);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut solved = 0;
    for _ in 0..n {
        let q = random_q(&m, &mut rng, 0.05);
        let t = base_from_tip(&m, &q, &tip).unwrap();
        let target = Point3::from(t.translation.vector);
        let opts = IkOptions {
            tool_axis_base: with_axis.then(|| Unit::new_normalize(t.rotation * Vector3::z())),
            preferred_q: (m.dof() == 7).then(|| vec![0.0; 7]),
            ..IkOptions::default()
        };
        let sol = ik_tip_position(&m, &target, &tip, &opts).unwrap();
        assert!(
            sol.reachable(),
            "{name} target {target} from q {q:?} not solved: {sol:?}"
        );
        m.check_q(&sol.q).unwrap();
        let p = base_from_tip(&m, &sol.q, &tip).unwrap().translation.vector;
        assert!((p - target.coords).norm() < ROUND_TRIP_TOL_M);
        if with_axis {
            let z = base_from_tip(&m, &sol.q, &tip).unwrap().rotation * Vector3::z();
            assert!((z - t.rotation * Vector3::z()).norm() < 1e-9);
        }
        solved += 1;
    }
    assert_eq!(solved, n);
}

#[test]
fn ik_round_trip_position_hp20() {
    round_trip("hp20", 500, false);
}

#[test]
fn ik_round_trip_position_va1400() {
    round_trip("va1400", 500, false);
}

#[test]
fn ik_round_trip_with_axis() {
    round_trip("hp20", 300, true);
    round_trip("va1400", 300, true);
}

#[test]
fn ik_unreachable_is_a_status() {
    let m = robot("hp20");
    let sol = ik_tip_position(
        &m,
        &Point3::new(5.0, 0.0, 1.0),
        &Vector3::zeros(),
        &IkOptions::default(),
    )
    .unwrap();
    assert_eq!(sol.status, IkStatus::Unreachable);
    assert!(sol.position_error_m > 1.0);
    m.check_q(&sol.q).unwrap();
}

/// Regression (found by the documentation's `plan` → `sim-cell session --plan` commands): a joint
/// at its limit, written to a session file as degrees with 6 decimals and read back, was up to
/// 8.7e-9 rad outside it and refused (the slack was 1e-9 rad). Every joint of the VA1400 at each
/// limit, through the file's rounding, must pass; 1e-6 rad (0.06 millidegree) beyond must not.
#[test]
fn check_q_accepts_a_limit_written_with_six_decimals_of_a_degree() {
    let m = robot("va1400");
    let written = |rad: f64| {
        let deg: f64 = format!("{:.6}", rad.to_degrees()).parse().unwrap();
        deg.to_radians()
    };
    for (k, j) in m.joints().iter().enumerate() {
        for limit in [j.lower, j.upper] {
            let mut q = vec![0.0; m.dof()];
            q[k] = written(limit);
            m.check_q(&q)
                .unwrap_or_else(|e| panic!("{} at {limit} rad as written: {e}", j.name));
            q[k] = limit + 1e-6 * limit.signum();
            assert!(m.check_q(&q).is_err(), "{} 1e-6 rad beyond", j.name);
        }
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let m = robot("hp20");
    let e = base_from_flange(&m, &[0.0; 5]).unwrap_err();
    assert!(matches!(
        e,
        KinematicsError::WrongLength {
            expected: 6,
            got: 5,
            ..
        }
    ));
    assert!(e.to_string().contains("5 values but hp20 has 6 joints"));
    let e = base_from_flange(&m, &[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
    assert!(matches!(e, KinematicsError::NotFinite { index: 2, .. }));
    let e = base_from_flange(&m, &[0.0, 0.0, 0.0, 0.0, 2.6, 0.0]).unwrap_err();
    assert!(
        matches!(e, KinematicsError::OutOfLimits { index: 5, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("joint_5_b"));
    let e = base_from_flange(&m, &[0.0, 30.0, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
    assert!(
        matches!(e, KinematicsError::LooksLikeDegrees { index: 2, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("degrees"));
    let bad = RobotModel::from_urdf_str("<robot name=\"x\"><link", "tool0").unwrap_err();
    assert!(matches!(bad, ModelError::Parse { .. }));
    let xml = std::fs::read_to_string(format!(
        "{}/../../robots/hp20.urdf",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let e = RobotModel::from_urdf_str(&xml, "flange").unwrap_err();
    assert!(matches!(e, ModelError::MissingLink { .. }));
    assert!(e.to_string().contains("tool0"));
    // Prismatic joints load (their limits read as metres); limits in millimetres and missing
    // limits are refused.
    let linear = RobotModel::from_urdf_str(
        &xml.replace("type=\"revolute\"", "type=\"prismatic\""),
        "tool0",
    )
    .unwrap();
    assert!(linear
        .joints()
        .iter()
        .all(|j| j.kind == JointKind::Prismatic));
    let e = RobotModel::from_urdf_str(
        &xml.replacen("type=\"revolute\"", "type=\"prismatic\"", 1)
            .replacen(
                "lower=\"-3.1416\" upper=\"3.1416\"",
                "lower=\"-3141.6\" upper=\"3141.6\"",
                1,
            ),
        "tool0",
    )
    .unwrap_err();
    assert!(
        matches!(e, ModelError::LimitsLookLikeMillimetres { .. }),
        "{e}"
    );
    let e = RobotModel::from_urdf_str(
        &xml.replace("type=\"revolute\"", "type=\"planar\""),
        "tool0",
    )
    .unwrap_err();
    assert!(matches!(e, ModelError::UnsupportedJoint { .. }), "{e}");
    let e = RobotModel::from_urdf_str(
        &xml.replace("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 0 0\"/>"),
        "tool0",
    )
    .unwrap_err();
    assert!(matches!(e, ModelError::ZeroAxis { .. }), "{e}");
    let branch = xml.replace(
        "</robot>",
        "<link name=\"extra\"/><joint name=\"j_extra\" type=\"fixed\"><parent link=\"link_2_l\"/><child link=\"extra\"/></joint></robot>",
    );
    // A branch off the chain is ignored and listed.
    let with_branch = RobotModel::from_urdf_str(&branch, "tool0").unwrap();
    assert_eq!(with_branch.ignored_joints(), ["j_extra"]);
    assert_eq!(with_branch.ignored_links(), ["extra"]);
    let e = RobotModel::from_urdf_str(
        &xml.replace(
            "lower=\"-3.1416\" upper=\"3.1416\"",
            "lower=\"-180\" upper=\"180\"",
        ),
        "tool0",
    )
    .unwrap_err();
    assert!(matches!(e, ModelError::LimitsLookLikeDegrees { .. }), "{e}");
    assert!(e.to_string().contains("joint_1_s") && e.to_string().contains("degrees"));
    let no_limit = xml.replace(
        "<limit lower=\"-1.9199\" upper=\"2.7053\" effort=\"1200\" velocity=\"2.9671\"/>",
        "",
    );
    assert_ne!(no_limit, xml);
    let e = RobotModel::from_urdf_str(&no_limit, "tool0").unwrap_err();
    assert!(matches!(e, ModelError::BadLimits { .. }), "{e}");
    assert!(e.to_string().contains("joint_2_l"));
    let e = RobotModel::from_urdf_file(Path::new("/nonexistent/x.urdf"), "tool0").unwrap_err();
    assert!(e.to_string().contains("/nonexistent/x.urdf"));
    assert!(ik_tip_position(
        &m,
        &Point3::new(f64::NAN, 0.0, 0.0),
        &Vector3::zeros(),
        &IkOptions::default()
    )
    .is_err());
}

#[test]
fn unchecked_matches_checked() {
    let m = robot("va1400");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let q = random_q(&m, &mut rng, 0.0);
    let a = base_from_flange(&m, &q).unwrap();
    let b = base_from_flange_unchecked(&m, &q);
    assert!((a.to_homogeneous() - b.to_homogeneous()).norm() < EXACT_TOL);
    // And against the plain product of URDF origins (no precomputation).
    let mut t = nalgebra::Isometry3::identity();
    for (j, &qi) in m.joints().iter().zip(&q) {
        t = t
            * j.fixed_prefix
            * origin_isometry(&j.origin_xyz, &j.origin_rpy)
            * nalgebra::UnitQuaternion::from_axis_angle(&j.axis, qi);
    }
    t *= m.last_from_flange();
    assert!((a.to_homogeneous() - t.to_homogeneous()).norm() < EXACT_TOL);
}

#[test]
fn fk_hand_computed_poses_va1400() {
    let m = robot("va1400");
    // L = 90° (axis +y): the upper arm (0.300 + 0.314) lies along +x, the U offset 0.200 too,
    // and the forearm + flange (0.640 + 0.100) point down.
    let t = base_from_flange(&m, &[0.0, FRAC_PI_2, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
    let expected = Vector3::new(0.150 + 0.614 + 0.200, 0.0, 0.450 - 0.740);
    assert!(
        (t.translation.vector - expected).norm() < EXACT_TOL,
        "{}",
        t.translation.vector
    );
    assert!((t.rotation * Vector3::z() - Vector3::new(0.0, 0.0, -1.0)).norm() < EXACT_TOL);
    // B = −90° (axis −y, so +90° about +y): the flange z turns from +x to −z; the flange stays
    // 0.100 from the B axis.
    let t = base_from_flange(&m, &[0.0, 0.0, 0.0, 0.0, 0.0, -FRAC_PI_2, 0.0]).unwrap();
    let expected = Vector3::new(0.150 + 0.640, 0.0, 0.450 + 0.614 + 0.200 - 0.100);
    assert!(
        (t.translation.vector - expected).norm() < EXACT_TOL,
        "{}",
        t.translation.vector
    );
    assert!((t.rotation * Vector3::z() - Vector3::new(0.0, 0.0, -1.0)).norm() < EXACT_TOL);
    // Exactly 180° about S on the hp20 (S range ±180°): x changes sign.
    let h = robot("hp20");
    let t = base_from_flange(&h, &[std::f64::consts::PI, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
    assert!((t.translation.vector - Vector3::new(-1.050, 0.0, 1.405)).norm() < EXACT_TOL);
    assert!((t.rotation * Vector3::z() + Vector3::x()).norm() < EXACT_TOL);
    // Tiny angles: 1e-9 rad about L moves the flange by 1e-9 × (lever arm) to first order.
    let t0 = base_from_flange(&h, &[0.0; 6]).unwrap();
    let t1 = base_from_flange(&h, &[0.0, 1e-9, 0.0, 0.0, 0.0, 0.0]).unwrap();
    let lever = Vector3::new(1.050 - 0.150, 0.0, 1.405 - 0.505);
    let expected = Vector3::y().cross(&lever) * 1e-9;
    assert!(((t1.translation.vector - t0.translation.vector) - expected).norm() < 1e-15);
}

#[test]
fn ik_resolves_redundancy_toward_preferred_q() {
    let m = robot("va1400");
    let tip = Vector3::new(0.0, 0.0, 0.15);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..50 {
        let q_star = random_q(&m, &mut rng, 0.15);
        let target = Point3::from(base_from_tip(&m, &q_star, &tip).unwrap().translation.vector);
        // A preferred posture 0.1 rad per joint away from a posture that reaches the target.
        let preferred: Vec<f64> = q_star
            .iter()
            .map(|q| q + rng.random_range(-0.1..0.1))
            .collect();
        let dist = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let opts = IkOptions {
            preferred_q: Some(preferred.clone()),
            ..IkOptions::default()
        };
        let sol = ik_tip_position(&m, &target, &tip, &opts).unwrap();
        assert!(sol.reachable());
        // The solution is at least as close to the preferred posture as q_star is (q_star is one
        // point of the solution set; the solver finds a nearer one by the null-space pull).
        assert!(
            dist(&sol.q, &preferred) <= dist(&q_star, &preferred) + 1e-6,
            "{} > {}",
            dist(&sol.q, &preferred),
            dist(&q_star, &preferred)
        );
    }
}

#[test]
fn ik_turns_the_tool_axis_all_the_way_round() {
    // Regression: an axis residual with zeros at z = ±a let the solver stop with the flange
    // pointing exactly away from the requested axis. Start with z = +x and ask for −x.
    let m = robot("hp20");
    let tip = Vector3::new(0.0, 0.0, 0.1);
    let opts = IkOptions {
        tool_axis_base: Some(-Vector3::x_axis()),
        initial_q: Some(vec![0.0; 6]),
        ..IkOptions::default()
    };
    let target = Point3::new(0.6, 0.2, 1.0);
    let sol = ik_tip_position(&m, &target, &tip, &opts).unwrap();
    assert!(sol.reachable(), "{sol:?}");
    let t = base_from_tip(&m, &sol.q, &tip).unwrap();
    assert!((t.rotation * Vector3::z() + Vector3::x()).norm() < 1e-9);
    assert!((t.translation.vector - target.coords).norm() < ROUND_TRIP_TOL_M);
}

#[test]
fn ik_is_deterministic_and_honours_the_initial_guess() {
    let m = robot("va1400");
    let tip = Vector3::new(0.0, 0.0, 0.15);
    let target = Point3::new(0.7, -0.4, 0.6);
    let opts = IkOptions::default();
    let a = ik_tip_position(&m, &target, &tip, &opts).unwrap();
    let b = ik_tip_position(&m, &target, &tip, &opts).unwrap();
    assert_eq!(a, b);
    // Starting at a solution returns it unchanged, with no iteration.
    let again = IkOptions {
        initial_q: Some(a.q.clone()),
        ..IkOptions::default()
    };
    let c = ik_tip_position(&m, &target, &tip, &again).unwrap();
    assert_eq!((c.q.clone(), c.iterations), (a.q.clone(), 0));
}

#[test]
fn ik_unreachable_with_axis_and_bad_options_are_reported() {
    let m = robot("va1400");
    let tip = Vector3::new(0.0, 0.0, 0.15);
    // Inside the reach sphere but pointing the flange at the base column from below the floor.
    let opts = IkOptions {
        tool_axis_base: Some(Vector3::z_axis()),
        ..IkOptions::default()
    };
    let sol = ik_tip_position(&m, &Point3::new(0.0, 0.0, -0.5), &tip, &opts).unwrap();
    assert_eq!(sol.status, IkStatus::Unreachable);
    m.check_q(&sol.q).unwrap();
    for bad in [
        IkOptions {
            preferred_q: Some(vec![0.0; 6]),
            ..IkOptions::default()
        },
        IkOptions {
            initial_q: Some(vec![f64::NAN; 7]),
            ..IkOptions::default()
        },
        IkOptions {
            tolerance_m: 0.0,
            ..IkOptions::default()
        },
        IkOptions {
            max_iterations: 0,
            ..IkOptions::default()
        },
    ] {
        let e = ik_tip_position(&m, &Point3::new(0.5, 0.0, 0.5), &tip, &bad).unwrap_err();
        assert!(matches!(e, KinematicsError::InvalidInput(_)), "{e}");
    }
    let e = ik_tip_position(
        &m,
        &Point3::new(0.5, 0.0, 0.5),
        &Vector3::new(f64::INFINITY, 0.0, 0.0),
        &opts,
    )
    .unwrap_err();
    assert!(e.to_string().contains("tip offset"), "{e}");
}

#[test]
fn jacobian_inputs_are_checked() {
    let m = robot("hp20");
    let e = geometric_jacobian(&m, &[0.0; 7], &Vector3::zeros(), JacobianFrame::Base).unwrap_err();
    assert!(matches!(
        e,
        KinematicsError::WrongLength {
            expected: 6,
            got: 7,
            ..
        }
    ));
    let e = tip_position_jacobian(&m, &[0.0, 0.0, 0.0, 0.0, 0.0, 100.0], &Vector3::zeros())
        .unwrap_err();
    assert!(
        matches!(e, KinematicsError::LooksLikeDegrees { index: 6, .. }),
        "{e}"
    );
}

/// A chain that exercises every FK path the shipped URDFs do not: non-zero origin rpy, a rotating
/// fixed joint before the first actuated joint and between actuated joints, ±x/±y/±z axes,
/// general (non-aligned) axes, a continuous joint and a rotated tool0.
const ODD_CHAIN: &str = r#"<robot name="odd">
  <link name="cell"/><link name="base_link"/><link name="a"/><link name="b"/><link name="b2"/>
  <link name="c"/><link name="d"/><link name="e"/><link name="f"/><link name="tool0"/>
  <joint name="mount" type="fixed"><parent link="cell"/><child link="base_link"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.1 -0.2 0.3"/></joint>
  <joint name="j1" type="revolute"><parent link="base_link"/><child link="a"/>
    <origin xyz="0 0 0.4" rpy="0 0 0"/><axis xyz="0 0 -1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.1 0.05 0.2" rpy="0.4 0 -0.3"/><axis xyz="0.3 0.4 0.866"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="bend" type="fixed"><parent link="b"/><child link="b2"/>
    <origin xyz="0.3 0 0.1" rpy="0 1.2 0"/></joint>
  <joint name="j3" type="revolute"><parent link="b2"/><child link="c"/>
    <origin xyz="0 0 0.25" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="j4" type="continuous"><parent link="c"/><child link="d"/>
    <origin xyz="0.2 0.1 0" rpy="-0.7 0.2 0.1"/><axis xyz="0 -1 0"/></joint>
  <joint name="j5" type="revolute"><parent link="d"/><child link="e"/>
    <origin xyz="0.15 0 0" rpy="0 0 0"/><axis xyz="-1 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j6" type="revolute"><parent link="e"/><child link="f"/>
    <origin xyz="0.1 0 0" rpy="0 0 3.14159"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="f"/><child link="tool0"/>
    <origin xyz="0.05 0 0.02" rpy="0.3 1.5707963267948966 0"/></joint>
</robot>"#;

#[test]
fn fk_matches_plain_urdf_product_on_an_odd_chain() {
    let m = RobotModel::from_urdf_str(ODD_CHAIN, "tool0").unwrap();
    assert_eq!(m.dof(), 6);
    // The root is not named `world`, so the fixed `mount` joint stays a prefix of joint 1 (the
    // world rule is tested in real_world_urdfs.rs).
    assert_eq!((m.root_link(), m.base_link()), ("cell", "cell"));
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let tip = Vector3::new(0.01, 0.02, 0.1);
    for _ in 0..100 {
        let q = random_q(&m, &mut rng, 0.0);
        // Reference: the product of URDF origins and axis-angle rotations, straight from the
        // parsed joints (no precomputation, no special cases).
        let mut t = nalgebra::Isometry3::identity();
        for (j, &qi) in m.joints().iter().zip(&q) {
            t = t
                * j.fixed_prefix
                * origin_isometry(&j.origin_xyz, &j.origin_rpy)
                * nalgebra::UnitQuaternion::from_axis_angle(&j.axis, qi);
        }
        t *= m.last_from_flange();
        let a = base_from_flange(&m, &q).unwrap();
        assert!((a.to_homogeneous() - t.to_homogeneous()).norm() < EXACT_TOL);
        let p = base_from_tip(&m, &q, &tip).unwrap().translation.vector;
        assert!((p - (t * Point3::from(tip)).coords).norm() < EXACT_TOL);
    }
    // Jacobians and IK on the same chain.
    for seed in 0..8 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let q = random_q(&m, &mut rng, 0.01);
        let jb = geometric_jacobian(&m, &q, &tip, JacobianFrame::Base).unwrap();
        for k in 0..m.dof() {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[k] += FD_STEP;
            qm[k] -= FD_STEP;
            let tp = base_from_tip_unchecked(&m, &qp, &tip);
            let tm = base_from_tip_unchecked(&m, &qm, &tip);
            let v = (tp.translation.vector - tm.translation.vector) / (2.0 * FD_STEP);
            let w = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * FD_STEP);
            assert!(
                (jb.column(k).fixed_rows::<3>(0) - v).norm() < FD_TOL,
                "v col {k}"
            );
            assert!(
                (jb.column(k).fixed_rows::<3>(3) - w).norm() < FD_TOL,
                "w col {k}"
            );
        }
        let target = Point3::from(base_from_tip(&m, &q, &tip).unwrap().translation.vector);
        let sol = ik_tip_position(&m, &target, &tip, &IkOptions::default()).unwrap();
        assert!(sol.reachable(), "{sol:?}");
        let p = base_from_tip(&m, &sol.q, &tip).unwrap().translation.vector;
        assert!((p - target.coords).norm() < ROUND_TRIP_TOL_M);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// FK returns a proper rigid transform and the checked and unchecked paths agree bit for bit.
    #[test]
    fn fk_is_a_rigid_transform(seed in any::<u64>()) {
        for name in ["hp20", "va1400"] {
            let m = robot(name);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let q = random_q(&m, &mut rng, 0.0);
            let t = base_from_flange(&m, &q).unwrap();
            let r = t.rotation.to_rotation_matrix();
            prop_assert!((r.matrix().transpose() * r.matrix() - nalgebra::Matrix3::identity()).norm() < 1e-14);
            prop_assert!((r.matrix().determinant() - 1.0).abs() < 1e-14);
            prop_assert_eq!(t, base_from_flange_unchecked(&m, &q));
        }
    }
}

/// Each stop reason the solver can report, provoked on hp20 (tip at the flange). The status
/// stays `Converged | Unreachable` and `reachable()` follows it.
#[test]
fn ik_reports_why_it_stopped() {
    let m = robot("hp20");
    let solve = |target: Point3<f64>, axis: bool, max_iterations: usize, restarts: usize| {
        let opts = IkOptions {
            tool_axis_base: axis.then(Vector3::z_axis),
            max_iterations,
            restarts,
            ..IkOptions::default()
        };
        let sol = ik_tip_position(&m, &target, &Vector3::zeros(), &opts).unwrap();
        m.check_q(&sol.q).unwrap();
        assert_eq!(sol.reachable(), sol.stop_reason == IkStopReason::Converged);
        assert_eq!(sol.reachable(), sol.status == IkStatus::Converged);
        sol
    };
    // A reachable target: converged at the first seed.
    let sol = solve(Point3::new(1.0, 0.3, 0.8), false, 300, 32);
    assert_eq!(sol.stop_reason, IkStopReason::Converged);
    assert_eq!(sol.seeds_tried, 1);
    // The same target with one iteration and no restart: the iteration cap.
    let sol = solve(Point3::new(1.0, 0.3, 0.8), false, 1, 0);
    assert_eq!(
        (sol.status, sol.stop_reason, sol.iterations, sol.seeds_tried),
        (IkStatus::Unreachable, IkStopReason::IterationCap, 1, 1)
    );
    // 5 m away (reach ≈ 1.7 m): every seed crawls along the boundary and stalls.
    let sol = solve(Point3::new(5.0, 0.0, 1.0), false, 300, 32);
    assert_eq!(sol.stop_reason, IkStopReason::Stalled);
    assert_eq!(sol.seeds_tried, 33);
    assert_eq!(sol.stop_reason.name(), "stalled");
    // Below the base, flange z up, from the zero seed alone: a local minimum where no damped
    // step lowers the cost (with restarts another seed reaches it).
    let sol = solve(Point3::new(0.0, 0.0, -0.5), true, 300, 0);
    assert_eq!(sol.stop_reason, IkStopReason::DampingLimit);
    assert!(sol.position_error_m > 0.1, "{}", sol.position_error_m);
    let sol = solve(Point3::new(0.0, 0.0, -0.5), true, 300, 32);
    assert_eq!(sol.stop_reason, IkStopReason::Converged);
}
