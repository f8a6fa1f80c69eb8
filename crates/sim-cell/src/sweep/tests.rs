//! Unit tests of the sweep: calib-core's fast kernels on drawn trials against its slow paths,
//! determinism whatever the thread count, replay of one trial, expected trends and the outputs.

use super::geometry::*;
use super::robot::{draw_kinematic_errors, most_spread_four, SPREAD4_EXHAUSTIVE};
use super::*;
use crate::layout::Layout;
use crate::placement::PAPER;
use crate::trial_rng;
use calib_core::{fit, PointPairs};
use calib_core::{project_rotation_family, zyz_from_rotation, Method, MountPair};
use nalgebra::Point3;
use rand::Rng;

/// Fast and slow paths compute the same maths: agreement to round-off (m, rad).
const SAME_MATHS_TOL: f64 = 1e-9;
/// Exact data: recovery to round-off (m, rad).
const EXACT_TOL: f64 = 1e-9;

fn small_config() -> SweepConfig {
    SweepConfig {
        mode: Mode::Geometry,
        mounts: PAPER.iter().map(|p| p.mounts).collect(),
        noise_mm: vec![0.5, 3.0],
        spread_m: vec![0.25, 1.5],
        n_points: vec![4, 12],
        methods: Method::ALL.map(SweepMethod::from).to_vec(),
        layout: Layout::Tetrahedron.into(),
        kinematic_errors: KinematicErrorDraw::None,
        trials: 30,
        seed: 7,
    }
}

#[test]
fn fit_fast_matches_calib_core_slow_paths() {
    for placement in PAPER {
        for n in [4, 7] {
            let spec =
                GeometrySpec::paper(&placement.mounts, Layout::Random, n, 1.0, 1e-3).unwrap();
            let mut p1 = vec![Point3::origin(); n];
            let mut p2 = vec![Point3::origin(); n];
            draw_geometry(&spec, &mut trial_rng(11, n as u64), &mut p1, &mut p2);
            let pairs = PointPairs::new(p1.clone(), p2.clone()).unwrap();
            for method in Method::ALL {
                let fast = fit_fast(method, &spec.mounts, &p1, &p2).unwrap();
                let slow = fit(&pairs, method, &spec.mounts).unwrap().b1_from_b2;
                assert!(
                    (fast.translation.vector - slow.translation.vector).amax() < SAME_MATHS_TOL
                        && fast.rotation.angle_to(&slow.rotation) < SAME_MATHS_TOL,
                    "{} n={n} {}",
                    placement.label(),
                    method.name()
                );
                let e = TrialErrors::between(&spec.b1_from_b2, &fast);
                let zyz = zyz_from_rotation(&spec.b1_from_b2.rotation.to_rotation_matrix());
                let f = TrialErrors::between_fast(&spec.b1_from_b2, &ErotTruth::new(zyz), &fast);
                assert!((e.e_tran - f.e_tran).abs() < SAME_MATHS_TOL);
                assert!((e.e_rot - f.e_rot).abs() < SAME_MATHS_TOL);
                assert!((e.geodesic - f.geodesic).abs() < SAME_MATHS_TOL);
            }
        }
    }
}

#[test]
fn zero_noise_recovers_the_truth_up_to_the_mount_family_deviation() {
    for placement in PAPER {
        // How far Table 1's true rotation is from the mounts' family (it is a measurement).
        let truth = placement.b1_from_b2();
        let projected = project_rotation_family(
            &truth.rotation.to_rotation_matrix().into_inner(),
            &placement.mounts,
        )
        .unwrap();
        let family_dev = truth.rotation.to_rotation_matrix().angle_to(&projected);
        for method in Method::ALL {
            for n in [4, 9] {
                let spec = GeometrySpec::paper(&placement.mounts, Layout::Tetrahedron, n, 1.0, 0.0)
                    .unwrap();
                let e = geometry_trial(&spec, method, &mut trial_rng(1, n as u64))
                    .unwrap()
                    .unwrap();
                let constrained = matches!(method, Method::Paper | Method::Constrained);
                // A constrained estimate lies in the family, so it is at least `family_dev` from the
                // truth; the least-squares member differs from the nearest one only to second
                // order, hence the 5 % margin.
                let allowed = if constrained {
                    1.05 * family_dev + EXACT_TOL
                } else {
                    EXACT_TOL
                };
                assert!(
                    e.geodesic <= allowed,
                    "{} {} n={n}: {e:?}",
                    placement.label(),
                    method.name()
                );
                if !constrained {
                    assert!(e.e_tran < EXACT_TOL);
                }
            }
        }
    }
}

