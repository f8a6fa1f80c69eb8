//! End-to-end tests for the simulator: a session simulated by `sim_cell` (robot mode: IK of both
//! robots, nominal-model tips) is valid input to `handclasp calibrate`, which recovers the cell's
//! true `b1_from_b2`. (The `sim-cell` binary itself is tested in `crates/sim-cell/tests/sim_cell/cli.rs`.)

use handclasp_cell::Cell;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde_json::Value;
use sim_cell::Layout;

use crate::support::{floats, json_ok, simulate, workspace, write_session_csv};

/// Zero-noise recovery through the CSV (6 decimals of mm and degrees): round-off, mm and degrees.
const ZERO_NOISE_XYZ_TOL_MM: f64 = 1e-3;
const ZERO_NOISE_ANGLE_TOL_DEG: f64 = 1e-5;
/// With the shipped cell's noise (0.3 mm alignment, 0.03 mm repeatability, 0.001° encoders) and a
/// 1 m tetrahedron of 8 points, the constrained fit is within a few σ: 2 mm / 0.2° is far outside
/// what chance gives (predicted 1σ ≈ 0.2 mm) yet catches unit or frame mistakes.
const NOISY_XYZ_TOL_MM: f64 = 2.0;
const NOISY_ANGLE_TOL_DEG: f64 = 0.2;

fn calibrate_all(csv: &std::path::Path, mounts: &str) -> Value {
    let csv = csv.to_str().unwrap();
    json_ok(&[
        "calibrate",
        csv,
        "--mounts",
        mounts,
        "--method",
        "all",
        "--json",
    ])
}

/// (largest translation difference, mm; geodesic angle, degrees) between the truth and a fit.
fn errors(v: &Value, cell: &Cell) -> (f64, f64) {
    let b = &v["b1_from_b2"];
    let xyz: Vec<f64> = floats(&b["xyz_mm"]);
    let q: Vec<f64> = floats(&b["quaternion_wxyz"]);
    let est = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    let t = cell.b1_from_b2.translation.vector * 1e3;
    let dt = (Vector3::new(xyz[0], xyz[1], xyz[2]) - t).amax();
    (dt, est.angle_to(&cell.b1_from_b2.rotation).to_degrees())
}

#[test]
fn simulated_zero_noise_session_is_recovered_by_calibrate() {
    // The floor-wall cell with its rotation exactly in the wall family (Table 1's is 0.126° off).
    let dir = tempfile::tempdir().unwrap();
    let text = handclasp_cell::cell::FLOOR_WALL_TOML.replace(
        "zyz_deg = [180.0, 89.874, -179.997]",
        "zyz_deg = [180.0, 90.0, -180.0]",
    );
    let mut cell = Cell::from_toml_str(&text, &workspace("cells")).unwrap();
    cell.noise.alignment_m = Vector3::zeros();
    cell.noise.repeatability_m = 0.0;
    cell.noise.encoder_resolution_rad = 0.0;
    let session = simulate(&cell, 6, Layout::Tetrahedron, 1.0, 3);
    let csv = write_session_csv(dir.path(), "session.csv", &session, &cell);
    let v = calibrate_all(&csv, "floor-wall");
    for m in ["generic", "generic-affine", "paper", "lsq", "constrained"] {
        let (dt, dr) = errors(&v["methods"][m], &cell);
        assert!(
            dt < ZERO_NOISE_XYZ_TOL_MM && dr < ZERO_NOISE_ANGLE_TOL_DEG,
            "{m}: {dt} mm, {dr}°"
        );
    }
}

#[test]
fn simulated_noisy_session_is_calibrated_within_its_noise() {
    let cell = Cell::default_floor_floor();
    let session = simulate(&cell, 8, Layout::Tetrahedron, 1.0, 4);
    let dir = tempfile::tempdir().unwrap();
    let csv = write_session_csv(dir.path(), "session.csv", &session, &cell);
    let v = calibrate_all(&csv, "floor-floor");
    for m in ["lsq", "constrained", "paper"] {
        let (dt, dr) = errors(&v["methods"][m], &cell);
        assert!(
            dt < NOISY_XYZ_TOL_MM && dr < NOISY_ANGLE_TOL_DEG,
            "{m}: {dt} mm, {dr}°"
        );
    }
}
