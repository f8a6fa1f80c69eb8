//! Tests of the whole-cell calibration on the shipped robots, one file per part:
//! `jacobians` (every analytic Jacobian against central differences), `checks` (bad input),
//! `solve` (the MAP fit and its stop reasons), `reduce`, `blunders`, `design`, `calibrate` (the
//! one call and the prior scale), `terms` (nuisance groups and optional model terms) and
//! `face_contact`. The fixtures, trial helpers and recovery tolerances they share are here.

use crate::{LmOptions, Robot, StopReason};
use std::time::Instant;

use kinematics::ErrorParam;
use nalgebra::{DVector, Isometry3, Matrix3, Point3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::fixtures::{sim_cell, Cell, SimCell};
use super::*;

mod blunders;
mod calibrate;
mod checks;
mod design;
mod face_contact;
mod jacobians;
mod lumped;
mod reduce;
mod result_check;
mod solve;
mod terms;
mod trunk;

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

/// A cell whose observations are simulated with truth `sc.truth`.
fn coincident_problem(sc: &SimCell, n: usize, sigma: f64, seed: u64) -> CellProblem {
    let mut p = sc.problem();
    p.observations = sc.coincident(n, sigma, 0.7, seed);
    p
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
