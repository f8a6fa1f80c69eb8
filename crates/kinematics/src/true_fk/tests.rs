//! Tests of the true chain and its Jacobians against central differences and independent
//! constructions.

use super::*;
use crate::all_params_for;
use crate::fk::base_from_tip;
use crate::test_fixtures::{
    model, oblique_origins, oblique_urdf, random_errors, random_q, random_vec, robots, G_FLOOR,
    HP20, VA1400,
};
use nalgebra::{Rotation3, Translation3, UnitQuaternion};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_tip(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(
        rng.random_range(-0.05..0.05),
        rng.random_range(-0.05..0.05),
        rng.random_range(0.0..0.3),
    )
}

fn random_g(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    // Any direction: floor, wall and ceiling mounts and everything between.
    let v = random_vec(rng, 1.0);
    9.81 * v / v.norm().max(1e-3)
}

/// Central-difference step in the parameter's own unit. A step of 1e-6 moves the tip by
/// ~1e-6 m for the metre and radian parameters. A compliance is multiplied by torques of up to
/// ~5e3 N·m (HP20), so its step is 1e-6 / 5e3 ≈ 2e-10 rad/(N·m) for the same tip motion.
fn fd_step(p: ErrorParam) -> f64 {
    match p {
        ErrorParam::Compliance { .. } => 2e-10,
        _ => 1e-6,
    }
}

/// Tolerance of a central difference with a tip motion of ~1e-6 m per step: truncation
/// ~h²·|p'''| ≲ 1e-12·few m, round-off ~eps·|p|/h ≈ 2.2e-16·3 m/1e-6 ≈ 7e-10 m per unit step.
/// So |analytic − fd|·h ≤ 1e-14 m + 1e-8 relative: compare the tip motions `column·h`.
const FD_TOL_M: f64 = 1e-14;
const FD_TOL_REL: f64 = 1e-7;

