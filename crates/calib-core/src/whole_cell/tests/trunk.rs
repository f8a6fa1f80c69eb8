//! Gravity compliance on a shared trunk ([`kinematics::trunk`]) in the whole-cell fit: the
//! simulated humanoid (`robots/humanoid.urdf`: a 3-joint torso, a fourth torso joint
//! `q4 = −(q1 + q2)`, two 7-joint arms), one tracker marker per hand in one camera frame, the
//! truth's compliance computed from the URDF masses with both arms loading the torso, the fit
//! given URDFs without any inertial (issue 22, items 1 and 7, and its humanoid target).

use super::*;

/// The humanoid URDF (with masses: the simulator's).
const HUMANOID: &str = include_str!("../../../../../robots/humanoid.urdf");

/// The torso's chain joints (torso_1 … torso_4) and its independent ones (torso_4 is coupled).
const TRUNK: usize = 4;
const TRUNK_INDEPENDENT: usize = 3;

/// The URDF without its `<inertial>` elements: the fit's, which knows no mass.
fn without_inertials(xml: &str) -> String {
    let mut out = String::with_capacity(xml.len());
    let mut rest = xml;
    while let Some(a) = rest.find("<inertial>") {
        out.push_str(&rest[..a]);
        let b = rest[a..].find("</inertial>").expect("closed") + a + "</inertial>".len();
        rest = &rest[b..];
    }
    out.push_str(rest);
    out
}

/// One arm of the humanoid from `xml`, with the torso coupling.
fn arm(xml: &str, tool: &str) -> kinematics::RobotModel {
    let coupling = kinematics::JointCoupling {
        joint: "torso_4".into(),
        terms: vec![("torso_1".into(), -1.0), ("torso_2".into(), -1.0)],
        offset: 0.0,
    };
    kinematics::RobotModel::from_urdf_str(xml, tool)
        .and_then(|m| m.with_couplings(std::slice::from_ref(&coupling)))
        .expect("humanoid")
}

/// The benchmark's settings.
#[derive(Debug, Clone, Copy)]
struct Humanoid {
    /// Training poses (two tracker rows each: both hands).
    train: usize,
    /// Held-out poses.
    held_out: usize,
    /// Tracker noise σ per axis, m (the rows state it: the honest σ).
    sigma_m: f64,
    /// Joint compliance of every joint, rad/(N·m).
    compliance: f64,
    /// The truth's kinematic errors as a multiple of the default tolerances (uniform draws).
    truth_factor: f64,
    /// Seed of the truth and the poses.
    seed: u64,
}

/// The problem on `poses` (each `(q_right, q_left)`, agreeing on the torso) with tracker
/// measurements of `truth` (from the mass model `truth_problem`) plus noise of `noise_m`
/// per axis (0: noise-free), rows stating σ `sigma_m`, on the models of `problem`.
fn tracker_rows(
    problem: &mut CellProblem,
    truth_problem: &CellProblem,
    truth: &CellEstimate,
    poses: &[(Vec<f64>, Vec<f64>)],
    sigma_m: f64,
    noise_m: f64,
    rng: &mut ChaCha8Rng,
) {
    let layout = ParamLayout::new(truth_problem, &[]);
    let ev = Evaluator::new(truth_problem, &layout);
    let normal = rand_distr::Normal::new(0.0, 1.0).expect("unit normal");
    problem.observations.clear();
    problem.other_arm_q.clear();
    for (q1, q2) in poses {
        for (robot, q, q_other) in [(Robot::One, q1, q2), (Robot::Two, q2, q1)] {
            let row = problem.observations.len() + 1;
            let (g, _) = ev
                .tip_in_anchor(truth, robot, 0, q, Some(q_other), Robot::One, false, row)
                .expect("truth tip");
            let m = truth.tracker_from_anchor[0] * Point3::from(g);
            let noise = Vector3::from_fn(|_, _| noise_m * rng.sample(normal));
            problem.observations.push(Observation {
                row,
                kind: ObservationKind::Tracker {
                    robot,
                    q: q.clone(),
                    tool: 0,
                    group: 0,
                    p_tracker: m + noise,
                    noise: Noise3::Isotropic { sigma_m },
                },
            });
            problem.other_arm_q.insert(row, q_other.clone());
        }
    }
}

