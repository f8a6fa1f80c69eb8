//! Criterion bench: diagnosing a 40-point session with the full catalogue (target: under 2 s on
//! 2 cores, so that an engineer can rerun it at the cell). Seeded inputs: a session simulated by `generate_session` on the shipped floor–wall
//! cell with one hidden joint offset (robot 2, joint 3, 0.2°), and a noise-only one.
//! Run: `cargo bench -p diagnose --bench diagnose -- --warm-up-time 1 --measurement-time 3`.
#![allow(missing_docs)] // criterion_group! generates an undocumented function

use criterion::{criterion_group, criterion_main, Criterion};
use diagnose::{diagnose_session, DiagnoseOptions};
use kinematics::ErrorParam;
use sim_cell::{generate_session, trial_rng, Cell, Layout, SessionSpec};

fn bench(c: &mut Criterion) {
    let cell = Cell::default_floor_wall();
    let mut truth = cell.clone();
    truth
        .robot2
        .errors
        .set(ErrorParam::JointOffset { joint: 2 }, 0.2f64.to_radians());
    let spec = SessionSpec::new(40, Layout::Random, 0.8);
    let hidden = generate_session(&truth, &spec, &mut trial_rng(7, 0)).expect("session");
    let clean = generate_session(&cell, &spec, &mut trial_rng(8, 0)).expect("session");
    let options = DiagnoseOptions::default();
    c.bench_function("diagnose_40_points_full_catalogue_one_effect", |b| {
        b.iter(|| diagnose_session(&cell, &hidden, &options).expect("diagnosis"))
    });
    c.bench_function("diagnose_40_points_full_catalogue_noise_only", |b| {
        b.iter(|| diagnose_session(&cell, &clean, &options).expect("diagnosis"))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
