//! End-to-end tests for `handclasp diagnose`: sessions simulated by sim-cell from the shipped
//! cells with a hidden effect, written as CSV, diagnosed by the binary as a user would run it.

use std::path::{Path, PathBuf};

use handclasp_cell::Cell;
use kinematics::ErrorParam;
use sim_cell::{trial_rng, Layout, SessionSpec};

use crate::support::{
    assert_success, cell_session_args, ctu_data_or_skip, ctu_import, floats, handclasp,
    random_session, shipped_cell, stdout_json, write_session_csv,
};

/// The shipped floor–floor cell file (nominal: no errors).
fn cell_path() -> PathBuf {
    shipped_cell("floor-floor")
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
    let s = random_session(&truth, n, seed);
    write_session_csv(dir, &format!("session_{seed}.csv"), &s, &cell)
}

/// A session of `n` points with robot 2's joint-3 offset = `offset_deg` hidden.
fn write_session(dir: &Path, offset_deg: f64, n: usize, seed: u64) -> PathBuf {
    let param = ErrorParam::JointOffset { joint: 2 };
    write_hidden(dir, 2, param, offset_deg.to_radians(), n, seed)
}

/// `handclasp diagnose --json` on the floor–floor cell and `session` (100 Monte Carlo trials); it
/// must succeed and print one JSON object.
fn diagnose_json(session: &Path) -> serde_json::Value {
    stdout_json(&handclasp(&diagnose_args(
        session,
        &["--json", "--trials", "100"],
    )))
}

/// `diagnose --cell <floor–floor> --session <session>` followed by `extra`.
fn diagnose_args(session: &Path, extra: &[&str]) -> Vec<String> {
    cell_session_args("diagnose", &cell_path(), session, extra)
}

/// The 95 % interval `[lo, hi]` of a JSON `effects` entry, in its `unit`.
fn ci95(effect: &serde_json::Value) -> (f64, f64) {
    (
        effect["ci95"][0].as_f64().unwrap(),
        effect["ci95"][1].as_f64().unwrap(),
    )
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
    let (lo, hi) = ci95(hit);
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
    // The coverage of both robots: 40 rows each, robot 1's 7 joints and robot 2's 6.
    assert_coverage(&v["coverage"], Some(40));
}

/// The coverage report `c` of a session of both robots (7 and 6 joints; `rows` rows each when
/// given): each joint's share of its travel in [0, 1] and its range inside its limits, the tool
/// points' radius inside the reach's (1 % slack: the reach is sampled), and the reach's share in
/// the region in [0, 1].
pub(crate) fn assert_coverage(c: &serde_json::Value, rows: Option<u64>) {
    let robots = c["robots"]
        .as_array()
        .unwrap_or_else(|| panic!("coverage: {c}"));
    assert_eq!(robots.len(), 2, "{c}");
    for (r, dof) in robots.iter().zip([7, 6]) {
        if let Some(n) = rows {
            assert_eq!(r["rows"], n, "{r}");
        }
        let joints = r["joints"].as_array().unwrap();
        assert_eq!(joints.len(), dof);
        for j in joints {
            let f = j["fraction"].as_f64().unwrap();
            let (range, limits) = (floats(&j["session_range"]), floats(&j["limits"]));
            assert!((0.0..=1.0).contains(&f), "{j}");
            assert!(limits[0] <= range[0] && range[1] <= limits[1], "{j}");
            assert_eq!(j["unit"], "deg");
        }
        let (s, reach) = (
            floats(&r["session"]["radius_mm"]),
            floats(&r["reach"]["radius_mm"]),
        );
        assert!(reach[0] <= s[0] && s[1] <= reach[1] * 1.01, "{r}");
        let inside = r["reach_fraction_in_region"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&inside), "{r}");
    }
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
    let (lo, hi) = ci95(hit);
    assert!(
        lo <= tilt_deg && tilt_deg <= hi,
        "{tilt_deg}° not in [{lo}, {hi}]"
    );
    assert_eq!(effects.len(), 1, "{v}");
}

#[test]
fn diagnose_noise_only_session_is_clean_in_text() {
    let dir = tempfile::tempdir().unwrap();
    let session = write_session(dir.path(), 0.0, 40, 14);
    let out = handclasp(&diagnose_args(&session, &["--trials", "50"]));
    assert_success(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("no significant effect"), "{text}");
    assert!(text.contains("confounded with the base frame"), "{text}");
}

