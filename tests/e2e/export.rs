//! End-to-end tests for `handclasp export --cell CELL --to DIR`: every target's files on the
//! shipped cells and on cells written by `calibrate --cell --export` and `diagnose --export`, the
//! folder rule, and the independent SciPy check (`tools/export_check.py`, skipped with a printed
//! reason where Python lacks numpy/scipy; `HANDCLASP_PYTHON` names the interpreter).

use std::path::{Path, PathBuf};
use std::process::Command;

use calib_core::Robot;
use handclasp_cell::Cell;
use kinematics::{base_from_flange, RobotModel};
use serde_json::Value;

use crate::support::{
    assert_success, cell_session_args, handclasp, json_ok, random_session, shipped_cell,
    stderr_of_failure, workspace, write_session_csv,
};

const SHIPPED: [&str; 4] = ["floor-wall", "floor-floor", "floor-ceiling", "ctu-motoman"];

fn export_json(cell: &Path, to: &Path) -> Value {
    json_ok(&[
        "export",
        "--cell",
        cell.to_str().unwrap(),
        "--to",
        to.to_str().unwrap(),
        "--json",
    ])
}

/// The keys of a JSON object, sorted (serde_json's map is sorted; the comparison is of sets).
fn keys(v: &Value) -> Vec<&str> {
    let mut k: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    k.sort_unstable();
    k
}

fn sorted(mut v: Vec<&str>) -> Vec<&str> {
    v.sort_unstable();
    v
}

#[test]
fn shipped_cells_every_format_with_the_documented_json() {
    let dir = tempfile::tempdir().unwrap();
    for name in SHIPPED {
        let to = dir.path().join(name);
        let v = export_json(&shipped_cell(name), &to);
        let f = &v["formats"];
        assert_eq!(
            keys(f),
            sorted(vec!["abb", "kuka", "fanuc", "yaskawa", "ros2"]),
            "{v}"
        );
        let want: [(&str, &[&str]); 5] = [
            ("abb", &["x_m", "y_m", "z_m", "q1", "q2", "q3", "q4"]),
            ("kuka", &["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"]),
            (
                "fanuc",
                &["x_mm", "y_mm", "z_mm", "w_deg", "p_deg", "r_deg"],
            ),
            (
                "yaskawa",
                &["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"],
            ),
            ("ros2", &["x_m", "y_m", "z_m", "qx", "qy", "qz", "qw"]),
        ];
        for (target, fields) in want {
            assert_eq!(keys(&f[target]), sorted(fields.to_vec()), "{target}");
        }
        assert!(f["abb"]["q1"].as_f64().unwrap() >= 0.0);
        let files = v["files"].as_array().unwrap();
        assert_eq!(files.len(), 7);
        for file in files {
            assert!(Path::new(file["path"].as_str().unwrap()).is_file());
            assert!(file["read_back_um"].as_f64().unwrap() <= 1.0);
            assert!(file["read_back_urad"].as_f64().unwrap() <= 1.0);
        }
        // Each file names its convention at the top.
        let fanuc = std::fs::read_to_string(to.join("fanuc_user_frame.txt")).unwrap();
        let top: Vec<&str> = fanuc.lines().take(6).collect();
        assert!(
            fanuc.starts_with("! ") && top.join("\n").contains("R = Rz(R)*Ry(P)*Rx(W)"),
            "{fanuc}"
        );
    }
}

#[test]
fn folder_rule_format_subset_and_text() {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join("out");
    let cell = shipped_cell("floor-wall");
    let out = handclasp(&[
        "export",
        "--cell",
        cell.to_str().unwrap(),
        "--to",
        to.to_str().unwrap(),
        "--format",
        "kuka,ros2",
    ]);
    assert_success(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("A B C (deg)") && text.contains("qx qy qz qw"),
        "{text}"
    );
    assert!(
        !text.contains("W P R") && text.contains("docs/guide/export.md"),
        "{text}"
    );
    assert_eq!(std::fs::read_dir(&to).unwrap().count(), 4);
    // A second export into the now non-empty folder is refused, naming --to and --force …
    let args = [
        "export",
        "--cell",
        cell.to_str().unwrap(),
        "--to",
        to.to_str().unwrap(),
        "--format",
        "fanuc",
    ];
    let err = stderr_of_failure(&args);
    assert!(err.contains("--to") && err.contains("--force"), "{err}");
    // … and allowed with --force.
    let mut forced = args.to_vec();
    forced.push("--force");
    assert_success(&handclasp(&forced));
    assert_eq!(std::fs::read_dir(&to).unwrap().count(), 5);
    let err = stderr_of_failure(&[
        "export",
        "--cell",
        "nope.toml",
        "--to",
        "x",
        "--format",
        "staubli",
    ]);
    assert!(err.contains("staubli"), "{err}");
}

