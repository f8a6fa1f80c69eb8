//! Tests of the whole-cell calibration on the shipped robots. One job, kept in one file: the
//! tests of every part (Jacobians against central differences, the fit, reduction, screening,
//! prediction, design and the one-call chain), sharing the fixtures and trial helpers here.

use crate::Robot;
use std::time::Instant;

use kinematics::ErrorParam;
use nalgebra::{DVector, Isometry3, Matrix3, Point3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::fixtures::{sim_cell, Cell, SimCell};
use super::*;

/// The test's tolerance draw: offsets ±0.05°, origins ±0.5 mm, tips ±0.5 mm, origin rpy not
/// drawn and not fitted (issue 11's "realistic errors").
fn realistic() -> Tolerance {
    Tolerance {
        origin_rpy_rad: 0.0,
        ..Tolerance::default()
    }
}

fn random_q(model: &kinematics::RobotModel, rng: &mut ChaCha8Rng) -> Vec<f64> {
    model
        .joints()
        .iter()
        .map(|j| {
            let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
            rng.random_range(lo + 0.1 * (hi - lo)..hi - 0.1 * (hi - lo))
        })
        .collect()
}

fn random_pose(rng: &mut ChaCha8Rng, scale: f64) -> Isometry3<f64> {
    let t = Vector3::from_fn(|_, _| rng.random_range(-scale..scale));
    let r = Vector3::from_fn(|_, _| rng.random_range(-1.5..1.5));
    Isometry3::new(t, r)
}

/// A problem with every observation kind, both tracker anchors, both plane anchors, a fitted
/// contact distance, two tools on robot 1, scale, compliance and periodic errors fitted, the
/// b1-anchored tracker with its scale and drift, at a random estimate.
fn every_kind(seed: u64) -> (CellProblem, CellEstimate) {
    let tol = Tolerance {
        joint_scale: Some(1e-4),
        compliance_rad_per_nm: Some(1e-6),
        periodic_rad: Some(1e-3),
        ..Tolerance::default()
    };
    let sc = sim_cell(Cell::Wall, tol, true, seed);
    let mut p = sc.problem();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xfeed);
    p.trackers = vec![
        TrackerGroup {
            name: "t-b1".into(),
            anchor: Robot::One,
            initial_tracker_from_anchor: None,
            fit_scale: true,
            fit_drift: true,
        },
        TrackerGroup {
            name: "t-b2".into(),
            anchor: Robot::Two,
            initial_tracker_from_anchor: None,
            fit_scale: false,
            fit_drift: false,
        },
    ];
    p.planes = vec![
        PlaneGroup {
            name: "p-b1".into(),
            anchor: Robot::One,
            initial: None,
        },
        PlaneGroup {
            name: "p-b2".into(),
            anchor: Robot::Two,
            initial: None,
        },
    ];
    p.contacts = vec![ContactGroup {
        name: "spheres".into(),
        distance_m: 0.116,
        fit_distance: true,
    }];
    let cov = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0) * 1e-8;
    let mut obs = Vec::new();
    let q = |r: Robot, rng: &mut ChaCha8Rng| random_q(&p.robot(r).model, rng);
    for (tool1, noise) in [
        (0, Noise3::Isotropic { sigma_m: 3e-4 }),
        (1, Noise3::Covariance { cov_m2: cov }),
    ] {
        obs.push(ObservationKind::Coincident {
            q1: q(Robot::One, &mut rng),
            q2: q(Robot::Two, &mut rng),
            tool1,
            tool2: 0,
            noise,
        });
    }
    obs.push(ObservationKind::Contact {
        q1: q(Robot::One, &mut rng),
        q2: q(Robot::Two, &mut rng),
        tool1: 1,
        tool2: 0,
        group: 0,
        sigma_m: 2e-4,
    });
    for (robot, group, tool) in [
        (Robot::One, 0usize, 1usize),
        (Robot::Two, 0, 0),
        (Robot::One, 1, 0),
        (Robot::Two, 1, 0),
    ] {
        obs.push(ObservationKind::Tracker {
            robot,
            q: q(robot, &mut rng),
            tool,
            group,
            p_tracker: Point3::new(0.3, -0.2, 1.1),
            noise: Noise3::Covariance { cov_m2: cov },
        });
        obs.push(ObservationKind::Plane {
            robot,
            q: q(robot, &mut rng),
            tool,
            group,
            sigma_m: 1e-4,
        });
    }
    // Face contacts (own generator, so the draws above stay as they were): generic normals
    // (not flush, so the faces' slide and the normals' rotation both enter), both tools of
    // robot 1.
    let mut rng_face = ChaCha8Rng::seed_from_u64(seed ^ 0xface);
    for tool1 in [0, 1] {
        let mut unit =
            || Unit::new_normalize(Vector3::from_fn(|_, _| rng_face.random_range(-1.0..1.0)));
        let (n1_tip, n2_tip) = (unit(), unit());
        obs.push(ObservationKind::FaceContact {
            q1: q(Robot::One, &mut rng_face),
            q2: q(Robot::Two, &mut rng_face),
            tool1,
            tool2: 0,
            n1_tip,
            n2_tip,
            group: 0,
            sigma_m: 1e-4,
        });
    }
    p.observations = obs
        .into_iter()
        .enumerate()
        .map(|(i, kind)| Observation { row: i + 1, kind })
        .collect();
    let mut est = sc.truth.clone();
    est.tracker_from_anchor = vec![random_pose(&mut rng, 2.0), random_pose(&mut rng, 2.0)];
    est.planes = (0..2)
        .map(|_| PlaneEstimate {
            normal_anchor: Unit::new_normalize(Vector3::from_fn(|_, _| {
                rng.random_range(-1.0..1.0)
            })),
            offset_m: rng.random_range(-1.0..1.0),
        })
        .collect();
    est.contact_distance_m = vec![0.1];
    est.tracker_scale = vec![rng.random_range(-1e-3..1e-3), 0.0];
    est.tracker_drift_m = vec![
        Vector3::from_fn(|_, _| rng.random_range(-1e-3..1e-3)),
        Vector3::zeros(),
    ];
    for r in [&mut est.robot1, &mut est.robot2] {
        for j in 0..r.errors.dof() {
            r.errors.joint_scale[j] = rng.random_range(-1e-4..1e-4);
            r.errors.compliance[j] = rng.random_range(-1e-6..1e-6);
            r.errors.periodic_sin[j] = rng.random_range(-1e-3..1e-3);
            r.errors.periodic_cos[j] = rng.random_range(-1e-3..1e-3);
        }
    }
    (p, est)
}

/// Central-difference step per column: 1e-6 in the column's unit moves a tip by ~1e-6 m for
/// metres and radians (arms ~1 m); a scale by q·1e-6 ≤ 3e-6 rad; a compliance multiplies
/// torques up to ~5e3 N·m (HP20), so its step is 2e-10 rad/(N·m) for the same tip motion.
fn fd_step(p: &CellParam) -> f64 {
    match p {
        CellParam::Kinematic {
            param: ErrorParam::Compliance { .. },
            ..
        } => 2e-10,
        _ => 1e-6,
    }
}

/// Tolerance on the residual change over a central step (m): truncation ~h²·|r'''| ≲ 1e-12 m and
/// round-off ~eps·|r|/1 ≈ 1e-15 m per evaluation, so |Δ| ≤ 1e-12 m + 1e-6 relative (the
/// manifold retractions are exact to second order, which central differences cancel).
const FD_TOL_M: f64 = 1e-12;
const FD_TOL_REL: f64 = 1e-6;

#[test]
fn every_jacobian_matches_central_differences() {
    for seed in [1u64, 2, 3] {
        let (p, est) = every_kind(seed);
        p.check().expect("valid problem");
        let layout = ParamLayout::new(&p, &[]);
        let ev = Evaluator::new(&p, &layout);
        for o in &p.observations {
            let lin = ev.linearise(o, &est, true).unwrap();
            for (j, param) in layout.params.iter().enumerate() {
                let h = fd_step(param);
                let mut d = DVector::zeros(layout.len());
                d[j] = h;
                let plus = ev.linearise(o, &layout.apply(&est, &d), false).unwrap();
                let minus = ev.linearise(o, &layout.apply(&est, &(-d)), false).unwrap();
                let fd = (plus.residual - minus.residual) / 2.0;
                let an = lin.jacobian.column(j) * h;
                let diff = (&fd - &an).norm();
                assert!(
                    diff <= FD_TOL_M + FD_TOL_REL * an.norm(),
                    "seed {seed} row {} ({}) column {}: analytic {:?} fd {:?}",
                    o.row,
                    o.kind.name(),
                    param.describe(&p),
                    an.as_slice(),
                    fd.as_slice()
                );
            }
        }
        // The cooperative vector's Jacobian as well.
        let pair = ConfigPair {
            q1: random_q(&p.robot1.model, &mut ChaCha8Rng::seed_from_u64(seed)),
            q2: random_q(&p.robot2.model, &mut ChaCha8Rng::seed_from_u64(seed + 9)),
            tool1: 1,
            tool2: 0,
        };
        let (_, jv) = ev.cooperative_vector(&est, &pair, true).unwrap();
        for (j, param) in layout.params.iter().enumerate() {
            let h = fd_step(param);
            let mut d = DVector::zeros(layout.len());
            d[j] = h;
            let (vp, _) = ev
                .cooperative_vector(&layout.apply(&est, &d), &pair, false)
                .unwrap();
            let (vm, _) = ev
                .cooperative_vector(&layout.apply(&est, &(-d)), &pair, false)
                .unwrap();
            let fd = (vp - vm) / 2.0;
            let an = Vector3::from_fn(|a, _| jv[(a, j)] * h);
            assert!((fd - an).norm() <= FD_TOL_M + FD_TOL_REL * an.norm());
        }
    }
}

/// The face-contact rows of [`every_kind`] (two per seed, generic normals, a fitted contact
/// distance, scale, compliance and periodic errors of both robots, the wall cell's rotated
/// placement): every column's analytic derivative matches central differences within
/// [`FD_TOL_M`] + [`FD_TOL_REL`] (step [`fd_step`]). Not vacuous: the placement is far from the
/// identity, the faces slide (the tip-to-tip vector has a tangential part, so the normals'
/// rotation enters), and every robot-2 kinematic column and placement rotation column is
/// non-zero on at least one row.
#[test]
fn face_contact_jacobian_matches_central_differences() {
    for seed in [1u64, 2, 3] {
        let (p, est) = every_kind(seed);
        let layout = ParamLayout::new(&p, &[]);
        let ev = Evaluator::new(&p, &layout);
        assert!(est.b1_from_b2.rotation.angle() > 1.0);
        let faces: Vec<&Observation> = p
            .observations
            .iter()
            .filter(|o| matches!(o.kind, ObservationKind::FaceContact { .. }))
            .collect();
        assert_eq!(faces.len(), 2);
        let mut touched = vec![false; layout.len()];
        for o in faces {
            let lin = ev.linearise(o, &est, true).unwrap();
            for (j, param) in layout.params.iter().enumerate() {
                let h = fd_step(param);
                let mut d = DVector::zeros(layout.len());
                d[j] = h;
                let plus = ev.linearise(o, &layout.apply(&est, &d), false).unwrap();
                let minus = ev.linearise(o, &layout.apply(&est, &(-d)), false).unwrap();
                let fd = (plus.residual[0] - minus.residual[0]) / 2.0;
                let an = lin.jacobian[(0, j)] * h;
                assert!(
                    (fd - an).abs() <= FD_TOL_M + FD_TOL_REL * an.abs(),
                    "seed {seed} row {} column {}: analytic {an:e} fd {fd:e}",
                    o.row,
                    param.describe(&p)
                );
                touched[j] |= an != 0.0;
            }
        }
        for (j, param) in layout.params.iter().enumerate() {
            let must = match param {
                CellParam::Kinematic { robot, .. } => *robot == Robot::Two,
                CellParam::PlacementRotation { .. } | CellParam::ContactDistance { .. } => true,
                _ => false,
            };
            assert!(
                !must || touched[j],
                "seed {seed}: column {} has no effect on any face row",
                param.describe(&p)
            );
        }
    }
}