fn check_param_jacobian(model: &RobotModel, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let q = random_q(model, &mut rng);
    let errors = random_errors(model, &mut rng);
    let tip = random_tip(&mut rng);
    let g = random_g(&mut rng);
    let params = all_params_for(model);
    let jac = tip_error_jacobian(model, &errors, &q, &tip, &g, &params).unwrap();
    for (c, &p) in params.iter().enumerate() {
        let h = fd_step(p);
        let mut ep = errors.clone();
        let mut em = errors.clone();
        ep.add(p, h);
        em.add(p, -h);
        let tp = true_base_from_tip(model, &ep, &q, &tip, &g)
            .unwrap()
            .translation
            .vector;
        let tm = true_base_from_tip(model, &em, &q, &tip, &g)
            .unwrap()
            .translation
            .vector;
        // Tip motion over the central step, m.
        let fd_motion = (tp - tm) / 2.0;
        let an_motion = jac.column(c) * h;
        let diff = (fd_motion - an_motion).norm();
        assert!(
            diff <= FD_TOL_M + FD_TOL_REL * an_motion.norm().max(1e-9),
            "{} seed {seed} {p}: analytic {:?} vs fd {:?} (per unit), |Δ|·h = {diff:e} m",
            model.name(),
            jac.column(c).as_slice(),
            (fd_motion / h).as_slice(),
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn error_jacobian_matches_central_differences(seed in any::<u64>()) {
        for m in robots() {
            check_param_jacobian(&m, seed);
        }
    }

    /// The one-walk pose and Jacobian equal the two separate calls bit for bit: random errors
    /// (every kind, compliance included), zero errors (the nominal shortcut), and compliance
    /// columns asked for with every compliance zero; every parameter column, and the joint
    /// offsets alone.
    #[test]
    fn tip_with_error_jacobian_equals_the_two_calls(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for m in robots() {
            let q = random_q(&m, &mut rng);
            let tip = random_tip(&mut rng);
            let g = random_g(&mut rng);
            let random = random_errors(&m, &mut rng);
            let mut no_compliance = random.clone();
            no_compliance.compliance.iter_mut().for_each(|c| *c = 0.0);
            let all = all_params_for(&m);
            let offsets: Vec<ErrorParam> = all
                .iter()
                .copied()
                .filter(|p| matches!(p, ErrorParam::JointOffset { .. }))
                .collect();
            for errors in [random, no_compliance, KinematicErrors::zero_for(&m)] {
                for params in [&all, &offsets] {
                    let (pose, jac) =
                        true_tip_with_error_jacobian(&m, &errors, &q, &tip, &g, params).unwrap();
                    prop_assert_eq!(pose, true_base_from_tip(&m, &errors, &q, &tip, &g).unwrap());
                    prop_assert_eq!(
                        &jac,
                        &tip_error_jacobian(&m, &errors, &q, &tip, &g, params).unwrap()
                    );
                    // The prepared inputs give the same values, bit for bit.
                    let prepared = PreparedTip::new(&m, &errors, &tip, &g, params).unwrap();
                    prop_assert_eq!(&prepared.tip_with_error_jacobian(&q).unwrap(), &(pose, jac));
                    prop_assert_eq!(prepared.tip(&q).unwrap(), pose);
                    // A joint vector of the wrong length is an error, not a panic.
                    prop_assert!(prepared.tip_with_error_jacobian(&q[1..]).is_err());
                    prop_assert!(prepared.tip(&q[1..]).is_err());
                }
            }
        }
    }

    #[test]
    fn zero_errors_reproduce_nominal_fk_exactly(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for m in robots() {
            let q = random_q(&m, &mut rng);
            let tip = random_tip(&mut rng);
            let g = random_g(&mut rng);
            let nominal = base_from_tip(&m, &q, &tip).unwrap();
            let zero = KinematicErrors::zero_for(&m);
            let t = true_base_from_tip(&m, &zero, &q, &tip, &g).unwrap();
            prop_assert_eq!(t, nominal);
            // The general path (no zero shortcut) agrees to round-off.
            let general = true_tip_general(&m, &zero, &q, &tip, &g, None);
            prop_assert!((general.translation.vector - nominal.translation.vector).norm() < EXACT_TOL);
            prop_assert!(general.rotation.angle_to(&nominal.rotation) < EXACT_TOL);
            // And the flange agrees as well.
            let flange = true_base_from_flange(&m, &zero, &q, &g).unwrap();
            let nominal_flange = crate::base_from_flange(&m, &q).unwrap();
            prop_assert!((flange.translation.vector - nominal_flange.translation.vector).norm() < EXACT_TOL);
            prop_assert!(flange.rotation.angle_to(&nominal_flange.rotation) < EXACT_TOL);
        }
    }

    #[test]
    fn joint_jacobian_true_matches_central_differences(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for m in robots() {
            let q = random_q(&m, &mut rng);
            let errors = random_errors(&m, &mut rng);
            let tip = random_tip(&mut rng);
            let g = random_g(&mut rng);
            let jac = tip_joint_jacobian_true(&m, &errors, &q, &tip, &g).unwrap();
            // Step 1e-6 rad, tolerance as for the parameter Jacobian (tip motions ~1e-6 m).
            let h = 1e-6;
            for i in 0..m.dof() {
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[i] += h;
                qm[i] -= h;
                let tp = true_base_from_tip(&m, &errors, &qp, &tip, &g).unwrap().translation.vector;
                let tm = true_base_from_tip(&m, &errors, &qm, &tip, &g).unwrap().translation.vector;
                let fd_motion = (tp - tm) / 2.0;
                let an_motion = jac.column(i) * h;
                let diff = (fd_motion - an_motion).norm();
                prop_assert!(
                    diff <= FD_TOL_M + FD_TOL_REL * an_motion.norm().max(1e-9),
                    "{} joint {}: |Δ|·h = {:e} m", m.name(), i + 1, diff
                );
            }
        }
    }
}

/// The joint terms of `e` (offset, scale, compliance, periodic), everything else zero.
fn joint_terms_only(e: &KinematicErrors) -> KinematicErrors {
    let mut only = KinematicErrors::zero(e.dof());
    only.joint_offset.clone_from(&e.joint_offset);
    only.joint_scale.clone_from(&e.joint_scale);
    only.compliance.clone_from(&e.compliance);
    only.periodic_sin.clone_from(&e.periodic_sin);
    only.periodic_cos.clone_from(&e.periodic_cos);
    only
}

/// The contract's true joint values, written out with libm's sin and cos: the chain's reported
/// values `q_rep` and gravity torques `tau`.
fn true_values_by_hand(e: &KinematicErrors, q_rep: &[f64], tau: &[f64]) -> Vec<f64> {
    (0..q_rep.len())
        .map(|i| {
            q_rep[i] * (1.0 + e.joint_scale[i])
                + e.joint_offset[i]
                + e.compliance[i] * tau[i]
                + e.periodic_sin[i] * q_rep[i].sin()
                + e.periodic_cos[i] * q_rep[i].cos()
        })
        .collect()
}

/// Exact-arithmetic comparisons of metre-scale poses (a few ulps).
const EXACT_TOL: f64 = 1e-12;

fn assert_pose_eq(a: &Isometry3<f64>, b: &Isometry3<f64>, what: &str) {
    let dt = (a.translation.vector - b.translation.vector).norm();
    let dr = a.rotation.angle_to(&b.rotation);
    assert!(
        dt < EXACT_TOL && dr < EXACT_TOL,
        "{what}: Δt = {dt:e} m, Δr = {dr:e} rad"
    );
}

/// The semantics of each error kind, against independent constructions: a URDF with the
/// modified origins, nominal FK at modified angles, the mount composed in front.
#[test]
fn each_error_kind_means_what_the_contract_says() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let origins = oblique_origins();
    let m = model(&oblique_urdf(&origins));
    let n = m.dof();
    let q = random_q(&m, &mut rng);
    let tip = random_tip(&mut rng);
    let g = random_g(&mut rng);
    let e = random_errors(&m, &mut rng);

    // Origins: a URDF with xyz + origin_xyz, rpy + origin_rpy.
    let mut only = KinematicErrors::zero(n);
    only.origin_xyz.clone_from(&e.origin_xyz);
    only.origin_rpy.clone_from(&e.origin_rpy);
    let mut modified = origins;
    for (k, o) in modified.iter_mut().enumerate() {
        o.0 += e.origin_xyz[k];
        o.1 += e.origin_rpy[k];
    }
    let m_mod = model(&oblique_urdf(&modified));
    assert_pose_eq(
        &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
        &base_from_tip(&m_mod, &q, &tip).unwrap(),
        "origin errors",
    );

    // Joint offset, scale, compliance and the periodic first harmonic: nominal FK at q_true.
    let only = joint_terms_only(&e);
    assert!(
        e.periodic_sin
            .iter()
            .chain(&e.periodic_cos)
            .any(|v| *v != 0.0),
        "the draw must set some periodic term"
    );
    let tau = crate::gravity_torques(&m, &q, &g).unwrap();
    let q_true = true_values_by_hand(&e, &q, &tau);
    assert!(
        tau.iter().any(|t| t.abs() > 1.0),
        "the test arm must feel gravity: {tau:?}"
    );
    assert_pose_eq(
        &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
        &base_from_tip(&m, &q_true, &tip).unwrap(),
        "joint errors",
    );

    // Tip: added to flange_from_tip in flange axes.
    let mut only = KinematicErrors::zero(n);
    only.tip = e.tip;
    assert_pose_eq(
        &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
        &base_from_tip(&m, &q, &(tip + e.tip)).unwrap(),
        "tip error",
    );

    // Mount: nominal_base_from_base in front, R = Rz·Ry·Rx.
    let mut only = KinematicErrors::zero(n);
    only.mount_xyz = e.mount_xyz;
    only.mount_rpy = e.mount_rpy;
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), e.mount_rpy.z)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), e.mount_rpy.y)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), e.mount_rpy.x);
    let nominal_base_from_base = Isometry3::from_parts(
        Translation3::from(e.mount_xyz),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    assert_pose_eq(
        &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
        &(nominal_base_from_base * base_from_tip(&m, &q, &tip).unwrap()),
        "mount error",
    );

    // All together, and true_base_from_flange consistent with the tip.
    let flange = true_base_from_flange(&m, &e, &q, &g).unwrap();
    let t = true_base_from_tip(&m, &e, &q, &tip, &g).unwrap();
    assert_pose_eq(
        &t,
        &Isometry3::from_parts(
            Translation3::from((flange * nalgebra::Point3::from(tip + e.tip)).coords),
            flange.rotation,
        ),
        "flange vs tip",
    );
}

