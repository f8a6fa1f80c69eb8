//! Criterion bench: diagnosing a 40-point session with the full catalogue (issue #5: < 2 s on
//! 2 cores). Seeded inputs: a session from the project's URDFs with one hidden joint offset.
//! Run: `cargo bench -p sim-cell --bench diagnose -- --warm-up-time 1 --measurement-time 3`.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use kinematics::{ErrorParam, KinematicErrors};
use sim_cell::diagnose::{self, DiagnoseOptions};

fn bench(c: &mut Criterion) {
    let robots = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let dir = std::env::temp_dir().join("handclasp-diagnose-bench");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("cell.toml");
    let toml = format!(
        "[robot1]\nurdf = \"{}\"\nmount = \"floor\"\ntip_mm = [0.0, 0.0, 150.0]\n[robot2]\nurdf = \"{}\"\nmount = \"floor\"\ntip_mm = [0.0, 0.0, 120.0]\n[b1_from_b2]\nxyz_mm = [1800.0, 50.0, 0.0]\nzyz_deg = [180.0, 0.0, 0.0]\n[noise]\nalignment_mm = 0.1\n",
        robots.join("va1400.urdf").display(),
        robots.join("hp20.urdf").display()
    );
    std::fs::write(&path, toml).expect("write cell");
    let cell = diagnose::load_cell(&path).expect("cell loads");
    let e1 = KinematicErrors::zero(cell.robot1.model.dof());
    let mut e2 = KinematicErrors::zero(cell.robot2.model.dof());
    e2.set(ErrorParam::JointOffset { joint: 2 }, 0.2f64.to_radians());
    let session = diagnose::simulate_session(&cell, &e1, &e2, 40, 0.5, 7).expect("session");
    let options = DiagnoseOptions::default();
    c.bench_function("diagnose_40_points_full_catalogue", |b| {
        b.iter(|| diagnose::diagnose(&cell, &session, &options).expect("diagnosis"))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