#[test]
fn bad_input_is_a_named_error() {
    let (mut p, _) = every_kind(4);
    if let ObservationKind::Tracker { tool, .. } = &mut p.observations[3].kind {
        *tool = 7;
    }
    let e = p.check().unwrap_err().to_string();
    assert!(e.contains("row 4") && e.contains("tool"), "{e}");
    let (mut p, _) = every_kind(4);
    if let ObservationKind::Coincident { q1, .. } = &mut p.observations[0].kind {
        q1.pop();
    }
    let e = p.check().unwrap_err().to_string();
    assert!(e.contains("row 1"), "{e}");
    // A zero or NaN face normal names the row, the field and the fix.
    for bad in [Vector3::zeros(), Vector3::new(f64::NAN, 0.0, 1.0)] {
        let (mut p, _) = every_kind(4);
        let o = p
            .observations
            .iter_mut()
            .find(|o| matches!(o.kind, ObservationKind::FaceContact { .. }))
            .unwrap();
        let row = o.row;
        if let ObservationKind::FaceContact { n2_tip, .. } = &mut o.kind {
            *n2_tip = Unit::new_unchecked(bad);
        }
        let e = p.check().unwrap_err().to_string();
        assert!(
            e.contains(&format!("row {row}")) && e.contains("n2_tip") && e.contains("outward"),
            "{e}"
        );
    }
    // Two outward normals that point the same way in b1 (faces not facing each other) are an
    // error at evaluation, naming the row and the fix.
    let (mut p, est) = every_kind(4);
    let i = p
        .observations
        .iter()
        .position(|o| matches!(o.kind, ObservationKind::FaceContact { .. }))
        .unwrap();
    let rotation = |r: Robot, tool: usize, q: &[f64]| {
        let rb = p.robot(r);
        kinematics::true_base_from_tip(
            &rb.model,
            &est.robot(r).errors_for_tool(tool),
            q,
            &rb.tools[tool].flange_from_tip,
            &rb.g_base,
        )
        .unwrap()
        .rotation
    };
    let row = p.observations[i].row;
    if let ObservationKind::FaceContact {
        q1,
        q2,
        tool1,
        tool2,
        n1_tip,
        ..
    } = &p.observations[i].kind
    {
        let n1_b1 = rotation(Robot::One, *tool1, q1) * n1_tip.into_inner();
        let n2_b2 = est.b1_from_b2.rotation.inverse() * n1_b1;
        let same = Unit::new_normalize(rotation(Robot::Two, *tool2, q2).inverse() * n2_b2);
        if let ObservationKind::FaceContact { n2_tip, .. } = &mut p.observations[i].kind {
            *n2_tip = same;
        }
    }
    p.check().expect("unit normals pass the problem check");
    let layout = ParamLayout::new(&p, &[]);
    let e = Evaluator::new(&p, &layout)
        .linearise(&p.observations[i], &est, true)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("row {row}")) && e.contains("same way") && e.contains("OUTWARD"),
        "{e}"
    );
    let (mut p, _) = every_kind(4);
    p.robot2.tolerance.tip_m = f64::NAN;
    let e = p.check().unwrap_err().to_string();
    assert!(e.contains("robot 2") && e.contains("tip_m"), "{e}");
    // A starting estimate of the wrong shape is an error, not a panic.
    let (p, mut est) = every_kind(4);
    est.planes.pop();
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let e = fit_cell_with(
        &p,
        ParamLayout::new(&p, &[]),
        &active,
        None,
        Some(&est),
        &SolveOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("plane"), "{e}");
}

/// A cell whose observations are simulated with truth `sc.truth`.
fn coincident_problem(sc: &SimCell, n: usize, sigma: f64, seed: u64) -> CellProblem {
    let mut p = sc.problem();
    p.observations = sc.coincident(n, sigma, 0.7, seed);
    p
}

/// Noise-free data from a truth the model can represent: the fit reproduces the data exactly
/// and predicts the cooperative vectors far better than the placement-only fit.
#[test]
fn noise_free_fit_reproduces_the_data_and_stops_converged() {
    let sc = sim_cell(Cell::Floor, realistic(), false, 11);
    let p = coincident_problem(&sc, 30, 1e-6, 12);
    let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
    assert_eq!(fit.stopped, StopReason::Converged, "{:?}", fit.stopped);
    assert!(fit.iterations < 30, "{} iterations", fit.iterations);
    // σ = 1 µm: the data χ² of 90 rows stays of order 90 (the prior pulls a little).
    assert!(fit.data_chi2 < 300.0, "data χ² {}", fit.data_chi2);
}

#[test]
fn iteration_cap_is_a_stop_reason_not_an_error() {
    let sc = sim_cell(Cell::Wall, realistic(), false, 5);
    let p = coincident_problem(&sc, 20, 3e-4, 6);
    let opts = SolveOptions {
        max_iterations: 1,
        ..SolveOptions::default()
    };
    let fit = fit_cell(&p, &opts).unwrap();
    assert_eq!(fit.iterations, 1);
    assert_eq!(fit.stopped, StopReason::IterationCap);
    let bad = SolveOptions {
        max_iterations: 0,
        ..SolveOptions::default()
    };
    assert!(fit_cell(&p, &bad).is_err());
}

/// Placement-only fit: every tolerance zero, so only `b1_from_b2` is fitted.
fn placement_only(p: &CellProblem) -> CellFit {
    let mut q = p.clone();
    q.robot1.tolerance = Tolerance::none();
    q.robot2.tolerance = Tolerance::none();
    fit_cell(&q, &SolveOptions::default()).unwrap()
}

/// Measured cooperative error of a placement-only fit (its estimate has zero corrections).
fn placement_error(p: &CellProblem, sc: &SimCell, pairs: &[ConfigPair]) -> CooperativeError {
    let f = placement_only(p);
    let est = CellEstimate {
        b1_from_b2: f.estimate.b1_from_b2,
        ..CellEstimate::nominal(p, f.estimate.b1_from_b2)
    };
    measure_cooperative_error(p, &est, &sc.truth, pairs).unwrap()
}

struct Trial {
    placement_rms: f64,
    whole_rms: f64,
    predicted_rms: f64,
    whole_p95: f64,
    predicted_p95: f64,
    seconds: f64,
}

fn trial(cell: Cell, seed: u64, n: usize, sigma: f64, n_eval: usize) -> Trial {
    let sc = sim_cell(cell, realistic(), false, seed);
    let p = coincident_problem(&sc, n, sigma, seed + 1000);
    let pairs = sc.eval_pairs(n_eval, 0.7, seed + 2000);
    let start = Instant::now();
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let init = initial_estimate(&p, None, &active).unwrap();
    let red = reduce(&p, &init, &active).unwrap();
    let fit = fit_cell_with(
        &p,
        red.layout,
        &active,
        None,
        Some(&init),
        &SolveOptions::default(),
    )
    .unwrap();
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(fit.stopped, StopReason::Converged);
    let pred = predict_cooperative_accuracy(&p, &fit, &pairs, seed).unwrap();
    let meas = measure_cooperative_error(&p, &fit.estimate, &sc.truth, &pairs).unwrap();
    let place = placement_error(&p, &sc, &pairs);
    Trial {
        placement_rms: place.rms_m,
        whole_rms: meas.rms_m,
        predicted_rms: pred.predicted_rms_m,
        whole_p95: meas.p95_m,
        predicted_p95: pred.predicted_p95_m,
        seconds,
    }
}

/// Issue 11's realistic-errors test on a floor–wall cell: offsets U(±0.05°), origins and tips
/// U(±0.5 mm) on both robots, σ = 0.3 mm, 40 points. Over a small seeded Monte Carlo the
/// whole-cell fit's cooperative rms beats the placement-only fit's in every trial and on
/// average, and the predicted rms (root-mean-square over trials) is within ±25 % of the measured.
#[test]
fn whole_cell_beats_placement_and_predicts_its_accuracy() {
    let trials: Vec<Trial> = (0..10)
        .map(|s| trial(Cell::Wall, 100 + s, 40, 3e-4, 200))
        .collect();
    let rms = |f: &dyn Fn(&Trial) -> f64| {
        (trials.iter().map(|t| f(t).powi(2)).sum::<f64>() / trials.len() as f64).sqrt()
    };
    let place = rms(&|t| t.placement_rms);
    let whole = rms(&|t| t.whole_rms);
    let pred = rms(&|t| t.predicted_rms);
    for t in &trials {
        assert!(
            t.whole_rms < t.placement_rms,
            "{} vs {}",
            t.whole_rms,
            t.placement_rms
        );
    }
    eprintln!(
        "floor–wall, 40 pts, σ 0.3 mm, 10 trials: placement-only {:.3} mm, whole-cell {:.3} mm, \
         predicted {:.3} mm (ratio {:.2}); fit {:.1} ms mean",
        place * 1e3,
        whole * 1e3,
        pred * 1e3,
        pred / whole,
        1e3 * trials.iter().map(|t| t.seconds).sum::<f64>() / trials.len() as f64
    );
    assert!(whole < 0.7 * place, "whole {whole} vs placement {place}");
    assert!(
        (pred / whole - 1.0).abs() <= 0.25,
        "predicted {pred} vs measured {whole}"
    );
}

/// The reduction on a floor–floor cell with every default tolerance (origin rpy included):
/// both robots' first-joint origins are rigid motions of a base (confounded with
/// `b1_from_b2`), and a joint offset about z and the same joint's origin yaw cannot be told
/// apart (one is merged into the other). The fit on the reduced layout still converges.
#[test]
fn reduction_names_what_the_placement_absorbs_and_what_is_merged() {
    let sc = sim_cell(Cell::Floor, Tolerance::default(), false, 21);
    let p = coincident_problem(&sc, 40, 3e-4, 22);
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let init = initial_estimate(&p, None, &active).unwrap();
    let red = reduce(&p, &init, &active).unwrap();
    for d in &red.dropped {
        eprintln!("{}", d.message);
    }
    eprintln!(
        "kept {} (data-determined {}, prior-dominated {})",
        red.kept, red.data_determined, red.prior_dominated
    );
    for r in [Robot::One, Robot::Two] {
        for axis in kinematics::Axis::ALL {
            let p = CellParam::Kinematic {
                robot: r,
                param: ErrorParam::OriginXyz { joint: 0, axis },
            };
            let e = red
                .dropped
                .iter()
                .find(|d| d.param == p)
                .unwrap_or_else(|| panic!("{r} joint 1 origin {axis} not dropped"));
            assert!(
                matches!(
                    e.reason,
                    ReductionReason::ConfoundedWithPlacement | ReductionReason::MergedInto { .. }
                ),
                "{}",
                e.message
            );
        }
    }
    assert!(red.dropped.iter().any(|d| matches!(
        d.reason,
        ReductionReason::ConfoundedWithPlacement
    ) && d.message.contains("confounded with b1_from_b2")));
    assert!(red
        .dropped
        .iter()
        .any(|d| matches!(d.reason, ReductionReason::MergedInto { .. })));
    assert_eq!(
        red.kept + red.dropped.len(),
        ParamLayout::new(&p, &[]).len() - 6
    );
    let fit = fit_cell_with(
        &p,
        red.layout,
        &active,
        None,
        Some(&init),
        &SolveOptions::default(),
    )
    .unwrap();
    assert_eq!(fit.stopped, StopReason::Converged);
    assert!(!fit.singular, "the reduced problem is fully determined");
}

