//! Property tests of the kinematics crate (issue 10, "Fuzzing and properties"), beside the
//! fuzz targets in `fuzz/`:
//! - a converged IK is within the joint limits and puts the tip on its target to the tolerance it
//!   was given, on every shipped robot, for reachable and arbitrary targets, with and without a
//!   tool axis (`kinematics.rs` checks fixed round trips at the default tolerance only);
//! - a corrected URDF's FK equals nominal + errors on the shipped Motoman arms and the chains of
//!   the test fixtures (`urdf_patch.rs` covers hp20, va1400 and an oblique-axis chain).

use std::path::Path;

use kinematics::*;
use nalgebra::{Point3, Unit, Vector3};
use proptest::prelude::*;

/// Slack on top of the IK's tolerance for a fresh FK of its answer: round-off of a metre-scale
/// tip position (a few ulps of sums of ~10 terms of size ≤ 3 m).
const FK_ROUND_OFF_M: f64 = 1e-12;

const ROBOTS: [&str; 4] = ["hp20", "va1400", "motoman_right_arm", "motoman_left_arm"];

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap()
}

fn robot(name: &str) -> RobotModel {
    RobotModel::from_urdf_str(&read(&format!("../../robots/{name}.urdf")), "tool0").unwrap()
}

/// Joint `k` at fraction `f` ∈ [0, 1] of its range (±π for a continuous joint).
fn at_fraction(model: &RobotModel, fractions: &[f64]) -> Vec<f64> {
    model
        .joints()
        .iter()
        .enumerate()
        .map(|(k, j)| {
            let (lo, hi) = if j.lower.is_finite() && j.upper.is_finite() {
                (j.lower, j.upper)
            } else {
                (-std::f64::consts::PI, std::f64::consts::PI)
            };
            lo + (hi - lo) * fractions[k % fractions.len()]
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Targets: FK of a joint vector anywhere in the limits (reachable) or a point in a 6 m cube
    /// around the base (often not); tolerance 1e-4 … 1e-10 m; optionally the flange axis of the
    /// reachable pose. Every Ok solution is within the limits; a converged one is within its
    /// position tolerance (+ FK round-off) and, with an axis, within its axis tolerance.
    #[test]
    fn converged_ik_is_within_limits_and_on_target(
        which in 0..ROBOTS.len(),
        fractions in proptest::collection::vec(0.0..=1.0f64, 7),
        box_target in proptest::option::of(proptest::array::uniform3(-3.0..3.0f64)),
        tip_z in 0.0..0.3f64,
        tol_exp in 4..=10i32,
        with_axis in any::<bool>(),
        restarts in 0..6usize,
    ) {
        let model = robot(ROBOTS[which]);
        let tip = Vector3::new(0.0, 0.0, tip_z);
        let q = at_fraction(&model, &fractions);
        let pose = base_from_tip(&model, &q, &tip).unwrap();
        let target = match box_target {
            Some(p) => Point3::from(p),
            None => Point3::from(pose.translation.vector),
        };
        let options = IkOptions {
            tool_axis_base: (with_axis && box_target.is_none())
                .then(|| Unit::new_normalize(pose.rotation * Vector3::z())),
            tolerance_m: 10f64.powi(-tol_exp),
            axis_tolerance_rad: 10f64.powi(-tol_exp),
            restarts,
            ..IkOptions::default()
        };
        let sol = ik_tip_position(&model, &target, &tip, &options).unwrap();
        prop_assert!(model.check_q(&sol.q).is_ok(), "{:?} outside the limits", sol.q);
        prop_assert_eq!(sol.reachable(), sol.stop_reason == IkStopReason::Converged);
        if sol.reachable() {
            let reached = base_from_tip(&model, &sol.q, &tip).unwrap();
            let miss = (reached.translation.vector - target.coords).norm();
            prop_assert!(
                miss <= options.tolerance_m + FK_ROUND_OFF_M,
                "{}: misses by {miss} m at tolerance {} m", ROBOTS[which], options.tolerance_m
            );
            prop_assert!(sol.position_error_m <= options.tolerance_m);
            if let Some(axis) = options.tool_axis_base {
                let z = reached.rotation * Vector3::z();
                // atan2(|z × a|, z·a): `Vector3::angle` goes through acos, which cannot resolve
                // angles below ~1.5e-8 rad (it reported 2^-26 rad for a converged 1e-8 solve).
                let angle = z.cross(&axis).norm().atan2(z.dot(&axis));
                prop_assert!(angle <= options.axis_tolerance_rad + FK_ROUND_OFF_M, "axis off by {angle} rad");
            }
        }
    }
}

/// `(URDF text, tool link)` of the chains the URDF-patch property runs on.
fn patch_chains() -> Vec<(String, &'static str)> {
    vec![
        (read("../../robots/motoman_right_arm.urdf"), "tool0"),
        (read("../../robots/motoman_left_arm.urdf"), "tool0"),
        (read("tests/fixtures/world_root.urdf"), "tool0"),
        (read("tests/fixtures/transmission_first.urdf"), "tool0"),
        (read("tests/fixtures/ros_industrial_branches.urdf"), "tool0"),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// Origin xyz (±5 mm), origin rpy (±0.05 rad) and joint offset (±0.05 rad) errors on every
    /// joint: the patched URDF's flange equals `true_base_from_flange` of (nominal, errors) to
    /// [`PATCH_TOLERANCE_M`] at joint vectors spread over the limits.
    #[test]
    fn patched_fk_equals_nominal_plus_errors_on_more_chains(
        xyz in proptest::collection::vec(proptest::array::uniform3(-0.005..0.005f64), 8),
        rpy in proptest::collection::vec(proptest::array::uniform3(-0.05..0.05f64), 8),
        offsets in proptest::collection::vec(-0.05..0.05f64, 8),
        fractions in proptest::collection::vec(proptest::collection::vec(0.0..=1.0f64, 8), 5),
    ) {
        for (xml, tool) in patch_chains() {
            let model = RobotModel::from_urdf_str(&xml, tool).unwrap();
            let n = model.dof();
            let mut errors = KinematicErrors::zero(n);
            for k in 0..n {
                errors.origin_xyz[k] = Vector3::from(xyz[k % 8]);
                errors.origin_rpy[k] = Vector3::from(rpy[k % 8]);
                errors.joint_offset[k] = offsets[k % 8];
            }
            let patched = patch_urdf_text(&xml, &model, &errors).unwrap();
            let patched_model = RobotModel::from_urdf_str(&patched, tool).unwrap();
            for f in &fractions {
                let q = at_fraction(&model, f);
                let want = true_base_from_flange(&model, &errors, &q, &Vector3::zeros()).unwrap();
                let got = base_from_flange(&patched_model, &q).unwrap();
                let dp = (want.translation.vector - got.translation.vector).norm();
                let da = want.rotation.angle_to(&got.rotation);
                prop_assert!(dp <= PATCH_TOLERANCE_M && da <= PATCH_TOLERANCE_M, "{tool}: {dp} m, {da} rad");
            }
        }
    }
}