#[test]
fn invalid_specs_are_errors_not_panics() {
    let mut spec =
        GeometrySpec::paper(&MountPair::floor_floor(), Layout::Random, 4, 1.0, 1e-3).unwrap();
    spec.n = MAX_GEOMETRY_POINTS + 1;
    assert!(geometry_trial(&spec, Method::Lsq, &mut trial_rng(1, 1)).is_err());
    spec.n = 4;
    spec.spread_m = f64::NAN;
    assert!(geometry_trial(&spec, Method::Lsq, &mut trial_rng(1, 1)).is_err());
    let mut c = small_config();
    c.noise_mm = vec![];
    assert!(c.validate().unwrap_err().to_string().contains("noise"));
    let mut c = small_config();
    c.mounts = vec![MountPair {
        robot1: calib_core::Mount::Floor,
        robot2: calib_core::Mount::Tilt { rx: 0.1, ry: 0.0 },
    }];
    assert!(c
        .validate()
        .unwrap_err()
        .to_string()
        .contains("paper's cells"));
    // Too few points for a method is a failed fit, not a panic.
    let spec3 =
        GeometrySpec::paper(&MountPair::floor_floor(), Layout::Random, 3, 1.0, 1e-3).unwrap();
    assert_eq!(
        geometry_trial(&spec3, Method::Generic, &mut trial_rng(1, 1)).unwrap(),
        None
    );
}

fn csv_with_threads(config: &SweepConfig, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let finished = std::sync::atomic::AtomicU64::new(0);
    let progress = |n: u64| {
        finished.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    };
    let result = pool.install(|| run_sweep(config, &[], &progress)).unwrap();
    // Every trial is counted once, even when a trial is split between two workers.
    assert_eq!(
        finished.load(std::sync::atomic::Ordering::Relaxed),
        config.total_trials() as u64
    );
    let mut out = Vec::new();
    write_trials_csv(&result, &mut out).unwrap();
    write_summary_csv(&summarize_cells(&result), &mut out).unwrap();
    out
}

#[test]
fn same_seed_gives_byte_identical_csv_with_one_and_two_threads() {
    let mut config = small_config();
    // More trials than one work chunk so that two threads really split the work.
    config.trials = 2 * CHUNK / config.grid().len() + 7;
    let a = csv_with_threads(&config, 1);
    let b = csv_with_threads(&config, 2);
    assert_eq!(a, b);
    config.seed = 8;
    assert_ne!(a, csv_with_threads(&config, 2));
}

#[test]
fn trial_rngs_equal_trial_rng() {
    for seed in [0, 1, 7, u64::MAX] {
        let rngs = TrialRngs::new(seed);
        for index in [0, 1, 2, 63, 64, 1 << 20, u64::MAX] {
            let (mut a, mut b) = (rngs.get(index), trial_rng(seed, index));
            for _ in 0..100 {
                assert_eq!(a.random::<u64>(), b.random::<u64>());
            }
        }
    }
}

#[test]
fn trial_k_replays_alone() {
    let config = small_config();
    let result = run_sweep(&config, &[], &|_| {}).unwrap();
    let k = 3 * config.trials + 5; // grid cell 3
    let g = result.grid[k / config.trials];
    let spec = GeometrySpec::paper(
        &config.mounts[g.mounts],
        Layout::Tetrahedron,
        config.n_points[g.n],
        config.spread_m[g.spread],
        config.noise_mm[g.noise] / 1000.0,
    )
    .unwrap();
    for (m, method) in config.methods.iter().enumerate() {
        let SweepMethod::Registration(method) = *method else {
            unreachable!("geometry sweeps fit registration methods only")
        };
        let alone = geometry_trial(&spec, method, &mut trial_rng(config.seed, k as u64)).unwrap();
        assert_eq!(
            alone.ok_or(Failure::FitFailed),
            result.outcome(k, m).map(|o| o.errors)
        );
    }
}