/// Regression (the placement-only model in `handclasp calibrate --cell --model placement`): with
/// every tolerance 0 there is no kinematic unknown; the reduction used to panic in nalgebra's SVD
/// of a matrix without columns. It now keeps nothing and drops nothing.
#[test]
fn reduction_without_kinematic_unknowns_is_empty() {
    let none = Tolerance {
        joint_offset_rad: 0.0,
        origin_xyz_m: 0.0,
        origin_rpy_rad: 0.0,
        tip_m: 0.0,
        joint_scale: None,
        compliance_rad_per_nm: None,
        periodic_rad: None,
    };
    let sc = sim_cell(Cell::Floor, none, false, 31);
    let p = coincident_problem(&sc, 12, 3e-4, 32);
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let init = initial_estimate(&p, None, &active).unwrap();
    let red = reduce(&p, &init, &active).unwrap();
    assert_eq!(red.kept, 0);
    assert!(red.dropped.is_empty());
}

/// Issue 11's blunder test: three 5–10 mm blunders in a 40-point floor–wall session whose
/// robot 2 hides a 0.12° joint-3 offset (the only error; every realistic parameter is fitted,
/// with robot 2's offset tolerance widened to 0.2° so the prior admits it). The three rows are
/// named (and only they), each well above the threshold; the screened fit equals the fit of the
/// clean rows; the hidden offset is found (its 95 % interval, ±1.96 posterior σ, excludes 0 and
/// it is within 3 σ of the truth); and the cooperative
/// error stays at the clean level while the unscreened fit's is several times worse.
#[test]
fn three_blunders_are_named_and_the_hidden_offset_is_still_found() {
    let mut sc = sim_cell(Cell::Wall, realistic(), false, 31);
    sc.robot2.tolerance.joint_offset_rad = 0.2f64.to_radians();
    let x = sc.truth.b1_from_b2;
    sc.truth = CellEstimate::nominal(&sc.problem(), x);
    let j3 = ErrorParam::JointOffset { joint: 2 };
    sc.truth.robot2.errors.add(j3, 0.12f64.to_radians());
    let blunders = [(7, 5e-3), (19, 7.5e-3), (33, 10e-3)];
    let mut p = sc.problem();
    p.observations = sc.coincident_with_blunders(40, 3e-4, 0.7, 32, &blunders);
    let solve = SolveOptions::default();
    let s = fit_screened(&p, None, &solve, &ScreenOptions::default()).unwrap();
    let rows: Vec<usize> = s.rejected.iter().map(|r| r.row).collect();
    for r in &s.rejected {
        eprintln!(
            "rejected row {} ({}): {:.1} σ, {:.2} mm (threshold {:.2} σ)",
            r.row,
            r.kind,
            r.size_sigma,
            r.residual_m * 1e3,
            s.threshold_sigma_3
        );
    }
    assert_eq!(rows, vec![7, 19, 33]);
    assert!(s
        .rejected
        .iter()
        .all(|r| r.size_sigma > s.threshold_sigma_3));
    // The screened fit is the fit of the clean rows.
    let clean: Vec<usize> = (0..40).filter(|i| ![6, 18, 32].contains(i)).collect();
    let clean_fit =
        fit_cell_with(&p, ParamLayout::new(&p, &[]), &clean, None, None, &solve).unwrap();
    let dx = (clean_fit.estimate.b1_from_b2.translation.vector
        - s.fit.estimate.b1_from_b2.translation.vector)
        .norm();
    assert!(dx < 1e-9, "screened vs clean placement differ by {dx} m");
    let col = s
        .fit
        .layout
        .column(&CellParam::Kinematic {
            robot: Robot::Two,
            param: j3,
        })
        .expect("robot 2 joint 3 offset is fitted");
    let fitted = s.fit.layout.values(&s.fit.estimate)[col];
    let se = s.fit.std_error(col);
    let truth = sc.truth.robot2.errors.get(j3);
    eprintln!(
        "robot 2 joint 3 offset: fitted {:.4}°, true {:.4}° (posterior σ {:.4}°)",
        fitted.to_degrees(),
        truth.to_degrees(),
        se.to_degrees()
    );
    assert!(fitted.abs() > 1.96 * se && (fitted - truth).abs() < 3.0 * se);
    let pairs = sc.eval_pairs(100, 0.7, 33);
    let screened = measure_cooperative_error(&p, &s.fit.estimate, &sc.truth, &pairs).unwrap();
    let plain = fit_cell(&p, &solve).unwrap();
    let unscreened = measure_cooperative_error(&p, &plain.estimate, &sc.truth, &pairs).unwrap();
    eprintln!(
        "cooperative rms: screened {:.3} mm, unscreened {:.3} mm",
        screened.rms_m * 1e3,
        unscreened.rms_m * 1e3
    );
    assert!(unscreened.rms_m > 2.0 * screened.rms_m);
}

/// Clean data: nothing is rejected (α = 1 % family-wise, so a false alarm in these seeds would
/// be a 1-in-100 event each).
#[test]
fn clean_sessions_lose_no_rows() {
    for seed in [41u64, 42, 43] {
        let sc = sim_cell(Cell::Floor, realistic(), false, seed);
        let p = coincident_problem(&sc, 30, 3e-4, seed + 7);
        let s = fit_screened(
            &p,
            None,
            &SolveOptions::default(),
            &ScreenOptions::default(),
        )
        .unwrap();
        assert!(s.rejected.is_empty(), "seed {seed}: {:?}", s.rejected);
    }
}

/// When the rows left after rejection are too few, the error names the rows to re-record.
#[test]
fn too_few_rows_after_rejection_names_the_rows_to_re_record() {
    let sc = sim_cell(Cell::Wall, realistic(), false, 51);
    let mut p = sc.problem();
    p.observations = sc.coincident_with_blunders(12, 3e-4, 0.7, 52, &[(3, 8e-3), (9, 6e-3)]);
    let screen = ScreenOptions {
        min_redundancy: 30,
        ..ScreenOptions::default()
    };
    let Err(e) = fit_screened(&p, None, &SolveOptions::default(), &screen) else {
        panic!("expected TooFewRows, got a fit");
    };
    assert!(e.to_string().contains("re-record rows [3, 9]"), "{e}");
    match e {
        CellFitError::TooFewRows { rejected_rows, .. } => assert_eq!(rejected_rows, vec![3, 9]),
        other => panic!("expected TooFewRows, got {other:?}"),
    }
}

/// With no row rejected, the error says the session is too small, not "re-record rows []"
/// (regression: `calibrate --cell` on a 6-row face-contact session printed exactly that).
#[test]
fn too_few_rows_without_rejection_asks_for_more_rows() {
    let e = CellFitError::TooFewRows {
        remaining: 6,
        needed: 13,
        rejected_rows: vec![],
    };
    let text = e.to_string();
    assert!(
        text.contains("only 6 residual rows") && text.contains("record more rows"),
        "{text}"
    );
    assert!(!text.contains("[]"), "{text}");
}

/// Candidate handclasps (noise-free pairs of the nominal cell) as coincident observations.
fn candidates(sc: &SimCell, n: usize, sigma: f64, seed: u64) -> Vec<Observation> {
    sc.eval_pairs(n, 0.9, seed)
        .into_iter()
        .enumerate()
        .map(|(i, pair)| Observation {
            row: i + 1,
            kind: ObservationKind::Coincident {
                q1: pair.q1,
                q2: pair.q2,
                tool1: 0,
                tool2: 0,
                noise: Noise3::Isotropic { sigma_m: sigma },
            },
        })
        .collect()
}

/// The greedy A-optimal (cooperative) and D-optimal choices of 20 of 120 candidates beat every
/// one of 20 seeded random subsets of the same size on their own criterion, and the criterion
/// the design reports equals the one recomputed from scratch for its chosen set.
#[test]
fn greedy_design_beats_random_subsets_on_its_criterion() {
    let mut sc = sim_cell(Cell::Wall, realistic(), false, 61);
    let x = sc.truth.b1_from_b2;
    sc.truth = CellEstimate::nominal(&sc.problem(), x);
    let p = sc.problem();
    let cands = candidates(&sc, 120, 3e-4, 62);
    let eval = sc.eval_pairs(60, 0.7, 63);
    let layout = ParamLayout::new(&p, &[]);
    let at = CellEstimate::nominal(&p, x);
    let mut rng = ChaCha8Rng::seed_from_u64(64);
    for crit in [DesignCriterion::CooperativeA, DesignCriterion::D] {
        let d = greedy_design(&p, &layout, &at, &cands, &eval, 20, crit).unwrap();
        assert_eq!(d.chosen.len(), 20);
        let again = design_criterion(&p, &layout, &at, &cands, &d.chosen, &eval, crit).unwrap();
        assert!(
            (again - d.criterion).abs() <= 1e-6 * d.criterion.abs(),
            "{crit:?}: Woodbury {} vs direct {again}",
            d.criterion
        );
        let mut random = Vec::new();
        for _ in 0..20 {
            let mut idx: Vec<usize> = (0..cands.len()).collect();
            for i in 0..20 {
                let j = rng.random_range(i..idx.len());
                idx.swap(i, j);
            }
            random
                .push(design_criterion(&p, &layout, &at, &cands, &idx[..20], &eval, crit).unwrap());
        }
        let mean = random.iter().sum::<f64>() / random.len() as f64;
        eprintln!(
            "{crit:?}: greedy {:.6e}, random mean {:.6e}",
            d.criterion, mean
        );
        for r in &random {
            match crit {
                DesignCriterion::CooperativeA => assert!(d.criterion < *r),
                _ => assert!(d.criterion > *r),
            }
        }
    }
}