#[test]
fn gravity_direction_only_matters_through_compliance() {
    let m = model(HP20);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let q = random_q(&m, &mut rng);
    let tip = random_tip(&mut rng);
    let mut e = random_errors(&m, &mut rng);
    e.compliance.iter_mut().for_each(|c| *c = 0.0);
    let a = true_base_from_tip(&m, &e, &q, &tip, &G_FLOOR).unwrap();
    let b = true_base_from_tip(&m, &e, &q, &tip, &(-G_FLOOR)).unwrap();
    assert_eq!(a, b);
    e.compliance[1] = 1e-5;
    let c = true_base_from_tip(&m, &e, &q, &tip, &(-G_FLOOR)).unwrap();
    assert!((a.translation.vector - c.translation.vector).norm() > 1e-4);
}

#[test]
fn bad_inputs_are_named_errors() {
    let m = model(VA1400);
    let q = vec![0.1; m.dof()];
    let tip = Vector3::new(0.0, 0.0, 0.1);
    let short = KinematicErrors::zero(m.dof() - 1);
    let err = true_base_from_tip(&m, &short, &q, &tip, &G_FLOOR).unwrap_err();
    assert!(err.to_string().contains("joint_offset"), "{err}");
    let mut short_periodic = KinematicErrors::zero(m.dof());
    short_periodic.periodic_cos.pop();
    let err = true_base_from_tip(&m, &short_periodic, &q, &tip, &G_FLOOR).unwrap_err();
    assert!(err.to_string().contains("periodic_cos"), "{err}");
    let mut nan = KinematicErrors::zero(m.dof());
    nan.origin_rpy[2].y = f64::NAN;
    let err = true_base_from_tip(&m, &nan, &q, &tip, &G_FLOOR).unwrap_err();
    assert!(
        err.to_string().contains("origin_rpy") && err.to_string().contains("joint 3"),
        "{err}"
    );
    let zero = KinematicErrors::zero(m.dof());
    let err = tip_error_jacobian(
        &m,
        &zero,
        &q,
        &tip,
        &G_FLOOR,
        &[ErrorParam::JointOffset { joint: 7 }],
    )
    .unwrap_err();
    assert!(err.to_string().contains("joint 8"), "{err}");
    assert!(true_base_from_tip(&m, &zero, &q[..3], &tip, &G_FLOOR).is_err());
    assert!(
        true_base_from_tip(&m, &zero, &q, &Vector3::new(f64::NAN, 0.0, 0.0), &G_FLOOR).is_err()
    );
    assert!(
        true_base_from_tip(&m, &zero, &q, &tip, &Vector3::new(0.0, 0.0, f64::INFINITY)).is_err()
    );
}