#[test]
fn diagnose_text_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let session = write_session(dir.path(), 0.2, 40, 12);
    let export = dir.path().join("corrected");
    let out = handclasp(&diagnose_args(
        &session,
        &[
            "--export",
            export.to_str().unwrap(),
            "--trials",
            "50",
            "--truth-xyz-mm",
            "37.9,1476.5,54.5",
            "--truth-zyz-deg",
            "-0.001,0.001,-44.5",
        ],
    ));
    assert_success(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("joint_offset robot 2 joint 3"), "{text}");
    assert!(text.contains("against the truth"), "{text}");
    let urdf2 = std::fs::read_to_string(export.join("robot2_corrected.urdf")).unwrap();
    assert!(urdf2.contains("<calibration rising="));
    let cell2 = std::fs::read_to_string(export.join("cell_corrected.toml")).unwrap();
    assert!(cell2.contains("robot2_corrected.urdf") && cell2.contains("zyz_deg"));
    // Exporting again into the (now non-empty) folder is refused before the diagnosis runs.
    let again = handclasp(&diagnose_args(
        &session,
        &["--export", export.to_str().unwrap()],
    ));
    assert!(!again.status.success());
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.contains("the folder is not empty") && err.contains("--overwrite"),
        "{err}"
    );
    // The exported cell is valid input: diagnosing the same session with it finds nothing.
    let out = handclasp(&cell_session_args(
        "diagnose",
        &export.join("cell_corrected.toml"),
        &session,
        &["--trials", "50"],
    ));
    // The session's tip columns were computed with the old nominal model, so the corrected cell
    // must reject them as inconsistent (it would otherwise silently mix two models).
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("FK"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The verdict at the work site needs the whole-cell diagnosis (its exported model has a
/// posterior): on a session of coincident handclasps `--accept-mm`, `--accept-deg` and
/// `--work-points` are refused naming why and what gives the verdict, and a bad acceptance is
/// refused before anything runs.
#[test]
fn diagnose_refuses_a_verdict_on_a_coincident_session() {
    let dir = tempfile::tempdir().unwrap();
    let session = write_session(dir.path(), 0.0, 20, 17);
    for extra in [&["--accept-mm", "1"][..], &["--accept-deg", "0.1"]] {
        let out = handclasp(&diagnose_args(&session, extra));
        assert!(!out.status.success(), "{extra:?} must be refused");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("coincident rows only") && err.contains("calibrate --cell"),
            "{err}"
        );
    }
    let out = handclasp(&diagnose_args(&session, &["--accept-mm", "0"]));
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--accept-mm"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn diagnose_rejects_bad_sessions_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let session = write_session(dir.path(), 0.0, 40, 13);
    // `diagnose` on the floor–floor cell and `bad`: refused; its stderr.
    let refused = |bad: &Path| {
        let out = handclasp(&diagnose_args(bad, &[]));
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let text = std::fs::read_to_string(&session).unwrap();
    let header = text.lines().next().unwrap();
    let n_q = header.split(',').filter(|h| h.ends_with("_deg")).count();
    // The session with the data fields of the columns `i` where `pick(i)` replaced by
    // `scale(value)`, written as `dir/name`.
    let rescaled = |name: &str, pick: &dyn Fn(usize) -> bool, scale: fn(f64) -> f64| {
        let rows: Vec<String> = text
            .lines()
            .skip(1)
            .map(|l| {
                l.split(',')
                    .enumerate()
                    .map(|(i, f)| {
                        if pick(i) {
                            format!("{}", scale(f.parse::<f64>().unwrap()))
                        } else {
                            f.to_string()
                        }
                    })
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect();
        let path = dir.path().join(name);
        std::fs::write(&path, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
        path
    };
    // Joint angles written in radians under *_deg headers.
    let err = refused(&rescaled(
        "radians.csv",
        &|i| (1..=n_q).contains(&i),
        f64::to_radians,
    ));
    assert!(
        err.contains("radians") && err.contains("radians.csv"),
        "{err}"
    );
    // Tips written in metres under *_mm headers.
    let err = refused(&rescaled("metres.csv", &|i| i > n_q, |mm| mm / 1000.0));
    assert!(
        err.contains("metres") && err.contains("millimetres"),
        "{err}"
    );
    // Too few points: says how many are needed.
    let few = dir.path().join("few.csv");
    let first: Vec<&str> = text.lines().take(4).collect();
    std::fs::write(&few, first.join("\n") + "\n").unwrap();
    let err = refused(&few);
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
    let err = refused(&short);
    assert!(err.contains("joints"), "{err}");
}

/// The value and 95 % interval (mm) of the parameter `name` of the effect `family`, if named.
fn effect_param_mm(
    report: &serde_json::Value,
    family: &str,
    name: &str,
) -> Option<(f64, f64, f64)> {
    let effect = report["effects"]
        .as_array()?
        .iter()
        .find(|e| e["family"]["name"] == family)?;
    let p = effect["parameters"]
        .as_array()?
        .iter()
        .find(|p| p["name"] == name)?;
    let ci = p["ci95_mm"].as_array()?;
    Some((p["value_mm"].as_f64()?, ci[0].as_f64()?, ci[1].as_f64()?))
}

#[test]
fn diagnose_ctu_self_contact_names_the_marker_tip_geometry() {
    let Some(data) = ctu_data_or_skip() else {
        return;
    };
    let cell = shipped_cell("ctu-motoman");
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("self.csv");
    ctu_import(
        &data,
        "self_contact.toml",
        &[
            "no_leica_self_lower1_4x4_dataset.csv",
            "no_leica_self_lower2_4x4_dataset.csv",
            "no_leica_self_upper1_4x4_dataset.csv",
            "no_leica_self_upper2_4x4_dataset.csv",
        ],
        &session,
    );
    let r = stdout_json(&handclasp(&cell_session_args(
        "diagnose",
        &cell,
        &session,
        &["--json"],
    )));
    assert_eq!(r["mode"], "whole_cell");
    assert_eq!(r["rows_by_kind"][0]["rows"], 502, "{}", r["rows_by_kind"]);
    // The end-effector geometry: both marker centres lie off the nominal tip laterally (tool0 x),
    // by 1–2.5 mm (studies/ctu-motoman/docs/findings.md: ~1.3–1.7 mm), each interval excluding 0.
    for (robot, family) in [(1, "robot 1 tool `tip` tip"), (2, "robot 2 tool `tip` tip")] {
        let name = format!("robot {robot} tool `tip` tip x");
        let (v, lo, hi) = effect_param_mm(&r, family, &name)
            .unwrap_or_else(|| panic!("`{family}` not named: {}", r["effects"]));
        assert!((1.0..2.5).contains(&v.abs()), "{name} = {v} mm");
        assert!(lo * hi > 0.0, "{name}: 95 % [{lo}, {hi}] mm contains 0");
    }
    // …and that explains most of the contact-distance scatter on held-out groups.
    let held = |k: &str| r[k][0]["held_out_rms_mm"].as_f64().unwrap();
    let (before, after) = (held("baseline"), held("final_residuals"));
    assert!(
        after < 0.5 * before,
        "held-out contact rms {before} → {after} mm"
    );
}

#[test]
fn diagnose_mixed_session_runs_the_whole_cell_diagnosis() {
    let dir = tempfile::tempdir().unwrap();
    let cell = Cell::from_toml_file(&cell_path()).expect("cell loads");
    let spec = SessionSpec::new(36, Layout::Random, 0.7);
    let kinds = sim_cell::KindSpec {
        kind: sim_cell::SimKind::Mixed,
        ..sim_cell::KindSpec::default()
    };
    let (s, _) = sim_cell::generate_kind_session(&cell, &spec, &kinds, None, &mut trial_rng(4, 0))
        .expect("session");
    let path = write_session_csv(dir.path(), "mixed.csv", &s, &cell);
    let r = stdout_json(&handclasp(&diagnose_args(&path, &["--json"])));
    assert_eq!(r["mode"], "whole_cell");
    let kinds: Vec<&str> = r["baseline"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["contact", "tracker", "plane", "coincident"]);
    assert_coverage(&r["coverage"], None);
    // Added fields: the rejected families (the candidates of the stopping step) and whether the
    // session determines the placement.
    assert_eq!(r["placement_fitted"], true);
    let rejected = r["rejected_families"]
        .as_array()
        .expect("rejected_families");
    assert_eq!(
        rejected.len(),
        r["stopped_candidates_held_out_chi2"]
            .as_array()
            .unwrap()
            .len()
    );
    assert!(rejected
        .iter()
        .all(|f| f["parameters"].is_array() && f["reason"].is_string()));
    // Text, and the export of the fitted cell.
    let export = dir.path().join("exported");
    let export_arg = export.to_str().unwrap();
    let out = handclasp(&diagnose_args(&path, &["--export", export_arg]));
    assert_success(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Whole-cell diagnosis: 36 rows"), "{text}");
    assert!(
        text.contains("Baseline (nominal kinematics, nuisances fitted):"),
        "{text}"
    );
    for f in [
        "robot1_corrected.urdf",
        "robot2_corrected.urdf",
        "cell_corrected.toml",
        "effects.json",
        "report.json",
        "report.txt",
    ] {
        assert!(
            text.contains(&format!("wrote {}", export.join(f).display())),
            "{text}"
        );
    }
    // The exported cell is a cell: `fk --cell` evaluates it.
    let exported = export.join("cell_corrected.toml");
    let q_deg = vec!["5"; cell.robot1.model.dof()].join(",");
    assert_success(&handclasp(&[
        "fk",
        "--cell",
        exported.to_str().unwrap(),
        "--robot",
        "1",
        "--q-deg",
        &q_deg,
    ]));
    // A second export into the now non-empty folder is refused before the diagnosis runs…
    let out = handclasp(&diagnose_args(&path, &["--export", export_arg]));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("the folder is not empty") && err.contains("--overwrite"),
        "{err}"
    );
    // …and done with --overwrite (the same report: the diagnosis is deterministic).
    let again = stdout_json(&handclasp(&diagnose_args(
        &path,
        &["--json", "--export", export_arg, "--overwrite"],
    )));
    assert_eq!(again, r);
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(export.join("report.json")).unwrap())
            .unwrap();
    assert_eq!(written, r);
    // A truth placement is the coincident path's: refused with the reason.
    let out = handclasp(&diagnose_args(
        &path,
        &["--truth-xyz-mm", "0,0,0", "--truth-zyz-deg", "0,0,0"],
    ));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--truth-* applies to coincident-only sessions"),
        "{err}"
    );
}
