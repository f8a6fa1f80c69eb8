//! End-to-end tests of the result check of `calibrate --cell` (issue 21): each likely mistake,
//! made on a session simulated by sim-cell's library (`generate_session`, as `sim-cell session`
//! does) and written with the tips the reported cell's models give (what the controllers
//! report), must end in a refusal or a `warning:` line that names it; the healthy counterparts
//! (a correct session, the paper's noise level, 3 % random blunders) must stay quiet.
//! Run with `--nocapture` to see the table mistake → message.

use std::path::{Path, PathBuf};
use std::process::Output;

use handclasp_cell::{Cell, Session};
use kinematics::base_from_tip;
use nalgebra::Point3;
use serde_json::Value;

use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

use crate::support::{
    cell_session_args, handclasp, random_session, shipped_cell, workspace, write_session_csv,
    RANDOM_SPREAD_M,
};

/// A temporary folder for one test; kept (its path printed) when `RESULT_CHECK_KEEP` is set,
/// so that the sessions can be given to another build (the table before/after).
pub(crate) fn workdir() -> tempfile::TempDir {
    let mut dir = tempfile::tempdir().unwrap();
    if std::env::var_os("RESULT_CHECK_KEEP").is_some() {
        dir.disable_cleanup(true);
        eprintln!("kept {}", dir.path().display());
    }
    dir
}

/// Points per session: the sessions had 40.
const N: usize = 40;

/// The example truth (docs/examples/truth.toml: the floor-wall cell with tolerance-sized
/// errors and robot 2's joint 2 zero 0.15° off).
pub(crate) fn truth() -> Cell {
    Cell::from_toml_file(&workspace("docs/examples/truth.toml")).expect("truth cell")
}

