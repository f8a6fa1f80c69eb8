//! Criterion bench of the coincident-handclasp diagnosis (`diagnose_session`).
//!
//! - 40 points, full catalogue (target: under 2 s on 2 cores, so that an engineer can rerun it at
//!   the cell): a session simulated by `generate_session` on the shipped floor–wall cell with one
//!   hidden joint offset (robot 2, joint 3, 0.2°), and a noise-only one.
//! - 200 points with six hidden effects on both robots (the selection accepts several steps, so
//!   the re-screen, the backward elimination and the held-out folds all run: the work that grows
//!   with the session), in a 1-thread and a 2-thread rayon pool. The report is identical in both
//!   (see `engine::tests::the_report_is_identical_whatever_the_thread_count`).
//!
//! Seeded inputs. Run:
//! `cargo bench -p diagnose --bench diagnose -- --warm-up-time 1 --measurement-time 3`
//! (one id: append its name, e.g. `diagnose_200_points_six_effects/threads_2`).
#![allow(missing_docs)] // criterion_group! generates an undocumented function

use criterion::{criterion_group, criterion_main, Criterion};
use diagnose::{diagnose_session, DiagnoseOptions};
use handclasp_cell::Cell;
use kinematics::{Axis, ErrorParam};
use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};

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

    // Six effects: robot 1 joint offsets (joints 2 and 5) and tip x, robot 2 joint 3 offset,
    // joint 2 origin x and joint 2 compliance (0.05 deg/(kN·m)).
    let mut truth = cell.clone();
    let e1 = &mut truth.robot1.errors;
    e1.set(ErrorParam::JointOffset { joint: 1 }, 0.03f64.to_radians());
    e1.set(
        ErrorParam::JointOffset { joint: 4 },
        (-0.04f64).to_radians(),
    );
    e1.set(ErrorParam::Tip { axis: Axis::X }, 0.3e-3);
    let e2 = &mut truth.robot2.errors;
    e2.set(ErrorParam::JointOffset { joint: 2 }, 0.05f64.to_radians());
    e2.set(
        ErrorParam::OriginXyz {
            joint: 1,
            axis: Axis::X,
        },
        0.4e-3,
    );
    e2.set(
        ErrorParam::Compliance { joint: 1 },
        0.05f64.to_radians() / 1e3,
    );
    let spec = SessionSpec::new(200, Layout::Random, 0.6);
    let session = generate_session(&truth, &spec, &mut trial_rng(7, 0)).expect("session");
    let mut group = c.benchmark_group("diagnose_200_points_six_effects");
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        group.bench_function(format!("threads_{threads}"), |b| {
            b.iter(|| {
                pool.install(|| diagnose_session(&cell, &session, &options).expect("diagnosis"))
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
