//! Tests of session planning, and the seeded Monte Carlo study of planned against random sessions
//! (`cargo test --release -p sim-cell --lib plan::tests::monte_carlo -- --ignored --nocapture`).

use super::*;
use calib_core::whole_cell::{
    calibrate_cell, measure_cooperative_error, predict_cooperative_accuracy, ScreenOptions,
    SolveOptions,
};
use handclasp_cell::problem::truth_estimate;
use kinematics::base_from_tip;
use std::path::Path;

/// FK consistency of a planned pose's tip columns: the pose is computed by the same FK, so only
/// round-off separates them.
const FK_TOL_M: f64 = 1e-9;
/// The two nominal tips of a planned pose meet (IK tolerance 1e-9 m per robot, with margin).
const MEET_TOL_M: f64 = 1e-6;
/// Joint round trip through the CSV's 6 decimals of a degree: ≤ 5e-7° = 8.7e-9 rad.
const CSV_Q_TOL_RAD: f64 = 1e-8;
/// Tip round trip through 6 decimals of a mm: ≤ 5e-10 m.
const CSV_TIP_TOL_M: f64 = 1e-9;

fn small_plan(cell: &Cell, criterion: DesignCriterion, seed: u64) -> Plan {
    let spec = PlanSpec {
        seed,
        random_draws: 8,
        spread_m: 0.8,
        ..PlanSpec::new(10, 40, criterion)
    };
    plan_session(cell, &spec, &mut |_, _| {}).expect("plan")
}

#[test]
fn planned_poses_are_within_limits_and_fk_consistent() {
    for cell in [Cell::default_floor_floor(), Cell::default_floor_ceiling()] {
        let plan = small_plan(&cell, DesignCriterion::CooperativeA, 3);
        assert_eq!(plan.session.points.len(), 10);
        let mut seen = plan.chosen.clone();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), 10, "a pose chosen twice: {:?}", plan.chosen);
        for (k, p) in plan.session.points.iter().enumerate() {
            assert_eq!(p.point, k + 1);
            for (r, q, tip) in [
                (&cell.robot1, &p.q1, p.p_b1.coords),
                (&cell.robot2, &p.q2, p.p_b2.coords),
            ] {
                r.model.check_q(q).expect("within the joint limits");
                let fk = base_from_tip(&r.model, q, &r.flange_from_tip).unwrap();
                assert!((fk.translation.vector - tip).norm() < FK_TOL_M);
            }
            let gap = (p.p_b1 - cell.b1_from_b2 * p.p_b2).norm();
            assert!(gap < MEET_TOL_M, "pose {}: tips {gap:e} m apart", p.point);
        }
    }
}

#[test]
fn the_plan_beats_random_picks_on_its_criterion() {
    let cell = Cell::default_floor_wall();
    let a = small_plan(&cell, DesignCriterion::CooperativeA, 5);
    assert!(
        a.predicted.cooperative_rms_m < a.random_mean.cooperative_rms_m,
        "A plan {:e} m vs random {:e} m",
        a.predicted.cooperative_rms_m,
        a.random_mean.cooperative_rms_m
    );
    let better = a
        .random
        .iter()
        .filter(|r| a.predicted.cooperative_rms_m < r.cooperative_rms_m)
        .count();
    assert_eq!(
        better,
        a.random.len(),
        "the greedy A plan lost to a random pick"
    );
    let d = small_plan(&cell, DesignCriterion::D, 5);
    assert!(
        d.predicted.log_det_info > d.random_mean.log_det_info,
        "D plan {} vs random {}",
        d.predicted.log_det_info,
        d.random_mean.log_det_info
    );
    // Same seed, same candidates and picks: the plan is reproducible.
    let again = small_plan(&cell, DesignCriterion::CooperativeA, 5);
    assert_eq!(again.chosen, a.chosen);
    assert_eq!(again.predicted, a.predicted);
}

#[test]
fn plan_csv_reads_back_as_a_session() {
    let cell = Cell::default_floor_floor();
    let plan = small_plan(&cell, DesignCriterion::CooperativeA, 9);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.csv");
    plan.session.write_csv(&path, &cell).unwrap();
    let back = Session::read_csv(&path, &cell).expect("plan.csv is a session CSV");
    assert_eq!(back.points.len(), plan.session.points.len());
    for (a, b) in back.points.iter().zip(&plan.session.points) {
        assert_eq!(a.point, b.point);
        for (x, y) in a.q1.iter().chain(&a.q2).zip(b.q1.iter().chain(&b.q2)) {
            assert!((x - y).abs() < CSV_Q_TOL_RAD);
        }
        assert!((a.p_b1 - b.p_b1).norm() < CSV_TIP_TOL_M);
        assert!((a.p_b2 - b.p_b2).norm() < CSV_TIP_TOL_M);
    }
}

