//! End-to-end tests for the calibrate commands.

use serde_json::Value;
use std::io::Write;

use crate::support::{floats, handclasp, json_ok};

/// Zero-noise recovery through the CSV (mm printed with 6 decimals): 1e-3 mm / 1e-6° is round-off.
const XYZ_TOL_MM: f64 = 1e-3;
const ANGLE_TOL_DEG: f64 = 1e-5;

/// Points of a floor–floor cell: b1_from_b2 = (37.9, 1476.5, 54.5) mm, Rz(−44.5°), written with the
/// sim-cell session header (joint columns present and ignored).
fn floor_floor_csv(extra_error_row: Option<(usize, f64)>) -> tempfile::NamedTempFile {
    let (t, yaw) = ([37.9, 1476.5, 54.5], (-44.5f64).to_radians());
    let p_b2 = [
        [1200.0, 300.0, 400.0],
        [-800.0, 1200.0, 300.0],
        [900.0, -700.0, 1300.0],
        [400.0, 900.0, 900.0],
        [-300.0, -500.0, 100.0],
        [700.0, 650.0, 1500.0],
    ];
    let mut f = tempfile::Builder::new().suffix(".csv").tempfile().unwrap();
    writeln!(
        f,
        "point,r1_q1_deg,r1_q2_deg,r1_x_mm,r1_y_mm,r1_z_mm,r2_q1_deg,r2_x_mm,r2_y_mm,r2_z_mm"
    )
    .unwrap();
    for (i, p) in p_b2.iter().enumerate() {
        let (c, s) = (yaw.cos(), yaw.sin());
        let mut q = [
            c * p[0] - s * p[1] + t[0],
            s * p[0] + c * p[1] + t[1],
            p[2] + t[2],
        ];
        if let Some((row, dy)) = extra_error_row {
            if row == i {
                q[1] += dy;
            }
        }
        writeln!(
            f,
            "{},10.0,20.0,{:.6},{:.6},{:.6},5.0,{},{},{}",
            i + 1,
            q[0],
            q[1],
            q[2],
            p[0],
            p[1],
            p[2]
        )
        .unwrap();
    }
    f.flush().unwrap();
    f
}

fn check_truth(v: &Value) {
    let b = &v["b1_from_b2"];
    let xyz: Vec<f64> = floats(&b["xyz_mm"]);
    let zyz: Vec<f64> = floats(&b["zyz_deg"]);
    for (a, e) in xyz.iter().zip([37.9, 1476.5, 54.5]) {
        assert!((a - e).abs() < XYZ_TOL_MM, "{} xyz {xyz:?}", v["method"]);
    }
    // θ = 0: eq 32 puts the whole yaw into ψ (φ = 0).
    assert!(zyz[1].abs() < ANGLE_TOL_DEG, "{} zyz {zyz:?}", v["method"]);
    assert!(
        ((zyz[0] + zyz[2]) - (-44.5)).abs() < ANGLE_TOL_DEG,
        "{} zyz {zyz:?}",
        v["method"]
    );
    assert_eq!(b["rotation"].as_array().unwrap().len(), 3);
    assert_eq!(b["quaternion_wxyz"].as_array().unwrap().len(), 4);
}

#[test]
fn calibrate_single_method_json_recovers_truth() {
    let f = floor_floor_csv(None);
    let path = f.path().to_str().unwrap();
    for method in ["generic", "paper", "lsq", "constrained"] {
        let v = json_ok(&[
            "calibrate",
            path,
            "--mounts",
            "floor-floor",
            "--method",
            method,
            "--json",
        ]);
        assert_eq!(v["method"], method);
        check_truth(&v);
        assert_eq!(v["residuals_mm"].as_array().unwrap().len(), 6);
    }
    // Default with mounts: constrained, with uncertainty; without mounts: lsq.
    let v = json_ok(&["calibrate", path, "--mounts", "floor-floor", "--json"]);
    assert_eq!(v["method"], "constrained");
    assert!(v["uncertainty"]["e_tran_1sigma_mm"].as_f64().unwrap() < 1e-3);
    let v = json_ok(&["calibrate", path, "--json"]);
    assert_eq!(v["method"], "lsq");
    // Tilted mounts given explicitly (floor = tilt:0,0).
    let v = json_ok(&[
        "calibrate",
        path,
        "--mount1",
        "tilt:0,0",
        "--mount2",
        "floor",
        "--json",
    ]);
    check_truth(&v);
}

#[test]
fn calibrate_all_methods_json() {
    let f = floor_floor_csv(None);
    let v = json_ok(&[
        "calibrate",
        f.path().to_str().unwrap(),
        "--mounts",
        "floor-floor",
        "--method",
        "all",
        "--json",
    ]);
    for m in ["generic", "paper", "lsq", "constrained"] {
        check_truth(&v["methods"][m]);
    }
}

