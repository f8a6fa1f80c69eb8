use kinematics::*;
use nalgebra::{Point3, Unit, Vector3};
use rand::{Rng, SeedableRng};
fn main() {
    for name in ["hp20", "va1400"] {
        let p = format!("{}/../../robots/{name}.urdf", env!("CARGO_MANIFEST_DIR"));
        let m = RobotModel::from_urdf_file(std::path::Path::new(&p), "tool0").unwrap();
        let tip = Vector3::new(0.0, 0.0, 0.15);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut fail, mut its) = (0, 0);
        for _ in 0..300 {
            let q: Vec<f64> = m.joints().iter().map(|j| { let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0)); let s = hi - lo; rng.random_range(lo + 0.05 * s..hi - 0.05 * s) }).collect();
            let t = base_from_tip(&m, &q, &tip).unwrap();
            let opts = IkOptions { tool_axis_base: Some(Unit::new_normalize(t.rotation * Vector3::z())), ..Default::default() };
            let sol = ik_tip_position(&m, &Point3::from(t.translation.vector), &tip, &opts).unwrap();
            if !sol.reachable() { fail += 1; }
            its += sol.iterations;
        }
        println!("{name}: fail {fail}/300 mean iters {}", its / 300);
    }
}
