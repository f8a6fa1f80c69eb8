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
