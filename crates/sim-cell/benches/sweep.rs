//! Criterion benches of sim-cell: the geometry-mode trial (single thread and the 2-thread sweep)
//! and robot-mode sessions. Seeded inputs.
//!
//! `cargo bench -p sim-cell --bench sweep -- --warm-up-time 1 --measurement-time 3`
#![allow(missing_docs)] // criterion_group! generates an undocumented function

use calib_core::{Method, MountPair};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use handclasp_cell::Cell;
use nalgebra::Point3;
use sim_cell::layout::Layout;
use sim_cell::sweep::{geometry_trial_into, run_sweep, GeometrySpec, Mode, SweepConfig, TrialRngs};
use sim_cell::{generate_session, trial_rng, SessionSpec};
use std::hint::black_box;

/// Trials per measured iteration of the batched benches.
const BATCH: usize = 10_000;

fn geometry_single_thread(c: &mut Criterion) {
    let mut g = c.benchmark_group("geometry_trial");
    g.throughput(Throughput::Elements(BATCH as u64));
    for (mounts, name, method, n) in [
        ("floor-floor", "generic_n4", Method::Generic, 4),
        ("floor-floor", "paper_n4", Method::Paper, 4),
        ("floor-floor", "lsq_n4", Method::Lsq, 4),
        ("floor-floor", "lsq_n12", Method::Lsq, 12),
        // Regular truth (θ = 89.874°): e_rot by eq 33 on the nearest branch.
        ("floor-wall", "generic_n4", Method::Generic, 4),
    ] {
        let mount_pair = MountPair::parse_paper(mounts).unwrap();
        let spec = GeometrySpec::paper(&mount_pair, Layout::Tetrahedron, n, 1.0, 1e-3).unwrap();
        let erot_truth = spec.erot_truth();
        g.bench_function(BenchmarkId::new(mounts, name), |b| {
            let mut p1 = vec![Point3::origin(); n];
            let mut p2 = vec![Point3::origin(); n];
            let rngs = TrialRngs::new(7);
            let mut k = 0u64;
            b.iter(|| {
                let mut acc = 0.0;
                for _ in 0..BATCH {
                    let mut rng = rngs.get(k);
                    k += 1;
                    if let Some(e) =
                        geometry_trial_into(&spec, &erot_truth, method, &mut rng, &mut p1, &mut p2)
                    {
                        acc += e.e_tran;
                    }
                }
                black_box(acc)
            })
        });
    }
    g.finish();
}

fn geometry_sweep_two_threads(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let trials = 200_000;
    let mut g = c.benchmark_group("geometry_sweep_2_threads");
    g.sample_size(10);
    g.throughput(Throughput::Elements(trials as u64));
    for (name, methods) in [
        ("generic_n4", vec![Method::Generic]),
        ("all_methods_n4", Method::ALL.to_vec()),
    ] {
        let config = SweepConfig {
            mode: Mode::Geometry,
            mounts: vec![MountPair::floor_floor()],
            noise_mm: vec![1.0],
            spread_m: vec![1.0],
            n_points: vec![4],
            methods: methods.into_iter().map(Into::into).collect(),
            layout: Layout::Tetrahedron.into(),
            kinematic_errors: sim_cell::sweep::KinematicErrorDraw::None,
            trials,
            seed: 7,
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                black_box(
                    pool.install(|| run_sweep(&config, &[], &|_| {}))
                        .unwrap()
                        .outcomes
                        .len(),
                )
            })
        });
    }
    g.finish();
}

fn robot_sessions(c: &mut Criterion) {
    let mut g = c.benchmark_group("robot_session");
    g.sample_size(10);
    for cell_name in ["floor-floor", "floor-wall", "floor-ceiling"] {
        let cell = match cell_name {
            "floor-floor" => Cell::default_floor_floor(),
            "floor-wall" => Cell::default_floor_wall(),
            _ => Cell::default_floor_ceiling(),
        };
        let spec = SessionSpec::new(4, Layout::Tetrahedron, 1.0);
        g.throughput(Throughput::Elements(1));
        g.bench_function(BenchmarkId::new("n4_spread1000mm", cell_name), |b| {
            let mut k = 0u64;
            b.iter(|| {
                k += 1;
                black_box(
                    generate_session(&cell, &spec, &mut trial_rng(3, k))
                        .map(|s| s.points.len())
                        .ok(),
                )
            })
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    geometry_single_thread,
    geometry_sweep_two_threads,
    robot_sessions
);
criterion_main!(benches);