#[test]
fn bad_requests_say_what_to_change() {
    let cell = Cell::default_floor_floor();
    let none = &mut |_: usize, _: usize| {};
    let e = plan_session(&cell, &PlanSpec::new(50, 40, DesignCriterion::D), none)
        .unwrap_err()
        .to_string();
    assert!(e.contains("more than the 40 candidates"), "{e}");
    let e = plan_session(&cell, &PlanSpec::new(0, 40, DesignCriterion::D), none)
        .unwrap_err()
        .to_string();
    assert!(e.contains("plan at least 1"), "{e}");
    // A cube 20 m away from both robots: nothing is reachable.
    let far = PlanSpec {
        centre_b1: Some(Point3::new(20.0, 20.0, 0.0)),
        ..PlanSpec::new(4, 8, DesignCriterion::D)
    };
    let e = plan_session(&cell, &far, none).unwrap_err();
    assert!(matches!(e, SimError::Unreachable { .. }), "{e}");
    assert!(e.to_string().contains("move the centre"), "{e}");
}

#[test]
fn drawn_errors_stay_in_their_bands() {
    let mut cell = Cell::default_floor_wall();
    draw_errors_from_tolerance(&mut cell, &mut trial_rng(4, 0));
    let tol = cell.robot2.tolerance;
    let e = &cell.robot2.errors;
    assert!(e
        .joint_offset
        .iter()
        .all(|v| v.abs() <= tol.joint_offset_rad));
    assert!(e.joint_offset.iter().any(|v| *v != 0.0));
    assert!(e.origin_xyz.iter().all(|v| v.amax() <= tol.origin_xyz_m));
    assert!(e.tip.amax() <= tol.tip_m && e.tip.amax() > 0.0);
    assert!(e.mount_xyz == Vector3::zeros() && e.compliance.iter().all(|c| *c == 0.0));
}

/// On a shared-trunk cell the tolerance draw gives the trunk one set of errors: robot 2's
/// trunk parameters equal robot 1's drawn ones (they used to be drawn on their own, a truth the
/// model cannot describe), robot 2's arm keeps its own draw, and robot 1's draw is the one
/// without sharing (the random stream is unchanged).
#[test]
fn a_shared_trunk_draws_one_set_of_trunk_errors() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/humanoid-trunk.toml");
    let mut cell = Cell::from_toml_file(&path).unwrap();
    let k = cell.shared_joints;
    assert_eq!(k, 4);
    draw_errors_from_tolerance(&mut cell, &mut trial_rng(4, 0));
    let (e1, e2) = (&cell.robot1.errors, &cell.robot2.errors);
    assert!(e1.joint_offset[..k].iter().any(|v| *v != 0.0));
    assert_eq!(e2.joint_offset[..k], e1.joint_offset[..k]);
    assert_eq!(e2.joint_scale[..k], e1.joint_scale[..k]);
    assert_eq!(e2.origin_xyz[..k], e1.origin_xyz[..k]);
    assert_eq!(e2.origin_rpy[..k], e1.origin_rpy[..k]);
    assert_eq!(e2.compliance[..k], e1.compliance[..k]);
    assert!(e2.joint_offset[k..].iter().any(|v| *v != 0.0));
    assert_ne!(e2.joint_offset[k..], e1.joint_offset[k..]);
    // The same draw without the sharing: robot 1's errors and robot 2's arm are unchanged.
    let mut alone = Cell::from_toml_file(&path).unwrap();
    alone.shared_joints = 0;
    draw_errors_from_tolerance(&mut alone, &mut trial_rng(4, 0));
    assert_eq!(alone.robot1.errors, cell.robot1.errors);
    assert_eq!(alone.robot2.errors.joint_offset[k..], e2.joint_offset[k..]);
    assert_ne!(alone.robot2.errors.joint_offset[..k], e2.joint_offset[..k]);
}

/// One calibrated session of the Monte Carlo: measured and predicted cooperative rms (m),
/// e_tran (m) and e_rot (rad).
struct Outcome {
    measured_rms_m: f64,
    predicted_rms_m: f64,
    e_tran_m: f64,
    e_rot_rad: f64,
}