/// Errors, tip offset, gravity, parameters, and a word the error must name.
type BadTipInputs<'a> = (
    &'a KinematicErrors,
    Vector3<f64>,
    Vector3<f64>,
    &'a [ErrorParam],
    &'static str,
);

/// `check_tip_inputs` on its own: it accepts good inputs whatever the joint values (it does not
/// check them: a short or non-finite `q` is `RobotModel::check_q`'s), and it refuses each bad
/// input with the error the checked `true_tip_with_error_jacobian` gives for it at good joint
/// values, in the documented order: tip offset, gravity, errors, then each parameter.
#[test]
fn check_tip_inputs_refuses_what_the_checked_call_refuses_in_its_order() {
    use crate::test_fixtures::RAIL_6R;
    for m in [model(VA1400), model(RAIL_6R)] {
        let q = vec![0.1; m.dof()];
        let tip = Vector3::new(0.0, 0.0, 0.1);
        let good = KinematicErrors::zero_for(&m);
        let params = all_params_for(&m);
        check_tip_inputs(&m, &good, &tip, &G_FLOOR, &params).unwrap();
        // The joint values are not its business: the checked call refuses a short `q` that
        // these same inputs pass.
        assert!(true_tip_with_error_jacobian(&m, &good, &q[..2], &tip, &G_FLOOR, &params).is_err());

        let nan_tip = Vector3::new(f64::NAN, 0.0, 0.0);
        let inf_g = Vector3::new(0.0, 0.0, f64::INFINITY);
        let mut nan_errors = good.clone();
        nan_errors.origin_rpy[2].y = f64::NAN;
        let mut short = good.clone();
        short.joint_offset.pop();
        let past_the_chain = [ErrorParam::JointOffset {
            joint: m.chain_joints().len(),
        }];
        // (errors, tip, gravity, params, a word the error names): one bad input each, then
        // several at once, where the first in the documented order must be the one named.
        let cases: Vec<BadTipInputs<'_>> = vec![
            (&good, nan_tip, G_FLOOR, &params, "tip"),
            (&good, tip, inf_g, &params, "gravity"),
            (&nan_errors, tip, G_FLOOR, &params, "origin_rpy"),
            (&short, tip, G_FLOOR, &params, "joint_offset"),
            (&good, tip, G_FLOOR, &past_the_chain, "joint"),
            (&nan_errors, nan_tip, inf_g, &past_the_chain, "tip"),
            (&nan_errors, tip, inf_g, &past_the_chain, "gravity"),
            (&nan_errors, tip, G_FLOOR, &past_the_chain, "origin_rpy"),
        ];
        for (k, (errors, tip, g, params, word)) in cases.into_iter().enumerate() {
            let err = check_tip_inputs(&m, errors, &tip, &g, params).unwrap_err();
            let prepared = PreparedTip::new(&m, errors, &tip, &g, params).unwrap_err();
            assert_eq!(
                err.to_string(),
                prepared.to_string(),
                "{} case {k}",
                m.name()
            );
            let checked =
                true_tip_with_error_jacobian(&m, errors, &q, &tip, &g, params).unwrap_err();
            assert_eq!(
                err.to_string(),
                checked.to_string(),
                "{} case {k}",
                m.name()
            );
            assert!(
                err.to_string().to_lowercase().contains(word),
                "{} case {k}: {err} does not name {word}",
                m.name()
            );
        }
    }
    // A periodic parameter of a prismatic joint (RAIL_6R's first) is refused as a parameter.
    let rail = model(RAIL_6R);
    let zero = KinematicErrors::zero_for(&rail);
    let err = check_tip_inputs(
        &rail,
        &zero,
        &Vector3::zeros(),
        &G_FLOOR,
        &[ErrorParam::PeriodicSin { joint: 0 }],
    )
    .unwrap_err();
    assert!(err.to_string().contains("prismatic"), "{err}");
}