/// Median of a statistic over a grid cell's rows.
fn median_of(
    rows: &[SummaryRow],
    mounts: &str,
    method: Method,
    noise: f64,
    spread: f64,
    n: usize,
) -> (f64, f64) {
    let r = rows
        .iter()
        .find(|r| {
            r.mounts == mounts
                && r.method == SweepMethod::from(method)
                && r.noise_mm == Some(noise)
                && r.spread_m == Some(spread)
                && r.n == Some(n)
        })
        .unwrap();
    (r.e_tran_mm_median.value, r.geodesic_deg_median.value)
}

#[test]
fn small_sweep_shows_the_expected_trends() {
    let mut config = small_config();
    config.trials = 300;
    config.mounts = vec![MountPair::floor_floor(), MountPair::floor_ceiling()];
    let methods = [
        Method::Generic,
        Method::Paper,
        Method::Lsq,
        Method::Constrained,
    ];
    config.methods = methods.map(SweepMethod::from).to_vec();
    let rows = summarize_cells(&run_sweep(&config, &[], &|_| {}).unwrap());
    for mounts in ["floor-floor", "floor-ceiling"] {
        for method in methods {
            // Error falls with spread (n = 4, σ = 1 mm... here 0.5 and 3 mm).
            for noise in [0.5, 3.0] {
                let small = median_of(&rows, mounts, method, noise, 0.25, 4);
                let large = median_of(&rows, mounts, method, noise, 1.5, 4);
                assert!(
                    large.0 < small.0 && large.1 < small.1,
                    "{mounts} {method:?} spread: {small:?} -> {large:?}"
                );
            }
            // Error falls with the point count.
            let few = median_of(&rows, mounts, method, 3.0, 1.5, 4);
            let many = median_of(&rows, mounts, method, 3.0, 1.5, 12);
            assert!(
                many.0 < few.0 && many.1 < few.1,
                "{mounts} {method:?} points: {few:?} -> {many:?}"
            );
            // Error rises with noise.
            let quiet = median_of(&rows, mounts, method, 0.5, 1.5, 12);
            let loud = median_of(&rows, mounts, method, 3.0, 1.5, 12);
            assert!(
                loud.0 > quiet.0 && loud.1 > quiet.1,
                "{mounts} {method:?} noise: {quiet:?} -> {loud:?}"
            );
        }
    }
}

