//! End-to-end tests for `handclasp fk` and `handclasp ik`: the built binary, run as a user would.

use std::path::Path;
use std::process::{Command, Output};

use kinematics::{base_from_tip, RobotModel};
use nalgebra::Vector3;
use serde_json::Value;

const HP20: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/hp20.urdf");
const VA1400: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/va1400.urdf");
/// JSON carries full f64 precision; hand-computed poses agree to round-off of mm-scale sums.
const EXACT_MM: f64 = 1e-9;
/// IK round trip through the CLI: the library converges to 1e-10 m = 1e-7 mm.
const ROUND_TRIP_MM: f64 = 1e-6;
/// Angle round-off, deg.
const EXACT_DEG: f64 = 1e-9;

fn handclasp(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_handclasp"))
        .args(args)
        .output()
        .expect("run handclasp")
}

fn json_ok(args: &[&str]) -> Value {
    let out = handclasp(args);
    assert!(
        out.status.success(),
        "handclasp {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

fn err_text(args: &[&str]) -> String {
    let out = handclasp(args);
    assert!(!out.status.success(), "handclasp {args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn fk_zero_pose_hp20_is_hand_computed() {
    let v = json_ok(&[
        "fk",
        "--robot",
        HP20,
        "--q-deg",
        "0,0,0,0,0,0",
        "--tip-mm",
        "0,0,150",
        "--json",
    ]);
    // 150 + 795 + 105 + 150 (tip along flange z = base x) out, 505 + 760 + 140 up.
    let xyz = floats(&v["xyz_mm"]);
    for (got, want) in xyz.iter().zip([1200.0, 0.0, 1405.0]) {
        assert!((got - want).abs() < EXACT_MM, "{xyz:?}");
    }
    // Flange z along base x: R = Ry(90°), ZYZ (0, 90, 0).
    let zyz = floats(&v["zyz_deg"]);
    for (got, want) in zyz.iter().zip([0.0, 90.0, 0.0]) {
        assert!((got - want).abs() < EXACT_DEG, "{zyz:?}");
    }
    let rot: Vec<Vec<f64>> = v["rotation"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    let want = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]];
    for r in 0..3 {
        for c in 0..3 {
            assert!((rot[r][c] - want[r][c]).abs() < 1e-12, "{rot:?}");
        }
    }
}

#[test]
fn fk_matches_the_library_for_the_documented_example() {
    let v = json_ok(&[
        "fk",
        "--robot",
        HP20,
        "--q-deg",
        "0,10,-20,0,30,0",
        "--tip-mm",
        "0,0,150",
        "--json",
    ]);
    let model = RobotModel::from_urdf_file(Path::new(HP20), "tool0").unwrap();
    let q: Vec<f64> = [0.0f64, 10.0, -20.0, 0.0, 30.0, 0.0]
        .iter()
        .map(|d| d.to_radians())
        .collect();
    let t = base_from_tip(&model, &q, &Vector3::new(0.0, 0.0, 0.15)).unwrap();
    let xyz = floats(&v["xyz_mm"]);
    for (got, want) in xyz.iter().zip(t.translation.vector.iter()) {
        assert!((got - want * 1e3).abs() < EXACT_MM);
    }
    let zyz = floats(&v["zyz_deg"]);
    let r = kinematics::rotation_from_zyz([
        zyz[0].to_radians(),
        zyz[1].to_radians(),
        zyz[2].to_radians(),
    ]);
    assert!(r.angle_to(&t.rotation.to_rotation_matrix()) < 1e-12);
    assert_eq!(floats(&v["q_deg"]), vec![0.0, 10.0, -20.0, 0.0, 30.0, 0.0]);
}

#[test]
fn fk_table_output_is_readable() {
    let out = handclasp(&["fk", "--robot", HP20, "--q-deg", "90,0,0,0,0,0"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("x_mm") && text.contains("theta_deg"),
        "{text}"
    );
    // S = 90°: the zero-pose flange (1050, 0, 1405) turns to (0, 1050, 1405).
    assert!(
        text.contains("1050.0000") && text.contains("1405.0000"),
        "{text}"
    );
}

#[test]
fn ik_round_trips_through_fk_for_both_robots() {
    for (robot, q_deg) in [
        (HP20, "20,30,-40,50,-60,70"),
        (HP20, "-120,-30,70,-100,45,200"),
        (VA1400, "20,30,-40,50,-60,70,-80"),
        (VA1400, "-100,60,30,90,20,-45,100"),
    ] {
        let fk = json_ok(&[
            "fk",
            "--robot",
            robot,
            "--q-deg",
            q_deg,
            "--tip-mm",
            "5,-10,150",
            "--json",
        ]);
        let xyz = floats(&fk["xyz_mm"]);
        let rot: Vec<Vec<f64>> = fk["rotation"]
            .as_array()
            .unwrap()
            .iter()
            .map(floats)
            .collect();
        let axis = format!("{},{},{}", rot[0][2], rot[1][2], rot[2][2]);
        let xyz_text = format!("{},{},{}", xyz[0], xyz[1], xyz[2]);
        for with_axis in [false, true] {
            let mut args = vec![
                "ik",
                "--robot",
                robot,
                "--xyz-mm",
                &xyz_text,
                "--tip-mm",
                "5,-10,150",
                "--json",
            ];
            if with_axis {
                args.extend(["--axis", axis.as_str()]);
            }
            let ik = json_ok(&args);
            assert_eq!(ik["reachable"], Value::Bool(true), "{robot} {q_deg}: {ik}");
            let q_text = floats(&ik["q_deg"])
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(",");
            let back = json_ok(&[
                "fk",
                "--robot",
                robot,
                "--q-deg",
                &q_text,
                "--tip-mm",
                "5,-10,150",
                "--json",
            ]);
            let p = floats(&back["xyz_mm"]);
            for k in 0..3 {
                assert!(
                    (p[k] - xyz[k]).abs() < ROUND_TRIP_MM,
                    "{robot} {q_deg} axis={with_axis}: {p:?} vs {xyz:?}"
                );
            }
            if with_axis {
                let r: Vec<Vec<f64>> = back["rotation"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(floats)
                    .collect();
                for k in 0..3 {
                    assert!((r[k][2] - rot[k][2]).abs() < 1e-9, "{robot} {q_deg}");
                }
            }
        }
    }
}

#[test]
fn ik_unreachable_is_a_result_not_an_error() {
    let v = json_ok(&[
        "ik",
        "--robot",
        HP20,
        "--xyz-mm",
        "5000,0,1000",
        "--tip-mm",
        "0,0,150",
        "--json",
    ]);
    assert_eq!(v["reachable"], Value::Bool(false));
    assert!(v["position_error_mm"].as_f64().unwrap() > 1000.0);
    assert_eq!(floats(&v["q_deg"]).len(), 6);
    let out = handclasp(&["ik", "--robot", HP20, "--xyz-mm", "5000,0,1000"]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("UNREACHABLE"));
}

#[test]
fn bad_inputs_say_what_is_wrong_and_how_to_fix_it() {
    let e = err_text(&["fk", "--robot", HP20, "--q-deg", "0,10,-20,0,30"]);
    assert!(
        e.contains("--q-deg has 5 values but hp20 has 6 joints"),
        "{e}"
    );
    let e = err_text(&["fk", "--robot", HP20, "--q-deg", "0,10,-200,0,30,0"]);
    assert!(
        e.contains("joint_3_u") && e.contains("outside its limits"),
        "{e}"
    );
    let e = err_text(&["fk", "--robot", HP20, "--q-deg", "0,ten,0,0,0,0"]);
    assert!(e.contains("value 2") && e.contains("not a number"), "{e}");
    let e = err_text(&["fk", "--robot", HP20, "--q-deg", "0,NaN,0,0,0,0"]);
    assert!(e.contains("not a finite number"), "{e}");
    let e = err_text(&[
        "fk",
        "--robot",
        HP20,
        "--q-deg",
        "0,0,0,0,0,0",
        "--tool-link",
        "flange",
    ]);
    assert!(
        e.contains("link `flange` not found") && e.contains("tool0"),
        "{e}"
    );
    let e = err_text(&["fk", "--robot", "no/such/robot.urdf", "--q-deg", "0"]);
    assert!(
        e.contains("no/such/robot.urdf") && e.contains("check the path"),
        "{e}"
    );
    let e = err_text(&[
        "fk",
        "--robot",
        HP20,
        "--q-deg",
        "0,0,0,0,0,0",
        "--tip-mm",
        "0,150",
    ]);
    assert!(e.contains("--tip-mm has 2 values"), "{e}");
    let e = err_text(&[
        "ik",
        "--robot",
        HP20,
        "--xyz-mm",
        "1000,0,1000",
        "--axis",
        "0,0,0",
    ]);
    assert!(e.contains("--axis") && e.contains("zero vector"), "{e}");
    let e = err_text(&["ik", "--robot", VA1400, "--xyz-mm", "1000,0"]);
    assert!(e.contains("--xyz-mm has 2 values"), "{e}");
    let e = err_text(&[
        "ik",
        "--robot",
        VA1400,
        "--xyz-mm",
        "800,0,800",
        "--preferred-deg",
        "0,0,0,0,0,0",
    ]);
    assert!(
        e.contains("--preferred-deg has 6 values but va1400 has 7 joints"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.urdf");
    std::fs::write(&bad, "<robot name=\"x\"><link").unwrap();
    let e = err_text(&["fk", "--robot", bad.to_str().unwrap(), "--q-deg", "0"]);
    assert!(
        e.contains("bad.urdf") && e.contains("not a valid URDF"),
        "{e}"
    );
}