/// Prismatic and coupled joints: a prismatic joint's offset (m), scale and compliance (m/N, under
/// the gravity force along its axis) and a coupled joint's own offset, scale, compliance and
/// periodic terms, applied after its coupling, equal the nominal FK of the same chain with every
/// joint independent at the true values.
#[test]
fn joint_errors_of_prismatic_and_coupled_joints_mean_what_the_contract_says() {
    use crate::test_fixtures::{mixed_coupled, MIMIC_TORSO, MIXED, RAIL_6R};
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let no_mimic = model(&MIXED.replace(r#"<mimic joint="j2" multiplier="-1" offset="0.1"/>"#, ""));
    let torso_free = model(&MIMIC_TORSO.replace(
        r#"<mimic joint="torso_pitch_1" multiplier="-1" offset="0.05"/>"#,
        "",
    ));
    let chains = [
        (model(RAIL_6R), model(RAIL_6R)),
        (model(MIXED), no_mimic.clone()),
        (mixed_coupled(), no_mimic),
        (model(MIMIC_TORSO), torso_free),
    ];
    for (m, free) in &chains {
        let q = random_q(m, &mut rng);
        let tip = random_tip(&mut rng);
        let g = random_g(&mut rng);
        let e = random_errors(m, &mut rng);
        let only = joint_terms_only(&e);
        let tau = crate::gravity_torques(m, &q, &g).unwrap();
        let q_true = true_values_by_hand(&e, &m.chain_values(&q).unwrap(), &tau);
        // The free chain's limits do not bound the true values: evaluate unchecked.
        let want = crate::base_from_tip_unchecked(free, &q_true, &tip);
        assert_pose_eq(
            &true_base_from_tip(m, &only, &q, &tip, &g).unwrap(),
            &want,
            m.name(),
        );
    }
    // The rail's offset is a length: 5 mm of offset is the arm 5 mm further along the rail.
    let rail = model(RAIL_6R);
    let q = [1.0, 0.2, 0.3, -0.1, 0.4, 0.5, 0.6];
    let mut e = KinematicErrors::zero_for(&rail);
    e.joint_offset[0] = 0.005;
    let mut q_moved = q;
    q_moved[0] += 0.005;
    assert_pose_eq(
        &true_base_from_tip(&rail, &e, &q, &Vector3::zeros(), &G_FLOOR).unwrap(),
        &base_from_tip(&rail, &q_moved, &Vector3::zeros()).unwrap(),
        "rail offset",
    );
}

/// A periodic term of a prismatic joint is refused (errors and Jacobian parameters), and the
/// units of its offset and compliance are metres.
#[test]
fn prismatic_joints_have_no_periodic_terms_and_metre_units() {
    use crate::test_fixtures::RAIL_6R;
    let m = model(RAIL_6R);
    let q = [1.0, 0.2, 0.3, -0.1, 0.4, 0.5, 0.6];
    let tip = Vector3::zeros();
    let mut e = KinematicErrors::zero_for(&m);
    e.periodic_cos[0] = 1e-3;
    let err = true_base_from_tip(&m, &e, &q, &tip, &G_FLOOR).unwrap_err();
    assert!(
        err.to_string().contains("periodic_cos") && err.to_string().contains("prismatic"),
        "{err}"
    );
    let zero = KinematicErrors::zero_for(&m);
    let err = tip_error_jacobian(
        &m,
        &zero,
        &q,
        &tip,
        &G_FLOOR,
        &[ErrorParam::PeriodicSin { joint: 0 }],
    )
    .unwrap_err();
    assert!(err.to_string().contains("rail"), "{err}");
    // The catalogue for the model leaves them out; the arm's joints keep theirs.
    let params = all_params_for(&m);
    assert_eq!(params.len(), 11 * 7 + 9 - 2);
    assert!(tip_error_jacobian(&m, &zero, &q, &tip, &G_FLOOR, &params).is_ok());
    assert_eq!(ErrorParam::JointOffset { joint: 0 }.unit_si_in(&m), "m");
    assert_eq!(ErrorParam::Compliance { joint: 0 }.unit_si_in(&m), "m/N");
    assert_eq!(
        ErrorParam::Compliance { joint: 1 }.unit_si_in(&m),
        "rad/(N·m)"
    );
    assert_eq!(ErrorParam::JointScale { joint: 0 }.unit_si_in(&m), "ratio");
}

/// Errors sized for the independent joints of a coupled chain are refused, naming the chain.
#[test]
fn coupled_chain_errors_have_one_entry_per_chain_joint() {
    let m = crate::test_fixtures::mixed_coupled();
    let q = [0.2, 0.3, -0.4, 0.1];
    let err = true_base_from_tip(
        &m,
        &KinematicErrors::zero(m.dof()),
        &q,
        &Vector3::zeros(),
        &G_FLOOR,
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("6 chain joints (4 independent"),
        "{err}"
    );
}