#[test]
fn calibrate_text_output_and_outlier_row() {
    let f = floor_floor_csv(Some((3, 25.0)));
    let out = handclasp(&[
        "calibrate",
        f.path().to_str().unwrap(),
        "--mounts",
        "floor-floor",
    ]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("b1_from_b2")
            && text.contains("quaternion")
            && text.contains("NOT an accuracy"),
        "{text}"
    );
    // The 4th data row is file line 5.
    assert!(text.contains("rows [5]"), "{text}");
    let v = json_ok(&[
        "calibrate",
        f.path().to_str().unwrap(),
        "--mounts",
        "floor-floor",
        "--json",
    ]);
    assert_eq!(v["outliers"]["flagged_rows"], serde_json::json!([5]));
}

fn run_err(args: &[&str]) -> String {
    let out = handclasp(args);
    assert!(!out.status.success(), "expected failure for {args:?}");
    assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    String::from_utf8(out.stderr).unwrap()
}

fn write(text: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::Builder::new().suffix(".csv").tempfile().unwrap();
    f.write_all(text.as_bytes()).unwrap();
    f
}

#[test]
fn calibrate_bad_input_names_row_and_fix() {
    let h = "r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n";
    let good = "1000,0,500,10,20,30\n0,1000,500,-990,1020,30\n500,500,1200,-490,520,730\n300,800,200,-690,820,-270\n";
    // NaN cell.
    let f = write(&format!("{h}{}", good.replace("-990", "NaN")));
    let e = run_err(&["calibrate", f.path().to_str().unwrap()]);
    assert!(
        e.contains("line 3") && e.contains("r2_x_mm") && e.contains("Fix"),
        "{e}"
    );
    // Missing column.
    let f = write("r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm\n1,2,3,4,5\n");
    let e = run_err(&["calibrate", f.path().to_str().unwrap()]);
    assert!(e.contains("r2_z_mm"), "{e}");
    // Metres.
    let f = write(&format!(
        "{h}1.0,0,0.5,0.01,0.02,0.03\n0,1.0,0.5,-0.99,1.02,0.03\n0.5,0.5,1.2,-0.49,0.52,0.73\n"
    ));
    let e = run_err(&["calibrate", f.path().to_str().unwrap()]);
    assert!(e.contains("metres") && e.contains("1000"), "{e}");
    // Too few points for the 4-point method.
    let three: String = good.lines().take(3).map(|l| format!("{l}\n")).collect();
    let f = write(&format!("{h}{three}"));
    let e = run_err(&[
        "calibrate",
        f.path().to_str().unwrap(),
        "--method",
        "generic",
    ]);
    assert!(e.contains("at least 4") && e.contains("got 3"), "{e}");
    // Coplanar points for the 4-point method.
    let f = write(&format!(
        "{h}0,0,0,0,0,0\n1000,0,0,1000,0,0\n0,1000,0,0,1000,0\n1000,1000,0,1000,1000,0\n"
    ));
    let e = run_err(&[
        "calibrate",
        f.path().to_str().unwrap(),
        "--method",
        "generic",
    ]);
    assert!(
        e.contains("coplanar") && e.contains("rows [2, 3, 4, 5]"),
        "{e}"
    );
    // Duplicate points.
    let f = write(&format!("{h}{good}1000,0,500,10,20,30\n"));
    let e = run_err(&["calibrate", f.path().to_str().unwrap()]);
    assert!(e.contains("rows 2 and 6") && e.contains("duplicate"), "{e}");
    // Spread mismatch (robot 2 in metres but not all below 5).
    let f = write(&format!(
        "{h}1000,0,500,10,20,30\n0,1000,500,9,21,30\n500,500,1200,9.5,20.5,30.7\n"
    ));
    let e = run_err(&["calibrate", f.path().to_str().unwrap()]);
    assert!(e.contains("spread"), "{e}");
    // Paper method without mounts; unknown mount.
    let f = write(&format!("{h}{good}"));
    let e = run_err(&["calibrate", f.path().to_str().unwrap(), "--method", "paper"]);
    assert!(e.contains("--mounts"), "{e}");
    let e = run_err(&[
        "calibrate",
        f.path().to_str().unwrap(),
        "--mount1",
        "floor",
        "--mount2",
        "roof",
    ]);
    assert!(e.contains("tilt:RX,RY"), "{e}");
    // Missing file.
    let e = run_err(&["calibrate", "/nonexistent/points.csv"]);
    assert!(e.contains("/nonexistent/points.csv"), "{e}");
    // The operating system's reason is said once. Regression (stop 16): a library error that
    // names its I/O error in its text and also returns it as its source printed it twice.
    let cell = crate::support::shipped_cell("floor-wall");
    let e = run_err(&[
        "calibrate",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        "/nonexistent/session.csv",
    ]);
    assert!(e.contains("/nonexistent/session.csv"), "{e}");
    assert_eq!(e.matches("os error").count(), 1, "{e}");
    let e = run_err(&[
        "fk",
        "--robot",
        "/nonexistent/r.urdf",
        "--q-deg",
        "0,0,0,0,0,0",
    ]);
    assert_eq!(e.matches("os error").count(), 1, "{e}");
}