/// The floor–floor cell with a 0.1° offset on robot 2's joint 3 (URDF paths absolute).
fn cell_with_errors(dir: &Path) -> PathBuf {
    let robots = workspace("robots/");
    let mut text = std::fs::read_to_string(shipped_cell("floor-floor"))
        .unwrap()
        .replace("../robots/", &format!("{}/", robots.display()));
    text += "\n[robot2.errors]\njoint_offset_deg = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0]\n";
    let path = dir.join("truth.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The chains of `cell.urdf` against the exported cell's own URDFs and placement: the cell URDF
/// carries the calibrated joint origins.
fn assert_cell_urdf_matches(cell_toml: &Path, exported: &Path) {
    let cell = Cell::from_toml_file(cell_toml).unwrap();
    let xml = std::fs::read_to_string(exported.join("cell.urdf")).unwrap();
    for (robot, prefix) in [(Robot::One, "robot1_"), (Robot::Two, "robot2_")] {
        let setup = cell.robot(robot);
        let loaded =
            RobotModel::from_urdf_str(&xml, &format!("{prefix}{}", setup.tool_link)).unwrap();
        let placed = *loaded.root_from_base().unwrap();
        let want = if robot == Robot::One {
            nalgebra::Isometry3::identity()
        } else {
            cell.b1_from_b2
        };
        assert!((placed.translation.vector - want.translation.vector).norm() < 1e-12);
        assert!(placed.rotation.angle_to(&want.rotation) < 1e-12);
        let q: Vec<f64> = setup
            .model
            .joints()
            .iter()
            .map(|j| 0.3 * j.lower + 0.1 * j.upper)
            .collect();
        let a = base_from_flange(&setup.model, &q).unwrap();
        let b = base_from_flange(&loaded, &q).unwrap();
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-12);
    }
}

#[test]
fn calibrated_and_diagnosed_cells_export() {
    let dir = tempfile::tempdir().unwrap();
    let truth_path = cell_with_errors(dir.path());
    let truth = Cell::from_toml_file(&truth_path).unwrap();
    let nominal = Cell::from_toml_file(&shipped_cell("floor-floor")).unwrap();
    let session = write_session_csv(
        dir.path(),
        "s.csv",
        &random_session(&truth, 30, 5),
        &nominal,
    );
    let nominal_path = shipped_cell("floor-floor");
    let cal = dir.path().join("cal");
    json_ok(&cell_session_args(
        "calibrate",
        &nominal_path,
        &session,
        &[
            "--model",
            "kinematic",
            "--json",
            "--export",
            cal.to_str().unwrap(),
        ],
    ));
    let diag = dir.path().join("diag");
    assert_success(&handclasp(&cell_session_args(
        "diagnose",
        &nominal_path,
        &session,
        &["--trials", "50", "--export", diag.to_str().unwrap()],
    )));
    for cell_toml in [cal.join("cell.toml"), diag.join("cell_corrected.toml")] {
        let to = dir.path().join(format!(
            "x-{}",
            cell_toml
                .parent()
                .unwrap()
                .file_name()
                .unwrap()
                .to_string_lossy()
        ));
        let v = export_json(&cell_toml, &to);
        // The placement exported is the calibrated one.
        let cell = Cell::from_toml_file(&cell_toml).unwrap();
        let k = &v["formats"]["kuka"];
        assert!((k["x_mm"].as_f64().unwrap() - cell.b1_from_b2.translation.x * 1e3).abs() < 1e-9);
        assert_cell_urdf_matches(&cell_toml, &to);
        check_independently(std::slice::from_ref(&cell_toml));
    }
}

/// Runs tools/export_check.py on `cells` when a Python with numpy and scipy is there.
fn check_independently(cells: &[PathBuf]) {
    let python = std::env::var("HANDCLASP_PYTHON").unwrap_or_else(|_| "python3".into());
    let probe = Command::new(&python)
        .args(["-c", "import numpy, scipy"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        eprintln!(
            "skipped: the independent SciPy check needs `{python}` with numpy and scipy \
             (set HANDCLASP_PYTHON to a venv's python; see tools/export_check.py)"
        );
        return;
    }
    let mut cmd = Command::new(&python);
    cmd.arg(workspace("tools/export_check.py"))
        .args(["--handclasp", env!("CARGO_BIN_EXE_handclasp")])
        .args(cells);
    let out = cmd.output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("AGREE"),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{}", text.lines().last().unwrap_or(""));
}

#[test]
fn shipped_cells_agree_with_scipy() {
    let cells: Vec<PathBuf> = SHIPPED.iter().map(|n| shipped_cell(n)).collect();
    check_independently(&cells);
}

/// Largest difference between a rotation matrix rebuilt by hand from an exported file's numbers
/// and the cell's (1e-9, far below the files' 1 µrad read-back tolerance: the files carry 1e-9°
/// and 1e-12 quaternion components).
const HAND_ROTATION_TOL: f64 = 1e-9;

/// `Rz(a)·Ry(b)·Rx(c)` with the elementary matrices written out (angles in degrees): a second
/// formula, not the kinematics crate's.
fn rz_ry_rx(a_deg: f64, b_deg: f64, c_deg: f64) -> [[f64; 3]; 3] {
    let (a, b, c) = (a_deg.to_radians(), b_deg.to_radians(), c_deg.to_radians());
    let rz = [
        [a.cos(), -a.sin(), 0.0],
        [a.sin(), a.cos(), 0.0],
        [0.0, 0.0, 1.0],
    ];
    let ry = [
        [b.cos(), 0.0, b.sin()],
        [0.0, 1.0, 0.0],
        [-b.sin(), 0.0, b.cos()],
    ];
    let rx = [
        [1.0, 0.0, 0.0],
        [0.0, c.cos(), -c.sin()],
        [0.0, c.sin(), c.cos()],
    ];
    let mul = |p: [[f64; 3]; 3], q: [[f64; 3]; 3]| {
        let mut m = [[0.0; 3]; 3];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|k| p[i][k] * q[k][j]).sum();
            }
        }
        m
    };
    mul(mul(rz, ry), rx)
}

