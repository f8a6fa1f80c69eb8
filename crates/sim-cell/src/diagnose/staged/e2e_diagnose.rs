//! End-to-end tests for `handclasp diagnose`: sessions simulated from the project's URDFs with a
//! hidden effect, written as CSV, diagnosed by the binary as a user would run it.

use std::path::{Path, PathBuf};
use std::process::Command;

use kinematics::{ErrorParam, KinematicErrors};
use sim_cell::diagnose;

fn write_cell(dir: &Path) -> PathBuf {
    let robots = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let path = dir.join("cell.toml");
    let toml = format!(
        "[robot1]\nurdf = \"{}\"\nmount = \"floor\"\ntip_mm = [0.0, 0.0, 150.0]\n[robot2]\nurdf = \"{}\"\nmount = \"floor\"\ntip_mm = [0.0, 0.0, 120.0]\n[b1_from_b2]\nxyz_mm = [1800.0, 50.0, 0.0]\nzyz_deg = [180.0, 0.0, 0.0]\n[noise]\nalignment_mm = 0.1\n",
        robots.join("va1400.urdf").display(),
        robots.join("hp20.urdf").display()
    );
    std::fs::write(&path, toml).expect("write cell");
    path
}

/// A 40-point session with robot 2's joint-3 offset = `offset_deg` hidden.
fn write_session(dir: &Path, cell_path: &Path, offset_deg: f64, n: usize, seed: u64) -> PathBuf {
    let cell = diagnose::load_cell(cell_path).expect("cell loads");
    let e1 = KinematicErrors::zero(cell.robot1.model.dof());
    let mut e2 = KinematicErrors::zero(cell.robot2.model.dof());
    e2.set(
        ErrorParam::JointOffset { joint: 2 },
        offset_deg.to_radians(),
    );
    let s = diagnose::simulate_session(&cell, &e1, &e2, n, 0.5, seed).expect("session");
    let path = dir.join(format!("session_{seed}.csv"));
    diagnose::write_session_csv(&path, &s).expect("write session");
    path
}

fn handclasp(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_handclasp"))
        .args(args)
        .output()
        .expect("runs handclasp")
}

#[test]
fn diagnose_names_a_hidden_joint_offset_in_json() {
    let dir = tempfile::tempdir().unwrap();
    let cell = write_cell(dir.path());
    let session = write_session(dir.path(), &cell, 0.2, 40, 11);
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        session.to_str().unwrap(),
        "--json",
        "--trials",
        "100",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let effects = v["effects"].as_array().expect("effects");
    let hit = effects
        .iter()
        .find(|e| e["kind"] == "joint_offset" && e["robot"] == 2 && e["joint"] == 3)
        .unwrap_or_else(|| panic!("joint 3 offset of robot 2 not named: {v}"));
    assert_eq!(hit["unit"], "deg");
    assert!(hit["axis"].is_null());
    let (lo, hi) = (
        hit["ci95"][0].as_f64().unwrap(),
        hit["ci95"][1].as_f64().unwrap(),
    );
    assert!(lo <= 0.2 && 0.2 <= hi, "0.2° not in [{lo}, {hi}]");
    for key in [
        "rms_before_mm",
        "rms_after_mm",
        "heldout_rms_before_mm",
        "heldout_rms_after_mm",
    ] {
        assert!(v[key].as_f64().is_some(), "{key} missing");
    }
    assert!(
        v["heldout_rms_after_mm"].as_f64().unwrap() < v["heldout_rms_before_mm"].as_f64().unwrap()
    );
    assert_eq!(v["b1_from_b2"]["xyz_mm"].as_array().unwrap().len(), 3);
    assert_eq!(v["b1_from_b2"]["zyz_deg"].as_array().unwrap().len(), 3);
}

#[test]
fn diagnose_text_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let cell = write_cell(dir.path());
    let session = write_session(dir.path(), &cell, 0.2, 40, 12);
    let export = dir.path().join("corrected");
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        session.to_str().unwrap(),
        "--export",
        export.to_str().unwrap(),
        "--trials",
        "50",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("joint_offset robot 2 joint 3"), "{text}");
    let urdf2 = std::fs::read_to_string(export.join("robot2_corrected.urdf")).unwrap();
    assert!(urdf2.contains("<calibration rising="));
    let cell2 = std::fs::read_to_string(export.join("cell_corrected.toml")).unwrap();
    assert!(cell2.contains("robot2_corrected.urdf") && cell2.contains("zyz_deg"));
}

#[test]
fn diagnose_rejects_bad_sessions_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let cell = write_cell(dir.path());
    let session = write_session(dir.path(), &cell, 0.0, 40, 13);
    let text = std::fs::read_to_string(&session).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    // Joint angles written in radians under *_deg headers.
    let n1 = header
        .split(',')
        .filter(|h| h.starts_with("r1_q") || h.starts_with("r2_q"))
        .count();
    let rad: Vec<String> = lines
        .clone()
        .map(|l| {
            l.split(',')
                .enumerate()
                .map(|(i, f)| {
                    if (1..=n1).contains(&i) {
                        format!("{}", f.parse::<f64>().unwrap().to_radians())
                    } else {
                        f.to_string()
                    }
                })
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    let bad = dir.path().join("radians.csv");
    std::fs::write(&bad, format!("{header}\n{}\n", rad.join("\n"))).unwrap();
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        bad.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("radians"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Too few points: says how many are needed.
    let few = dir.path().join("few.csv");
    let first: Vec<&str> = text.lines().take(4).collect();
    std::fs::write(&few, first.join("\n") + "\n").unwrap();
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        few.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("at least"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A joint column missing: the joint counts do not match the URDFs.
    let cut: Vec<String> = text
        .lines()
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| *i != 1)
                .map(|(_, f)| f)
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    let short = dir.path().join("short.csv");
    std::fs::write(&short, cut.join("\n") + "\n").unwrap();
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        short.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("joint"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
