//! Robot-mode sessions: true tips meet, zero-noise recovery by every method and by the whole-cell
//! placement fit, encoder quantisation, and errors that name the teach point. (The session CSV's
//! own tests are handclasp-cell's.)

use calib_core::whole_cell::{calibrate_cell, ScreenOptions, SolveOptions};
use calib_core::{fit, Method, MountPair};
use handclasp_cell::problem::{cell_problem, truth_estimate, FitModel};
use handclasp_cell::Cell;
use kinematics::true_base_from_tip;
use nalgebra::{Point3, Vector3};
use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};
use std::path::Path;

/// Zero-noise recovery: IK and the true-robot Newton correction stop at 1e-9 m, so the fit is
/// exact to ~1e-8 m / rad (m, rad).
const ZERO_NOISE_TOL: f64 = 1e-7;
/// True tips of both robots meet to the Newton tolerance (1e-9 m) plus round-off, m.
const MEET_TOL_M: f64 = 1e-8;
/// Recovery tolerance of b1_from_b2 from a noise-free, error-free session by the whole-cell
/// placement fit: the solver's convergence (cost tolerance 1e-10 relative) leaves ≪ 1 µm, m and rad.
const PLACEMENT_TOL_M: f64 = 1e-5;

fn cells_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells")
}

/// A shipped cell with its rotation moved into the mount family exactly, and extra TOML appended.
fn cell_text(name: &str, zyz_in_family: &str, extra: &str) -> Cell {
    let text = std::fs::read_to_string(cells_dir().join(format!("{name}.toml"))).unwrap();
    let start = text.find("zyz_deg = [").unwrap();
    let end = start + text[start..].find(']').unwrap() + 1;
    let text = format!(
        "{}zyz_deg = [{zyz_in_family}]{}\n{extra}",
        &text[..start],
        &text[end..]
    );
    Cell::from_toml_str(&text, &cells_dir()).unwrap()
}

fn zero_noise(mut cell: Cell) -> Cell {
    cell.noise.alignment_m = Vector3::zeros();
    cell.noise.repeatability_m = 0.0;
    cell.noise.encoder_resolution_rad = 0.0;
    cell
}

#[test]
fn zero_noise_session_lets_every_method_recover_the_truth() {
    for (name, zyz, mounts) in [
        ("floor-floor", "0.0, 0.0, -44.5", MountPair::floor_floor()),
        ("floor-wall", "180.0, 90.0, -180.0", MountPair::floor_wall()),
        (
            "floor-ceiling",
            "0.0, 180.0, 0.0",
            MountPair::floor_ceiling(),
        ),
    ] {
        let cell = zero_noise(cell_text(name, zyz, ""));
        assert_eq!(cell.mounts(), mounts);
        let session = generate_session(
            &cell,
            &SessionSpec::new(6, Layout::Tetrahedron, 1.0),
            &mut trial_rng(5, 0),
        )
        .unwrap();
        let pairs = session.to_point_pairs();
        for method in Method::ALL {
            let est = fit(&pairs, method, &mounts).unwrap().b1_from_b2;
            let dt = (est.translation.vector - cell.b1_from_b2.translation.vector).amax();
            let dr = est.rotation.angle_to(&cell.b1_from_b2.rotation);
            assert!(
                dt < ZERO_NOISE_TOL && dr < ZERO_NOISE_TOL,
                "{name} {}: {dt} m, {dr} rad",
                method.name()
            );
        }
    }
}

