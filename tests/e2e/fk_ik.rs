//! End-to-end tests for `handclasp fk` and `handclasp ik`: the built binary, run as a user would.

use std::path::Path;

use kinematics::{base_from_tip, RobotModel};
use nalgebra::Vector3;
use serde_json::Value;

use crate::support::{floats, handclasp, json_ok, stderr_of_failure};

const HP20: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/hp20.urdf");
const VA1400: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/va1400.urdf");
/// JSON carries full f64 precision; hand-computed poses agree to round-off of mm-scale sums.
const EXACT_MM: f64 = 1e-9;
/// IK round trip through the CLI: the library converges to 1e-10 m = 1e-7 mm.
const ROUND_TRIP_MM: f64 = 1e-6;
/// Angle round-off, deg.
const EXACT_DEG: f64 = 1e-9;

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
    let e = stderr_of_failure(&["fk", "--robot", HP20, "--q-deg", "0,10,-20,0,30"]);
    assert!(
        e.contains("--q-deg has 5 values but hp20 has 6 joints"),
        "{e}"
    );
    let e = stderr_of_failure(&["fk", "--robot", HP20, "--q-deg", "0,10,-200,0,30,0"]);
    assert!(
        e.contains("joint_3_u") && e.contains("outside its limits"),
        "{e}"
    );
    let e = stderr_of_failure(&["fk", "--robot", HP20, "--q-deg", "0,ten,0,0,0,0"]);
    assert!(e.contains("value 2") && e.contains("not a number"), "{e}");
    let e = stderr_of_failure(&["fk", "--robot", HP20, "--q-deg", "0,NaN,0,0,0,0"]);
    assert!(e.contains("not a finite number"), "{e}");
    let e = stderr_of_failure(&[
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
    let e = stderr_of_failure(&["fk", "--robot", "no/such/robot.urdf", "--q-deg", "0"]);
    assert!(
        e.contains("no/such/robot.urdf") && e.contains("check the path"),
        "{e}"
    );
    let e = stderr_of_failure(&[
        "fk",
        "--robot",
        HP20,
        "--q-deg",
        "0,0,0,0,0,0",
        "--tip-mm",
        "0,150",
    ]);
    assert!(e.contains("--tip-mm has 2 values"), "{e}");
    let e = stderr_of_failure(&[
        "ik",
        "--robot",
        HP20,
        "--xyz-mm",
        "1000,0,1000",
        "--axis",
        "0,0,0",
    ]);
    assert!(e.contains("--axis") && e.contains("zero vector"), "{e}");
    let e = stderr_of_failure(&["ik", "--robot", VA1400, "--xyz-mm", "1000,0"]);
    assert!(e.contains("--xyz-mm has 2 values"), "{e}");
    let e = stderr_of_failure(&[
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
    let e = stderr_of_failure(&["fk", "--robot", bad.to_str().unwrap(), "--q-deg", "0"]);
    assert!(
        e.contains("bad.urdf") && e.contains("not a valid URDF"),
        "{e}"
    );
}

/// A floor–floor cell (hp20 as robot 1, va1400 as robot 2) whose robot 1 carries compliance, a
/// joint scale and a joint offset in `[robot1.errors]`: terms a URDF cannot hold (the first two).
fn write_error_cell(dir: &Path) -> std::path::PathBuf {
    let text = format!(
        r#"[robot1]
urdf = "{HP20}"
mount = "floor"
tip_mm = [0.0, 0.0, 150.0]

[robot2]
urdf = "{VA1400}"
mount = "floor"
tip_mm = [0.0, 0.0, 120.0]

[b1_from_b2]
xyz_mm = [37.9, 1476.5, 54.5]
zyz_deg = [0.0, 0.0, -44.5]

[robot1.errors]
joint_offset_deg = [0.0, 0.02, -0.01, 0.0, 0.0, 0.0]
joint_scale = [0.0, 2e-4, 0.0, 0.0, 0.0, 0.0]
compliance_deg_per_knm = [0.0, 0.3, 0.3, 0.0, 0.0, 0.0]
tip_mm = [0.0, 0.0, 0.2]
"#
    );
    let path = dir.join("cell.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Joint angles (deg) of the batch tests: three hp20 poses with a lever for gravity.
const BATCH_Q_DEG: [[f64; 6]; 3] = [
    [0.0, 20.0, -10.0, 0.0, 30.0, 0.0],
    [35.5, -15.25, 40.0, 10.0, -45.0, 90.0],
    [-60.0, 45.0, 5.0, -120.0, 20.0, -30.0],
];

fn write_q_csv(dir: &Path) -> std::path::PathBuf {
    let mut text = String::from("pose_id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,note\n");
    for (i, q) in BATCH_Q_DEG.iter().enumerate() {
        let cols: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        text += &format!("P{i},{},hand\n", cols.join(","));
    }
    let path = dir.join("q.csv");
    std::fs::write(&path, text).unwrap();
    path
}

/// Reads `fk --q-csv` output: header and rows of strings.
fn read_out(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

/// `fk --cell --q-csv --cell-tip` equals kinematics::true_base_from_tip with the cell's errors
/// and gravity to 1e-9 m, and differs from the bare URDF by the compliance and scale terms.
#[test]
fn fk_cell_q_csv_equals_true_fk_with_compliance() {
    let dir = tempfile::tempdir().unwrap();
    let cell_path = write_error_cell(dir.path());
    let q_csv = write_q_csv(dir.path());
    let out = dir.path().join("out.csv");
    let run = handclasp(&[
        "fk",
        "--cell",
        cell_path.to_str().unwrap(),
        "--robot",
        "1",
        "--q-csv",
        q_csv.to_str().unwrap(),
        "--id-column",
        "pose_id",
        "--cell-tip",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("ignoring column(s) note"), "{stderr}");
    let (header, rows) = read_out(&out);
    assert_eq!(
        header,
        ["pose_id", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    );
    assert_eq!(rows.len(), BATCH_Q_DEG.len());

    let cell = handclasp_cell::Cell::from_toml_file(&cell_path).unwrap();
    let r1 = &cell.robot1;
    assert!(r1.errors.compliance[1] > 0.0);
    let nominal = RobotModel::from_urdf_file(Path::new(HP20), "tool0").unwrap();
    for (i, (row, q_deg)) in rows.iter().zip(&BATCH_Q_DEG).enumerate() {
        assert_eq!(row[0], format!("P{i}"));
        let v: Vec<f64> = row[1..].iter().map(|x| x.parse().unwrap()).collect();
        let q: Vec<f64> = q_deg.iter().map(|d| d.to_radians()).collect();
        let truth = kinematics::true_base_from_tip(
            &r1.model,
            &r1.errors,
            &q,
            &r1.flange_from_tip,
            &r1.g_base,
        )
        .unwrap();
        let t_mm = truth.translation.vector * 1e3;
        let got_mm = Vector3::new(v[0], v[1], v[2]);
        assert!(
            (got_mm - t_mm).norm() < 1e-9 * 1e3,
            "row {i}: {got_mm} vs {t_mm}"
        );
        let qt = truth.rotation.quaternion();
        let sign = if qt.w < 0.0 { -1.0 } else { 1.0 };
        for (got, want) in v[3..].iter().zip([qt.w, qt.i, qt.j, qt.k]) {
            assert!((got - sign * want).abs() < 1e-12, "row {i}: quaternion");
        }
        let bare = base_from_tip(&nominal, &q, &r1.flange_from_tip).unwrap();
        let gap_mm = (bare.translation.vector * 1e3 - got_mm).norm();
        assert!(
            gap_mm > 0.1,
            "row {i}: the cell's errors moved the tip only {gap_mm} mm"
        );
    }
}

/// Each batch row equals the single-pose `fk --cell --q-deg` of the same angles (the two paths
/// agree), and `--tip-mm` is applied as given in the flange frame.
#[test]
fn fk_cell_q_csv_round_trips_single_pose_fk() {
    let dir = tempfile::tempdir().unwrap();
    let cell_path = write_error_cell(dir.path());
    let q_csv = write_q_csv(dir.path());
    let cell = cell_path.to_str().unwrap();
    let run = handclasp(&[
        "fk",
        "--cell",
        cell,
        "--robot",
        "1",
        "--q-csv",
        q_csv.to_str().unwrap(),
        "--tip-mm",
        "10,-5,150",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = String::from_utf8(run.stdout).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "x_mm,y_mm,z_mm,qw,qx,qy,qz");
    for (line, q_deg) in lines.zip(&BATCH_Q_DEG) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let q_text: Vec<String> = q_deg.iter().map(|d| d.to_string()).collect();
        let single = json_ok(&[
            "fk",
            "--cell",
            cell,
            "--robot",
            "1",
            "--q-deg",
            &q_text.join(","),
            "--tip-mm",
            "10,-5,150",
            "--json",
        ]);
        let xyz = floats(&single["xyz_mm"]);
        for k in 0..3 {
            assert!((v[k] - xyz[k]).abs() < EXACT_MM, "{line} vs {xyz:?}");
        }
        let q = floats(&single["quaternion_wxyz"]);
        let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
        for k in 0..4 {
            assert!((v[3 + k] - sign * q[k]).abs() < 1e-12);
        }
    }
}

/// Bad q files fail naming the line and column: out of limits, not a number, a missing column,
/// a column too many; a radian file is warned about.
#[test]
fn fk_cell_q_csv_errors_name_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let cell_path = write_error_cell(dir.path());
    let cell = cell_path.to_str().unwrap();
    let case = |name: &str, text: &str| -> std::process::Output {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        handclasp(&[
            "fk",
            "--cell",
            cell,
            "--robot",
            "1",
            "--q-csv",
            path.to_str().unwrap(),
        ])
    };
    let head = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n";
    let err = |o: std::process::Output| {
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = err(case(
        "limits.csv",
        &format!("{head}0,0,0,0,0,0\n0,500,0,0,0,0\n"),
    ));
    assert!(
        e.contains("line 3, column `q2_deg`") && e.contains("outside its limits"),
        "{e}"
    );
    // With --out, a bad row (checked before anything is written) leaves no file and no
    // temporary file beside it (the poses are streamed into a temporary file then renamed).
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let out = out_dir.join("poses.csv");
    let e = err(handclasp(&[
        "fk",
        "--cell",
        cell,
        "--robot",
        "1",
        "--q-csv",
        dir.path().join("limits.csv").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(e.contains("line 3, column `q2_deg`"), "{e}");
    assert_eq!(std::fs::read_dir(&out_dir).unwrap().count(), 0);
    let e = err(case("nan.csv", &format!("{head}0,0,NaN,0,0,0\n")));
    assert!(
        e.contains("line 2, column `q3_deg`") && e.contains("not a finite"),
        "{e}"
    );
    let e = err(case("text.csv", &format!("{head}0,0,0,x,0,0\n")));
    assert!(e.contains("line 2, column `q4_deg`"), "{e}");
    let e = err(case(
        "short.csv",
        "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg\n0,0,0,0,0\n",
    ));
    assert!(e.contains("missing column `q6_deg`"), "{e}");
    let e = err(case(
        "long.csv",
        "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,q7_deg\n0,0,0,0,0,0,0\n",
    ));
    assert!(e.contains("`q7_deg`") && e.contains("6 joints"), "{e}");
    let ok = case("radians.csv", &format!("{head}0.1,0.5,-0.3,1.2,0.4,-2.0\n"));
    assert!(ok.status.success());
    let w = String::from_utf8_lossy(&ok.stderr);
    assert!(w.contains("look like radians"), "{w}");
    let e = err(handclasp(&[
        "fk",
        "--cell",
        cell,
        "--robot",
        "3",
        "--q-deg",
        "0,0,0,0,0,0",
    ]));
    assert!(e.contains("1 or 2"), "{e}");
}

/// A tip offset written in metres (0,0,0.15) is refused naming the unit, in fk and ik.
#[test]
fn tip_mm_in_metres_is_refused() {
    let e = stderr_of_failure(&[
        "fk",
        "--robot",
        HP20,
        "--q-deg",
        "0,0,0,0,0,0",
        "--tip-mm",
        "0,0,0.15",
    ]);
    assert!(
        e.contains("looks like metres") && e.contains("0,0,150"),
        "{e}"
    );
    let e = stderr_of_failure(&[
        "ik",
        "--robot",
        HP20,
        "--xyz-mm",
        "1000,0,900",
        "--tip-mm",
        "0,0,0.15",
    ]);
    assert!(e.contains("looks like metres"), "{e}");
}

/// `--verbose` names the URDF joints and links outside the chain (a gripper branch here).
#[test]
fn verbose_lists_ignored_branches() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("branch.urdf");
    std::fs::write(
        &urdf,
        r#"<robot name="arm">
  <link name="base_link"/><link name="tool0"/><link name="gripper"/>
  <joint name="j1" type="revolute"><parent link="base_link"/><child link="tool0"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="gripper_mount" type="fixed"><parent link="base_link"/><child link="gripper"/></joint>
</robot>"#,
    )
    .unwrap();
    let out = handclasp(&[
        "fk",
        "--robot",
        urdf.to_str().unwrap(),
        "--q-deg",
        "10",
        "--verbose",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("joints [gripper_mount]") && e.contains("links [gripper]"),
        "{e}"
    );
    let out = handclasp(&["ik", "--robot", HP20, "--xyz-mm", "1000,0,900", "--verbose"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("no URDF joint or link outside the chain"), "{e}");
}

/// A robot on a rail (`crates/kinematics/tests/fixtures/rail_6r.urdf`: the hp20 on a 4 m track
/// along the floor's x axis turned 0.2 rad about z): the track's value is in millimetres in the
/// `--q-deg` list, the JSON names the units, and the pose is the library's at 1.5 m. Out of travel
/// and metres-looking values are refused or warned about in mm.
#[test]
fn fk_and_ik_take_a_prismatic_joint_in_millimetres() {
    const RAIL: &str = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../kinematics/tests/fixtures/rail_6r.urdf"
    );
    let v = json_ok(&[
        "fk",
        "--robot",
        RAIL,
        "--q-deg",
        "1500,0,10,-20,0,30,0",
        "--json",
    ]);
    let model = RobotModel::from_urdf_file(Path::new(RAIL), "tool0").unwrap();
    let q = [
        1.5,
        0.0,
        10f64.to_radians(),
        -20f64.to_radians(),
        0.0,
        30f64.to_radians(),
        0.0,
    ];
    let want = base_from_tip(&model, &q, &Vector3::zeros())
        .unwrap()
        .translation
        .vector
        * 1e3;
    for (got, want) in floats(&v["xyz_mm"]).iter().zip(want.iter()) {
        assert!((got - want).abs() < EXACT_MM, "{v}");
    }
    let units: Vec<&str> = v["q_units"]
        .as_array()
        .unwrap()
        .iter()
        .map(|u| u.as_str().unwrap())
        .collect();
    assert_eq!(units, ["mm", "deg", "deg", "deg", "deg", "deg", "deg"]);
    // A revolute-only robot's JSON has no q_units.
    let hp20 = json_ok(&["fk", "--robot", HP20, "--q-deg", "0,0,0,0,0,0", "--json"]);
    assert!(hp20.get("q_units").is_none());

    let err = stderr_of_failure(&["fk", "--robot", RAIL, "--q-deg", "4500,0,0,0,0,0,0"]);
    assert!(
        err.contains("is prismatic and 4500 mm, outside its limits 0.000..4000.000 mm"),
        "{err}"
    );
    let out = handclasp(&["fk", "--robot", RAIL, "--q-deg", "0.5,0,0,0,0,0,0"]);
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.starts_with("warning: --q-deg: joint 1 (rail) is prismatic and 0.5 mm"),
        "{stderr}"
    );

    // IK reports the rail in mm, and its answer reaches the target.
    let target = format!("{},{},{}", want.x, want.y, want.z);
    let v = json_ok(&["ik", "--robot", RAIL, "--xyz-mm", &target, "--json"]);
    assert_eq!(v["reachable"], Value::Bool(true));
    assert_eq!(v["q_units"][0], "mm");
    let q_cli = floats(&v["q_deg"]);
    let q_si: Vec<f64> = q_cli
        .iter()
        .enumerate()
        .map(|(i, x)| if i == 0 { x * 1e-3 } else { x.to_radians() })
        .collect();
    let reached = base_from_tip(&model, &q_si, &Vector3::zeros())
        .unwrap()
        .translation
        .vector
        * 1e3;
    assert!((reached - want).norm() < ROUND_TRIP_MM, "{v}");
}

/// `fk --q-csv` on a robot with a prismatic joint reads that joint's column as `qK_mm`
/// (millimetres, as the session file's `rN_qK_mm`) and gives the pose `fk --q-deg` gives; a
/// `qK_deg` column for the prismatic joint is refused naming `qK_mm`. Freezes a silent wrong
/// answer found at stop 34: the batch path read every column as degrees, so a rail's 1500 mm
/// was refused against limits in "degrees" and 0.1 (metres meant) became 1.7 mm.
#[test]
fn fk_q_csv_reads_a_prismatic_joint_in_millimetres() {
    let cell = concat!(env!("CARGO_MANIFEST_DIR"), "/../../cells/rail-tracker.toml");
    let dir = tempfile::tempdir().unwrap();
    let q = "1500,0,10,-20,0,30,0";
    let one = json_ok(&["fk", "--cell", cell, "--robot", "1", "--q-deg", q, "--json"]);
    // `fk --q-csv` of a one-pose file with the first column named `first`.
    let batch = |first: &str| {
        let csv = dir.path().join(format!("rail_{first}.csv"));
        std::fs::write(
            &csv,
            format!("{first},q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,q7_deg\n{q}\n"),
        )
        .unwrap();
        handclasp(&[
            "fk",
            "--cell",
            cell,
            "--robot",
            "1",
            "--q-csv",
            csv.to_str().unwrap(),
        ])
    };
    let out = batch("q1_mm");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let row: Vec<f64> = text.lines().nth(1).unwrap()[..]
        .split(',')
        .take(3)
        .map(|v| v.parse().unwrap())
        .collect();
    for (got, want) in row.iter().zip(floats(&one["xyz_mm"])) {
        assert!((got - want).abs() < EXACT_MM, "{text} vs {one}");
    }
    let wrong = batch("q1_deg");
    assert!(!wrong.status.success());
    let e = String::from_utf8_lossy(&wrong.stderr);
    assert!(e.contains("`q1_mm`") && e.contains("prismatic"), "{e}");
}