#[test]
fn table_and_summary_csv_render() {
    let result = run_sweep(&small_config(), &[], &|_| {}).unwrap();
    let t = render_table(&summarize_pooled(&result));
    assert!(t.contains("floor-wall") && t.contains("generic-affine") && t.contains('['));
    let mut out = Vec::new();
    write_summary_csv(&summarize_cells(&result), &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert_eq!(text.lines().count(), 1 + result.grid.len() * 5);
}

#[test]
fn most_spread_four_picks_the_largest_tetrahedron() {
    // A unit cube's corners plus interior points: the largest tetrahedron of a cube's corners
    // is the regular one (volume 1/3, |det| = 2); both searches find a quadruple of that size.
    let mut pts: Vec<Point3<f64>> = (0..8)
        .map(|i| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    pts.extend((0..5).map(|i| Point3::new(0.5, 0.1 * i as f64 + 0.3, 0.5)));
    let det = |idx: [usize; 4]| {
        let [a, b, c, d] = idx.map(|i| pts[i]);
        (b - a).cross(&(c - a)).dot(&(d - a)).abs()
    };
    assert!((det(most_spread_four(&pts).unwrap()) - 2.0).abs() < EXACT_TOL);
    assert_eq!(most_spread_four(&pts[..3]), None);
    // Beyond the exhaustive size the greedy search still finds a corner tetrahedron.
    let mut many = pts.clone();
    many.extend((0..SPREAD4_EXHAUSTIVE).map(|i| Point3::new(0.5, 0.5, i as f64 / 100.0 + 0.2)));
    let idx = most_spread_four(&many).unwrap();
    assert!(idx.iter().all(|&i| i < 8), "{idx:?}");
}

/// Robot mode with per-trial tolerance-drawn errors, the planned layout and the whole-cell
/// methods: the new columns are written (cooperative for every method, predicted for the
/// whole-cell ones only) and the CSVs are byte-identical with one and two threads.
#[test]
fn robot_sweep_cooperative_columns_are_thread_independent() {
    use handclasp_cell::cell::Cell;
    let config = SweepConfig {
        mode: Mode::Robot,
        mounts: vec![MountPair::floor_floor()],
        noise_mm: vec![0.3],
        spread_m: vec![0.8],
        n_points: vec![10],
        methods: vec![
            Method::Lsq.into(),
            SweepMethod::PaperSpread4,
            SweepMethod::Placement,
            SweepMethod::Kinematic,
        ],
        layout: SweepLayout::Planned,
        kinematic_errors: KinematicErrorDraw::Tolerance,
        trials: 3,
        seed: 11,
    };
    let cells = vec![Cell::default_floor_floor()];
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let r = pool
            .install(|| run_sweep(&config, &cells, &|_| {}))
            .unwrap();
        let mut out = Vec::new();
        write_trials_csv(&r, &mut out).unwrap();
        write_summary_csv(&summarize_cells(&r), &mut out).unwrap();
        out
    };
    let one = run(1);
    assert_eq!(one, run(2));
    let text = String::from_utf8(one).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (method, status) = (col("method"), col("status"));
    let (coop, p95, pred) = (
        col("cooperative_rms_mm"),
        col("cooperative_p95_mm"),
        col("predicted_cooperative_rms_mm"),
    );
    let rows: Vec<Vec<&str>> = lines
        .take(3 * config.methods.len())
        .map(|l| l.split(',').collect())
        .collect();
    for r in &rows {
        assert_eq!(r[status], "ok", "{r:?}");
        assert_eq!(r[col("layout")], "planned");
        assert_eq!(r[col("kinematic_errors")], "tolerance");
        let rms: f64 = r[coop].parse().unwrap();
        let q95: f64 = r[p95].parse().unwrap();
        // Sub-mm to a few mm (σ 0.3 mm, errors of 0.05° / 0.5 mm): finite, positive, p95 ≥ rms/2.
        assert!(rms > 0.0 && rms < 10.0 && q95 > 0.5 * rms, "{r:?}");
        let whole_cell = matches!(r[method], "placement" | "kinematic");
        assert_eq!(!r[pred].is_empty(), whole_cell, "{r:?}");
    }
    assert!(text.contains("cooperative_rms_mm_median,cooperative_rms_mm_median_lo"));
}

/// Tolerance draws stay inside their bands, move every selected parameter, and depend on the
/// generator alone.
#[test]
fn kinematic_errors_are_drawn_inside_the_tolerances() {
    use handclasp_cell::cell::Cell;
    use kinematics::ErrorParam;
    let cell = Cell::default_floor_wall();
    let mut robot = cell.robot2.clone();
    draw_kinematic_errors(&mut robot, &mut trial_rng(3, 9));
    let tol = robot.tolerance;
    let dof = robot.model.dof();
    for joint in 0..dof {
        let offset = robot.errors.get(ErrorParam::JointOffset { joint });
        assert!(
            offset != 0.0 && offset.abs() <= tol.joint_offset_rad,
            "{joint}: {offset}"
        );
    }
    assert!(robot
        .errors
        .tip
        .iter()
        .all(|t| *t != 0.0 && t.abs() <= tol.tip_m));
    let mut again = cell.robot2.clone();
    draw_kinematic_errors(&mut again, &mut trial_rng(3, 9));
    assert_eq!(again.errors, robot.errors);
}