/// A shipped cell's text with `edit` applied, then its URDF paths made absolute, written to
/// `dir/name`.
fn cell_variant(dir: &Path, shipped: &str, name: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let robots = workspace("robots/");
    let text = edit(std::fs::read_to_string(shipped_cell(shipped)).unwrap())
        .replace("../robots/", &format!("{}/", robots.display()));
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `session` with each point's tips recomputed from its (possibly altered) joints by
/// `reported`'s nominal models: what the controllers would report.
pub(crate) fn with_reported_tips(session: &Session, reported: &Cell) -> Session {
    let mut s = session.clone();
    let tip = |r: &handclasp_cell::CellRobot, q: &[f64]| {
        Point3::from(
            base_from_tip(&r.model, q, &r.flange_from_tip)
                .expect("fk")
                .translation
                .vector,
        )
    };
    for p in &mut s.points {
        p.p_b1 = tip(&reported.robot1, &p.q1);
        p.p_b2 = tip(&reported.robot2, &p.q2);
    }
    s
}

/// What one run said: its exit status, its stderr, its JSON (when it printed one).
struct Run {
    ok: bool,
    stderr: String,
    json: Option<Value>,
}

fn run(cell: &Path, session: &Path, model: &str, extra: &[&str]) -> Run {
    let mut rest = vec!["--model", model, "--json"];
    rest.extend_from_slice(extra);
    let out: Output = handclasp(&cell_session_args("calibrate", cell, session, &rest));
    Run {
        ok: out.status.success(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        json: serde_json::from_slice(&out.stdout).ok(),
    }
}

/// The session `session` written for `reported` into `dir/name`, then calibrated with both
/// models: each run must refuse or warn, naming `expect` (one of the texts, case-sensitive).
fn assert_named(dir: &Path, name: &str, session: &Session, reported: &Path, expect: &[&str]) {
    let cell = Cell::from_toml_file(reported).unwrap();
    let csv = write_session_csv(dir, name, &with_reported_tips(session, &cell), &cell);
    for model in ["placement", "kinematic"] {
        let r = run(reported, &csv, model, &[]);
        let said: Vec<&str> = r
            .stderr
            .lines()
            .filter(|l| l.starts_with("error:") || l.starts_with("warning:"))
            .collect();
        let noise = r
            .json
            .as_ref()
            .map(|j| j["result_check"]["checks"][0]["value"].clone());
        eprintln!(
            "{name} ({model}): exit {} (noise {noise:?}) | {}",
            i32::from(!r.ok),
            said.join(" | ")
        );
        assert!(
            !r.ok || said.iter().any(|l| l.starts_with("warning:")),
            "{name} ({model}): a clean exit 0 over a contradiction:\n{}",
            r.stderr
        );
        assert!(
            expect.iter().any(|e| r.stderr.contains(e)),
            "{name} ({model}): the message names none of {expect:?}:\n{}",
            r.stderr
        );
    }
}

/// Robot 2's joints 4 and 6 swapped in the file: refused, naming the swap.
#[test]
fn joints_4_and_6_swapped_are_named() {
    let dir = workdir();
    let mut s = random_session(&truth(), N, 11);
    for p in &mut s.points {
        p.q2.swap(3, 5);
    }
    assert_named(
        dir.path(),
        "swap46.csv",
        &s,
        &shipped_cell("floor-wall"),
        &["likely mistake: robot 2's joints 4 and 6 swapped"],
    );
}

/// Robot 2's joint 5 with the wrong sign (a joint of symmetric limits, so that the flipped
/// angles stay within them): refused, naming it.
#[test]
fn a_flipped_joint_sign_is_named() {
    let dir = workdir();
    let mut s = random_session(&truth(), N, 12);
    for p in &mut s.points {
        p.q2[4] = -p.q2[4];
    }
    assert_named(
        dir.path(),
        "flip.csv",
        &s,
        &shipped_cell("floor-wall"),
        &["likely mistake: robot 2's joint 5 with the wrong sign"],
    );
}

/// Robot 2's joints exported in radians and read as degrees: refused, naming it.
#[test]
fn radians_read_as_degrees_are_named() {
    let dir = workdir();
    let mut s = random_session(&truth(), N, 13);
    for p in &mut s.points {
        for q in &mut p.q2 {
            *q = q.to_radians();
        }
    }
    assert_named(
        dir.path(),
        "rad.csv",
        &s,
        &shipped_cell("floor-wall"),
        &["likely mistake: robot 2's joints in radians, read as degrees"],
    );
}

/// Robot 2's columns shifted by one row: refused, naming the shift.
#[test]
fn robot_2_rows_shifted_by_one_are_named() {
    let dir = workdir();
    let mut s = random_session(&truth(), N + 1, 14);
    let q2: Vec<Vec<f64>> = s.points.iter().map(|p| p.q2.clone()).collect();
    for (i, p) in s.points.iter_mut().enumerate().take(N) {
        p.q2 = q2[i + 1].clone();
    }
    s.points.truncate(N);
    assert_named(
        dir.path(),
        "shift.csv",
        &s,
        &shipped_cell("floor-wall"),
        &["likely mistake: robot 2's joint columns shifted by 1 row"],
    );
}

/// Robot 2's URDF 450 mm off (its upper arm): no likely mistake explains it, a refusal (or a
/// warning) saying the model misfits.
#[test]
fn a_wrong_urdf_for_robot_2_is_a_misfit() {
    let dir = workdir();
    let urdf = std::fs::read_to_string(workspace("robots/hp20.urdf"))
        .unwrap()
        .replacen("<origin xyz=\"0 0 0.76\"", "<origin xyz=\"0 0 1.21\"", 1);
    std::fs::write(dir.path().join("hp20-wrong.urdf"), urdf).unwrap();
    let wrong = dir.path().join("hp20-wrong.urdf");
    let cell = cell_variant(dir.path(), "floor-wall", "wrong-urdf.toml", |t| {
        t.replace("../robots/hp20.urdf", &wrong.display().to_string())
    });
    let s = random_session(&truth(), N, 15);
    assert_named(
        dir.path(),
        "wrong-urdf.csv",
        &s,
        &cell,
        &["model misfit", "the model misfits"],
    );
}

/// A session recorded in the floor-ceiling cell, calibrated with the floor-wall cell: the
/// placement is 90° and 1.2 m from the stated one; refused, naming the other shipped cell.
#[test]
fn a_session_of_another_cell_is_named() {
    let dir = workdir();
    let ceiling = Cell::from_toml_file(&shipped_cell("floor-ceiling")).unwrap();
    let s = random_session(&ceiling, N, 16);
    assert_named(
        dir.path(),
        "ceiling.csv",
        &s,
        &shipped_cell("floor-wall"),
        &["another cell, floor-ceiling.toml"],
    );
}

/// Two identical robots whose columns were swapped: the fit is the inverse placement; refused,
/// naming the swap.
#[test]
fn two_identical_robots_swapped_are_named() {
    let dir = workdir();
    let cell = cell_variant(dir.path(), "floor-floor", "twins.toml", |t| {
        t.replace("va1400.urdf", "hp20.urdf")
            .replace("tip_mm = [0.0, 0.0, 150.0]", "tip_mm = [0.0, 0.0, 120.0]")
    });
    let twins = Cell::from_toml_file(&cell).unwrap();
    let mut s = random_session(&twins, N, 17);
    for p in &mut s.points {
        std::mem::swap(&mut p.q1, &mut p.q2);
    }
    assert_named(
        dir.path(),
        "twins.csv",
        &s,
        &cell,
        &["likely mistake: the two robots' columns swapped"],
    );
}

/// Robot 2's tip_mm with the wrong sign in the cell: refused, naming the tip.
#[test]
fn a_tip_with_the_wrong_sign_is_named() {
    let dir = workdir();
    let cell = cell_variant(dir.path(), "floor-wall", "tip.toml", |t| {
        t.replace("tip_mm = [0.0, 0.0, 120.0]", "tip_mm = [0.0, 0.0, -120.0]")
    });
    let s = random_session(&truth(), N, 18);
    assert_named(
        dir.path(),
        "tip.csv",
        &s,
        &cell,
        &["likely mistake: robot 2's tip_mm with the wrong sign"],
    );
}

/// σ stated 10× too small: a warning that the residuals are far above the stated noise.
#[test]
fn sigma_ten_times_too_small_warns() {
    let dir = workdir();
    let cell = cell_variant(dir.path(), "floor-wall", "small.toml", |t| {
        t.replace("alignment_mm = 0.3", "alignment_mm = 0.03")
            .replace("repeatability_mm = 0.03", "repeatability_mm = 0.003")
    });
    let s = random_session(&truth(), N, 19);
    assert_named(
        dir.path(),
        "small.csv",
        &s,
        &cell,
        &["× the stated noise (warning above"],
    );
}

/// σ stated 10× too large: a warning that the stated noise looks overstated.
#[test]
fn sigma_ten_times_too_large_warns() {
    let dir = workdir();
    let cell = cell_variant(dir.path(), "floor-wall", "large.toml", |t| {
        t.replace("alignment_mm = 0.3", "alignment_mm = 3.0")
            .replace("repeatability_mm = 0.03", "repeatability_mm = 0.3")
    });
    let s = random_session(&truth(), N, 20);
    assert_named(
        dir.path(),
        "large.csv",
        &s,
        &cell,
        &["[noise] looks overstated"],
    );
}

/// The session `s` written for `cell` and calibrated with both models: exit 0, no `warning:`
/// from the result check, status `ok`.
fn assert_quiet(dir: &Path, name: &str, s: &Session, cell: &Path) -> Vec<Value> {
    let reported = Cell::from_toml_file(cell).unwrap();
    let csv = write_session_csv(dir, name, &with_reported_tips(s, &reported), &reported);
    let mut out = Vec::new();
    for model in ["placement", "kinematic"] {
        let r = run(cell, &csv, model, &[]);
        eprintln!(
            "{name} ({model}): exit {} | {}",
            i32::from(!r.ok),
            r.stderr.trim()
        );
        assert!(r.ok, "{name} ({model}) failed:\n{}", r.stderr);
        assert!(
            !r.stderr.contains("warning:"),
            "{name} ({model}): a false alarm:\n{}",
            r.stderr
        );
        let json = r.json.expect("JSON on stdout");
        assert_eq!(json["result_check"]["status"], "ok", "{name} ({model})");
        out.push(json);
    }
    out
}

/// A correct session stays quiet.
#[test]
fn a_correct_session_is_quiet() {
    let dir = workdir();
    let s = random_session(&truth(), N, 21);
    let runs = assert_quiet(dir.path(), "ok.csv", &s, &shipped_cell("floor-wall"));
    for json in runs {
        assert!(json["result_check"]["likely_mistake"].is_null());
        assert_eq!(json["result_check"]["screen"]["mode"], "auto");
    }
}

/// A session at the paper's noise level (σ ≈ 4.4 mm per axis, stated so in the cell) stays
/// quiet.
#[test]
fn the_papers_noise_level_is_quiet() {
    let dir = workdir();
    let cell = cell_variant(dir.path(), "floor-wall", "paper.toml", |t| {
        t.replace("alignment_mm = 0.3", "alignment_mm = 4.4")
    });
    let s = random_session(&Cell::from_toml_file(&cell).unwrap(), N, 22);
    assert_quiet(dir.path(), "paper.csv", &s, &cell);
}

/// 3 % random blunders (3 rows of 100, robot 2's first joint 2° off) are rejected as
/// blunders, not called a misfit, and the run stays quiet.
#[test]
fn three_percent_blunders_are_blunders_not_misfit() {
    let dir = workdir();
    let mut s = random_session(&truth(), 100, 23);
    for i in [17, 52, 88] {
        s.points[i].q2[0] += 2f64.to_radians();
    }
    let runs = assert_quiet(dir.path(), "blunders.csv", &s, &shipped_cell("floor-wall"));
    for json in runs {
        let rejected: Vec<u64> = json["rejected_points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["row"].as_u64().unwrap())
            .collect();
        assert_eq!(rejected, vec![18, 53, 89]);
        assert_eq!(json["result_check"]["screen"]["pattern"]["misfit"], false);
    }
}

/// `calibrate --cell --export` writes a fitted named tool (`[robot1.tools] reflector`, 7.5 mm
/// off in the cell; robot 2's reflector right) into the exported cell, and the export re-predicts the training rows as
/// the fit did (else it is refused): the exported reflector lands near the truth.
#[test]
fn export_carries_fitted_named_tools() {
    let dir = workdir();
    let with_reflector = |at: &'static str| {
        move |t: String| {
            t.replace(
                "tip_mm = [0.0, 0.0, 120.0]",
                "tip_mm = [0.0, 0.0, 120.0]\n\n[robot2.tools]\nreflector = [0.0, 20.0, 100.0]",
            )
            .replace(
                "tip_mm = [0.0, 0.0, 150.0]   # tip offset in the tool0 frame",
                &format!(
                    "tip_mm = [0.0, 0.0, 150.0]\n\n[robot1.tools]\nreflector = {at}\n\n\
                     [robot1.tolerance]\ntip_mm = 20.0"
                ),
            )
        }
    };
    let truth_path = cell_variant(
        dir.path(),
        "floor-wall",
        "truth.toml",
        with_reflector("[35.0, -4.0, 104.0]"),
    );
    let cell = cell_variant(
        dir.path(),
        "floor-wall",
        "stated.toml",
        with_reflector("[30.0, 0.0, 100.0]"),
    );
    let truth_cell = Cell::from_toml_file(&truth_path).unwrap();
    let spec = SessionSpec::new(48, Layout::Random, RANDOM_SPREAD_M);
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        tracker_tool: "reflector".into(),
        ..KindSpec::default()
    };
    let (mixed, _) =
        generate_kind_session(&truth_cell, &spec, &kinds, None, &mut trial_rng(5, 0)).unwrap();
    let session = write_session_csv(dir.path(), "mixed.csv", &mixed, &truth_cell);
    let out_dir = dir.path().join("calibrated");
    let r = run(
        &cell,
        &session,
        "kinematic",
        &["--export", &out_dir.display().to_string()],
    );
    assert!(r.ok, "{}", r.stderr);
    let exported = Cell::from_toml_file(&out_dir.join("cell.toml")).unwrap();
    let reflector = exported.robot1.tools[0].flange_from_tip * 1e3;
    let truth = nalgebra::Vector3::new(35.0, -4.0, 104.0);
    let stated = nalgebra::Vector3::new(30.0, 0.0, 100.0);
    // The stated reflector is 7.5 mm from the truth; the fitted one must come within a third.
    assert!(
        (reflector - truth).norm() < (stated - truth).norm() / 3.0,
        "exported reflector {reflector:?}, truth {truth:?}"
    );
}

/// `--screen strict` keeps the old screen (a wrong model ends in "re-record rows"); `auto`
/// keeps the rows and calls it a model misfit; `off` rejects nothing.
#[test]
fn screen_modes_strict_auto_off() {
    let dir = workdir();
    let mut s = random_session(&truth(), N, 11);
    for p in &mut s.points {
        p.q2.swap(3, 5);
    }
    let reported = shipped_cell("floor-wall");
    let cell = Cell::from_toml_file(&reported).unwrap();
    let csv = write_session_csv(
        dir.path(),
        "swap.csv",
        &with_reported_tips(&s, &cell),
        &cell,
    );
    let strict = run(
        &reported,
        &csv,
        "kinematic",
        &["--screen", "strict", "--force"],
    );
    assert!(
        !strict.ok && strict.stderr.contains("re-record rows"),
        "{}",
        strict.stderr
    );
    let auto = run(&reported, &csv, "kinematic", &["--force"]);
    assert!(auto.ok, "{}", auto.stderr);
    assert!(auto
        .stderr
        .contains("warning: kept by --force: model misfit, not blunders"));
    let json = auto.json.unwrap();
    assert_eq!(json["rejected_points"].as_array().unwrap().len(), 0);
    assert_eq!(json["result_check"]["screen"]["rows_kept"], true);
    assert_eq!(json["result_check"]["status"], "refused");
    let off = run(
        &reported,
        &csv,
        "placement",
        &["--screen", "off", "--force"],
    );
    let json = off.json.unwrap();
    assert_eq!(json["result_check"]["screen"]["mode"], "off");
    assert_eq!(json["rows_used"], N as u64);
}

/// `diagnose` runs the same result check first: a likely data mistake refuses the diagnosis
/// (which would otherwise name effects the mistake made), naming it, with the refusal's JSON
/// on stdout; `--force` diagnoses anyway, the finding a `warning: kept by --force:` line.
#[test]
fn diagnose_names_a_likely_mistake_first() {
    let dir = workdir();
    let mut s = random_session(&truth(), N, 11);
    for p in &mut s.points {
        p.q2.swap(3, 5);
    }
    let reported = shipped_cell("floor-wall");
    let cell = Cell::from_toml_file(&reported).unwrap();
    let csv = write_session_csv(
        dir.path(),
        "swap.csv",
        &with_reported_tips(&s, &cell),
        &cell,
    );
    let out = handclasp(&cell_session_args(
        "diagnose",
        &reported,
        &csv,
        &["--json", "--trials", "20"],
    ));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "error: result check (placement fit): the session contradicts what the cell states: \
             likely mistake: robot 2's joints 4 and 6 swapped"
        ),
        "{stderr}"
    );
    let refusal: Value = serde_json::from_slice(&out.stdout).expect("the refusal's JSON");
    assert_eq!(refusal["status"], "refused");
    assert_eq!(refusal["command"], "diagnose");
    assert!(!refusal["result_check"]["likely_mistake"].is_null());
    let forced = handclasp(&cell_session_args(
        "diagnose",
        &reported,
        &csv,
        &["--json", "--trials", "20", "--force"],
    ));
    // The diagnosis then runs (on this session its own blunder screen gives up: the mistake
    // moves every row), the finding kept as a warning.
    let stderr = String::from_utf8_lossy(&forced.stderr);
    assert!(
        stderr.contains(
            "warning: kept by --force: result check (placement fit): likely mistake: robot 2's \
             joints 4 and 6 swapped"
        ),
        "{stderr}"
    );
}

/// `diagnose --max-steps 1` on a mixed session whose robots carry several errors: the
/// selection stops at the cap while still accepting, and says so (JSON and `warning:`).
#[test]
fn diagnose_reports_its_step_cap() {
    let dir = workdir();
    let truth = truth();
    let spec = SessionSpec::new(36, Layout::Random, 0.7);
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        ..KindSpec::default()
    };
    let (mixed, _) =
        generate_kind_session(&truth, &spec, &kinds, None, &mut trial_rng(4, 0)).unwrap();
    let cell = shipped_cell("floor-wall");
    let csv = write_session_csv(dir.path(), "mixed.csv", &mixed, &truth);
    let out = handclasp(&cell_session_args(
        "diagnose",
        &cell,
        &csv,
        &["--json", "--max-steps", "1"],
    ));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["max_steps"], 1);
    if json["effects"].as_array().unwrap().len() == 1 && json["stopped_at"].is_null() {
        assert_eq!(json["step_cap_hit"], true);
        assert!(
            stderr.contains("warning: the selection stopped at its step cap"),
            "{stderr}"
        );
    } else {
        panic!(
            "expected one accepted family and no stop: {}",
            json["effects"]
        );
    }
}
