//! End-to-end tests for `handclasp validate`: a cell calibrated by `calibrate --cell --export`
//! on one simulated session, scored on sessions of the same truth it never saw (coincident
//! handclasps; and every kind, with the tracker frame, plane and contact distance refitted on
//! half their rows or carried over from the calibration session), against the nominal cell.

use std::path::{Path, PathBuf};

use handclasp_cell::{Cell, Session};
use serde_json::Value;
use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

use crate::calibrate_cell::write_cell;
use crate::support::{
    assert_success, handclasp, random_session, stderr_of_failure, stdout_json, write_session_csv,
    RANDOM_SPREAD_M,
};

/// A mixed session (coincident, contact, tracker and plane rows in turn) of `2·n`
/// random-layout rows on `truth` (one tracker frame, one plane, one contact distance), cut into
/// its first `n` rows and the others, written with their nominal tips as `train.csv` and
/// `held.csv`.
fn mixed_sessions(dir: &Path, truth: &Cell, n: usize, seed: u64) -> [PathBuf; 2] {
    let spec = SessionSpec::new(2 * n, Layout::Random, RANDOM_SPREAD_M);
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        ..KindSpec::default()
    };
    let (s, _) = generate_kind_session(truth, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .expect("mixed session");
    let part = |first: bool| Session {
        points: s
            .points
            .iter()
            .filter(|p| (p.point <= n) == first)
            .cloned()
            .collect(),
        observations: s
            .observations
            .iter()
            .filter(|o| (o.point <= n) == first)
            .cloned()
            .collect(),
        ..Session::default()
    };
    [
        write_session_csv(dir, "train.csv", &part(true), truth),
        write_session_csv(dir, "held.csv", &part(false), truth),
    ]
}