#[test]
fn true_tips_meet_despite_kinematic_errors_and_nominal_tips_are_biased() {
    let extra = r#"
[robot1.errors]
joint_offset_deg = [0.02, -0.03, 0.0, 0.01, 0.0, 0.0, 0.0]
compliance_deg_per_knm = [0.0, 0.1, 0.0, 0.1, 0.0, 0.0, 0.0]
[robot2.errors]
origin_xyz_mm = [[0.2, 0, 0], [0, 0, 0], [0, 0, -0.3], [0, 0, 0], [0, 0, 0], [0, 0, 0]]
mount_rpy_deg = [0.01, 0.0, 0.0]
tip_mm = [0.0, 0.1, 0.2]
"#;
    let cell = zero_noise(cell_text("floor-wall", "180.0, 90.0, -180.0", extra));
    assert!(!cell.robot1.errors.is_zero() && !cell.robot2.errors.is_zero());
    let session = generate_session(
        &cell,
        &SessionSpec::new(5, Layout::Random, 0.8),
        &mut trial_rng(9, 1),
    )
    .unwrap();
    let mut max_bias: f64 = 0.0;
    for p in &session.points {
        let r1 = &cell.robot1;
        let r2 = &cell.robot2;
        let t1 = true_base_from_tip(
            &r1.model,
            &r1.errors,
            &p.q1,
            &r1.flange_from_tip,
            &r1.g_base,
        )
        .unwrap();
        let t2 = true_base_from_tip(
            &r2.model,
            &r2.errors,
            &p.q2,
            &r2.flange_from_tip,
            &r2.g_base,
        )
        .unwrap();
        let gap = (t1.translation.vector
            - (cell.b1_from_b2 * Point3::from(t2.translation.vector)).coords)
            .norm();
        assert!(
            gap < MEET_TOL_M,
            "point {}: true tips {gap} m apart",
            p.point
        );
        max_bias = max_bias.max((t1.translation.vector - p.p_b1.coords).norm());
    }
    // The controller's nominal tip differs from the true one by the errors' effect (≥ 0.1 mm here).
    assert!(
        max_bias > 1e-4,
        "nominal tips should be biased, max {max_bias} m"
    );
}

#[test]
fn encoder_quantisation_and_noise_show_in_the_session() {
    let cell = Cell::default_floor_floor(); // encoder 0.001°, alignment 0.3 mm
    let session = generate_session(
        &cell,
        &SessionSpec::new(6, Layout::Tetrahedron, 1.0),
        &mut trial_rng(4, 0),
    )
    .unwrap();
    let res = cell.noise.encoder_resolution_rad;
    for p in &session.points {
        for q in p.q1.iter().chain(&p.q2) {
            let k = q / res;
            assert!(
                (k - k.round()).abs() < 1e-6,
                "{q} rad is not a multiple of the resolution"
            );
        }
    }
    let fit = fit(&session.to_point_pairs(), Method::Lsq, &cell.mounts()).unwrap();
    let rms = fit.residual_rms_m();
    // 0.3 mm per axis alignment noise: residual RMS of a 6-point fit is a fraction of 0.52 mm.
    assert!(rms > 0.05e-3 && rms < 1.5e-3, "residual RMS {rms} m");
}

#[test]
fn same_seed_same_session() {
    let cell = Cell::default_floor_wall();
    let spec = SessionSpec::new(5, Layout::Random, 0.7);
    let a = generate_session(&cell, &spec, &mut trial_rng(8, 3)).unwrap();
    let b = generate_session(&cell, &spec, &mut trial_rng(8, 3)).unwrap();
    assert_eq!(a, b);
}

#[test]
fn teach_point_outside_the_common_workspace_is_named() {
    let cell = Cell::default_floor_wall();
    let mut spec = SessionSpec::new(0, Layout::Random, 1.0);
    spec.points_b1 = Some(vec![
        cell.centre_b1,
        Point3::new(-3.0, 0.0, 0.5),
        cell.centre_b1 + Vector3::new(0.2, 0.0, 0.0),
    ]);
    let e = generate_session(&cell, &spec, &mut trial_rng(1, 0))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("teach point 2") && e.contains("-3000.0") && e.contains("common workspace"),
        "{e}"
    );
    // A layout that cannot fit anywhere near: says what would work.
    let spec = SessionSpec::new(4, Layout::Tetrahedron, 6.0);
    let e = generate_session(&cell, &spec, &mut trial_rng(1, 0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("reduce the spread"), "{e}");
    // A library names no CLI flag (the binary adds them).
    assert!(!e.contains("--"), "{e}");
}