/// Simulates the poses' meeting points on `truth` (robot 1's nominal tips as the points; the
/// session generator re-solves both robots on the true models, with the cell's noise), fits the
/// whole cell and scores it on the held-out pairs.
fn calibrate_at(
    truth: &Cell,
    poses: &[&SessionPoint],
    held_out: &[ConfigPair],
    seed: u64,
) -> Option<Outcome> {
    let spec = SessionSpec {
        points_b1: Some(poses.iter().map(|p| p.p_b1).collect()),
        ..SessionSpec::new(poses.len(), Layout::Random, 1.0)
    };
    let session = generate_session(truth, &spec, &mut trial_rng(seed, 0)).ok()?;
    let problem = cell_problem(truth, &session, FitModel::Kinematic);
    let cal = calibrate_cell(
        &problem,
        &SolveOptions::default(),
        &ScreenOptions::default(),
    )
    .ok()?;
    let truth_est = truth_estimate(truth, &problem);
    let measured =
        measure_cooperative_error(&problem, &cal.fit.estimate, &truth_est, held_out).ok()?;
    let predicted = predict_cooperative_accuracy(&problem, &cal.fit, held_out, 1).ok()?;
    Some(Outcome {
        measured_rms_m: measured.rms_m,
        predicted_rms_m: predicted.predicted_rms_m,
        e_tran_m: calib_core::e_tran(&truth.b1_from_b2, &cal.fit.estimate.b1_from_b2),
        e_rot_rad: calib_core::e_rot(&truth.b1_from_b2, &cal.fit.estimate.b1_from_b2),
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The planning study of BENCHMARKS.md ("Planning"): on each shipped cell, 40 A-planned poses
/// from 400 candidates (seed 1) against 40 random picks of the same candidates (a new pick per
/// trial); each trial draws the robots' errors from the cell's tolerances, simulates both
/// sessions at σ (the cell's alignment noise overridden), fits the whole cell and measures the
/// cooperative rms on the plan's 200 held-out handclasp poses. Env `PLAN_MC_TRIALS`
/// (default 20) and `PLAN_MC_SIGMA_MM` (default 0.3).
#[test]
#[ignore = "study: run in release with --ignored --nocapture"]
fn monte_carlo() {
    let trials: usize = std::env::var("PLAN_MC_TRIALS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20);
    let sigma_mm: f64 = std::env::var("PLAN_MC_SIGMA_MM")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.3);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    println!(
        "planning study: {trials} trials per cell, σ {sigma_mm} mm, 40 poses of 400 candidates, {} held-out pairs",
        EVAL_POSES
    );
    println!("| cell | predicted plan / random (design) | measured plan / random (median) | plan gain | e_tran plan / random | e_rot plan / random | posterior predicted / measured (plan) |");
    println!("|---|---|---|---|---|---|---|");
    for name in ["floor-floor", "floor-wall", "floor-ceiling"] {
        let mut cell = Cell::from_toml_file(&root.join(format!("{name}.toml"))).unwrap();
        cell.noise.alignment_m = Vector3::repeat(sigma_mm * 1e-3);
        let t0 = std::time::Instant::now();
        let spec = PlanSpec {
            seed: 1,
            ..PlanSpec::new(40, 400, DesignCriterion::CooperativeA)
        };
        let plan = plan_session(&cell, &spec, &mut |_, _| {}).unwrap();
        let plan_s = t0.elapsed().as_secs_f64();
        let planned: Vec<&SessionPoint> = plan.session.points.iter().collect();
        let (mut mp, mut mr, mut pp, mut tp, mut tr, mut rp, mut rr) =
            (vec![], vec![], vec![], vec![], vec![], vec![], vec![]);
        let mut failed = 0;
        for t in 0..trials {
            let mut truth = cell.clone();
            draw_errors_from_tolerance(&mut truth, &mut trial_rng(100 + t as u64, 0));
            let pick = rand::seq::index::sample(
                &mut trial_rng(200 + t as u64, 0),
                plan.candidates.len(),
                40,
            )
            .into_vec();
            let random: Vec<&SessionPoint> = pick.iter().map(|&i| &plan.candidates[i]).collect();
            let a = calibrate_at(&truth, &planned, &plan.eval_pairs, 300 + t as u64);
            let b = calibrate_at(&truth, &random, &plan.eval_pairs, 300 + t as u64);
            let (Some(a), Some(b)) = (a, b) else {
                failed += 1;
                continue;
            };
            mp.push(a.measured_rms_m);
            mr.push(b.measured_rms_m);
            pp.push(a.predicted_rms_m / a.measured_rms_m);
            tp.push(a.e_tran_m);
            tr.push(b.e_tran_m);
            rp.push(a.e_rot_rad);
            rr.push(b.e_rot_rad);
        }
        let (p, r) = (median(mp.clone()), median(mr.clone()));
        println!(
            "| {name} | {:.3} / {:.3} mm | {:.3} / {:.3} mm | {:.0} % | {:.3} / {:.3} mm | {:.4} / {:.4}° | {:.2} (median ratio) |",
            plan.predicted.cooperative_rms_m * 1e3,
            plan.random_mean.cooperative_rms_m * 1e3,
            p * 1e3,
            r * 1e3,
            (1.0 - p / r) * 100.0,
            median(tp) * 1e3,
            median(tr) * 1e3,
            median(rp).to_degrees(),
            median(rr).to_degrees(),
            median(pp),
        );
        println!(
            "  ({} candidates from {} draws, plan {plan_s:.1} s; {failed} trials failed to simulate; plan better than random in {} of {} trials)",
            plan.candidates.len(),
            plan.attempts,
            mp.iter().zip(&mr).filter(|(a, b)| a < b).count(),
            mp.len()
        );
    }
}
