//! IK success rate and timing over random reachable targets (a development aid):
//! `cargo run --release -p kinematics --example ikrate -- [samples]`.
use kinematics::*;
use nalgebra::{Point3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use std::time::Instant;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000);
    let restarts: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(32);
    let max_iterations: usize = std::env::args()
        .nth(3)
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    for name in ["hp20", "va1400"] {
        let p = format!("{}/../../robots/{name}.urdf", env!("CARGO_MANIFEST_DIR"));
        let m = RobotModel::from_urdf_file(std::path::Path::new(&p), "tool0").unwrap();
        let tip = Vector3::new(0.0, 0.0, 0.15);
        for with_axis in [false, true] {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
            let (mut fail, mut its) = (0, 0);
            let mut times = Vec::new();
            let mut seeds_hist = [0usize; 10];
            for _ in 0..n {
                let q: Vec<f64> = m
                    .joints()
                    .iter()
                    .map(|j| {
                        let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
                        let s = hi - lo;
                        rng.random_range(lo + 0.05 * s..hi - 0.05 * s)
                    })
                    .collect();
                let t = base_from_tip(&m, &q, &tip).unwrap();
                let opts = IkOptions {
                    tool_axis_base: with_axis
                        .then(|| Unit::new_normalize(t.rotation * Vector3::z())),
                    preferred_q: (m.dof() == 7).then(|| vec![0.0; 7]),
                    restarts,
                    max_iterations,
                    ..Default::default()
                };
                let t0 = Instant::now();
                let sol =
                    ik_tip_position(&m, &Point3::from(t.translation.vector), &tip, &opts).unwrap();
                times.push(t0.elapsed().as_secs_f64() * 1e6);
                if !sol.reachable() {
                    fail += 1;
                    if fail <= 3 {
                        eprintln!(
                            "  fail q={q:?} pe={} ae={}",
                            sol.position_error_m, sol.axis_error_rad
                        );
                    }
                }
                its += sol.iterations;
                seeds_hist[(sol.iterations / max_iterations).min(9)] += 1;
            }
            times.sort_by(|a, b| a.partial_cmp(b).unwrap());
            println!(
                "{name} axis={with_axis}: fail {fail}/{n} mean iters {:.1} median {:.1} us p90 {:.1} us max {:.0} us",
                its as f64 / n as f64,
                times[n / 2],
                times[n * 9 / 10],
                times[n - 1]
            );
            println!("  iterations/max_iterations histogram {seeds_hist:?}");
        }
    }
}