/// The shared-trunk humanoid problem on models `xml` (no rows yet).
fn humanoid_problem(xml: &str, tolerance: Tolerance) -> CellProblem {
    let robot = |tool: &str, shared_joints| CellRobot {
        model: arm(xml, tool),
        tools: vec![Tool {
            name: "tip".into(),
            flange_from_tip: Vector3::new(0.0, 0.0, 0.05),
        }],
        g_base: Vector3::new(0.0, 0.0, -9.81),
        tolerance,
        shared_joints,
    };
    CellProblem {
        robot1: robot("right_tool0", 0),
        robot2: robot("left_tool0", TRUNK),
        observations: Vec::new(),
        trackers: vec![TrackerGroup {
            name: "camera".into(),
            anchor: Robot::One,
            initial_tracker_from_anchor: None,
            fit_scale: false,
            fit_drift: false,
        }],
        planes: Vec::new(),
        contacts: Vec::new(),
        placement_prior: Some(PlacementPrior {
            nominal_b1_from_b2: Isometry3::identity(),
            sigma_m: 1e-6,
            sigma_rad: 1e-6,
        }),
        other_arm_q: Default::default(),
    }
}

/// The truth of `b`: kinematic errors drawn uniform in ±`truth_factor` × the default
/// tolerances on every default family (the torso's once, both arms' copies equal), compliance
/// `b.compliance` on every joint (the deflection from the URDF masses, both arms on the
/// torso), a camera 2.5 m in front of the pelvis looking back at it; and the generator that
/// then draws the poses.
fn humanoid_truth(b: &Humanoid, truth_problem: &CellProblem) -> (CellEstimate, ChaCha8Rng) {
    let mut rng = ChaCha8Rng::seed_from_u64(b.seed);
    let mut truth = CellEstimate::nominal(truth_problem, Isometry3::identity());
    let tol = Tolerance::default();
    for param in truth_problem.robot1.fitted_params() {
        let t = tol.prior_sigma(param) * 3f64.sqrt() * b.truth_factor;
        truth.robot1.errors.set(param, rng.random_range(-t..=t));
    }
    for param in truth_problem.robot2.fitted_params() {
        let v = if param.joint().is_some_and(|j| j < TRUNK) {
            truth.robot1.errors.get(param)
        } else {
            let t = tol.prior_sigma(param) * 3f64.sqrt() * b.truth_factor;
            rng.random_range(-t..=t)
        };
        truth.robot2.errors.set(param, v);
    }
    for r in [&mut truth.robot1, &mut truth.robot2] {
        r.errors.compliance = vec![b.compliance; r.errors.dof()];
        let t_tip = tol.tip_m * b.truth_factor;
        r.tool_tip_m = vec![Vector3::from_fn(|_, _| rng.random_range(-t_tip..=t_tip))];
    }
    truth.tracker_from_anchor = vec![Isometry3::new(
        Vector3::new(-2.5, 0.1, 1.2),
        Vector3::new(0.0, 0.0, std::f64::consts::PI),
    )
    .inverse()];
    (truth, rng)
}

/// `n` pose pairs of the humanoid (the arms' joints in their middle 80 %, the torso shared).
fn pose_pairs(p: &CellProblem, n: usize, rng: &mut ChaCha8Rng) -> Vec<(Vec<f64>, Vec<f64>)> {
    (0..n)
        .map(|_| {
            let q1 = random_q(&p.robot1.model, rng);
            let mut q2 = random_q(&p.robot2.model, rng);
            q2[..TRUNK_INDEPENDENT].copy_from_slice(&q1[..TRUNK_INDEPENDENT]);
            (q1, q2)
        })
        .collect()
}