/// A mixed session on a floor–wall cell with two tools on robot 1: 30 coincident handclasps,
/// 20 tracker readings of robot 1's reflector (tracker frame unknown, anchored to b1), 15
/// touches of robot 2's tip on an unknown plane (anchored to b2) and 10 sphere contacts at an
/// unknown distance. All noise σ = 0.05 mm. The MAP fit converges, its data χ² is that of the
/// noise, the contact distance and the plane come back within 4 posterior σ, and the cooperative
/// error beats the placement-only fit's.
#[test]
fn mixed_session_recovers_groups_and_beats_placement_only() {
    let sigma = 5e-5;
    let sc = sim_cell(Cell::Wall, realistic(), true, 71);
    let mut p = sc.problem();
    let mut obs: Vec<ObservationKind> = sc
        .coincident(30, sigma, 0.7, 72)
        .into_iter()
        .map(|o| o.kind)
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(73);
    let normal = |rng: &mut ChaCha8Rng| {
        Vector3::from_fn(|_, _| {
            let z: f64 = rand_distr::Distribution::sample(&rand_distr::StandardNormal, rng);
            z * sigma
        })
    };
    // Tracker.
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, -0.2, 2.5));
    p.trackers = vec![TrackerGroup {
        name: "leica".into(),
        anchor: Robot::One,
        initial_tracker_from_anchor: None,
        fit_scale: false,
        fit_drift: false,
    }];
    for _ in 0..20 {
        let q = random_q(&p.robot1.model, &mut rng);
        let t = sc.true_tip(Robot::One, 1, &q);
        obs.push(ObservationKind::Tracker {
            robot: Robot::One,
            q,
            tool: 1,
            group: 0,
            p_tracker: tracker_from_b1 * Point3::from(t) + normal(&mut rng),
            noise: Noise3::Isotropic { sigma_m: sigma },
        });
    }
    // Plane z = 0.3 m in b2, touched by robot 2's tip pointing into it.
    let (n_true, d_true) = (Vector3::z_axis(), 0.3);
    p.planes = vec![PlaneGroup {
        name: "table".into(),
        anchor: Robot::Two,
        initial: None,
    }];
    let mut touched = 0;
    while touched < 15 {
        let target = Point3::new(
            rng.random_range(0.6..1.1),
            rng.random_range(-0.5..0.5),
            d_true + normal(&mut rng).z,
        );
        if let Some(q) = sc.solve_true(Robot::Two, 0, &target, -Vector3::z_axis()) {
            obs.push(ObservationKind::Plane {
                robot: Robot::Two,
                q,
                tool: 0,
                group: 0,
                sigma_m: sigma,
            });
            touched += 1;
        }
    }
    // Sphere contacts 50 mm apart.
    let d_contact = 0.05;
    p.contacts = vec![ContactGroup {
        name: "spheres".into(),
        distance_m: 0.045,
        fit_distance: true,
    }];
    let mut contacts = 0;
    while contacts < 10 {
        let dir = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize();
        let along = d_contact + normal(&mut rng).x;
        if let Some(pair) = sc.draw_pair(&mut rng, 0.6, 1, dir * along) {
            obs.push(ObservationKind::Contact {
                q1: pair.q1,
                q2: pair.q2,
                tool1: 1,
                tool2: 0,
                group: 0,
                sigma_m: sigma,
            });
            contacts += 1;
        }
    }
    p.observations = obs
        .into_iter()
        .enumerate()
        .map(|(i, kind)| Observation { row: i + 1, kind })
        .collect();
    let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
    assert_eq!(fit.stopped, StopReason::Converged);
    let chi2_per_row = fit.data_chi2 / fit.residual_rows as f64;
    let col_d = fit
        .layout
        .column(&CellParam::ContactDistance { group: 0 })
        .unwrap();
    let col_off = fit
        .layout
        .column(&CellParam::PlaneOffset { group: 0 })
        .unwrap();
    let d_fit = fit.estimate.contact_distance_m[0];
    let plane = fit.estimate.planes[0];
    // The fitted normal may point either way.
    let sign = plane.normal_anchor.dot(&n_true).signum();
    eprintln!(
        "mixed: {} iterations, χ²/row {chi2_per_row:.2}, contact {:.4} mm (σ {:.4}), plane \
         offset {:.4} mm (σ {:.4}), normal error {:.2e} rad",
        fit.iterations,
        d_fit * 1e3,
        fit.std_error(col_d) * 1e3,
        sign * plane.offset_m * 1e3,
        fit.std_error(col_off) * 1e3,
        (plane.normal_anchor.into_inner() * sign - n_true.into_inner()).norm()
    );
    assert!((0.5..1.5).contains(&chi2_per_row));
    assert!((d_fit - d_contact).abs() < 4.0 * fit.std_error(col_d));
    assert!((sign * plane.offset_m - d_true).abs() < 4.0 * fit.std_error(col_off));
    let pairs = sc.eval_pairs(100, 0.7, 74);
    let whole = measure_cooperative_error(&p, &fit.estimate, &sc.truth, &pairs).unwrap();
    let mut q = p.clone();
    q.observations.truncate(30);
    q.trackers.clear();
    q.planes.clear();
    q.contacts.clear();
    let place = placement_error(&q, &sc, &pairs);
    eprintln!(
        "mixed: cooperative rms {:.3} mm vs placement-only {:.3} mm",
        whole.rms_m * 1e3,
        place.rms_m * 1e3
    );
    assert!(whole.rms_m < 0.5 * place.rms_m);
}

/// The larger Monte Carlo behind the reported figures (run in release:
/// `cargo test --release -p calib-core --lib whole_cell::tests::monte_carlo -- --ignored --nocapture`).
/// Per shipped cell, 40 seeded trials of 40 points at σ = 0.3 mm, truths drawn from the
/// realistic tolerances, 200 held-out pairs each: placement-only vs whole-cell cooperative rms,
/// predicted vs measured, time per fit (reduction + MAP); then the time of a fit with every
/// default tolerance (origin rpy too: ~100 parameters) at 20, 40 and 80 points.
#[test]
#[ignore = "a Monte Carlo for the report: run in release with --ignored --nocapture"]
fn monte_carlo_three_cells() {
    for cell in [Cell::Floor, Cell::Wall, Cell::Ceiling] {
        let trials: Vec<Trial> = (0..40)
            .map(|s| trial(cell, 500 + s, 40, 3e-4, 200))
            .collect();
        let rms = |f: &dyn Fn(&Trial) -> f64| {
            (trials.iter().map(|t| f(t).powi(2)).sum::<f64>() / trials.len() as f64).sqrt()
        };
        let mut whole: Vec<f64> = trials.iter().map(|t| t.whole_rms).collect();
        whole.sort_by(f64::total_cmp);
        let mut place: Vec<f64> = trials.iter().map(|t| t.placement_rms).collect();
        place.sort_by(f64::total_cmp);
        eprintln!(
            "{cell:?}: cooperative rms over 40 trials (rms of trials / median): placement-only \
             {:.3}/{:.3} mm, whole-cell {:.3}/{:.3} mm, predicted {:.3} mm (predicted/measured \
             {:.2}); fit {:.1} ms mean, {:.1} ms max",
            rms(&|t| t.placement_rms) * 1e3,
            crate::stats::quantile(&place, 0.5) * 1e3,
            rms(&|t| t.whole_rms) * 1e3,
            crate::stats::quantile(&whole, 0.5) * 1e3,
            rms(&|t| t.predicted_rms) * 1e3,
            rms(&|t| t.predicted_rms) / rms(&|t| t.whole_rms),
            1e3 * trials.iter().map(|t| t.seconds).sum::<f64>() / trials.len() as f64,
            1e3 * trials.iter().map(|t| t.seconds).fold(0.0, f64::max),
        );
    }
    // Where the whole-cell fit stops paying: the floor–wall cell at σ = 1 mm and 4.4 mm.
    for sigma in [3e-4, 1e-3, 4.4e-3] {
        let trials: Vec<Trial> = (0..40)
            .map(|s| trial(Cell::Wall, 700 + s, 40, sigma, 200))
            .collect();
        let mean = |f: &dyn Fn(&Trial) -> f64| trials.iter().map(f).sum::<f64>() / 40.0;
        let worse = trials
            .iter()
            .filter(|t| t.whole_rms > t.placement_rms)
            .count();
        eprintln!(
            "Wall σ {:.1} mm: mean cooperative rms placement-only {:.3} mm, whole-cell {:.3} mm \
             (worse in {worse}/40 trials), predicted {:.3} mm; mean p95 measured {:.3} mm, \
             predicted {:.3} mm",
            sigma * 1e3,
            mean(&|t| t.placement_rms) * 1e3,
            mean(&|t| t.whole_rms) * 1e3,
            mean(&|t| t.predicted_rms) * 1e3,
            mean(&|t| t.whole_p95) * 1e3,
            mean(&|t| t.predicted_p95) * 1e3,
        );
    }
    for n in [20usize, 40, 80] {
        let sc = sim_cell(Cell::Ceiling, Tolerance::default(), false, 900 + n as u64);
        let p = coincident_problem(&sc, n, 3e-4, 901);
        let n_params = ParamLayout::new(&p, &[]).len();
        let start = Instant::now();
        let active: Vec<usize> = (0..n).collect();
        let init = initial_estimate(&p, None, &active).unwrap();
        let red = reduce(&p, &init, &active).unwrap();
        let fit = fit_cell_with(
            &p,
            red.layout,
            &active,
            None,
            Some(&init),
            &SolveOptions::default(),
        )
        .unwrap();
        let reduced = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let plain = fit_cell(&p, &SolveOptions::default()).unwrap();
        let unreduced = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let screened = fit_screened(
            &p,
            None,
            &SolveOptions::default(),
            &ScreenOptions::default(),
        )
        .unwrap();
        let screen_s = start.elapsed().as_secs_f64();
        eprintln!(
            "floor–ceiling, {n} points, {n_params} unknowns (all default tolerances): reduce+fit \
             {:.1} ms ({} it, {:?}), full fit {:.1} ms ({} it, {:?}), screened fit {:.1} ms \
             ({} rejected)",
            reduced * 1e3,
            fit.iterations,
            fit.stopped,
            unreduced * 1e3,
            plain.iterations,
            plain.stopped,
            screen_s * 1e3,
            screened.rejected.len()
        );
    }
}

/// The one-call calibration on a session with a blunder: the report names the row, lists what
/// was dropped, and serialises in file units with its keys in alphabetical order (the order of
/// the `serde_json::Value` the CLI built before the report had types).
#[test]
fn calibrate_cell_reports_rows_reduction_and_serialises() {
    let sc = sim_cell(Cell::Ceiling, realistic(), false, 81);
    let mut p = sc.problem();
    p.observations = sc.coincident_with_blunders(30, 3e-4, 0.7, 82, &[(11, 6e-3)]);
    let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
    let report = cal.report(&p);
    assert_eq!(report.rejected_points.len(), 1);
    assert_eq!(report.rejected_points[0].row, 11);
    // The 6 mm blunder, in mm.
    assert!(report.rejected_points[0].residual_mm > 1.0);
    assert_eq!(report.stopped, StopReason::Converged);
    assert!(!report.unidentifiable.is_empty());
    assert!(!report.parameters.is_empty());
    assert_eq!(report.b1_from_b2.sigma.len(), 6);
    let json = serde_json::to_string(&report).unwrap();
    for key in [
        "\"size_sigma\"",
        "\"prior_sigma\"",
        "\"residual_mm\"",
        "\"stopped\":\"converged\"",
    ] {
        assert!(json.contains(key), "{key} missing in {json}");
    }
    let sorted = serde_json::to_string(&serde_json::to_value(&report).unwrap()).unwrap();
    assert_eq!(json, sorted, "report keys out of alphabetical order");
}