/// A floor–floor cell whose robot 2 stands 0.4° tilted: the soft mount estimates the tilt and
/// recovers the truth; the hard constraint cannot.
#[test]
fn calibrate_soft_mount_estimates_tilt() {
    use nalgebra::{Isometry3, Point3, Vector3};
    let tilt = 0.4f64.to_radians();
    let truth = Isometry3::new(
        Vector3::new(0.04, 1.48, 0.05),
        Vector3::new(0.0, 0.0, -0.78),
    ) * Isometry3::rotation(Vector3::new(0.0, tilt, 0.0));
    let mut f = tempfile::Builder::new().suffix(".csv").tempfile().unwrap();
    writeln!(f, "r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm").unwrap();
    for i in 0..7 {
        let a = i as f64 * 0.9;
        let p2 = Point3::new(0.9 * a.cos(), 0.8 * a.sin(), 0.1 + 0.15 * i as f64);
        let p1 = truth * p2;
        writeln!(
            f,
            "{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
            p1.x * 1e3,
            p1.y * 1e3,
            p1.z * 1e3,
            p2.x * 1e3,
            p2.y * 1e3,
            p2.z * 1e3
        )
        .unwrap();
    }
    f.flush().unwrap();
    let path = f.path().to_str().unwrap();
    let v = json_ok(&[
        "calibrate",
        path,
        "--mounts",
        "floor-floor",
        "--tilt-sigma-deg",
        "2",
        "--json",
    ]);
    let est = v["soft_mount"]["tilt_estimate_deg"].as_f64().unwrap();
    // 1e-6 mm printing of the inputs: the tilt comes back to well under 1e-3°.
    assert!((est - 0.4).abs() < 1e-3, "{est}");
    let hard = json_ok(&["calibrate", path, "--mounts", "floor-floor", "--json"]);
    assert!(hard["residual_rms_mm"].as_f64().unwrap() > 1.0);
    assert!(v["residual_rms_mm"].as_f64().unwrap() < 1e-3);
}

