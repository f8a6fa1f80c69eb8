//! Test fixtures shared by the unit tests of the crate: the shipped URDFs, small hand-made
//! arms, and seeded random joint vectors.

use nalgebra::Vector3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::coupling::JointCoupling;
use crate::error_model::{all_params_for, KinematicErrors};
use crate::model::RobotModel;

/// robots/va1400.urdf (7 axes).
pub(crate) const VA1400: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../robots/va1400.urdf"
));
/// robots/hp20.urdf (6 axes).
pub(crate) const HP20: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../robots/hp20.urdf"
));

/// A 4-joint test arm that exercises what the shipped URDFs do not: non-zero origin rpy, a
/// fixed joint between two actuated joints, an oblique axis, a fixed joint before the first
/// actuated joint and a rotated tool0. `origins[k]` = (xyz, rpy) of actuated joint k.
pub(crate) fn oblique_urdf(origins: &[(Vector3<f64>, Vector3<f64>); 4]) -> String {
    let o = |k: usize| {
        let (x, r) = &origins[k];
        format!(
            r#"<origin xyz="{:e} {:e} {:e}" rpy="{:e} {:e} {:e}"/>"#,
            x.x, x.y, x.z, r.x, r.y, r.z
        )
    };
    let link = |name: &str, com: &str, mass: f64| {
        format!(
            r#"<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>
            <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>"#
        )
    };
    let lim = r#"<limit lower="-3" upper="3" effort="100" velocity="1"/>"#;
    format!(
        r#"<robot name="oblique">
        <link name="floor"/>
        {}{}{}{}{}{}
        <link name="tool0"/>
        <joint name="world-base" type="fixed"><parent link="floor"/><child link="base"/>
          <origin xyz="0.1 -0.05 0.2" rpy="0.05 -0.1 0.3"/></joint>
        <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{}<axis xyz="0 0 1"/>{lim}</joint>
        <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>{}<axis xyz="0 1 0"/>{lim}</joint>
        <joint name="l2-l2b" type="fixed"><parent link="l2"/><child link="l2b"/>
          <origin xyz="0.3 0.02 0.1" rpy="0.2 0.1 -0.4"/></joint>
        <joint name="j3" type="revolute"><parent link="l2b"/><child link="l3"/>{}<axis xyz="0.3 -0.5 0.8"/>{lim}</joint>
        <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>{}<axis xyz="-1 0 0"/></joint>
        <joint name="l4-tool0" type="fixed"><parent link="l4"/><child link="tool0"/>
          <origin xyz="0.05 0 0.01" rpy="0 1.5707963267948966 0.2"/></joint>
        </robot>"#,
        link("base", "0 0 0.1", 20.0),
        link("l1", "0.05 0 0.2", 15.0),
        link("l2", "0.2 0 0.05", 10.0),
        link("l2b", "0.1 0.01 0", 4.0),
        link("l3", "0 0.1 0.3", 6.0),
        link("l4", "0.04 0 0", 2.0),
        o(0),
        o(1),
        o(2),
        o(3),
    )
}

pub(crate) fn oblique_origins() -> [(Vector3<f64>, Vector3<f64>); 4] {
    [
        (Vector3::new(0.0, 0.0, 0.4), Vector3::new(0.0, 0.0, 0.0)),
        (Vector3::new(0.15, 0.0, 0.1), Vector3::new(0.3, -0.2, 0.1)),
        (Vector3::new(0.0, 0.05, 0.5), Vector3::new(-0.1, 0.25, 0.5)),
        (Vector3::new(0.6, 0.0, 0.0), Vector3::new(1.2, 0.0, -0.3)),
    ]
}

/// tests/fixtures/rail_6r.urdf: the hp20 on a 4 m track (a prismatic first joint).
pub(crate) const RAIL_6R: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/rail_6r.urdf"
));

/// tests/fixtures/mimic_torso.urdf: a torso with a `<mimic>` joint and a 4-joint arm.
pub(crate) const MIMIC_TORSO: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/mimic_torso.urdf"
));

/// tests/fixtures/mixed_chain.urdf: a 6-joint chain mixing what the shipped URDFs do not have: a prismatic joint on an oblique
/// axis first (`rail`, −0.5..1.5 m), a prismatic joint in the middle with a rotated origin
/// (`lift`, 0..0.4 m), a revolute joint on an oblique axis that mimics `j2` (`j3`: multiplier
/// −1, offset 0.1 rad), a continuous joint, fixed joints before the chain and before tool0, and
/// inertials on every link.
pub(crate) const MIXED: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/mixed_chain.urdf"
));

/// The one-to-many coupling [`mixed_coupled`] adds: `j4 = 0.5·j1 − 2·lift + 0.3` (rad; the lift
/// coefficient in rad/m).
pub(crate) fn mixed_j4_coupling() -> JointCoupling {
    JointCoupling {
        joint: "j4".into(),
        terms: vec![("j1".into(), 0.5), ("lift".into(), -2.0)],
        offset: 0.3,
    }
}