/// Issue 11's time bound, by iteration count (not wall clock), on the kind of session that made
/// `diagnose` run for minutes: 20 points on the floor–ceiling cell at σ = 0.3 mm with errors on
/// every joint of both robots (every default tolerance fitted: ~100 unknowns).
#[test]
fn every_joint_session_converges_within_the_iteration_bound() {
    for seed in [91u64, 92, 93, 94, 920] {
        let sc = sim_cell(Cell::Ceiling, Tolerance::default(), false, seed);
        let p = coincident_problem(&sc, 20, 3e-4, 901);
        let active: Vec<usize> = (0..p.observations.len()).collect();
        let init = initial_estimate(&p, None, &active).unwrap();
        let red = reduce(&p, &init, &active).unwrap();
        let opts = SolveOptions::default();
        let fit = fit_cell_with(&p, red.layout, &active, None, Some(&init), &opts).unwrap();
        let full = fit_cell(&p, &opts).unwrap();
        eprintln!(
            "seed {seed}: reduced {} iterations {:?}, full {} iterations {:?}",
            fit.iterations, fit.stopped, full.iterations, full.stopped
        );
        for f in [&fit, &full] {
            assert_eq!(f.stopped, StopReason::Converged);
            assert!(f.iterations <= 10, "{} iterations", f.iterations);
        }
    }
}

/// Cooperative rms (m) of the one-call calibration, of the scale-1 MAP fit on its rows (the
/// fit before the prior scale was chosen) and of the placement-only fit, and the chosen scale.
struct ScaleTrial {
    chosen_rms: f64,
    scale1_rms: f64,
    placement_rms: f64,
    scale: f64,
    /// Wall-clock time of the one-call calibration, s.
    seconds: f64,
}

/// `truth_fraction`: the truth is drawn from `U(±truth_fraction·tolerance)` while the prior
/// keeps the full tolerances (1: the prior is right; < 1: the robots are better than their
/// tolerances, the prior too wide).
fn scale_trial(cell: Cell, seed: u64, n: usize, sigma: f64, truth_fraction: f64) -> ScaleTrial {
    let tol = realistic();
    let truth_tol = Tolerance {
        joint_offset_rad: tol.joint_offset_rad * truth_fraction,
        origin_xyz_m: tol.origin_xyz_m * truth_fraction,
        tip_m: tol.tip_m * truth_fraction,
        ..tol
    };
    let sc = sim_cell(cell, truth_tol, false, seed);
    let mut p = coincident_problem(&sc, n, sigma, seed + 1000);
    p.robot1.tolerance = tol;
    p.robot2.tolerance = tol;
    let pairs = sc.eval_pairs(200, 0.7, seed + 2000);
    let start = Instant::now();
    let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let chosen = measure_cooperative_error(&p, &cal.fit.estimate, &sc.truth, &pairs).unwrap();
    let all: Vec<usize> = (0..n).collect();
    let init = initial_estimate(&p, None, &all).unwrap();
    let scale1 = fit_cell_with(
        &p,
        cal.reduction.layout.clone(),
        &cal.fit.active,
        None,
        Some(&init),
        &SolveOptions::default(),
    )
    .unwrap();
    let scale1 = measure_cooperative_error(&p, &scale1.estimate, &sc.truth, &pairs).unwrap();
    ScaleTrial {
        chosen_rms: chosen.rms_m,
        scale1_rms: scale1.rms_m,
        placement_rms: placement_error(&p, &sc, &pairs).rms_m,
        scale: cal.prior_scale.scale,
        seconds,
    }
}

/// Item 3's measurement (`cargo test --release -p calib-core --lib whole_cell::tests::prior_scale_monte_carlo -- --ignored --nocapture`):
/// floor–wall, 40 points, 40 trials per σ: cooperative rms of the scale-1 MAP fit (before) and
/// of the evidence-chosen scale (after) against the placement-only fit.
#[test]
#[ignore = "a Monte Carlo for the report: run in release with --ignored --nocapture"]
fn prior_scale_monte_carlo() {
    for (sigma, fraction) in [
        (3e-4, 1.0),
        (1e-3, 1.0),
        (4.4e-3, 1.0),
        (1e-3, 0.25),
        (4.4e-3, 0.25),
    ] {
        let t: Vec<ScaleTrial> = (0..40)
            .map(|s| scale_trial(Cell::Wall, 700 + s, 40, sigma, fraction))
            .collect();
        let mean = |f: &dyn Fn(&ScaleTrial) -> f64| t.iter().map(f).sum::<f64>() / 40.0 * 1e3;
        let worse =
            |f: &dyn Fn(&ScaleTrial) -> f64| t.iter().filter(|x| f(x) > x.placement_rms).count();
        let worst = |f: &dyn Fn(&ScaleTrial) -> f64| {
            t.iter().map(|x| f(x) / x.placement_rms).fold(0.0, f64::max)
        };
        eprintln!(
            "Wall σ {:.1} mm, truth U(±{fraction}·tol): mean coop rms placement {:.3} mm; scale-1 MAP {:.3} mm (worse in \
             {}/40, worst ratio {:.2}); evidence-chosen {:.3} mm (worse in {}/40, worst ratio \
             {:.2}); calibrate_cell {:.1} ms mean, {:.1} ms max; scales chosen: {}",
            sigma * 1e3,
            mean(&|x| x.placement_rms),
            mean(&|x| x.scale1_rms),
            worse(&|x| x.scale1_rms),
            worst(&|x| x.scale1_rms),
            mean(&|x| x.chosen_rms),
            worse(&|x| x.chosen_rms),
            worst(&|x| x.chosen_rms),
            mean(&|x| x.seconds),
            t.iter().map(|x| x.seconds).fold(0.0, f64::max) * 1e3,
            t.iter()
                .map(|x| format!("{}", x.scale))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
}

/// Issue 11's accuracy target for a prediction: within ±25 % of the measured value.
const PREDICTION_TOL_REL: f64 = 0.25;

/// Issue 11 item 4: the placement-only model on sessions whose robots carry errors on every
/// joint (offsets ±0.05°, origins and tips ±0.5 mm, σ = 0.3 mm, 30 points). Its residuals hold
/// the unmodelled kinematic error, so the screen works at the residuals' robust scale: no clean
/// row is rejected, a 10 mm blunder still is, and the prediction carries the model-error term.
#[test]
fn placement_only_screen_and_prediction_allow_for_model_error() {
    for seed in [61u64, 62, 63] {
        let sc = sim_cell(Cell::Floor, realistic(), false, seed);
        let mut p = sc.problem();
        p.robot1.tolerance = Tolerance::none();
        p.robot2.tolerance = Tolerance::none();
        p.observations = sc.coincident(30, 3e-4, 0.7, seed + 7);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        assert!(cal.rejected.is_empty(), "seed {seed}: {:?}", cal.rejected);
        assert!(cal.noise_scale > 1.0, "seed {seed}: {}", cal.noise_scale);
        let pairs = sc.eval_pairs(200, 0.7, seed + 2000);
        let pred = predict_cooperative_accuracy(&p, &cal.fit, &pairs, seed).unwrap();
        let meas = measure_cooperative_error(&p, &cal.fit.estimate, &sc.truth, &pairs).unwrap();
        eprintln!(
            "seed {seed}: noise scale {:.2}, predicted {:.3} mm, measured {:.3} mm",
            cal.noise_scale,
            pred.predicted_rms_m * 1e3,
            meas.rms_m * 1e3
        );
        // The issue's ±25 % between predicted and measured cooperative rms (before the
        // model-error term the prediction was ~0.15 mm against ~1 mm measured).
        assert!(
            (pred.predicted_rms_m / meas.rms_m - 1.0).abs() <= PREDICTION_TOL_REL,
            "seed {seed}: predicted {} vs measured {}",
            pred.predicted_rms_m,
            meas.rms_m
        );
        let mut q = p.clone();
        q.observations = sc.coincident_with_blunders(30, 3e-4, 0.7, seed + 7, &[(12, 10e-3)]);
        let cal = calibrate_cell(&q, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let rows: Vec<usize> = cal.rejected.iter().map(|r| r.row).collect();
        assert_eq!(rows, vec![12], "seed {seed}");
    }
}

/// The evidence-chosen scale 1e-3 shrinks the kinematic corrections to ~1e-6 of their
/// tolerances: its fit is the placement-only fit far inside 0.1 %.
const PLACEMENT_LIMIT_REL: f64 = 1e-3;

/// Regression of issue 11's "never worse than lsq" at σ = 4.4 mm (floor–wall, 40 points, the
/// seed-709 session of `prior_scale_monte_carlo`): the MAP fit at the tolerances' prior lost to
/// the placement-only fit (1.637 vs 1.583 mm); the session's evidence now chooses the
/// placement-only limit and the calibration is at the placement-only fit's level.
#[test]
fn high_noise_session_is_not_worse_than_placement_only() {
    let t = scale_trial(Cell::Wall, 709, 40, 4.4e-3, 1.0);
    assert!(
        t.scale1_rms > t.placement_rms,
        "the session no longer shows the defect"
    );
    assert_eq!(t.scale, PRIOR_SCALES[PRIOR_SCALES.len() - 1]);
    assert!(
        t.chosen_rms <= t.placement_rms * (1.0 + PLACEMENT_LIMIT_REL),
        "chosen {} vs placement-only {}",
        t.chosen_rms,
        t.placement_rms
    );
}

/// Robots four times better than their tolerances (truth U(±tol/4), prior from tol), σ = 1 mm,
/// 7 sessions: the MAP fit at the tolerances' prior fits noise into the kinematic parameters and
/// loses to the placement-only fit by > 20 % on average; the evidence-chosen scale keeps the
/// calibration within 5 % of it (measured: +0.9 %; scale-1 +27 %).
#[test]
fn too_wide_a_prior_is_shrunk_to_placement_level_by_the_evidence() {
    let t: Vec<ScaleTrial> = (700..707)
        .map(|s| scale_trial(Cell::Wall, s, 40, 1e-3, 0.25))
        .collect();
    let mean = |f: &dyn Fn(&ScaleTrial) -> f64| t.iter().map(f).sum::<f64>() / t.len() as f64;
    let place = mean(&|x| x.placement_rms);
    assert!(mean(&|x| x.scale1_rms) > 1.2 * place);
    assert!(mean(&|x| x.chosen_rms) < 1.05 * place);
}

/// Interval half-width, in posterior σ, within which a hidden term must be recovered (and an
/// absent one must fit to 0): 4σ (as the other recovery tests here), a 99.994 % interval per
/// parameter under the model, so that ~100 checked values do not fail by chance (3σ would, about
/// one time in four).
const RECOVERY_SIGMAS: f64 = 4.0;

/// The rms of the standardised errors `z = (fitted − truth)/σ` over all checked values must lie
/// in this band: ~1 when the reported σ are honest (a σ off by a factor 1.5 either way fails).
const Z_RMS_BAND: std::ops::RangeInclusive<f64> = 0.67..=1.5;

/// Asserts that every listed column of `fit` lies within [`RECOVERY_SIGMAS`] posterior σ of
/// `truth(column)`, and appends the standardised errors `z` to `zs`.
fn assert_within_interval(
    fit: &CellFit,
    problem: &CellProblem,
    cols: &[usize],
    truth: impl Fn(usize) -> f64,
    what: &str,
    zs: &mut Vec<f64>,
) {
    let values = fit.layout.values(&fit.estimate);
    for &c in cols {
        let sigma = fit.std_error(c);
        let z = (values[c] - truth(c)) / sigma;
        assert!(
            sigma > 0.0 && z.abs() <= RECOVERY_SIGMAS,
            "{what}: {} fitted {:e}, truth {:e}, σ {:e} (z = {z:.2})",
            fit.layout.params[c].describe(problem),
            values[c],
            truth(c),
            sigma
        );
        zs.push(z);
    }
}

/// Asserts that the rms of `zs` lies in [`Z_RMS_BAND`]; returns it and the largest |z|.
fn assert_calibrated(zs: &[f64], what: &str) -> (f64, f64) {
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64).sqrt();
    let worst = zs.iter().fold(0.0f64, |m, z| m.max(z.abs()));
    assert!(
        Z_RMS_BAND.contains(&rms),
        "{what}: rms z {rms:.2} over {} values: the reported σ are not honest",
        zs.len()
    );
    (rms, worst)
}

/// Columns of the periodic parameters of both robots.
fn periodic_columns(layout: &ParamLayout) -> Vec<usize> {
    (0..layout.len())
        .filter(|&c| {
            matches!(
                layout.params[c],
                CellParam::Kinematic {
                    param: ErrorParam::PeriodicSin { .. } | ErrorParam::PeriodicCos { .. },
                    ..
                }
            )
        })
        .collect()
}

/// Joint-angle-periodic errors (first harmonic, ±0.02° per amplitude) hidden in simulated
/// 60-point handclasp sessions are recovered within 4 posterior σ when fitted; with the truth
/// free of them, fitting them returns values within 4σ of 0; over six sessions (three each) the
/// rms of the standardised errors is ~1. Some amplitudes must be determined by the data
/// (posterior σ below half the prior's), so the check is not the prior's.
#[test]
fn periodic_errors_are_recovered_within_their_intervals() {
    let periodic = Tolerance {
        periodic_rad: Some(0.02f64.to_radians()),
        ..realistic()
    };
    let mut zs = Vec::new();
    for (hidden, seed) in (0..6u64).map(|k| (k % 2 == 0, 81 + 2 * k)) {
        let truth_tol = if hidden { periodic } else { realistic() };
        let sc = sim_cell(Cell::Floor, truth_tol, false, seed);
        let mut p = coincident_problem(&sc, 60, 5e-5, seed + 1);
        p.robot1.tolerance = periodic;
        p.robot2.tolerance = periodic;
        let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
        assert_eq!(fit.stopped, StopReason::Converged, "{:?}", fit.stopped);
        let cols = periodic_columns(&fit.layout);
        let dofs = p.robot1.model.dof() + p.robot2.model.dof();
        assert_eq!(cols.len(), 2 * dofs, "sin and cos per joint of both robots");
        let truth_of = |c: usize| match &fit.layout.params[c] {
            CellParam::Kinematic { robot, param } => sc.truth.robot(*robot).errors.get(*param),
            _ => unreachable!("periodic columns only"),
        };
        if hidden {
            assert!(cols.iter().any(|&c| truth_of(c) != 0.0));
        } else {
            assert!(cols.iter().all(|&c| truth_of(c) == 0.0));
        }
        let determined = cols
            .iter()
            .filter(|&&c| fit.std_error(c) < 0.5 * fit.layout.prior_sigma(c))
            .count();
        assert!(
            determined >= 4,
            "only {determined} periodic amplitudes determined"
        );
        assert_within_interval(&fit, &p, &cols, truth_of, "periodic", &mut zs);
        eprintln!(
            "periodic (seed {seed}, hidden: {hidden}): {} iterations, {determined}/{} determined",
            fit.iterations,
            cols.len()
        );
    }
    let (rms, worst) = assert_calibrated(&zs, "periodic");
    eprintln!(
        "periodic: rms z {rms:.2}, worst |z| {worst:.2} over {} values",
        zs.len()
    );
}

/// A tracker session of robot 1's second tool: `n` rows (numbered after `first_row − 1`) of the
/// true tip seen by a tracker at `tracker_from_b1` with scale error `scale` and drift `drift_m`
/// over the normalised order `u = k/(n − 1) − ½`, plus isotropic noise `sigma`.
#[allow(clippy::too_many_arguments)]
fn tracker_rows(
    sc: &SimCell,
    tracker_from_b1: &Isometry3<f64>,
    scale: f64,
    drift_m: &Vector3<f64>,
    n: usize,
    sigma: f64,
    first_row: usize,
    seed: u64,
) -> Vec<Observation> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let q = random_q(&sc.robot1.model, &mut rng);
            let g = sc.true_tip(Robot::One, 1, &q);
            let u = k as f64 / (n - 1) as f64 - 0.5;
            let noise = Vector3::from_fn(|_, _| {
                let z: f64 =
                    rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng);
                z * sigma
            });
            let p = (tracker_from_b1 * Point3::from(g) + drift_m * u) * (1.0 + scale) + noise;
            Observation {
                row: first_row + k,
                kind: ObservationKind::Tracker {
                    robot: Robot::One,
                    q,
                    tool: 1,
                    group: 0,
                    p_tracker: p,
                    noise: Noise3::Isotropic { sigma_m: sigma },
                },
            }
        })
        .collect()
}