/// Robot-mode sweep: byte-identical output for 1 and 2 threads, and the error rises with noise.
#[test]
fn robot_mode_sweep_is_thread_independent_and_follows_noise() {
    use sim_cell::sweep::{run_sweep, summarize_cells, write_trials_csv, Mode, SweepConfig};
    let config = SweepConfig {
        mode: Mode::Robot,
        mounts: vec![MountPair::floor_floor()],
        noise_mm: vec![0.2, 3.0],
        spread_m: vec![1.0],
        n_points: vec![6],
        methods: vec![Method::Lsq.into(), Method::Constrained.into()],
        layout: Layout::Tetrahedron.into(),
        kinematic_errors: sim_cell::sweep::KinematicErrorDraw::None,
        trials: 12,
        seed: 5,
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
        (r, out)
    };
    let (r1, csv1) = run(1);
    let (_, csv2) = run(2);
    assert_eq!(csv1, csv2);
    assert!(!String::from_utf8(csv1).unwrap().contains("unreachable"));
    let rows = summarize_cells(&r1);
    for m in [Method::Lsq, Method::Constrained] {
        let at = |noise: f64| {
            rows.iter()
                .find(|r| r.method == m.into() && r.noise_mm == Some(noise))
                .unwrap()
                .e_tran_mm_median
                .value
        };
        assert!(at(3.0) > at(0.2), "{m:?}: {} vs {}", at(0.2), at(3.0));
    }
    // Cells in the wrong order for the grid are an error, not a silent mismatch.
    let wrong = vec![Cell::default_floor_wall()];
    assert!(run_sweep(&config, &wrong, &|_| {}).is_err());
}

/// A tilted mount's label holds a comma (`floor-tilt(0.5,0)`): trials.csv and summary.csv quote
/// it, so every row read back has the header's field count and the label round-trips.
#[test]
fn tilted_mount_sweep_csvs_read_back_with_the_header_field_count() {
    use sim_cell::placement::mounts_label;
    use sim_cell::sweep::{
        run_sweep, summarize_cells, write_summary_csv, write_trials_csv, Mode, SweepConfig,
    };
    let cells_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    let text = std::fs::read_to_string(cells_dir.join("floor-floor.toml")).unwrap();
    let (head, robot2) = text.split_at(text.find("[robot2]").unwrap());
    let robot2 = robot2.replacen("mount = \"floor\"", "mount = { tilt_deg = [0.5, 0.0] }", 1);
    let cell = Cell::from_toml_str(&format!("{head}{robot2}"), &cells_dir).unwrap();
    let label = mounts_label(&cell.mounts());
    assert!(label.contains(','), "{label}");
    let config = SweepConfig {
        mode: Mode::Robot,
        mounts: vec![cell.mounts()],
        noise_mm: vec![1.0],
        spread_m: vec![0.5],
        n_points: vec![4],
        methods: vec![Method::Lsq.into(), Method::Constrained.into()],
        layout: Layout::Tetrahedron.into(),
        kinematic_errors: sim_cell::sweep::KinematicErrorDraw::None,
        trials: 1,
        seed: 7,
    };
    let result = run_sweep(&config, &[cell], &|_| {}).unwrap();
    let mut trials = Vec::new();
    write_trials_csv(&result, &mut trials).unwrap();
    let mut summary = Vec::new();
    write_summary_csv(&summarize_cells(&result), &mut summary).unwrap();
    for (name, bytes, rows) in [("trials", trials, 2), ("summary", summary, 2)] {
        let mut reader = csv::ReaderBuilder::new()
            .flexible(true)
            .from_reader(bytes.as_slice());
        let header = reader.headers().unwrap().clone();
        let mounts = header.iter().position(|h| h == "mounts").unwrap();
        let records: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
        assert_eq!(records.len(), rows, "{name}");
        for r in &records {
            assert_eq!(r.len(), header.len(), "{name}: {r:?}");
            assert_eq!(&r[mounts], label, "{name}");
        }
    }
}

/// The whole-cell placement fit of a noise-free simulated session recovers the cell's
/// placement, and the cell's truth as an estimate holds it.
#[test]
fn noise_free_placement_fit_recovers_the_cell() {
    let mut cell = Cell::default_floor_floor();
    cell.noise.alignment_m = Vector3::zeros();
    cell.noise.repeatability_m = 0.0;
    cell.noise.encoder_resolution_rad = 0.0;
    let session = generate_session(
        &cell,
        &SessionSpec::new(8, Layout::Tetrahedron, 1.0),
        &mut trial_rng(5, 0),
    )
    .unwrap();
    let p = cell_problem(&cell, &session, FitModel::Placement);
    let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
    let x = cal.fit.estimate.b1_from_b2;
    assert!((x.translation.vector - cell.b1_from_b2.translation.vector).amax() < PLACEMENT_TOL_M);
    assert!(x.rotation.angle_to(&cell.b1_from_b2.rotation) < PLACEMENT_TOL_M);
    let truth = truth_estimate(&cell, &p);
    assert_eq!(truth.b1_from_b2, cell.b1_from_b2);
}
