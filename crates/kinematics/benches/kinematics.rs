//! Kinematics benchmarks: `cargo bench -p kinematics -- --warm-up-time 1 --measurement-time 3`.
//!
//! Ids: `fk/<robot>` (checked `base_from_tip`), `fk_unchecked/<robot>`, `jacobian/<robot>`
//! (`geometric_jacobian`, base axes), `ik/<robot>` (position-only `ik_tip_position` with default
//! options, cycling over 256 reachable targets drawn from seeded joint vectors) and
//! `ik_axis/<robot>` (the same with the flange z axis constrained). Robots: the shipped hp20 and
//! va1400, and two test fixtures: `rail_6r` (the hp20 on a track: a prismatic first joint) and
//! `mimic_torso` (a coupled joint: the FK's chain-value step).

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_main, Criterion};
use kinematics::{
    base_from_tip, base_from_tip_unchecked, geometric_jacobian, ik_tip_position, IkOptions,
    JacobianFrame, RobotModel,
};
use nalgebra::{Point3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const ROBOTS: [&str; 4] = ["hp20", "va1400", "rail_6r", "mimic_torso"];
const SEED: u64 = 20_140_101;
const N_INPUTS: usize = 256;

/// A shipped robot (`robots/<name>.urdf`) or, for `rail_6r` and `mimic_torso`, the test fixture.
fn robot(name: &str) -> RobotModel {
    let dir = if name == "rail_6r" || name == "mimic_torso" {
        "tests/fixtures"
    } else {
        "../../robots"
    };
    let p = format!("{}/{dir}/{name}.urdf", env!("CARGO_MANIFEST_DIR"));
    RobotModel::from_urdf_file(Path::new(&p), "tool0").expect("URDF loads")
}

/// Seeded joint vectors inside the limits (5 % margin of each span).
fn joint_vectors(model: &RobotModel) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    (0..N_INPUTS)
        .map(|_| {
            model
                .joints()
                .iter()
                .map(|j| {
                    let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
                    let m = 0.05 * (hi - lo);
                    rng.random_range(lo + m..hi - m)
                })
                .collect()
        })
        .collect()
}

fn benches(c: &mut Criterion) {
    let tip = Vector3::new(0.0, 0.0, 0.15);
    for name in ROBOTS {
        let model = robot(name);
        let qs = joint_vectors(&model);
        let mut i = 0;
        c.bench_function(&format!("fk/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % N_INPUTS;
                base_from_tip(black_box(&model), black_box(&qs[i]), black_box(&tip)).unwrap()
            })
        });
        c.bench_function(&format!("fk_unchecked/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % N_INPUTS;
                base_from_tip_unchecked(black_box(&model), black_box(&qs[i]), black_box(&tip))
            })
        });
        c.bench_function(&format!("jacobian/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % N_INPUTS;
                geometric_jacobian(&model, black_box(&qs[i]), &tip, JacobianFrame::Base).unwrap()
            })
        });
        let poses: Vec<_> = qs
            .iter()
            .map(|q| base_from_tip(&model, q, &tip).unwrap())
            .collect();
        let preferred = (model.dof() > 6).then(|| vec![0.0; model.dof()]);
        let opts = IkOptions {
            preferred_q: preferred.clone(),
            ..IkOptions::default()
        };
        c.bench_function(&format!("ik/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % N_INPUTS;
                let target = Point3::from(poses[i].translation.vector);
                ik_tip_position(&model, black_box(&target), &tip, &opts).unwrap()
            })
        });
        c.bench_function(&format!("ik_axis/{name}"), |b| {
            b.iter(|| {
                i = (i + 1) % N_INPUTS;
                let opts = IkOptions {
                    tool_axis_base: Some(Unit::new_normalize(poses[i].rotation * Vector3::z())),
                    preferred_q: preferred.clone(),
                    ..IkOptions::default()
                };
                let target = Point3::from(poses[i].translation.vector);
                ik_tip_position(&model, black_box(&target), &tip, &opts).unwrap()
            })
        });
    }
}

// criterion_group! generates an undocumented public function.
#[allow(missing_docs)]
mod group {
    criterion::criterion_group!(kinematics_benches, super::benches);
}
criterion_main!(group::kinematics_benches);