/// A tracker's scale error (2e-4) and drift ((0.3, −0.2, 0.25) mm over the recording) hidden in
/// simulated sessions (30 handclasp rows, 40 tracker rows) are recovered within 4 posterior σ
/// and reported with their σ; without them in the data, fitting them returns values within 4σ
/// of 0; over eight sessions (four each) the rms of the standardised errors is ~1 (measured over
/// 30 sessions while writing this test: rms 1.02, largest |z| 3.05 of 120). Normalised order: the tracker rows are 31..70, so `u` runs from −½ to +½. The joint
/// origins are neither drawn nor fitted here: with them fitted (and no length reference) the
/// scale is confounded with the link lengths (measured: posterior σ 2.4e-4, as large as the
/// hidden scale), which is the Python study's "scale redundant with lengths".
#[test]
fn tracker_scale_and_drift_are_recovered_within_their_intervals() {
    let sigma = 5e-5;
    let tol = Tolerance {
        origin_xyz_m: 0.0,
        ..realistic()
    };
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, -0.2, 2.5));
    let mut zs = Vec::new();
    for (hidden, seed) in (0..8u64).map(|k| (k % 2 == 0, 91 + 2 * k)) {
        let (scale, drift) = if hidden {
            (2e-4, Vector3::new(3e-4, -2e-4, 2.5e-4))
        } else {
            (0.0, Vector3::zeros())
        };
        let sc = sim_cell(Cell::Wall, tol, true, seed);
        let mut p = sc.problem();
        p.observations = sc.coincident(30, sigma, 0.7, seed + 1);
        p.observations.extend(tracker_rows(
            &sc,
            &tracker_from_b1,
            scale,
            &drift,
            40,
            sigma,
            31,
            seed + 2,
        ));
        p.trackers = vec![TrackerGroup {
            name: "leica".into(),
            anchor: Robot::One,
            initial_tracker_from_anchor: None,
            fit_scale: true,
            fit_drift: true,
        }];
        assert_eq!(p.tracker_order(0, 31), -0.5);
        assert_eq!(p.tracker_order(0, 70), 0.5);
        let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
        assert_eq!(fit.stopped, StopReason::Converged, "{:?}", fit.stopped);
        let s_col = fit
            .layout
            .column(&CellParam::TrackerScale { group: 0 })
            .unwrap();
        let d_cols: Vec<usize> = kinematics::Axis::ALL
            .iter()
            .map(|&axis| {
                fit.layout
                    .column(&CellParam::TrackerDrift { group: 0, axis })
                    .unwrap()
            })
            .collect();
        let truth_of = |c: usize| {
            if c == s_col {
                scale
            } else {
                drift[d_cols.iter().position(|&d| d == c).unwrap()]
            }
        };
        let mut cols = vec![s_col];
        cols.extend(&d_cols);
        assert_within_interval(&fit, &p, &cols, truth_of, "tracker nuisance", &mut zs);
        // Reported like the other nuisances: unpenalised, with a posterior σ well below the
        // hidden values (so the hidden case is a detection, not a prior's guess).
        let report = fit.parameters(&p);
        let s_report = report
            .iter()
            .find(|f| f.param == CellParam::TrackerScale { group: 0 })
            .unwrap();
        assert_eq!(s_report.prior_sigma, 0.0);
        assert!(s_report.posterior_sigma < 0.25 * 2e-4, "{s_report:?}");
        assert!(s_report.value.abs() > 4.0 * s_report.posterior_sigma || !hidden);
        for &c in &d_cols {
            assert!(fit.std_error(c) < 0.25 * 2e-4, "{}", report[c].name);
        }
        eprintln!(
            "tracker (seed {seed}, hidden: {hidden}): {} iterations, scale {:.2e} ± {:.1e}, drift \
             {:.3?} mm ± {:.3?} mm",
            fit.iterations,
            fit.estimate.tracker_scale[0],
            fit.std_error(s_col),
            (fit.estimate.tracker_drift_m[0] * 1e3).as_slice(),
            d_cols
                .iter()
                .map(|&c| fit.std_error(c) * 1e3)
                .collect::<Vec<_>>(),
        );
    }
    let (rms, worst) = assert_calibrated(&zs, "tracker nuisance");
    eprintln!(
        "tracker: rms z {rms:.2}, worst |z| {worst:.2} over {} values",
        zs.len()
    );
}

/// The new terms stay out of serialised estimates while they are zero (so reports of fits
/// without them are byte-identical to before), and appear once set.
#[test]
fn new_terms_serialise_only_when_set() {
    let (p, _) = every_kind(5);
    let mut est = CellEstimate::nominal(&p, Isometry3::identity());
    let json = serde_json::to_string(&est).unwrap();
    for key in [
        "periodic_sin",
        "periodic_cos",
        "tracker_scale",
        "tracker_drift_m",
    ] {
        assert!(!json.contains(key), "`{key}` in {json}");
    }
    est.robot2.errors.periodic_cos[1] = 1e-4;
    est.robot1.errors.periodic_sin[6] = -1e-4;
    est.tracker_scale[0] = 1e-5;
    est.tracker_drift_m[1].z = 1e-4;
    let json = serde_json::to_string(&est).unwrap();
    for key in [
        "periodic_sin",
        "periodic_cos",
        "tracker_scale",
        "tracker_drift_m",
    ] {
        assert!(json.contains(key), "`{key}` missing from {json}");
    }
}

