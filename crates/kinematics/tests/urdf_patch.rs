//! The corrected-URDF writer (`patch_urdf_text`): byte identity with the previous writer on the
//! shipped URDFs, the regressions that writer had (named after their inputs in `fixtures/`), and
//! the contract "the patched URDF's FK is the nominal model plus the errors".

use std::path::Path;

use kinematics::{
    base_from_flange, patch_urdf_text, split_for_urdf, true_base_from_flange, verify_patched_urdf,
    JointCoupling, KinematicErrors, RobotModel, UrdfPatchError, PATCH_TOLERANCE_M,
};
use nalgebra::Vector3;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn read(path: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn shipped(robot: &str) -> String {
    read(&format!("../../robots/{robot}.urdf"))
}

fn fixture(name: &str) -> String {
    read(&format!("tests/fixtures/{name}"))
}

fn load(xml: &str) -> RobotModel {
    RobotModel::from_urdf_str(xml, "tool0").expect("test URDF loads")
}

/// The lines of `b` that differ from `a` (same line count assumed where it matters).
fn changed_lines(a: &str, b: &str) -> Vec<String> {
    let al: Vec<&str> = a.lines().collect();
    b.lines()
        .enumerate()
        .filter(|(i, l)| al.get(*i) != Some(l))
        .map(|(_, l)| l.to_string())
        .collect()
}

const G: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

/// The patched model's flange agrees with the error model at random joint vectors (an rng of
/// its own, independent of the writer's verification set).
fn assert_fk_matches(patched_xml: &str, model: &RobotModel, errors: &KinematicErrors, seed: u64) {
    let patched = load(patched_xml)
        .with_couplings(model.added_couplings())
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..50 {
        let q: Vec<f64> = model
            .joints()
            .iter()
            .map(|j| rng.random_range(j.lower.max(-3.0)..j.upper.min(3.0)))
            .collect();
        let want = true_base_from_flange(model, errors, &q, &G).unwrap();
        let got = base_from_flange(&patched, &q).unwrap();
        let dt = (want.translation.vector - got.translation.vector).norm();
        let dr = want.rotation.angle_to(&got.rotation);
        assert!(
            dt <= PATCH_TOLERANCE_M && dr <= PATCH_TOLERANCE_M,
            "{}: Δt = {dt:e} m, Δr = {dr:e} rad at {q:?}",
            model.name()
        );
    }
}

/// `handclasp diagnose --export` on the golden session (robot 2 = hp20 with a 0.12° joint-3
/// offset, identified as 0.12040765519846718°) wrote fixtures/hp20_joint3_offset_golden.urdf
/// (= /work/goldens/ref/export_err/robot2_corrected.urdf). The new writer reproduces it byte for
/// byte.
#[test]
fn hp20_joint3_offset_matches_the_golden_export() {
    let xml = shipped("hp20");
    let model = load(&xml);
    let mut errors = KinematicErrors::zero(model.dof());
    errors.joint_offset[2] = 0.12040765519846718 / (180.0 / std::f64::consts::PI);
    let patched = patch_urdf_text(&xml, &model, &errors).unwrap();
    assert_eq!(patched, fixture("hp20_joint3_offset_golden.urdf"));
    assert_fk_matches(&patched, &model, &errors, 1);
}

/// The previous writer (sim-cell's `correct_urdf_text`, origin xyz errors and joint offsets on
/// several joints) wrote fixtures/{hp20,va1400}_xyz_and_offsets_previous.urdf; the new writer
/// reproduces both byte for byte.
#[test]
fn shipped_urdfs_with_xyz_and_offsets_match_the_previous_writer() {
    for robot in ["hp20", "va1400"] {
        let xml = shipped(robot);
        let model = load(&xml);
        let n = model.dof();
        let mut e = KinematicErrors::zero(n);
        e.origin_xyz[0] = Vector3::new(0.0004, -0.0002, 0.0013);
        e.origin_xyz[1] = Vector3::new(-0.0011, 0.0, 0.0);
        e.origin_xyz[4] = Vector3::new(0.0, 0.00025, -0.0007);
        e.joint_offset[1] = -0.0031;
        e.joint_offset[3] = 0.0017;
        e.joint_offset[n - 1] = 0.0009;
        let patched = patch_urdf_text(&xml, &model, &e).unwrap();
        assert_eq!(
            patched,
            fixture(&format!("{robot}_xyz_and_offsets_previous.urdf")),
            "{robot}"
        );
        assert_fk_matches(&patched, &model, &e, 2);
    }
}

/// fixtures/transmission_first.urdf: a `<transmission>` naming joint_1_s comes before the
/// joint. The previous writer corrected the transmission's `<joint>` and left the real joint
/// wrong (FK off by the whole 11.5 mm correction).
#[test]
fn transmission_first() {
    let xml = fixture("transmission_first.urdf");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.origin_xyz[0].z = 0.0115;
    let patched = patch_urdf_text(&xml, &model, &e).unwrap();
    assert_eq!(
        changed_lines(&xml, &patched),
        [r#"    <origin xyz="0.000000000 0.000000000 0.516500000" rpy="0 0 0"/>"#]
    );
    assert_fk_matches(&patched, &model, &e, 3);
}

/// fixtures/comment_first.urdf: a commented-out `<joint name="joint_1_s">` with an `<origin>`
/// comes first. The previous writer edited the comment; the comment stays as it was.
#[test]
fn comment_first() {
    let xml = fixture("comment_first.urdf");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.origin_xyz[0] = Vector3::new(0.001, 0.0, -0.002);
    e.joint_offset[0] = 0.01;
    let patched = patch_urdf_text(&xml, &model, &e).unwrap();
    let comment = xml.lines().find(|l| l.contains("<!-- old:")).unwrap();
    assert!(patched.contains(comment));
    assert_eq!(patched.matches("<!-- old:").count(), 1);
    let changed = changed_lines(&xml, &patched);
    assert!(
        changed[0].starts_with(r#"    <origin xyz="0.001000000 0.000000000 0.503000000" rpy=""#),
        "{changed:?}"
    );
    assert!(patched.contains(r#"<calibration rising="0.010000000"/>"#));
    assert_fk_matches(&patched, &model, &e, 4);
}

/// fixtures/single_quotes.urdf: joint_1_s's origin uses single quotes. The previous writer
/// looked for `xyz="` only and added a second `xyz` attribute (an XML error).
#[test]
fn single_quotes() {
    let xml = fixture("single_quotes.urdf");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.origin_xyz[0].z = 0.001;
    e.origin_rpy[0].x = 0.002;
    let patched = patch_urdf_text(&xml, &model, &e).unwrap();
    assert_eq!(
        changed_lines(&xml, &patched),
        [
            r#"    <origin xyz='0.000000000 0.000000000 0.506000000' rpy='0.002000000 0.000000000 0.000000000'/>"#
        ]
    );
    assert_fk_matches(&patched, &model, &e, 5);
}

/// Spaces around `=` (legal XML) defeated the previous writer's `xyz="` search too.
#[test]
fn spaces_around_equals() {
    let xml = shipped("hp20").replace(
        r#"<origin xyz="0.15 0 0" rpy="0 0 0"/>"#,
        r#"<origin xyz = "0.15 0 0"  rpy= '0 0 0' />"#,
    );
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.origin_xyz[1].x = -0.001;
    e.joint_offset[1] = 0.001;
    let patched = patch_urdf_text(&xml, &model, &e).unwrap();
    assert_eq!(
        changed_lines(&xml, &patched)[0],
        r#"    <origin xyz = "0.149000000 0.000000000 0.000000000"  rpy= '0.000000000 0.001000000 0.000000000' />"#
    );
    assert_fk_matches(&patched, &model, &e, 6);
}

/// A joint without `<origin>` gets one (indented like its siblings); an `<origin>` without
/// `rpy` gets the attribute.
#[test]
fn missing_origin_and_attribute_are_inserted() {
    let xml = r#"<robot name="arm">
  <link name="base"/><link name="l1"/><link name="tool0"/>
  <joint name="j1" type="revolute">
    <parent link="base"/>
    <child link="l1"/>
    <axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/>
    <child link="tool0"/>
    <origin xyz="0.5 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
</robot>"#;
    let model = load(xml);
    let mut e = KinematicErrors::zero(2);
    e.origin_xyz[0].z = 0.25;
    e.origin_rpy[0].z = 0.1;
    e.joint_offset[1] = -0.2;
    let patched = patch_urdf_text(xml, &model, &e).unwrap();
    assert!(
        patched.contains(
            "<joint name=\"j1\" type=\"revolute\">\n    <origin xyz=\"0.000000000 0.000000000 0.250000000\" rpy=\"0.000000000 0.000000000 0.100000000\"/>\n    <parent"
        ),
        "{patched}"
    );
    assert!(
        patched.contains(r#"<origin rpy="0.000000000 -0.200000000 0.000000000" xyz="0.5 0 0"/>"#),
        "{patched}"
    );
    assert_fk_matches(&patched, &model, &e, 7);
}

#[test]
fn what_a_urdf_cannot_express_is_refused_with_where_it_goes() {
    let xml = shipped("hp20");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.joint_offset[0] = 0.001;
    e.joint_scale[1] = 1e-4;
    e.compliance[2] = 1e-6;
    e.periodic_cos[4] = 1e-4;
    e.tip.z = 0.001;
    e.mount_rpy.x = 0.001;
    let err = patch_urdf_text(&xml, &model, &e).unwrap_err();
    let msg = err.to_string();
    assert!(
        matches!(err, UrdfPatchError::NotExpressible { .. }),
        "{msg}"
    );
    for needle in [
        "joint_scale of joint 2 (joint_2_l)",
        "compliance of joint 3 (joint_3_u)",
        "periodic_sin/periodic_cos of joint 5",
        "flange_from_tip",
        "mount_xyz/mount_rpy",
        "placement",
    ] {
        assert!(msg.contains(needle), "`{needle}` missing from: {msg}");
    }
    // The expressible part goes through; the rest is what was refused.
    let (urdf, rest) = split_for_urdf(&e);
    assert!(patch_urdf_text(&xml, &model, &urdf).is_ok());
    assert_eq!(rest.joint_offset, vec![0.0; 6]);
    assert_eq!((rest.joint_scale[1], rest.tip.z), (1e-4, 0.001));
    assert_eq!(rest.periodic_cos[4], 1e-4);
}

#[test]
fn unusable_text_and_missing_or_duplicate_joints_are_named_errors() {
    let xml = shipped("hp20");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.origin_xyz[2].x = 0.001;
    let err = patch_urdf_text(
        &xml.replace("joint_3_u\" type", "joint_3_x\" type"),
        &model,
        &e,
    )
    .unwrap_err();
    assert!(matches!(err, UrdfPatchError::JointNotFound { .. }), "{err}");
    assert!(err.to_string().contains("joint_3_u"), "{err}");
    let doubled =
        xml.replace("</robot>", "") + &xml[xml.find("  <joint name=\"joint_3_u\"").unwrap()..];
    let err = patch_urdf_text(&doubled, &model, &e).unwrap_err();
    assert!(
        matches!(err, UrdfPatchError::DuplicateJoint { .. }),
        "{err}"
    );
    let err = patch_urdf_text(&xml[..xml.len() / 2], &model, &e).unwrap_err();
    assert!(matches!(err, UrdfPatchError::Xml(_)), "{err}");
    let bad = xml.replace(r#"<origin xyz="0 0 0.76""#, r#"<origin xyz="0 0.76""#);
    let err = patch_urdf_text(&bad, &model, &e).unwrap_err();
    assert!(
        matches!(err, UrdfPatchError::BadOrigin { line: 71, .. }),
        "{err}"
    );
    let mut short = KinematicErrors::zero(3);
    short.joint_offset[0] = 0.1;
    assert!(matches!(
        patch_urdf_text(&xml, &model, &short).unwrap_err(),
        UrdfPatchError::Errors(_)
    ));
}

/// The verification catches a text that does not carry the errors.
#[test]
fn verification_rejects_an_unpatched_text() {
    let xml = shipped("va1400");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    e.origin_xyz[3].y = 2e-9;
    let err = verify_patched_urdf(&xml, &model, &e).unwrap_err();
    assert!(matches!(err, UrdfPatchError::Verification { .. }), "{err}");
    // Zero errors: the error model's general path and the nominal FK agree to round-off.
    assert!(verify_patched_urdf(&xml, &model, &KinematicErrors::zero(7)).unwrap() < 1e-12);
}

/// Corrections below the 9-decimal resolution that add up to more than the tolerance are
/// written with every digit (the 9-decimal text would drop them all).
#[test]
fn sub_nanometre_corrections_are_written_in_full() {
    let xml = shipped("hp20");
    let model = load(&xml);
    let mut e = KinematicErrors::zero(model.dof());
    for k in 0..model.dof() {
        e.origin_xyz[k].z = 4.9e-10;
        e.origin_xyz[k].x = 4.9e-10;
    }
    let patched = patch_urdf_text(&xml, &model, &e).unwrap();
    assert!(
        patched.contains(r#"<origin xyz="0.00000000049 0 0.50500000049" rpy="0 0 0"/>"#),
        "{patched}"
    );
    assert_fk_matches(&patched, &model, &e, 8);
}

/// A 4-joint arm with what the shipped URDFs lack: origin rpy, an oblique axis, fixed joints
/// before, between and after the actuated ones, a continuous joint, a joint without `rpy`.
const OBLIQUE: &str = r#"<robot name="oblique">
  <link name="floor"/><link name="base"/><link name="l1"/><link name="l2"/><link name="l2b"/>
  <link name="l3"/><link name="l4"/><link name="tool0"/>
  <joint name="floor-base" type="fixed"><parent link="floor"/><child link="base"/>
    <origin xyz="0.1 -0.05 0.2" rpy="0.05 -0.1 0.3"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.15 0 0.1" rpy="0.3 -0.2 0.1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="l2-l2b" type="fixed"><parent link="l2"/><child link="l2b"/>
    <origin xyz="0.3 0.02 0.1" rpy="0.2 0.1 -0.4"/></joint>
  <joint name="j3" type="revolute"><parent link="l2b"/><child link="l3"/>
    <origin xyz="0 0.05 0.5" rpy="-0.1 0.25 0.5"/><axis xyz="0.3 -0.5 0.8"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.6 0 0" rpy="1.2 0 -0.3"/><axis xyz="-1 0 0"/></joint>
  <joint name="l4-tool0" type="fixed"><parent link="l4"/><child link="tool0"/>
    <origin xyz="0.05 0 0.01" rpy="0 1.5707963267948966 0.2"/></joint>
</robot>"#;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Random origin xyz (±5 mm), origin rpy (±0.05 rad) and joint offset (±0.05 rad, or m
    /// for a prismatic joint) errors, each joint's kinds switched on at random: the patched
    /// URDF's flange equals the nominal model plus the errors to PATCH_TOLERANCE_M at 50 random
    /// joint vectors. Also on a rail under an arm, a chain with prismatic joints and a mimic
    /// (with and without a coupling declared beside the URDF) and a coupled torso: a prismatic
    /// offset is folded into the origin xyz, a coupled joint's into its own origin.
    #[test]
    fn patched_fk_equals_nominal_plus_errors(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let j4 = JointCoupling {
            joint: "j4".into(),
            terms: vec![("j1".into(), 0.5), ("lift".into(), -2.0)],
            offset: 0.3,
        };
        for (xml, couplings) in [
            (shipped("hp20"), vec![]),
            (shipped("va1400"), vec![]),
            (OBLIQUE.to_string(), vec![]),
            (fixture("rail_6r.urdf"), vec![]),
            (fixture("mixed_chain.urdf"), vec![]),
            (fixture("mixed_chain.urdf"), vec![j4.clone()]),
            (fixture("mimic_torso.urdf"), vec![]),
        ] {
            let model = load(&xml).with_couplings(&couplings).unwrap();
            let mut e = KinematicErrors::zero_for(&model);
            for k in 0..model.chain_joints().len() {
                if rng.random_bool(0.6) {
                    e.origin_xyz[k] = Vector3::from_fn(|_, _| rng.random_range(-0.005..0.005));
                }
                if rng.random_bool(0.4) {
                    e.origin_rpy[k] = Vector3::from_fn(|_, _| rng.random_range(-0.05..0.05));
                }
                if rng.random_bool(0.6) {
                    e.joint_offset[k] = rng.random_range(-0.05..0.05);
                }
            }
            let patched = patch_urdf_text(&xml, &model, &e).unwrap();
            assert_fk_matches(&patched, &model, &e, seed);
        }
    }
}

/// A prismatic joint's offset (m) moves its origin along its axis: 5 mm on the rail (axis x of a
/// frame turned 0.2 rad about z) is xyz + 5 mm·(cos 0.2, sin 0.2, 0), recorded as a calibration in
/// m; the arm's joints are untouched.
#[test]
fn a_prismatic_offset_moves_the_origin_along_the_axis() {
    let xml = fixture("rail_6r.urdf");
    let model = load(&xml);
    let mut e = KinematicErrors::zero_for(&model);
    e.joint_offset[0] = 0.005;
    let patched = patch_urdf_text(&xml, &model, &e).unwrap();
    let (s, c) = 0.2f64.sin_cos();
    let want = format!(
        r#"<origin xyz="{:.9} {:.9} 0.300000000" rpy="0 0 0.2"/>"#,
        0.005 * c,
        0.005 * s
    );
    assert!(patched.contains(&want), "{patched}");
    assert!(patched.contains("joint offset 0.005000000 m folded into origin xyz"));
    assert!(patched.contains(r#"<calibration rising="0.005000000"/>"#));
    // Nothing else changed: undo the three edits and get the input back.
    let undone = patched
        .replace(&want, r#"<origin xyz="0 0 0.3" rpy="0 0 0.2"/>"#)
        .replace(
            "    <!-- handclasp diagnose: joint offset 0.005000000 m folded into origin xyz -->\n",
            "",
        )
        .replace("    <calibration rising=\"0.005000000\"/>\n", "");
    assert_eq!(undone, xml);
    assert_fk_matches(&patched, &model, &e, 5);
}