/// [`MIXED`] with [`mixed_j4_coupling`]: chain rail, j1, j2, lift, j3, j4; independent rail, j1,
/// j2, lift.
pub(crate) fn mixed_coupled() -> RobotModel {
    model(MIXED)
        .with_couplings(&[mixed_j4_coupling()])
        .expect("the coupling applies")
}

pub(crate) fn model(xml: &str) -> RobotModel {
    RobotModel::from_urdf_str(xml, "tool0").expect("test URDF loads")
}

/// The shipped arms, the oblique test arm, the rail-mounted hp20, the mixed chain with its URDF
/// mimic only and with the added one-to-many coupling, and the mimic torso.
pub(crate) fn robots() -> Vec<RobotModel> {
    vec![
        model(VA1400),
        model(HP20),
        model(&oblique_urdf(&oblique_origins())),
        model(RAIL_6R),
        model(MIXED),
        mixed_coupled(),
        model(MIMIC_TORSO),
    ]
}

/// Gravity of a floor-mounted robot, m/s², base frame.
pub(crate) const G_FLOOR: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

pub(crate) fn random_q(model: &RobotModel, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model
        .joints()
        .iter()
        .map(|j| {
            let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
            rng.random_range(lo + 0.05 * (hi - lo)..hi - 0.05 * (hi - lo))
        })
        .collect()
}

pub(crate) fn random_vec(rng: &mut ChaCha8Rng, s: f64) -> Vector3<f64> {
    Vector3::new(
        rng.random_range(-s..s),
        rng.random_range(-s..s),
        rng.random_range(-s..s),
    )
}

/// Two-link planar arm in the x–z plane, both axes +y, with a fixed joint carrying extra mass
/// and a non-trivial origin rotation: small enough to compute τ by hand.
pub(crate) const PLANAR: &str = r#"<robot name="planar">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.25 0 0"/><mass value="1"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="tool0"><inertial><origin xyz="0 0 0"/><mass value="3"/>
    <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="1 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2-tool0" type="fixed"><parent link="l2"/><child link="tool0"/>
    <origin xyz="0.5 0 0" rpy="0 1.5707963267948966 0"/></joint>
</robot>"#;

/// A two-joint arm (revolute with limits −1..2 rad, then continuous), tool link `tool0`.
pub(crate) const TWO_JOINT: &str = r#"<robot name="r"><link name="a"/><link name="b"/><link name="tool0"/>
            <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
              <axis xyz="0 0 1"/><limit lower="-1" upper="2" effort="1" velocity="1"/></joint>
            <joint name="j2" type="continuous"><parent link="b"/><child link="tool0"/>
              <origin xyz="1 0 0"/><axis xyz="0 1 0"/></joint></robot>"#;

/// Random errors of realistic-to-large size for `model`'s chain joints. The angles are large (up
/// to 0.3–0.5 rad) on purpose: the Jacobian must be exact, not a small-angle approximation. A
/// prismatic joint's offset is then up to 5 cm, its compliance up to 2e-5 m/N, and it has no
/// periodic terms.
pub(crate) fn random_errors(model: &RobotModel, rng: &mut ChaCha8Rng) -> KinematicErrors {
    let dof = model.chain_joints().len();
    let mut e = KinematicErrors::zero(dof);
    for j in 0..dof {
        e.joint_offset[j] = rng.random_range(-0.05..0.05);
        e.joint_scale[j] = rng.random_range(-0.01..0.01);
        e.origin_xyz[j] = random_vec(rng, 0.01);
        e.origin_rpy[j] = random_vec(rng, 0.3);
        e.compliance[j] = rng.random_range(-2e-5..2e-5);
        e.periodic_sin[j] = rng.random_range(-0.01..0.01);
        e.periodic_cos[j] = rng.random_range(-0.01..0.01);
    }
    e.tip = random_vec(rng, 0.05);
    e.mount_xyz = random_vec(rng, 0.5);
    e.mount_rpy = random_vec(rng, 0.5);
    // Zero about a third of the parameters (all of a joint's origin rpy, say), so that the
    // mixed paths (nominal step for some joints, perturbed for others; xyz-only origin
    // errors) are exercised too.
    for p in all_params_for(model) {
        if rng.random_range(0..3) == 0 {
            e.set(p, 0.0);
        }
    }
    for (j, joint) in model.chain_joints().iter().enumerate() {
        if joint.kind.is_prismatic() {
            e.periodic_sin[j] = 0.0;
            e.periodic_cos[j] = 0.0;
        }
    }
    for j in 0..dof {
        match rng.random_range(0..4) {
            0 => e.origin_rpy[j] = Vector3::zeros(),
            1 => e.origin_xyz[j] = Vector3::zeros(),
            _ => {}
        }
    }
    e
}