fn validate(args: &[&str]) -> (Value, String) {
    let out = handclasp(&[&["validate"], args, &["--json"]].concat());
    assert_success(&out);
    (
        stdout_json(&out),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn calibrated_cell_beats_nominal_on_held_out_sessions() {
    let dir = tempfile::tempdir().unwrap();
    let truth_path = write_cell(dir.path(), 11);
    let truth = Cell::from_toml_file(&truth_path).unwrap();
    // The nominal cell: the truth's text without its hidden [robotN.errors].
    let text = std::fs::read_to_string(&truth_path).unwrap();
    let nominal_path = dir.path().join("nominal.toml");
    std::fs::write(
        &nominal_path,
        &text[..text.find("\n[robot1.errors]").unwrap()],
    )
    .unwrap();
    // Calibrated on 40 mixed rows; 40 more of the same session (same tracker frame, plane and
    // contact distance, other poses) held out.
    let [train, mixed] = mixed_sessions(dir.path(), &truth, 40, 3);
    let out = dir.path().join("cal");
    let calibrated = handclasp(&[
        "calibrate",
        "--cell",
        truth_path.to_str().unwrap(),
        "--session",
        train.to_str().unwrap(),
        "--export",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert_success(&calibrated);
    // calibrate --cell reports the session's coverage.
    crate::diagnose::assert_coverage(&stdout_json(&calibrated)["coverage"], None);
    let cal_cell = out.join("cell.toml");
    let (cal_cell, truth_s) = (cal_cell.to_str().unwrap(), nominal_path.to_str().unwrap());

    // Held-out coincident handclasps: the coincident kind and the one unit of coincident rows.
    let coincident = random_session(&truth, 20, 1003);
    let held = write_session_csv(dir.path(), "coincident.csv", &coincident, &truth);
    let (v, stderr) = validate(&[
        "--cell",
        cal_cell,
        "--session",
        held.to_str().unwrap(),
        "--nominal",
        truth_s,
    ]);
    assert!(!stderr.contains("warning:"), "{stderr}");
    assert_eq!(v["by_kind"].as_array().unwrap().len(), 1);
    assert_eq!(v["by_kind"][0]["kind"], "coincident");
    assert_eq!(v["by_kind"][0]["rows"], 20);
    assert_eq!(v["nuisance"], "split");
    // The calibration's gain (seeded; measured 0.5–0.6 here): well below nominal.
    let ratio = f(&v["all"]["rms_ratio"]);
    assert!(ratio < 0.8, "calibrated / nominal rms {ratio}: {v}");
    assert!(
        (ratio - f(&v["all"]["calibrated"]["rms_mm"]) / f(&v["all"]["nominal"]["rms_mm"])).abs()
            < 1e-12
    );

    // Held-out rows of every kind, nuisances split and carried over: better in every group.
    for extra in [
        &[][..],
        &[
            "--nuisance",
            "fixed",
            "--calibration-session",
            train.to_str().unwrap(),
        ][..],
    ] {
        let (v, stderr) = validate(
            &[
                &[
                    "--cell",
                    cal_cell,
                    "--session",
                    mixed.to_str().unwrap(),
                    "--nominal",
                    truth_s,
                ][..],
                extra,
            ]
            .concat(),
        );
        let kinds: Vec<&str> = v["by_kind"]
            .as_array()
            .unwrap()
            .iter()
            .map(|u| u["kind"].as_str().unwrap())
            .collect();
        assert_eq!(kinds, ["coincident", "contact", "tracker", "plane"], "{v}");
        let groups = v["by_group"].as_array().unwrap();
        assert_eq!(groups.len(), 4, "{v}");
        // One per named group, then the coincident rows.
        let mut names: Vec<&str> = groups[..3]
            .iter()
            .map(|g| g["group"].as_str().unwrap())
            .collect();
        names.sort_unstable();
        assert_eq!(names, ["contact", "plane", "tracker"], "{v}");
        assert!(groups[3]["group"].is_null() && groups[3]["kind"] == "coincident");
        for g in groups {
            assert!(f(&g["rms_ratio"]) < 1.0, "{extra:?}: {g}");
        }
        assert_eq!(v["groups_improved"], serde_json::json!([4, 4]));
        assert!(f(&v["all"]["rms_ratio"]) < 0.8, "{extra:?}: {v}");
        // Within 3 times the stated noise (measured 1.7 with split nuisances): no warning.
        assert!(f(&v["all"]["calibrated"]["whitened_rms"]) < 3.0, "{v}");
        assert!(!stderr.contains("warning:"), "{stderr}");
    }

    // The text report names the units and the verdict.
    let text = handclasp(&[
        "validate",
        "--cell",
        cal_cell,
        "--session",
        mixed.to_str().unwrap(),
        "--nominal",
        truth_s,
    ]);
    assert_success(&text);
    let text = String::from_utf8_lossy(&text.stdout);
    for want in [
        "by kind:",
        "tracker \"tracker\"",
        "coincident rows",
        "the calibrated cell is better than nominal in 4 of 4 groups",
    ] {
        assert!(text.contains(want), "{want} in {text}");
    }

    // The nominal cell scored as if it were a calibration, against the calibrated one: worse,
    // and said so.
    let (v, stderr) = validate(&[
        "--cell",
        truth_s,
        "--session",
        mixed.to_str().unwrap(),
        "--nominal",
        cal_cell,
    ]);
    assert!(f(&v["all"]["rms_ratio"]) > 1.0, "{v}");
    // The nominal cell's rows are many times the stated noise (measured 17 with split
    // nuisances), and said so.
    assert!(f(&v["all"]["calibrated"]["whitened_rms"]) > 3.0, "{v}");
    assert!(
        stderr.contains("times the stated noise") && stderr.contains("(the nominal cell: "),
        "{stderr}"
    );
    assert!(
        stderr
            .contains("warning: the calibrated cell fits this session worse than the nominal cell"),
        "{stderr}"
    );

    // Refusals name the fix.
    let err = stderr_of_failure(&[
        "validate",
        "--cell",
        cal_cell,
        "--session",
        mixed.to_str().unwrap(),
        "--nuisance",
        "fixed",
    ]);
    assert!(err.contains("--calibration-session"), "{err}");
    // A session recorded with the nominal models, read with the calibrated cell alone.
    let err = stderr_of_failure(&[
        "validate",
        "--cell",
        cal_cell,
        "--session",
        held.to_str().unwrap(),
    ]);
    assert!(err.contains("--nominal"), "{err}");
}
