//! Runs N checked `base_from_tip` calls on seeded hp20 joint vectors, for `perf stat`
//! (cycles per call, independent of other load): `perf stat -e cycles,instructions
//! target/release/examples/fkloop [fk|ik|unreachable] N [robot]`.
use std::hint::black_box;

use kinematics::{base_from_tip, ik_tip_position, IkOptions, RobotModel};
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};

fn main() {
    let what = std::env::args().nth(1).unwrap_or_else(|| "fk".into());
    let n: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000_000);
    let robot = std::env::args().nth(3).unwrap_or_else(|| "hp20".into());
    // A shipped robot, or a test fixture (rail_6r: a prismatic track; mimic_torso: a coupling).
    let dir = if robot == "rail_6r" || robot == "mimic_torso" {
        "tests/fixtures"
    } else {
        "../../robots"
    };
    let p = format!("{}/{dir}/{robot}.urdf", env!("CARGO_MANIFEST_DIR"));
    let m = RobotModel::from_urdf_file(std::path::Path::new(&p), "tool0").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20_140_101);
    let qs: Vec<Vec<f64>> = (0..256)
        .map(|_| {
            m.joints()
                .iter()
                .map(|j| {
                    let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
                    let s = 0.05 * (hi - lo);
                    rng.random_range(lo + s..hi - s)
                })
                .collect()
        })
        .collect();
    let tip = Vector3::new(0.0, 0.0, 0.15);
    let mut acc = 0.0;
    if what == "fk" {
        // Same protocol as benches/pinocchio/fk_bench.cpp: 21 runs of n/21 calls, median and min.
        let per_run = (n / 21).max(1);
        let mut ns = Vec::new();
        for _ in 0..21 {
            let t0 = std::time::Instant::now();
            for i in 0..per_run {
                acc += base_from_tip(black_box(&m), black_box(&qs[i & 255]), &tip)
                    .unwrap()
                    .translation
                    .x;
            }
            ns.push(t0.elapsed().as_secs_f64() * 1e9 / per_run as f64);
        }
        ns.sort_by(f64::total_cmp);
        println!("median {:.1} ns min {:.1} ns", ns[10], ns[0]);
    } else if what == "unreachable" {
        let opts = IkOptions::default();
        let t0 = std::time::Instant::now();
        for i in 0..n {
            let target = Point3::new(3.0 + (i % 7) as f64 * 0.1, 0.0, 1.0);
            let sol = ik_tip_position(&m, black_box(&target), &tip, &opts).unwrap();
            acc += sol.iterations as f64;
        }
        println!("mean {:.1} us", t0.elapsed().as_secs_f64() * 1e6 / n as f64);
    } else {
        let targets: Vec<Point3<f64>> = qs
            .iter()
            .map(|q| Point3::from(base_from_tip(&m, q, &tip).unwrap().translation.vector))
            .collect();
        let opts = IkOptions {
            preferred_q: (m.dof() > 6).then(|| vec![0.0; m.dof()]),
            ..IkOptions::default()
        };
        for i in 0..n {
            acc += ik_tip_position(&m, black_box(&targets[i & 255]), &tip, &opts)
                .unwrap()
                .q[0];
        }
    }
    println!("{what} {robot} x{n}: {acc}");
}
