//! Criterion bench of `selection::regions::joint_regions` (seeded inputs, no timing
//! assertions): the region folds `calibrate --cell` (the prediction's model-error term) and
//! `diagnose --cv-folds regions` cut, whose exact spanning tree costs `rows²` distances (issue
//! 25: at 20,000 rows it was 44 % of `calibrate --cell`).
//! Run: `cargo bench -p calib-core --bench regions -- --warm-up-time 1 --measurement-time 10`
//!
//! Rows: two-robot joint vectors (7 + 6 joints, normalised to `[0, 1]`) on three smooth
//! three-dimensional sheets, as a teach-point layout with one approach direction gives (the
//! joints follow the point), the sheets 0.5 apart, plus one-robot rows (robot 2's joints
//! missing) on every tenth row; the prediction's minimum (4 rows) and cap (5 regions).

// criterion_main! generates an undocumented `main`.
#![allow(missing_docs)]

use calib_core::selection::regions::{joint_regions, REGION_SEED};
use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `rows` feature rows (see the module documentation), seeded.
fn rows(rows: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..rows)
        .map(|i| {
            let sheet = f64::from(rng.random_range(0..3u8)) * 0.5;
            let p: [f64; 3] = [rng.random(), rng.random(), rng.random()];
            (0..13)
                .map(|d| {
                    if i % 10 == 0 && d >= 7 {
                        return f64::NAN;
                    }
                    let w = d as f64 + 1.0;
                    0.1 * sheet
                        + 0.3 * (w * p[0]).sin()
                        + 0.3 * (w * p[1] + p[2]).cos()
                        + 0.2 * p[d % 3]
                        + if d == 12 { sheet } else { 0.0 }
                })
                .collect()
        })
        .collect()
}

fn bench_regions(c: &mut Criterion) {
    let mut group = c.benchmark_group("regions/joint_regions");
    group.sample_size(10);
    for n in [2_000, 20_000] {
        let x = rows(n, 25);
        group.bench_with_input(BenchmarkId::from_parameter(n), &x, |b, x| {
            b.iter(|| joint_regions(black_box(x), 4, 5, REGION_SEED))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_regions);
criterion_main!(benches);