/// Mean and rms 3-D error (m) on the held-out rows of `held` (noise-free measurements of the
/// truth): each row's predicted measurement at `est` on `problem`'s models against it.
fn held_out_error(problem: &CellProblem, est: &CellEstimate, held: &CellProblem) -> (f64, f64) {
    let layout = ParamLayout::new(problem, &[]);
    let mut eval = held.clone();
    eval.robot1 = problem.robot1.clone();
    eval.robot2 = problem.robot2.clone();
    let ev = Evaluator::new(&eval, &layout);
    let errs: Vec<f64> = held
        .observations
        .iter()
        .map(|o| ev.linearise(o, est, false).unwrap().residual.norm())
        .collect();
    let n = errs.len() as f64;
    (
        errs.iter().sum::<f64>() / n,
        (errs.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
    )
}

/// The benchmark's figures, m: (mean, rms) held-out 3-D error per model.
struct Figures {
    nominal: (f64, f64),
    kinematic: (f64, f64),
    oracle_kinematic: (f64, f64),
    geometry_known: (f64, f64),
    compliance: (f64, f64),
    truth_noise_scale: [f64; 2],
}

/// Runs the humanoid benchmark `b` (module docs): nominal (placement-only fit: the camera frame
/// registered), the whole-cell kinematic fit, the kinematic-only oracle (the same fit on
/// noise-free training rows), the truth's geometry with its compliance left out (what the
/// compliance alone moves the hands), and `kinematic+compliance` (lumped, no masses), all by
/// [`calibrate_cell`] with the default options and tolerances, every row kept.
fn run_humanoid(b: &Humanoid) -> Figures {
    let truth_problem = humanoid_problem(HUMANOID, Tolerance::default());
    let (truth, mut rng) = humanoid_truth(b, &truth_problem);
    let massless = without_inertials(HUMANOID);
    let train_poses = pose_pairs(&truth_problem, b.train, &mut rng);
    let held_poses = pose_pairs(&truth_problem, b.held_out, &mut rng);
    let mut held = humanoid_problem(&massless, Tolerance::default());
    tracker_rows(
        &mut held,
        &truth_problem,
        &truth,
        &held_poses,
        b.sigma_m,
        0.0,
        &mut rng,
    );
    let solve = SolveOptions {
        initial_b1_from_b2: Some(Isometry3::identity()),
        ..SolveOptions::default()
    };
    // Every row kept: a model that leaves the compliance out misfits every row alike, and the
    // CLI's `--screen auto` keeps the rows when the rejections are a model misfit (a blunder
    // screen would reject most rows of the kinematic-only fit instead).
    let screen = ScreenOptions {
        reject: false,
        ..ScreenOptions::default()
    };
    let fit = |tolerance: Tolerance, noise_m: f64, rng: &mut ChaCha8Rng| {
        let mut p = humanoid_problem(&massless, tolerance);
        tracker_rows(
            &mut p,
            &truth_problem,
            &truth,
            &train_poses,
            b.sigma_m,
            noise_m,
            rng,
        );
        let started = Instant::now();
        let cal = calibrate_cell(&p, &solve, &screen).expect("fit");
        eprintln!(
            "  fit: {:.1} s, {} columns, noise scale {:.3}, {} rejected, prior {}",
            started.elapsed().as_secs_f64(),
            cal.fit.layout.len(),
            cal.noise_scale,
            cal.rejected.len(),
            cal.prior_scale.why
        );
        let e = held_out_error(&p, &cal.fit.estimate, &held);
        (e, cal.noise_scale)
    };
    let mut rng_noise = ChaCha8Rng::seed_from_u64(b.seed + 1000);
    let (nominal, _) = fit(Tolerance::none(), b.sigma_m, &mut rng_noise.clone());
    let (kinematic, s_kin) = fit(Tolerance::default(), b.sigma_m, &mut rng_noise.clone());
    let (oracle_kinematic, _) = fit(Tolerance::default(), 0.0, &mut rng_noise.clone());
    let lumped = Tolerance {
        lumped_compliance_rad: Some(LUMPED_COMPLIANCE_TOLERANCE_RAD),
        ..Tolerance::default()
    };
    let (compliance, s_comp) = fit(lumped, b.sigma_m, &mut rng_noise);
    let mut geometry = truth.clone();
    for r in [&mut geometry.robot1, &mut geometry.robot2] {
        r.errors.compliance = vec![0.0; r.errors.dof()];
    }
    let geometry_known = held_out_error(&truth_problem, &geometry, &held);
    Figures {
        nominal,
        kinematic,
        oracle_kinematic,
        geometry_known,
        compliance,
        truth_noise_scale: [s_kin, s_comp],
    }
}

/// The issue-22 humanoid benchmark (ignored: a benchmark that prints BENCHMARKS.md's figures):
/// `cargo test -p calib-core --lib humanoid_benchmark -- --ignored --nocapture`.
/// 300 training and 200 held-out poses, σ 1 mm per axis, compliance 100 µrad/(N·m) on every
/// joint, kinematic errors up to 4× the default tolerances (±2 mm origins and tips, ±0.2°
/// offsets and origin angles), seed 22. Its targets: the kinematic fit within
/// [`GEOMETRIC_LIMIT_MARGIN`] of the kinematic-only oracle, and the lumped model at most half
/// the kinematic fit's error.
#[test]
#[ignore = "a benchmark: prints the humanoid figures of BENCHMARKS.md"]
fn humanoid_benchmark() {
    let b = Humanoid {
        train: 300,
        held_out: 200,
        sigma_m: 1e-3,
        compliance: 1e-4,
        truth_factor: 4.0,
        seed: 22,
    };
    let f = run_humanoid(&b);
    let mm =
        |(mean, rms): (f64, f64)| format!("mean {:.2} mm, rms {:.2} mm", mean * 1e3, rms * 1e3);
    eprintln!("humanoid benchmark {b:?}");
    eprintln!("  nominal (camera registered):       {}", mm(f.nominal));
    eprintln!("  whole-cell kinematic fit:          {}", mm(f.kinematic));
    eprintln!(
        "  kinematic-only oracle (no noise):  {}",
        mm(f.oracle_kinematic)
    );
    eprintln!(
        "  true geometry, compliance left out: {}",
        mm(f.geometry_known)
    );
    eprintln!("  kinematic+compliance (lumped):     {}", mm(f.compliance));
    eprintln!("  noise scales {:?}", f.truth_noise_scale);
    assert!(f.kinematic.0 <= GEOMETRIC_LIMIT_MARGIN * f.oracle_kinematic.0);
    assert!(f.compliance.0 <= 0.5 * f.kinematic.0);
}

/// How far above the kinematic-only oracle's mean error the kinematic fit may land and still
/// "reach the geometric limit": 10 %.
const GEOMETRIC_LIMIT_MARGIN: f64 = 1.1;

/// Recovery (issue 22 items 1 and 7): on a small humanoid session (80 training poses, σ 0.2 mm,
/// compliance 100 µrad/(N·m), kinematic errors at the default tolerances, seed 7), the lumped
/// fit without masses, with both arms loading the torso, beats the kinematic-only fit on 60
/// held-out poses by at least a factor 2 and lands within 3× the noise of the truth.
#[test]
fn shared_trunk_compliance_is_recovered_without_masses() {
    let b = Humanoid {
        train: 80,
        held_out: 60,
        sigma_m: 2e-4,
        compliance: 1e-4,
        truth_factor: 1.0,
        seed: 7,
    };
    let f = run_humanoid(&b);
    eprintln!(
        "shared-trunk recovery: kinematic rms {:.3} mm, kinematic+compliance rms {:.3} mm, \
         compliance alone {:.3} mm, σ {:.2} mm",
        f.kinematic.1 * 1e3,
        f.compliance.1 * 1e3,
        f.geometry_known.1 * 1e3,
        b.sigma_m * 1e3
    );
    assert!(f.compliance.1 < 0.5 * f.kinematic.1);
    assert!(f.compliance.1 < 3.0 * b.sigma_m * 3f64.sqrt());
}

/// The other arm's joints are refused by name on a cell without a shared trunk, with the wrong
/// length, with a trunk posture that differs from the row's, and at a row that is not a
/// one-robot row.
#[test]
fn other_arm_joints_are_checked() {
    let truth_problem = humanoid_problem(HUMANOID, Tolerance::default());
    let b = Humanoid {
        train: 3,
        held_out: 0,
        sigma_m: 1e-3,
        compliance: 1e-4,
        truth_factor: 1.0,
        seed: 3,
    };
    let (truth, mut rng) = humanoid_truth(&b, &truth_problem);
    let poses = pose_pairs(&truth_problem, b.train, &mut rng);
    let mut p = truth_problem.clone();
    tracker_rows(
        &mut p,
        &truth_problem,
        &truth,
        &poses,
        b.sigma_m,
        0.0,
        &mut rng,
    );
    p.check().expect("valid");
    let refused = |change: &dyn Fn(&mut CellProblem), needle: &str| {
        let mut q = p.clone();
        change(&mut q);
        let err = q.check().unwrap_err().to_string();
        assert!(err.contains(needle), "{needle}: {err}");
    };
    refused(&|q| q.robot2.shared_joints = 0, "no shared trunk");
    refused(
        &|q| {
            q.other_arm_q.get_mut(&1).expect("row 1").pop();
        },
        "observation row 1: the other arm (robot 2) has 10 joints",
    );
    refused(
        &|q| q.other_arm_q.get_mut(&2).expect("row 2")[1] += 0.01,
        "observation row 2: trunk joint 2",
    );
    refused(
        &|q| {
            let v = q.other_arm_q[&1].clone();
            q.other_arm_q.insert(99, v);
        },
        "observation row 99",
    );
}
