//! End-to-end tests for `handclasp diagnose`: sessions simulated by sim-cell from the shipped
//! cells with a hidden effect, written as CSV, diagnosed by the binary as a user would run it.

use std::path::{Path, PathBuf};
use std::process::Command;

use kinematics::ErrorParam;
use sim_cell::{generate_session, trial_rng, Cell, Layout, SessionSpec};

/// The shipped floor–floor cell file (nominal: no errors).
fn cell_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../cells/floor-floor.toml")
}

/// A session of `n` points on the shipped floor–floor cell with `param` of robot `robot` set to
/// `value` (SI units) in the true robot; the CSV reports what the nominal model believes.
fn write_hidden(
    dir: &Path,
    robot: u8,
    param: ErrorParam,
    value: f64,
    n: usize,
    seed: u64,
) -> PathBuf {
    let cell = Cell::from_toml_file(&cell_path()).expect("cell loads");
    let mut truth = cell.clone();
    let errors = if robot == 1 {
        &mut truth.robot1.errors
    } else {
        &mut truth.robot2.errors
    };
    errors.set(param, value);
    let spec = SessionSpec::new(n, Layout::Random, 0.8);
    let s = generate_session(&truth, &spec, &mut trial_rng(seed, 0)).expect("session");
    let path = dir.join(format!("session_{seed}.csv"));
    s.write_csv(&path, &cell).expect("write session");
    path
}

/// A session of `n` points with robot 2's joint-3 offset = `offset_deg` hidden.
fn write_session(dir: &Path, offset_deg: f64, n: usize, seed: u64) -> PathBuf {
    let param = ErrorParam::JointOffset { joint: 2 };
    write_hidden(dir, 2, param, offset_deg.to_radians(), n, seed)
}

/// `handclasp diagnose --json` on the floor–floor cell and `session` (100 Monte Carlo trials); it
/// must succeed and print one JSON object.
fn diagnose_json(session: &Path) -> serde_json::Value {
    let cell = cell_path();
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
    serde_json::from_slice(&out.stdout).expect("one JSON object")
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
    let v = diagnose_json(&write_session(dir.path(), 0.2, 40, 11));
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

/// A hidden tilt of robot 1's base (−0.12° about its y axis) is named in the JSON `effects` from
/// the placement check: kind `mount_tilt`, robot 1, axis "y", unit deg, interval covering it.
#[test]
fn diagnose_names_a_hidden_mount_tilt_in_json() {
    let dir = tempfile::tempdir().unwrap();
    let tilt_deg = -0.12f64;
    let param = ErrorParam::MountRpy {
        axis: kinematics::Axis::Y,
    };
    let v = diagnose_json(&write_hidden(
        dir.path(),
        1,
        param,
        tilt_deg.to_radians(),
        40,
        21,
    ));
    let effects = v["effects"].as_array().expect("effects");
    let hit = effects
        .iter()
        .find(|e| e["kind"] == "mount_tilt" && e["robot"] == 1 && e["axis"] == "y")
        .unwrap_or_else(|| panic!("robot 1's y tilt not named: {v}"));
    assert_eq!(hit["unit"], "deg");
    assert!(hit["joint"].is_null());
    let (lo, hi) = (
        hit["ci95"][0].as_f64().unwrap(),
        hit["ci95"][1].as_f64().unwrap(),
    );
    assert!(
        lo <= tilt_deg && tilt_deg <= hi,
        "{tilt_deg}° not in [{lo}, {hi}]"
    );
    assert_eq!(effects.len(), 1, "{v}");
}

#[test]
fn diagnose_noise_only_session_is_clean_in_text() {
    let dir = tempfile::tempdir().unwrap();
    let cell = cell_path();
    let session = write_session(dir.path(), 0.0, 40, 14);
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        session.to_str().unwrap(),
        "--trials",
        "50",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("no significant effect"), "{text}");
    assert!(text.contains("confounded with the base frame"), "{text}");
}

#[test]
fn diagnose_text_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let cell = cell_path();
    let session = write_session(dir.path(), 0.2, 40, 12);
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
        "--truth-xyz-mm",
        "37.9,1476.5,54.5",
        "--truth-zyz-deg",
        "-0.001,0.001,-44.5",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("joint_offset robot 2 joint 3"), "{text}");
    assert!(text.contains("against the truth"), "{text}");
    let urdf2 = std::fs::read_to_string(export.join("robot2_corrected.urdf")).unwrap();
    assert!(urdf2.contains("<calibration rising="));
    let cell2 = std::fs::read_to_string(export.join("cell_corrected.toml")).unwrap();
    assert!(cell2.contains("robot2_corrected.urdf") && cell2.contains("zyz_deg"));
    // The exported cell is valid input: diagnosing the same session with it finds nothing.
    let out = handclasp(&[
        "diagnose",
        "--cell",
        export.join("cell_corrected.toml").to_str().unwrap(),
        "--session",
        session.to_str().unwrap(),
        "--trials",
        "50",
    ]);
    // The session's tip columns were computed with the old nominal model, so the corrected cell
    // must reject them as inconsistent (it would otherwise silently mix two models).
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("FK"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn diagnose_rejects_bad_sessions_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let cell = cell_path();
    let session = write_session(dir.path(), 0.0, 40, 13);
    let text = std::fs::read_to_string(&session).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let n_q = header.split(',').filter(|h| h.ends_with("_deg")).count();
    // Joint angles written in radians under *_deg headers.
    let rad: Vec<String> = lines
        .clone()
        .map(|l| {
            l.split(',')
                .enumerate()
                .map(|(i, f)| {
                    if (1..=n_q).contains(&i) {
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
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("radians") && err.contains("radians.csv"),
        "{err}"
    );
    // Tips written in metres under *_mm headers.
    let metres: Vec<String> = text
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .enumerate()
                .map(|(i, f)| {
                    if i > n_q {
                        format!("{}", f.parse::<f64>().unwrap() / 1000.0)
                    } else {
                        f.to_string()
                    }
                })
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    let bad = dir.path().join("metres.csv");
    std::fs::write(&bad, format!("{header}\n{}\n", metres.join("\n"))).unwrap();
    let out = handclasp(&[
        "diagnose",
        "--cell",
        cell.to_str().unwrap(),
        "--session",
        bad.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("metres") && err.contains("millimetres"),
        "{err}"
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
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("at least"), "{err}");
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
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("joints"), "{err}");
}
