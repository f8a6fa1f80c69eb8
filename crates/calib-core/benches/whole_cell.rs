//! Criterion benches of the whole-cell calibration (seeded inputs, no timing assertions).
//! Run: `cargo bench -p calib-core --bench whole_cell -- --warm-up-time 1 --measurement-time 3`
//!
//! Per shipped cell (floor–ceiling, floor–wall) and 20 / 40 / 80 coincident points at
//! σ = 0.3 mm: a truth with every joint offset, origin xyz and tip of both robots drawn from
//! `U(±tolerance)` (0.05°, 0.5 mm; origin rpy not fitted), then
//! - `calibrate_cell`: starting values, base-parameter reduction and the screened MAP fit;
//! - `fit_cell`: the plain MAP fit on the full layout (no reduction, no screening).
//!
//! The data (inverse kinematics of the true robots) are built once per case, outside the timing.
//!
//! `whole_cell/rows`: `calibrate_cell` on floor–ceiling (seed 41) at 20, 200 and 2,000
//! coincident points, the cost against rows that `handclasp calibrate --cell --model kinematic`
//! pays (BENCHMARKS.md gives the command's own figures up to 20,000 rows); and `cli_path` at
//! 2,000 points: the whole-cell work of that command as `cli_support::cell_report` does it
//! (`calibrate_cell`, `widen_prior`, the prediction split, the predicted error over the
//! session's meeting pairs and over the seeded workspace poses, the coverage), without the
//! result check and the JSON. Only this group:
//! `cargo bench -p calib-core --bench whole_cell -- whole_cell/rows --warm-up-time 1 --measurement-time 5`

// criterion_main! generates an undocumented `main`.
#![allow(missing_docs)]

use calib_core::whole_cell::fixtures::{sim_cell, Cell};
use calib_core::whole_cell::{
    calibrate_cell, fit_cell, predict_error, session_coverage, widen_prior, workspace_pairs,
    CellProblem, ConfigPair, ObservationKind, PairSet, PredictionSplit, ScreenOptions,
    SolveOptions, Tolerance, WORKSPACE_POSES, WORKSPACE_SEED,
};
use calib_core::StopReason;
use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};

/// Coincident-point noise σ, m.
const SIGMA_M: f64 = 3e-4;
/// Side of the teach cube around the cell's teach centre, m.
const SPREAD_M: f64 = 0.7;

/// The tolerances of issue 11's realistic case: every default except origin rpy.
fn realistic() -> Tolerance {
    Tolerance {
        origin_rpy_rad: 0.0,
        ..Tolerance::default()
    }
}

/// A seeded problem of `n` coincident points in `cell`.
fn problem(cell: Cell, n: usize, seed: u64) -> CellProblem {
    let sc = sim_cell(cell, realistic(), false, seed);
    let mut p = sc.problem();
    p.observations = sc.coincident(n, SIGMA_M, SPREAD_M, seed + 1000);
    p
}

fn bench_whole_cell(c: &mut Criterion) {
    let solve = SolveOptions::default();
    let screen = ScreenOptions::default();
    for (name, cell, seed) in [
        ("floor_ceiling", Cell::Ceiling, 41),
        ("floor_wall", Cell::Wall, 42),
    ] {
        let mut group = c.benchmark_group(format!("whole_cell/{name}"));
        group.sample_size(20);
        for n in [20usize, 40, 80] {
            let p = problem(cell, n, seed);
            // The timed calls must do the work they claim: both fits converge on these data.
            let cal = calibrate_cell(&p, &solve, &screen).expect("valid problem");
            assert_eq!(cal.fit.stopped, StopReason::Converged, "{name} n={n}");
            let plain = fit_cell(&p, &solve).expect("valid problem");
            assert_eq!(plain.stopped, StopReason::Converged, "{name} n={n}");
            eprintln!(
                "{name}, {n} points: calibrate_cell {} unknowns ({} dropped or merged), {} \
                 rejected, {} iterations; fit_cell {} unknowns, {} iterations",
                cal.fit.layout.len(),
                cal.reduction.dropped.len(),
                cal.rejected.len(),
                cal.fit.iterations,
                plain.layout.len(),
                plain.iterations,
            );
            group.bench_with_input(BenchmarkId::new("calibrate_cell", n), &p, |b, p| {
                b.iter(|| calibrate_cell(black_box(p), &solve, &screen).expect("valid problem"))
            });
            group.bench_with_input(BenchmarkId::new("fit_cell", n), &p, |b, p| {
                b.iter(|| fit_cell(black_box(p), &solve).expect("valid problem"))
            });
        }
        group.finish();
    }
}

/// The whole-cell work of `handclasp calibrate --cell … --model kinematic --json` on `p`, in
/// the order `cli_support::cell_report::calibrate_session_with` does it (seeds 1, as there);
/// the result check and the report are left out. Gives the predicted rms over the workspace.
fn cli_path(p: &CellProblem, solve: &SolveOptions, screen: &ScreenOptions) -> f64 {
    let stated = calibrate_cell(p, solve, screen).expect("valid problem");
    let cal = widen_prior(p, &stated, solve, screen)
        .expect("valid problem")
        .unwrap_or(stated);
    let split = PredictionSplit::of_calibration(p, &cal).expect("valid problem");
    let meeting: Vec<ConfigPair> = p
        .observations
        .iter()
        .filter_map(|o| match &o.kind {
            ObservationKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                ..
            } => Some(ConfigPair {
                q1: q1.clone(),
                q2: q2.clone(),
                tool1: *tool1,
                tool2: *tool2,
            }),
            _ => None,
        })
        .collect();
    let (layout, est) = (&cal.fit.layout, &cal.fit.estimate);
    predict_error(p, layout, est, &split, &meeting, PairSet::MeetingPairs, 1).expect("pairs");
    let poses = workspace_pairs(p, &est.b1_from_b2, WORKSPACE_POSES, WORKSPACE_SEED);
    let over: Vec<ConfigPair> = poses.into_iter().map(|w| w.pair).collect();
    let workspace =
        predict_error(p, layout, est, &split, &over, PairSet::Workspace, 1).expect("pairs");
    session_coverage(p, 1).expect("valid problem");
    workspace.rms_m
}

/// `calibrate_cell` against the number of rows, and the CLI's whole path at 2,000 rows (see
/// the module doc).
fn bench_rows(c: &mut Criterion) {
    let solve = SolveOptions::default();
    let screen = ScreenOptions::default();
    let mut group = c.benchmark_group("whole_cell/rows");
    group.sample_size(10);
    for n in [20usize, 200, 2000] {
        let p = problem(Cell::Ceiling, n, 41);
        let cal = calibrate_cell(&p, &solve, &screen).expect("valid problem");
        assert_eq!(cal.fit.stopped, StopReason::Converged, "rows n={n}");
        eprintln!(
            "floor_ceiling, {n} points: {} residual rows, {} unknowns, {} rejected",
            cal.fit.residual_rows,
            cal.fit.layout.len(),
            cal.rejected.len()
        );
        group.bench_with_input(BenchmarkId::new("calibrate_cell", n), &p, |b, p| {
            b.iter(|| calibrate_cell(black_box(p), &solve, &screen).expect("valid problem"))
        });
        if n == 2000 {
            eprintln!(
                "floor_ceiling, {n} points, the CLI's path: predicted workspace rms {:.4} mm",
                cli_path(&p, &solve, &screen) * 1e3
            );
            group.bench_with_input(BenchmarkId::new("cli_path", n), &p, |b, p| {
                b.iter(|| cli_path(black_box(p), &solve, &screen))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_whole_cell, bench_rows);
criterion_main!(benches);
