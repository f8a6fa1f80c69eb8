//! Criterion benches of the registration kernels (seeded inputs, no timing assertions).
//! Run: `cargo bench -p calib-core --bench calib -- --warm-up-time 1 --measurement-time 3`

// criterion_main! generates an undocumented `main`.
#![allow(missing_docs)]

use calib_core::{
    constrained_lsq, generic_fast, nearest_rotation, paper_constrained, paper_fast, rigid_fit_fast,
    rigid_lsq, rotation_maximizing_trace, ConstrainedOptions, MountPair, PointPairs,
};
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn data(n: usize, seed: u64, mounts_wall: bool) -> (Vec<Point3<f64>>, Vec<Point3<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = if mounts_wall {
        Isometry3::from_parts(
            nalgebra::Translation3::new(1.2, 0.4, 0.9),
            nalgebra::UnitQuaternion::from_rotation_matrix(&calib_core::wall_rotation(0.4, 1.1)),
        )
    } else {
        Isometry3::new(
            Vector3::new(0.04, 1.48, 0.05),
            Vector3::new(0.0, 0.0, -0.78),
        )
    };
    let p_b2: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            Point3::new(
                rng.random_range(-0.8..0.8),
                rng.random_range(-0.8..0.8),
                rng.random_range(0.0..1.2),
            )
        })
        .collect();
    let p_b1 = p_b2
        .iter()
        .map(|p| truth * p + Vector3::from_fn(|_, _| rng.random_range(-5e-4..5e-4)))
        .collect();
    (p_b1, p_b2)
}

fn benches(c: &mut Criterion) {
    let (p1, p2) = data(4, 1, false);
    let a4 = [p1[0], p1[1], p1[2], p1[3]];
    let b4 = [p2[0], p2[1], p2[2], p2[3]];
    c.bench_function("rigid_fit_fast n=4", |b| {
        b.iter(|| rigid_fit_fast(black_box(&p1), black_box(&p2)))
    });
    let (p1_100, p2_100) = data(100, 2, false);
    c.bench_function("rigid_fit_fast n=100", |b| {
        b.iter(|| rigid_fit_fast(black_box(&p1_100), black_box(&p2_100)))
    });
    c.bench_function("generic_fast (4-point, eq 12)", |b| {
        b.iter(|| generic_fast(black_box(&a4), black_box(&b4), false))
    });
    let ff = MountPair::floor_floor();
    c.bench_function("paper_fast floor-floor", |b| {
        b.iter(|| paper_fast(black_box(&a4), black_box(&b4), &ff))
    });
    let (w1, w2) = data(4, 3, true);
    let wa = [w1[0], w1[1], w1[2], w1[3]];
    let wb = [w2[0], w2[1], w2[2], w2[3]];
    let fw = MountPair::floor_wall();
    c.bench_function("paper_fast floor-wall", |b| {
        b.iter(|| paper_fast(black_box(&wa), black_box(&wb), &fw))
    });
    let m = Matrix3::new(0.9, 0.2, -0.1, -0.3, 1.1, 0.05, 0.1, 0.0, 0.8);
    c.bench_function("nearest_rotation (SVD)", |b| {
        b.iter(|| nearest_rotation(black_box(&m)))
    });
    c.bench_function("rotation_maximizing_trace (Horn/QCP)", |b| {
        b.iter(|| rotation_maximizing_trace(black_box(&m)))
    });
    let pairs = PointPairs::new(p1.clone(), p2.clone()).unwrap();
    c.bench_function("rigid_lsq n=4 (full Fit, uncertainty)", |b| {
        b.iter(|| rigid_lsq(black_box(&pairs), None))
    });
    c.bench_function("paper_constrained floor-floor (full Fit)", |b| {
        b.iter(|| paper_constrained(black_box(&pairs), &ff))
    });
    c.bench_function("constrained_lsq floor-floor (full Fit)", |b| {
        b.iter(|| constrained_lsq(black_box(&pairs), &ff, &ConstrainedOptions::default()))
    });
}

criterion_group!(calib, benches);
criterion_main!(calib);