/// Issue 12 blamed the CTU `all+c` fit's iteration cap on compliance's units (rad/(N·m) next to
/// rad). In simulation a compliance fit with joint offsets, a tracker whose frame is fitted and
/// a reflector recorded at one tool orientation (a 4×4×3 grid of positions, flange z held
/// vertical, the CTU 6×6×6 file's design) converges in a few iterations, whether the reflector
/// offset's prior is free (10 m, the CTU example's) or physical (0.2 m); the Levenberg–Marquardt
/// damping `λ·diag H` already makes the steps independent of the columns' units. What the grid
/// leaves undetermined is the reflector offset along the held flange axis (confounded with the
/// tracker translation): its posterior σ is ~0.1 m against a 0.05 mm noise. Measured on the CTU
/// data (not reproducible here without it): the capped fit's last steps move exactly such a
/// pair, robot 2's reflector offset and its tracker's translation.
#[test]
fn compliance_fit_with_a_free_reflector_offset_converges() {
    let tol = Tolerance {
        compliance_rad_per_nm: Some(1e-6),
        origin_xyz_m: 0.0,
        origin_rpy_rad: 0.0,
        tip_m: 0.0,
        ..Tolerance::default()
    };
    let sc = sim_cell(Cell::Floor, tol, true, 61);
    let mut base = sc.problem();
    base.observations = sc.coincident(20, 5e-5, 0.7, 62);
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, -0.2, 2.5));
    let mut rng = ChaCha8Rng::seed_from_u64(63);
    for (i, j, k) in (0..4).flat_map(|i| (0..4).flat_map(move |j| (0..3).map(move |k| (i, j, k)))) {
        let target =
            sc.centre_b1 + Vector3::new(i as f64 - 1.5, j as f64 - 1.5, k as f64 - 1.0) * 0.12;
        if let Some(q) = sc.solve_true(Robot::One, 1, &target, -Vector3::z_axis()) {
            let g = sc.true_tip(Robot::One, 1, &q);
            let noise = Vector3::from_fn(|_, _| {
                let z: f64 =
                    rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng);
                z * 5e-5
            });
            base.observations.push(Observation {
                row: base.observations.len() + 1,
                kind: ObservationKind::Tracker {
                    robot: Robot::One,
                    q,
                    tool: 1,
                    group: 0,
                    p_tracker: tracker_from_b1 * Point3::from(g) + noise,
                    noise: Noise3::Isotropic { sigma_m: 5e-5 },
                },
            });
        }
    }
    base.trackers = vec![TrackerGroup {
        name: "leica".into(),
        anchor: Robot::One,
        initial_tracker_from_anchor: None,
        fit_scale: false,
        fit_drift: false,
    }];
    let active: Vec<usize> = (0..base.observations.len()).collect();
    for tip_tol in [10.0, 0.2] {
        let mut p = base.clone();
        p.robot1.tolerance.tip_m = tip_tol;
        p.robot2.tolerance.tip_m = 0.0;
        let fixed: Vec<CellParam> = kinematics::Axis::ALL
            .iter()
            .map(|&axis| CellParam::ToolTip {
                robot: Robot::One,
                tool: 0,
                axis,
            })
            .collect();
        let layout = ParamLayout::new(&p, &fixed);
        let fit = fit_cell_with(&p, layout, &active, None, None, &SolveOptions::default()).unwrap();
        let z_col = fit
            .layout
            .column(&CellParam::ToolTip {
                robot: Robot::One,
                tool: 1,
                axis: kinematics::Axis::Z,
            })
            .unwrap();
        eprintln!(
            "tip tolerance {tip_tol} m: {:?} after {} iterations, data χ² {:.1} ({} rows), \
             reflector {:?} mm, σ_z {:.1} mm",
            fit.stopped,
            fit.iterations,
            fit.data_chi2,
            fit.residual_rows,
            (fit.estimate.robot1.tool_tip_m[1] * 1e3).as_slice(),
            fit.std_error(z_col) * 1e3
        );
        assert_eq!(fit.stopped, StopReason::Converged);
        assert!(fit.iterations <= 15, "{} iterations", fit.iterations);
        assert!(fit.data_chi2 < 1.5 * fit.residual_rows as f64);
        // The flat direction: the offset along the held axis is barely determined (σ_z of
        // ~0.1 m against a noise σ of 0.05 mm).
        assert!(fit.std_error(z_col) > 0.02, "σ_z {}", fit.std_error(z_col));
    }
}

/// One simulated face contact: the pair of reported joints and both faces' outward normals in
/// their tip frames.
struct FaceRow {
    pair: ConfigPair,
    n1_tip: Unit<Vector3<f64>>,
    n2_tip: Unit<Vector3<f64>>,
}

impl FaceRow {
    /// The flush face contact of `pair` (tool 0 of each robot) whose robot-1 outward normal is
    /// `n1_b1` (b1 axes): both normals in their tip frames from the TRUE flange rotations,
    /// `n1_tip = R1ᵀ·n1`, `n2_tip = R2ᵀ·R_Xᵀ·(−n1)` (exactly antiparallel at the truth).
    fn flush(sc: &SimCell, pair: ConfigPair, n1_b1: Vector3<f64>) -> FaceRow {
        let r1 = sc.true_pose(Robot::One, 0, &pair.q1).rotation;
        let r2 = sc.true_pose(Robot::Two, 0, &pair.q2).rotation;
        let x = sc.truth.b1_from_b2.rotation;
        FaceRow {
            n1_tip: Unit::new_normalize(r1.inverse() * n1_b1),
            n2_tip: Unit::new_normalize(r2.inverse() * (x.inverse() * -n1_b1)),
            pair,
        }
    }

    /// The row as a face contact of group 0 with σ [`FACE_SIGMA_M`] (tool 0 of each robot).
    fn observation(self) -> ObservationKind {
        ObservationKind::FaceContact {
            q1: self.pair.q1,
            q2: self.pair.q2,
            tool1: 0,
            tool2: 0,
            n1_tip: self.n1_tip,
            n2_tip: self.n2_tip,
            group: 0,
            sigma_m: FACE_SIGMA_M,
        }
    }
}

/// `n` flush face contacts on `sc` (robot 1's tip, robot 2's tip), seeded: robot 1's outward
/// face normal `n1` is drawn uniformly on the sphere (b1), robot 2's TRUE tip sits at
/// `(d + σ·ν)·n1 + s` from robot 1's, `s ⟂ n1` a slide of the faces drawn uniformly in
/// `±max_slide_m` per axis and projected (0: the tips on the normal line), and the normals in
/// the tip frames come from the true flange rotations: `n1_tip = R1ᵀ·n1`,
/// `n2_tip = R2ᵀ·R_Xᵀ·(−n1)` (flush: exactly antiparallel at the truth).
fn face_rows(
    sc: &SimCell,
    n: usize,
    d: f64,
    sigma: f64,
    max_slide_m: f64,
    seed: u64,
) -> Vec<FaceRow> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let g = |rng: &mut ChaCha8Rng| -> f64 {
            rand_distr::Distribution::sample(&rand_distr::StandardNormal, rng)
        };
        let n1 = Vector3::new(g(&mut rng), g(&mut rng), g(&mut rng)).normalize();
        let raw = Vector3::from_fn(|_, _| rng.random_range(-1.0..=1.0)) * max_slide_m;
        let slide = raw - n1 * n1.dot(&raw);
        let along = d + sigma * g(&mut rng);
        if let Some(pair) = sc.draw_pair(&mut rng, 0.6, 0, n1 * along + slide) {
            out.push(FaceRow::flush(sc, pair, n1));
        }
    }
    out
}

/// A problem on `sc` with hidden joint offsets only fitted, one contact group (fitted, starting
/// `d_start`) and the given rows.
fn contact_problem(sc: &SimCell, d_start: f64, kinds: Vec<ObservationKind>) -> CellProblem {
    let mut p = sc.problem();
    p.contacts = vec![ContactGroup {
        name: "faces".into(),
        distance_m: d_start,
        fit_distance: true,
    }];
    p.observations = kinds
        .into_iter()
        .enumerate()
        .map(|(i, kind)| Observation { row: i + 1, kind })
        .collect();
    p
}

/// Joint offsets only (±0.05°), the hidden truth of the face-contact tests.
fn offsets_only() -> Tolerance {
    Tolerance {
        origin_xyz_m: 0.0,
        origin_rpy_rad: 0.0,
        tip_m: 0.0,
        ..Tolerance::default()
    }
}

/// Face-contact truth of the tests: distance 116 mm (two 58 mm marker polyhedra, as CTU's),
/// σ 0.05 mm along the normal.
const FACE_D_M: f64 = 0.116;
const FACE_SIGMA_M: f64 = 5e-5;

/// The starting placement of the face-contact fits: the truth moved by 2 mm and 2 mrad (a
/// face-contact session has no coincident row to start from).
fn perturbed_start(sc: &SimCell) -> Isometry3<f64> {
    Isometry3::new(
        Vector3::new(2e-3, -2e-3, 1e-3),
        Vector3::new(-1e-3, 2e-3, 1e-3),
    ) * sc.truth.b1_from_b2
}

/// Face contacts only (60 per session, faces sliding up to ±15 mm, σ 0.05 mm) on three wall
/// cells with hidden joint offsets (U(±0.05°), the prior's tolerance) and the contact distance
/// fitted from 3 mm off, started 2 mm / 2 mrad off the true placement (no placement prior: the
/// rotating face normals pin it): the fit converges with the data χ² of the noise, and every
/// joint offset, the contact distance and the six placement components lie within
/// [`RECOVERY_SIGMAS`] posterior σ of the truth, with an rms standardised error in
/// [`Z_RMS_BAND`] over the three sessions. Some offsets are determined by the data (posterior σ
/// below half the prior's), so the check is not the prior's.
#[test]
fn face_contacts_recover_joint_offsets_and_distance_within_their_intervals() {
    let mut zs = Vec::new();
    for seed in [91u64, 92, 93] {
        let sc = sim_cell(Cell::Wall, offsets_only(), false, seed);
        let rows = face_rows(&sc, 60, FACE_D_M, FACE_SIGMA_M, 0.015, seed + 10);
        let kinds = rows.into_iter().map(FaceRow::observation).collect();
        let p = contact_problem(&sc, FACE_D_M + 3e-3, kinds);
        let options = SolveOptions {
            initial_b1_from_b2: Some(perturbed_start(&sc)),
            ..SolveOptions::default()
        };
        let fit = fit_cell(&p, &options).unwrap();
        assert_eq!(fit.stopped, StopReason::Converged, "seed {seed}");
        let chi2_per_row = fit.data_chi2 / fit.residual_rows as f64;
        assert!(
            (0.5..1.5).contains(&chi2_per_row),
            "seed {seed}: χ²/row {chi2_per_row}"
        );
        let values = fit.layout.values(&fit.estimate);
        let kin: Vec<usize> = (0..fit.layout.len())
            .filter(|&c| matches!(fit.layout.params[c], CellParam::Kinematic { .. }))
            .collect();
        assert_eq!(kin.len(), p.robot1.model.dof() + p.robot2.model.dof());
        let col_d = fit
            .layout
            .column(&CellParam::ContactDistance { group: 0 })
            .unwrap();
        let truth_of = |c: usize| match &fit.layout.params[c] {
            CellParam::Kinematic { robot, param } => sc.truth.robot(*robot).errors.get(*param),
            CellParam::ContactDistance { .. } => FACE_D_M,
            _ => unreachable!("kinematic and contact columns only"),
        };
        let mut cols = kin.clone();
        cols.push(col_d);
        assert_within_interval(&fit, &p, &cols, truth_of, "face contact", &mut zs);
        // The placement: its error δ = X_fit·X_true⁻¹ (left perturbation) per component.
        let delta = fit.estimate.b1_from_b2 * sc.truth.b1_from_b2.inverse();
        let xi = [delta.translation.vector, delta.rotation.scaled_axis()];
        for j in 0..6 {
            let z = xi[j / 3][j % 3] / fit.std_error(j);
            assert!(
                z.abs() <= RECOVERY_SIGMAS,
                "seed {seed}: placement component {j} off by {:e} (z = {z:.2})",
                xi[j / 3][j % 3]
            );
            zs.push(z);
        }
        let determined = kin
            .iter()
            .filter(|&&c| fit.std_error(c) < 0.5 * fit.layout.prior_sigma(c))
            .count();
        assert!(
            determined >= 4,
            "seed {seed}: only {determined} offsets determined"
        );
        eprintln!(
            "face contact (seed {seed}): {} iterations, χ²/row {chi2_per_row:.2}, d {:.4} mm \
             (σ {:.4}), {determined}/{} offsets determined, placement σ {:.3} mm {:.3} mrad",
            fit.iterations,
            values[col_d] * 1e3,
            fit.std_error(col_d) * 1e3,
            kin.len(),
            fit.std_error(0) * 1e3,
            fit.std_error(3) * 1e3,
        );
    }
    let (rms, worst) = assert_calibrated(&zs, "face contact");
    eprintln!(
        "face contact: rms z {rms:.2}, worst |z| {worst:.2} over {} values",
        zs.len()
    );
}