/// The rotation matrix of a unit quaternion (w, x, y, z), the textbook closed form.
fn quaternion_matrix(w: f64, x: f64, y: f64, z: f64) -> [[f64; 3]; 3] {
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Every two-robot shipped cell (the coupled humanoid and its shared-trunk variant included)
/// exports, and each format's numbers rebuild the cell's `b1_from_b2` by a second, hand-written
/// formula (no SciPy needed): KUKA A B C as Rz·Ry·Rx, Fanuc W P R and Yaskawa Rx Ry Rz as the
/// same product about fixed axes, ABB's and ROS 2's quaternions by the closed-form matrix, the
/// translations in mm and m. A one-robot cell is refused, naming why and what to use.
#[test]
fn every_shipped_cell_agrees_with_a_hand_written_conversion() {
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "floor-wall",
        "floor-floor",
        "floor-ceiling",
        "ctu-motoman",
        "humanoid",
        "humanoid-trunk",
    ] {
        let path = shipped_cell(name);
        let cell = Cell::from_toml_file(&path).unwrap();
        let v = export_json(&path, &dir.path().join(name));
        let f = &v["formats"];
        let n = |o: &Value, k: &str| o[k].as_f64().unwrap_or_else(|| panic!("{name}: {k}: {o}"));
        let want = cell.b1_from_b2.rotation.to_rotation_matrix();
        let t = cell.b1_from_b2.translation.vector;
        let (k, fa, y, a, r) = (
            &f["kuka"],
            &f["fanuc"],
            &f["yaskawa"],
            &f["abb"],
            &f["ros2"],
        );
        let matrices = [
            (
                "kuka",
                rz_ry_rx(n(k, "a_deg"), n(k, "b_deg"), n(k, "c_deg")),
            ),
            (
                "fanuc",
                rz_ry_rx(n(fa, "r_deg"), n(fa, "p_deg"), n(fa, "w_deg")),
            ),
            (
                "yaskawa",
                rz_ry_rx(n(y, "rz_deg"), n(y, "ry_deg"), n(y, "rx_deg")),
            ),
            (
                "abb",
                quaternion_matrix(n(a, "q1"), n(a, "q2"), n(a, "q3"), n(a, "q4")),
            ),
            (
                "ros2",
                quaternion_matrix(n(r, "qw"), n(r, "qx"), n(r, "qy"), n(r, "qz")),
            ),
        ];
        for (format, m) in matrices {
            for (i, row) in m.iter().enumerate() {
                for (j, got) in row.iter().enumerate() {
                    assert!(
                        (got - want[(i, j)]).abs() < HAND_ROTATION_TOL,
                        "{name} {format}: R[{i}][{j}] {got} vs {}",
                        want[(i, j)]
                    );
                }
            }
        }
        assert!(n(a, "q1") >= 0.0, "{name}: ABB q1 ≥ 0");
        for (format, o, keys, per_m) in [
            ("kuka", k, ["x_mm", "y_mm", "z_mm"], 1e3),
            ("fanuc", fa, ["x_mm", "y_mm", "z_mm"], 1e3),
            ("yaskawa", y, ["x_mm", "y_mm", "z_mm"], 1e3),
            ("abb", a, ["x_m", "y_m", "z_m"], 1.0),
            ("ros2", r, ["x_m", "y_m", "z_m"], 1.0),
        ] {
            for (axis, key) in keys.iter().enumerate() {
                // 1 nm: the files' last decimal.
                assert!(
                    (n(o, key) / per_m - t[axis]).abs() < 1e-9,
                    "{name} {format}: {key}"
                );
            }
        }
    }
    let e = stderr_of_failure(&[
        "export",
        "--cell",
        shipped_cell("rail-tracker").to_str().unwrap(),
        "--to",
        dir.path().join("rail").to_str().unwrap(),
    ]);
    assert!(
        e.contains("one-robot cell") && e.contains("robot1.urdf"),
        "{e}"
    );
    let written = std::fs::read_dir(dir.path().join("rail"))
        .map(|d| d.count())
        .unwrap_or(0);
    assert_eq!(written, 0, "no file written: {e}");
}
