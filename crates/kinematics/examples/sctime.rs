//! temp
use std::hint::black_box;
use std::time::Instant;
fn main() {
    let n = 10_000_000;
    let t0 = Instant::now();
    let mut acc = 0.0;
    for i in 0..n {
        let (s, c) = black_box(i as f64 * 1e-7).sin_cos();
        acc += s + c;
    }
    println!("sin_cos {:.2} ns {acc}", t0.elapsed().as_nanos() as f64 / n as f64);
    let p = format!("{}/../../robots/hp20.urdf", env!("CARGO_MANIFEST_DIR"));
    let m = kinematics::RobotModel::from_urdf_file(std::path::Path::new(&p), "tool0").unwrap();
    let tip = nalgebra::Vector3::new(0.0, 0.0, 0.15);
    let t0 = Instant::now();
    let mut acc = 0.0;
    for i in 0..n / 10 {
        let x = i as f64 * 1e-7;
        let q = [x, 0.1, 0.2, 0.3, 0.4, 0.5];
        acc += kinematics::base_from_tip_unchecked(black_box(&m), black_box(&q), &tip).translation.x;
    }
    println!("fk {:.2} ns {acc}", t0.elapsed().as_nanos() as f64 / (n / 10) as f64);
}