/// Agreement of the face-contact and sphere-contact fits of the same flush, non-sliding rows,
/// in posterior σ of the sphere fit (values) and relative (σ): the two residuals and Jacobians
/// coincide at the truth and differ only at second order in the fitted error (the tangential
/// part a wrong estimate opens, ~(1e-4 m)²/0.1 m ≈ 1e-7 m ≪ σ = 5e-5 m).
const SAME_FIT_SIGMAS: f64 = 0.01;
const SAME_SIGMA_REL: f64 = 0.01;

/// Face contacts with exactly antiparallel faces and zero slide are sphere contacts: on the
/// same 60 rows (hidden joint offsets, fitted distance, started off the truth) the
/// `FaceContact` and `Contact` fits converge to the same estimate within [`SAME_FIT_SIGMAS`]
/// posterior σ per column, with the same σ within [`SAME_SIGMA_REL`] and the same χ². With a
/// face normal off by 5° the fits part (a check that the comparison can fail).
#[test]
fn flush_face_contacts_without_slide_fit_like_sphere_contacts() {
    let sc = sim_cell(Cell::Wall, offsets_only(), false, 95);
    let rows = face_rows(&sc, 60, FACE_D_M, FACE_SIGMA_M, 0.0, 96);
    let options = SolveOptions {
        initial_b1_from_b2: Some(perturbed_start(&sc)),
        ..SolveOptions::default()
    };
    let tilt = UnitQuaternion::from_scaled_axis(Vector3::new(5f64.to_radians(), 0.0, 0.0));
    let fit_of = |face: bool, tilt_n1: bool| {
        let kinds = rows
            .iter()
            .map(|r| {
                let (q1, q2) = (r.pair.q1.clone(), r.pair.q2.clone());
                if face {
                    let n1_tip = if tilt_n1 { tilt * r.n1_tip } else { r.n1_tip };
                    ObservationKind::FaceContact {
                        q1,
                        q2,
                        tool1: 0,
                        tool2: 0,
                        n1_tip,
                        n2_tip: r.n2_tip,
                        group: 0,
                        sigma_m: FACE_SIGMA_M,
                    }
                } else {
                    ObservationKind::Contact {
                        q1,
                        q2,
                        tool1: 0,
                        tool2: 0,
                        group: 0,
                        sigma_m: FACE_SIGMA_M,
                    }
                }
            })
            .collect();
        let p = contact_problem(&sc, FACE_D_M + 3e-3, kinds);
        let fit = fit_cell(&p, &options).unwrap();
        assert_eq!(fit.stopped, StopReason::Converged);
        fit
    };
    let sphere = fit_of(false, false);
    let face = fit_of(true, false);
    // Values and the placement (as the left perturbation between the two fits).
    let gap = |a: &CellFit, b: &CellFit| {
        let (va, vb) = (a.layout.values(&a.estimate), b.layout.values(&b.estimate));
        let delta = a.estimate.b1_from_b2 * b.estimate.b1_from_b2.inverse();
        let xi = [delta.translation.vector, delta.rotation.scaled_axis()];
        (0..a.layout.len())
            .map(|c| {
                let d = if c < 6 {
                    xi[c / 3][c % 3]
                } else {
                    va[c] - vb[c]
                };
                (d / b.std_error(c)).abs()
            })
            .fold(0.0f64, f64::max)
    };
    let worst = gap(&face, &sphere);
    let worst_sigma = (0..face.layout.len())
        .map(|c| (face.std_error(c) / sphere.std_error(c) - 1.0).abs())
        .fold(0.0f64, f64::max);
    eprintln!(
        "flush faces vs spheres: largest gap {worst:.2e} σ, largest σ ratio − 1 {worst_sigma:.2e}, \
         χ² {:.4} vs {:.4}",
        face.data_chi2, sphere.data_chi2
    );
    assert_eq!(face.layout.params, sphere.layout.params);
    assert!(worst <= SAME_FIT_SIGMAS, "fits differ by {worst} σ");
    assert!(worst_sigma <= SAME_SIGMA_REL, "σ differ by {worst_sigma}");
    assert!((face.data_chi2 - sphere.data_chi2).abs() <= SAME_SIGMA_REL * sphere.data_chi2);
    let tilted = fit_of(true, true);
    let worst_tilted = gap(&tilted, &sphere);
    eprintln!("a 5° tilted face normal: largest gap {worst_tilted:.2} σ");
    assert!(worst_tilted > 100.0 * SAME_FIT_SIGMAS);
}

/// As [`face_rows`], but every face normal lies along robot 1's approach (its flange z), the
/// rows of `sim-cell session --kind face_contact --face-tilt-deg 0`: robot 1 reaches a point
/// near the centre (±spread/2 per axis) with its flange z along `a1`, robot 2's TRUE tip sits
/// at `(d + σ·ν)·a1 + s` from robot 1's (`s ⟂ a1`, up to `±max_slide_m` per axis, projected),
/// meeting it head-on; the normals in the tip frames come from the true flange rotations.
fn axial_face_rows(
    sc: &SimCell,
    n: usize,
    d: f64,
    sigma: f64,
    max_slide_m: f64,
    seed: u64,
) -> Vec<FaceRow> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let x = sc.truth.b1_from_b2;
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p = sc.centre_b1 + Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5)) * 0.6;
        let toward2 = (x.translation.vector - p.coords).normalize();
        let tilt = Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5));
        let a1 = Unit::new_normalize(toward2 + tilt);
        let raw = Vector3::from_fn(|_, _| rng.random_range(-1.0..=1.0)) * max_slide_m;
        let slide = raw - a1.into_inner() * a1.dot(&raw);
        let along = d + sigma
            * rand_distr::Distribution::<f64>::sample(&rand_distr::StandardNormal, &mut rng);
        let Some(q1) = sc.solve_true(Robot::One, 0, &p, a1) else {
            continue;
        };
        let t1 = sc.true_tip(Robot::One, 0, &q1);
        let target2 = x.inverse() * Point3::from(t1 + a1.into_inner() * along + slide);
        let a2 = Unit::new_normalize(x.rotation.inverse() * (-a1.into_inner()));
        let Some(q2) = sc.solve_true(Robot::Two, 0, &target2, a2) else {
            continue;
        };
        let pair = ConfigPair {
            q1,
            q2,
            tool1: 0,
            tool2: 0,
        };
        out.push(FaceRow::flush(sc, pair, a1.into_inner()));
    }
    out
}

/// Largest merge coefficient (prior-σ units) a sane reduction of the axial face contacts
/// produces: measured ≤ 29 on the CTU cell's reproducer draws (below); the near-null pivots
/// of the old reduction gave 3e7 … 3e9.
const SANE_MERGE_COEFF: f64 = 1e3;

/// Largest correction of a fitted length (m) in the axial face-contact fit: the truth is within
/// the 0.5 mm tolerance, so 10 mm is already far off; the old reduction moved a tip by metres.
const SANE_LENGTH_M: f64 = 0.01;

/// Regression (found building the face-contact kind, reproduced with `sim-cell session --kind
/// face_contact --face-tilt-deg 0 --cell cells/ctu-motoman.toml` and `handclasp calibrate
/// --model kinematic`, where one draw stopped at the iteration cap with a tip x at 5.9 m): with
/// every face normal along robot 1's flange z nothing sees the tools' sideways offsets, whose
/// columns then carry ~1e-15 of their prior information. The relative rank test alone kept them
/// as pivots and merged other columns onto them with coefficients ~1e8. Now they are held as
/// [`ReductionReason::PriorDecided`], every merge coefficient is below [`SANE_MERGE_COEFF`], the
/// fit (every kinematic parameter free, distance fitted from 3 mm off) converges, and no length
/// moves by more than [`SANE_LENGTH_M`].
#[test]
fn axial_face_contacts_hold_the_unseen_sideways_offsets() {
    // The prior of every parameter as the tolerance, the truth nominal (as the CTU cell's, which
    // carries no kinematic error): the flanges then point exactly along the face normals.
    let mut sc = sim_cell(Cell::Wall, Tolerance::default(), false, 141);
    sc.truth = CellEstimate::nominal(&sc.problem(), sc.truth.b1_from_b2);
    let rows = axial_face_rows(&sc, 40, FACE_D_M, FACE_SIGMA_M, 5e-3, 142);
    let kinds = rows.into_iter().map(FaceRow::observation).collect();
    let p = contact_problem(&sc, FACE_D_M + 3e-3, kinds);
    let options = SolveOptions {
        // From the cell's placement, as `handclasp calibrate --cell` starts.
        initial_b1_from_b2: Some(sc.truth.b1_from_b2),
        ..SolveOptions::default()
    };
    let cal = calibrate_cell(&p, &options, &ScreenOptions::default()).unwrap();
    let red = &cal.reduction;
    let worst_coeff = red
        .dropped
        .iter()
        .filter_map(|d| match &d.reason {
            ReductionReason::MergedInto { into } => {
                Some(into.iter().map(|(_, c)| c.abs()).fold(0.0, f64::max))
            }
            _ => None,
        })
        .fold(0.0, f64::max);
    let values = cal.fit.layout.values(&cal.fit.estimate);
    let worst_length = (0..cal.fit.layout.len())
        .filter(|&c| match &cal.fit.layout.params[c] {
            CellParam::Kinematic { param, .. } => matches!(param, ErrorParam::OriginXyz { .. }),
            CellParam::ToolTip { .. } => true,
            _ => false,
        })
        .map(|c| values[c].abs())
        .fold(0.0, f64::max);
    eprintln!(
        "axial faces: {:?} after {} iterations, largest merge coefficient {worst_coeff:.3e}, \
         largest length {:.3} mm, {} held as prior-decided",
        cal.fit.stopped,
        cal.fit.iterations,
        worst_length * 1e3,
        red.dropped
            .iter()
            .filter(|d| d.reason == ReductionReason::PriorDecided)
            .count()
    );
    for d in &red.dropped {
        if d.reason == ReductionReason::PriorDecided {
            eprintln!("{}", d.message);
        }
    }
    assert!(
        worst_coeff <= SANE_MERGE_COEFF,
        "merge coefficient {worst_coeff:e}"
    );
    assert_eq!(cal.fit.stopped, StopReason::Converged);
    assert!(
        worst_length <= SANE_LENGTH_M,
        "a length moved {worst_length} m"
    );
    for r in [Robot::One, Robot::Two] {
        for axis in [kinematics::Axis::X, kinematics::Axis::Y] {
            let d = red
                .dropped
                .iter()
                .find(|d| matches!(&d.param, CellParam::ToolTip { robot, axis: a, .. } if *robot == r && *a == axis))
                .unwrap_or_else(|| panic!("{r} tip {axis} kept"));
            assert_eq!(d.reason, ReductionReason::PriorDecided, "{}", d.message);
            assert!(
                d.message.contains("barely seen by the data"),
                "{}",
                d.message
            );
        }
    }
}