#[test]
fn calibrate_warns_when_the_points_contradict_the_mounts() {
    // A floor–floor cell's points declared floor–wall with a known roll (robot 2's base z along
    // its level x): imposing it is 90° off. Found by hand: this used to print a 90°-wrong transform
    // with no warning at all.
    let f = floor_floor_csv(None);
    let path = f.path().to_str().unwrap();
    let v = json_ok(&[
        "calibrate",
        path,
        "--mount1",
        "floor",
        "--mount2",
        "tilt:0,-90",
        "--method",
        "constrained",
        "--json",
    ]);
    let c = &v["mount_check"];
    assert_eq!(c["consistent"], false, "{c}");
    // The least-squares member of the family is not the geodesically nearest one: about 94° here.
    assert!(c["rotation_gap_deg"].as_f64().unwrap() > 60.0, "{c}");
    let out = handclasp(&[
        "calibrate",
        path,
        "--mount1",
        "floor",
        "--mount2",
        "tilt:0,-90",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("WARNING: the points disagree with the mounts") && text.contains("--mount2"),
        "{text}"
    );
    // The right mounts: consistent, and the text says so.
    let v = json_ok(&["calibrate", path, "--mounts", "floor-floor", "--json"]);
    assert_eq!(v["mount_check"]["consistent"], true, "{v}");
}

/// Regression (issue 10, `repro/calibrate_huge_coords.csv`): six exact rigid pairs at about
/// 1e153 mm made `lsq` return a NaN pose and the text printer panic (`index out of bounds`).
/// The fit now rescales, so every method gives a finite pose: the file's 7-digit rounding leaves
/// residuals of ~1e145 mm, so without --force the plausibility check refuses it with a message
/// (no panic), and with --force it prints; the rotation is Rz(2 rad) = 114.5916° (1e-4° is the
/// file's precision).
#[test]
fn calibrate_huge_coords() {
    let f = write(
        "r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm
1.000000e+153,0.000000e+00,5.000000e+152,-4.161468e+152,-9.092974e+152,5.000000e+152
0.000000e+00,1.000000e+153,5.000000e+152,9.092974e+152,-4.161468e+152,5.000000e+152
5.000000e+152,5.000000e+152,1.200000e+153,2.465753e+152,-6.627221e+152,1.200000e+153
6.000000e+152,2.000000e+152,9.000000e+152,-6.782862e+151,-6.288078e+152,9.000000e+152
2.000000e+152,7.000000e+152,7.000000e+152,5.532788e+152,-4.731623e+152,7.000000e+152
9.000000e+152,9.000000e+152,6.000000e+152,4.438355e+152,-1.192900e+153,6.000000e+152
",
    );
    let path = f.path().to_str().unwrap();
    let err = run_err(&["calibrate", path]);
    assert!(err.contains("far beyond the alignment noise"), "{err}");
    for method in ["lsq", "generic", "generic-affine", "all"] {
        let out = handclasp(&["calibrate", path, "--method", method, "--force"]);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{method}: {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            stdout.contains("b1_from_b2:") && !stdout.contains("NaN"),
            "{stdout}"
        );
    }
    let v = json_ok(&["calibrate", path, "--method", "lsq", "--json", "--force"]);
    let zyz = v["b1_from_b2"]["zyz_deg"].as_array().unwrap();
    let yaw = zyz[0].as_f64().unwrap() + zyz[2].as_f64().unwrap();
    assert!((yaw - 2f64.to_degrees()).abs() < 1e-4, "{v}");
}

/// 12 exact floor–floor points (mm): robot 2's points and robot 1's (Rz(−44.5°), t = (37.9,
/// 1476.5, 54.5) mm), with `b2_of_row` choosing robot 2's point for each row and `swap_xy2`
/// swapping robot 2's x and y columns.
fn misfit_csv(b2_of_row: impl Fn(usize) -> usize, swap_xy2: bool) -> tempfile::NamedTempFile {
    let (t, yaw) = ([37.9, 1476.5, 54.5], (-44.5f64).to_radians());
    let p_b2: Vec<[f64; 3]> = (0..12)
        .map(|i| {
            let a = i as f64 * 0.9;
            [900.0 * a.cos(), 800.0 * a.sin(), 200.0 + 90.0 * i as f64]
        })
        .collect();
    let mut text = String::from("r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n");
    for (i, p) in p_b2.iter().enumerate() {
        let (c, s) = (yaw.cos(), yaw.sin());
        let q = [
            c * p[0] - s * p[1] + t[0],
            s * p[0] + c * p[1] + t[1],
            p[2] + t[2],
        ];
        let mut r2 = p_b2[b2_of_row(i)];
        if swap_xy2 {
            r2.swap(0, 1);
        }
        text += &format!(
            "{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
            q[0], q[1], q[2], r2[0], r2[1], r2[2]
        );
    }
    write(&text)
}

/// Regression (issue 10): point pairs shifted by one row, or x/y swapped for one robot, gave
/// residual RMS ~500 mm and exit 0 ("mount check: the points agree"). Now the fit fails naming
/// the cause and the worst rows, for lsq and constrained; --force keeps the fit (warning on
/// stderr); a raised --expected-noise-mm accepts it; valid points still pass.
#[test]
fn calibrate_shifted_rows_and_swapped_axes_fail_with_the_cause() {
    let shifted = misfit_csv(|i| (i + 1) % 12, false);
    let swapped = misfit_csv(|i| i, true);
    let good = misfit_csv(|i| i, false);
    for (file, cause) in [
        (
            &shifted,
            "rows out of order: robot 1's row i matches robot 2's row i-1",
        ),
        (
            &swapped,
            "swapped axes: robot 2's x and y columns are swapped",
        ),
    ] {
        let path = file.path().to_str().unwrap();
        for extra in [&["--method", "lsq"][..], &["--mounts", "floor-floor"][..]] {
            let mut args = vec!["calibrate", path];
            args.extend_from_slice(extra);
            let err = run_err(&args);
            assert!(err.contains("far beyond the alignment noise"), "{err}");
            assert!(err.contains(cause), "{extra:?}: {err}");
            assert!(err.contains("worst rows: row "), "{err}");
            args.push("--force");
            let out = handclasp(&args);
            assert!(out.status.success());
            assert!(String::from_utf8_lossy(&out.stderr).contains("kept by --force"));
            assert!(String::from_utf8_lossy(&out.stdout).contains("b1_from_b2:"));
        }
        let out = handclasp(&["calibrate", path, "--expected-noise-mm", "5000"]);
        assert!(out.status.success());
    }
    let v = json_ok(&["calibrate", good.path().to_str().unwrap(), "--json"]);
    assert!(v["residual_rms_mm"].as_f64().unwrap() < 1e-3, "{v}");
    let err = run_err(&[
        "calibrate",
        good.path().to_str().unwrap(),
        "--expected-noise-mm=-1",
    ]);
    assert!(err.contains("--expected-noise-mm"), "{err}");
}
