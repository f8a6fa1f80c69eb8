//! End-to-end: `calibrate --cell --export`'s do-no-harm rule (issue 20, item 2). The truth sags
//! by a gravity compliance far beyond anything the kinematic model can represent (1°/kN·m at
//! the shoulder and elbow of both robots) and the session sits in two small clusters of the
//! workspace: the kinematic corrections that fit those postures extrapolate worse than the
//! nominal robots to the region held out, so the rule withholds the families that harm, family
//! by family (`calib_core::whole_cell::decide_families`), and exports a refit without them;
//! `--force` exports the full model. With the docs' example truth's errors added (which the
//! model represents), the families kept beat the placement only on new poses. A healthy session (the nominal robots are the
//! truth, random layout) withholds nothing. The same for sessions of tracker rows only (each
//! held-out piece of the tracker group refits its frame on half its rows), and a mixed session
//! is judged on every kind of its rows.

use std::path::{Path, PathBuf};

use handclasp_cell::Cell;
use sim_cell::{trial_rng, KindSpec, Layout, SessionSpec, SimKind};

use crate::support::{
    cell_session_args, handclasp, shipped_cell, simulate, stdout_json, validate_rms_mm, workspace,
    write_session_csv,
};

/// The truth's compliance, deg/(kN·m), at joints 2 and 3 of both robots.
const SAG_DEG_PER_KNM: f64 = 1.0;
/// Handclasps of each session.
const ROWS: usize = 40;
/// Side of the layouts, m (cluster distance for the clustered one, cube side for the random).
const SPREAD_M: f64 = 0.6;

/// `--accept-mm` of the JSON runs: any value asks for the verdict at the work site.
const ACCEPT_MM: &str = "1000";

/// The shipped floor–wall cell (URDF paths absolute), with the sag as its hidden truth when
/// `sag`, written to `dir/name`.
fn write_cell(dir: &Path, name: &str, sag: bool) -> PathBuf {
    let robots = workspace("robots/");
    let mut text = std::fs::read_to_string(shipped_cell("floor-wall"))
        .unwrap()
        .replace("../robots/", &format!("{}/", robots.display()));
    if sag {
        let c = SAG_DEG_PER_KNM;
        text.push_str(&format!(
            "\n[robot1.errors]\ncompliance_deg_per_knm = [0.0, {c}, {c}, 0.0, 0.0, 0.0, 0.0]\n\
             \n[robot2.errors]\ncompliance_deg_per_knm = [0.0, {c}, {c}, 0.0, 0.0, 0.0]\n"
        ));
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `calibrate --cell CELL --session SESSION --model kinematic --export DIR --json` (and
/// `--force`): the JSON report.
fn export(cell: &Path, session: &Path, dir: &Path, force: bool) -> serde_json::Value {
    let dir = dir.display().to_string();
    let mut extra = vec![
        "--model",
        "kinematic",
        "--export",
        &dir,
        "--json",
        "--accept-mm",
        ACCEPT_MM,
    ];
    if force {
        extra.push("--force");
    }
    stdout_json(&handclasp(&cell_session_args(
        "calibrate",
        cell,
        session,
        &extra,
    )))
}

/// The cell tolerance key of a family kind of the JSON (`do_no_harm.families[].family.kind`).
fn tolerance_key(kind: &str) -> &'static str {
    match kind {
        "joint_offset" => "joint_offset_deg",
        "origin_xyz" => "origin_mm",
        "origin_rpy" => "origin_deg",
        "tip" => "tip_mm",
        other => panic!("no tolerance key of the floor-wall cell for family kind {other}"),
    }
}

/// `cell` (a floor–wall cell file without `[robotN.tolerance]`) with the families `withheld`
/// (the JSON's `do_no_harm.families[]` not kept) stated nominal: their tolerances 0, written to
/// `dir/name`.
fn cell_without(dir: &Path, cell: &Path, families: &[serde_json::Value], name: &str) -> PathBuf {
    let mut text = std::fs::read_to_string(cell).unwrap();
    for robot in [1, 2] {
        let keys: Vec<&str> = families
            .iter()
            .filter(|f| f["kept"] == false && f["family"]["robot"] == robot)
            .map(|f| tolerance_key(f["family"]["kind"].as_str().unwrap()))
            .collect();
        if !keys.is_empty() {
            text.push_str(&format!("\n[robot{robot}.tolerance]\n"));
            for k in keys {
                text.push_str(&format!("{k} = 0.0\n"));
            }
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_clustered_session_with_unmodelled_sag_withholds_the_harmful_families_and_force_keeps_the_model(
) {
    let tmp = tempfile::tempdir().unwrap();
    let cell_path = write_cell(tmp.path(), "sag.toml", true);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let session = simulate(&truth, ROWS, Layout::Clustered, SPREAD_M, 1);
    let csv = write_session_csv(tmp.path(), "session.csv", &session, &truth);

    let safe_dir = tmp.path().join("safe");
    let out = handclasp(&cell_session_args(
        "calibrate",
        &cell_path,
        &csv,
        &[
            "--model",
            "kinematic",
            "--export",
            &safe_dir.display().to_string(),
        ],
    ));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: do no harm: the kinematic model is worse than the nominal model")
            && stderr.contains("WITHHELD"),
        "{stderr}"
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(" — WITHHELD "), "{text}");

    let json_dir = tmp.path().join("safe-json");
    let r = export(&cell_path, &csv, &json_dir, false);
    let h = &r["do_no_harm"];
    assert_eq!(h["design"], "joint_regions", "{h}");
    assert_ne!(h["exported"], "kinematic", "{h}");
    assert_eq!(h["forced"], false);
    let withheld = h["withheld"].as_array().unwrap();
    assert!(!withheld.is_empty(), "{h}");
    // Each withheld family names the held-out regions that decided it.
    for w in withheld {
        assert!(!w["harmful_in"].as_array().unwrap().is_empty(), "{w}");
    }
    let folds = h["folds"].as_array().unwrap();
    assert!(folds.len() >= 3, "{h}");
    assert!(
        folds
            .iter()
            .any(|f| f["harmful"] == true && f["ratio"].as_f64().unwrap() > 1.0),
        "{h}"
    );
    // The export is a refit without the withheld families: the calibration of the same session
    // on the cell that states them nominal (tolerance 0), as fitted (--force: no rule applied).
    let families = h["families"].as_array().unwrap();
    let (refit_dir, refit) = if h["exported"] == "placement" {
        let dir = tmp.path().join("placement");
        let p = stdout_json(&handclasp(&cell_session_args(
            "calibrate",
            &cell_path,
            &csv,
            &[
                "--model",
                "placement",
                "--export",
                &dir.display().to_string(),
                "--json",
                "--accept-mm",
                ACCEPT_MM,
            ],
        )));
        assert!(p.get("do_no_harm").is_none(), "placement is not checked");
        (dir, p)
    } else {
        assert_eq!(h["exported"], "partial", "{h}");
        assert!(!h["kept"].as_array().unwrap().is_empty(), "{h}");
        assert!(h["exported_folds"]
            .as_array()
            .unwrap()
            .iter()
            .all(|f| f["harmful"] == false));
        let without = cell_without(tmp.path(), &cell_path, families, "without.toml");
        let dir = tmp.path().join("without");
        (dir.clone(), export(&without, &csv, &dir, true))
    };
    // The verdict is the exported model's (found by the lead's final read: it was the withheld
    // kinematic fit's, a PASS for a model the export did not write).
    assert_eq!(
        r["work_site"], refit["work_site"],
        "the verdict at the work site is the exported model's"
    );
    for f in ["robot1.urdf", "robot2.urdf"] {
        assert_eq!(
            std::fs::read_to_string(json_dir.join(f)).unwrap(),
            std::fs::read_to_string(refit_dir.join(f)).unwrap(),
            "{f}: the export is the refit without the withheld families"
        );
    }

    // --force exports the full model: its URDFs carry the withheld corrections too.
    let forced_dir = tmp.path().join("forced");
    let f = export(&cell_path, &csv, &forced_dir, true);
    assert_eq!(f["do_no_harm"]["exported"], "kinematic");
    assert_eq!(f["do_no_harm"]["forced"], true);
    // `--force` judges the full model but ranks no family (harm36b): nothing was withheld
    // family by family, and the JSON says the ranking was not checked and why.
    assert_eq!(
        f["do_no_harm"]["ranking"],
        "not checked: --force exports the full model"
    );
    assert!(f["do_no_harm"]["trials"].as_array().unwrap().is_empty());
    assert!(f["do_no_harm"]["families"]
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x["kept"] == true && x.get("rank").is_none_or(|r| r.is_null())));
    assert!(f["do_no_harm"]["withheld"].as_array().unwrap().is_empty());
    assert_ne!(
        std::fs::read_to_string(forced_dir.join("robot2.urdf")).unwrap(),
        std::fs::read_to_string(json_dir.join("robot2.urdf")).unwrap(),
        "--force writes the withheld corrections"
    );
}

/// The docs' example truth's kinematic errors (within the model: they help everywhere) plus the
/// unmodelled sag, on a clustered session: the rule keeps some families and withholds others,
/// and on new poses over the whole cube (`validate`, never seen by the rule) the partial export
/// beats the placement-only one (what the rule exported before it went family by family).
#[test]
fn a_session_where_some_families_help_and_others_harm_exports_the_helpful_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let nominal = write_cell(tmp.path(), "nominal.toml", false);
    let mut truth_text = std::fs::read_to_string(&nominal).unwrap();
    let example = std::fs::read_to_string(workspace("docs/examples/truth.toml")).unwrap();
    let errors = |robot: u8| -> String {
        let head = format!("[robot{robot}.errors]");
        let from = example.find(&head).unwrap();
        let rest = &example[from + head.len()..];
        let body = &rest[..rest.find("\n[").unwrap_or(rest.len())];
        body.lines()
            .filter(|l| l.contains('='))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let c = SAG_DEG_PER_KNM;
    truth_text.push_str(&format!(
        "\n[robot1.errors]\n{}\ncompliance_deg_per_knm = [0.0, {c}, {c}, 0.0, 0.0, 0.0, 0.0]\n\
         \n[robot2.errors]\n{}\ncompliance_deg_per_knm = [0.0, {c}, {c}, 0.0, 0.0, 0.0]\n",
        errors(1),
        errors(2)
    ));
    let truth_path = tmp.path().join("truth.toml");
    std::fs::write(&truth_path, truth_text).unwrap();
    let truth = Cell::from_toml_file(&truth_path).unwrap();
    let reported = Cell::from_toml_file(&nominal).unwrap();
    let session = simulate(&truth, ROWS, Layout::Clustered, SPREAD_M, 1);
    let csv = write_session_csv(tmp.path(), "session.csv", &session, &reported);
    let partial = tmp.path().join("partial");
    let r = export(&nominal, &csv, &partial, false);
    let h = &r["do_no_harm"];
    assert_eq!(h["exported"], "partial", "{h}");
    assert!(!h["kept"].as_array().unwrap().is_empty(), "{h}");
    assert!(!h["withheld"].as_array().unwrap().is_empty(), "{h}");

    let placement = tmp.path().join("placement");
    let p = handclasp(&cell_session_args(
        "calibrate",
        &nominal,
        &csv,
        &[
            "--model",
            "placement",
            "--export",
            &placement.display().to_string(),
        ],
    ));
    assert!(p.status.success(), "{}", String::from_utf8_lossy(&p.stderr));
    // New poses over the whole cube, recorded on the truth: held out from everything above.
    let new = simulate(
        &truth,
        ROWS,
        Layout::Random,
        crate::support::RANDOM_SPREAD_M,
        1001,
    );
    let new_csv = write_session_csv(tmp.path(), "new.csv", &new, &reported);
    let rms = |dir: &Path| -> f64 {
        let out = handclasp(&[
            "validate",
            "--cell",
            dir.join("cell.toml").to_str().unwrap(),
            "--session",
            new_csv.to_str().unwrap(),
            "--nominal",
            nominal.to_str().unwrap(),
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        stdout_json(&out)["all"]["calibrated"]["rms_mm"]
            .as_f64()
            .unwrap()
    };
    let (partial_mm, placement_mm) = (rms(&partial), rms(&placement));
    // The full model (--force), printed for the record only: the rule does not promise to beat it.
    let full = tmp.path().join("full");
    export(&nominal, &csv, &full, true);
    println!(
        "new poses: partial export {partial_mm:.3} mm, placement only {placement_mm:.3} mm, full \
         model {:.3} mm",
        rms(&full)
    );
    assert!(
        partial_mm < placement_mm,
        "partial {partial_mm:.3} mm vs placement only {placement_mm:.3} mm: {h}"
    );
}

#[test]
fn a_healthy_session_withholds_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let cell_path = write_cell(tmp.path(), "nominal.toml", false);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let session = simulate(&truth, ROWS, Layout::Random, SPREAD_M, 1);
    let csv = write_session_csv(tmp.path(), "session.csv", &session, &truth);
    let r = export(&cell_path, &csv, &tmp.path().join("out"), false);
    let h = &r["do_no_harm"];
    assert_eq!(h["exported"], "kinematic", "{h}");
    assert!(h["withheld"].as_array().unwrap().is_empty(), "{h}");
    // Every family kept, none tried without (the full model harms no region).
    let families = h["families"].as_array().unwrap();
    assert!(!families.is_empty(), "{h}");
    assert!(families.iter().all(|f| f["kept"] == true), "{h}");
    assert_eq!(h["kept"].as_array().unwrap().len(), families.len(), "{h}");
    assert!(h["trials"].as_array().unwrap().is_empty(), "{h}");
    let folds = h["folds"].as_array().unwrap();
    assert!(folds.len() >= 2, "{h}");
    assert!(folds.iter().all(|f| f["harmful"] == false), "{h}");
}

/// A simulated session (`sim-cell session --kind …`) of `spec`'s rows of `kind` on `truth`,
/// drawn from `trial_rng(seed, 0)`, written as `dir/name` against the reported cell `reported`
/// (the truth's hidden errors are not in the CSV).
fn write_kind_session(
    dir: &Path,
    name: &str,
    (truth, reported): (&Cell, &Cell),
    spec: &SessionSpec,
    kind: SimKind,
    seed: u64,
) -> PathBuf {
    let kinds = KindSpec {
        kind,
        ..KindSpec::default()
    };
    let (s, _) =
        sim_cell::generate_kind_session(truth, spec, &kinds, None, &mut trial_rng(seed, 0))
            .expect("session");
    write_session_csv(dir, name, &s, reported)
}

/// A session of [`ROWS`] rows of `kind` in `layout` ([`SPREAD_M`]) of `truth`, written as
/// `dir/name` against `truth` itself (its hidden errors are not in the CSV).
fn kind_session(
    dir: &Path,
    name: &str,
    truth: &Cell,
    kind: SimKind,
    layout: Layout,
    seed: u64,
) -> PathBuf {
    let spec = SessionSpec::new(ROWS, layout, SPREAD_M);
    write_kind_session(dir, name, (truth, truth), &spec, kind, seed)
}

/// Every scored kind of the check's folds with the rows of the comparisons it is in (a pooled
/// comparison's rows count for each of its kinds).
fn scored(h: &serde_json::Value) -> Vec<(String, u64)> {
    let mut out: Vec<(String, u64)> = Vec::new();
    for f in h["folds"].as_array().unwrap() {
        for k in f["kinds"].as_array().unwrap() {
            // A comparison of several small kinds pooled is labelled `contact+plane`.
            let label = k["kind"].as_str().unwrap();
            let rows = k["rows"].as_u64().unwrap();
            for name in label.split('+') {
                match out.iter_mut().find(|(n, _)| n == name) {
                    Some((_, r)) => *r += rows,
                    None => out.push((name.to_string(), rows)),
                }
            }
        }
    }
    out
}

#[test]
fn a_tracker_only_session_is_scored_and_its_harmful_model_withheld() {
    let tmp = tempfile::tempdir().unwrap();
    let cell_path = write_cell(tmp.path(), "sag.toml", true);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let csv = kind_session(
        tmp.path(),
        "tracker.csv",
        &truth,
        SimKind::Tracker,
        Layout::Clustered,
        1,
    );
    let r = export(&cell_path, &csv, &tmp.path().join("out"), false);
    let h = &r["do_no_harm"];
    // The tracker rows are held out and scored (on main they trained every fold: not checked).
    let kinds = scored(h);
    assert_eq!(kinds.len(), 1, "{h}");
    assert_eq!(kinds[0].0, "tracker", "{h}");
    assert!(kinds[0].1 as usize + h["kept_in_training"].as_u64().unwrap() as usize >= ROWS / 2);
    assert_ne!(h["exported"], "kinematic", "{h}");
    assert!(!h["withheld"].as_array().unwrap().is_empty(), "{h}");
    assert!(
        h["folds"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["harmful"] == true
                && f["kinds"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|k| k["kind"] == "tracker" && k["harmful"] == true)),
        "{h}"
    );
}

#[test]
fn a_healthy_tracker_only_session_withholds_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let cell_path = write_cell(tmp.path(), "nominal.toml", false);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let csv = kind_session(
        tmp.path(),
        "tracker.csv",
        &truth,
        SimKind::Tracker,
        Layout::Random,
        1,
    );
    let r = export(&cell_path, &csv, &tmp.path().join("out"), false);
    let h = &r["do_no_harm"];
    assert_ne!(h["design"], "not_checked", "{h}");
    assert_eq!(
        scored(h).first().map(|k| k.0.as_str()),
        Some("tracker"),
        "{h}"
    );
    assert_eq!(h["exported"], "kinematic", "{h}");
    assert!(h["withheld"].as_array().unwrap().is_empty(), "{h}");
}

#[test]
fn a_mixed_session_is_judged_on_every_kind_of_its_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let cell_path = write_cell(tmp.path(), "nominal.toml", false);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let csv = kind_session(
        tmp.path(),
        "mixed.csv",
        &truth,
        SimKind::Mixed,
        Layout::Random,
        1,
    );
    let r = export(&cell_path, &csv, &tmp.path().join("out"), false);
    let h = &r["do_no_harm"];
    let mut kinds: Vec<String> = scored(h).into_iter().map(|(k, _)| k).collect();
    kinds.sort();
    assert_eq!(kinds, ["coincident", "contact", "plane", "tracker"], "{h}");
    // The fold's verdict is its kinds': harmful exactly when one of them is.
    for f in h["folds"].as_array().unwrap() {
        let any = f["kinds"]
            .as_array()
            .unwrap()
            .iter()
            .any(|k| k["harmful"] == true);
        assert_eq!(f["harmful"], any, "{f}");
    }
}

/// `calibrate --cell CELL --session SESSION --export DIR --json` with the default model (as a
/// user runs it): the JSON's `do_no_harm` object, or the stderr when the run fails (e.g. the
/// result check refuses the fit).
fn try_default_export(
    cell: &Path,
    session: &Path,
    dir: &Path,
) -> Result<serde_json::Value, String> {
    let dir = dir.display().to_string();
    let out = handclasp(&cell_session_args(
        "calibrate",
        cell,
        session,
        &["--export", &dir, "--json"],
    ));
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    Ok(stdout_json(&out)["do_no_harm"].clone())
}

/// [`try_default_export`], the run required to succeed.
fn default_export(cell: &Path, session: &Path, dir: &Path) -> serde_json::Value {
    try_default_export(cell, session, dir).expect("calibrate --cell --export")
}

/// The docs' example truth (`docs/examples/truth.toml`: errors the kinematic model represents,
/// one joint zero three times its tolerance) and the shipped floor–wall cell it is reported as.
fn example_truth() -> (Cell, PathBuf) {
    let truth = Cell::from_toml_file(&workspace("docs/examples/truth.toml")).unwrap();
    (truth, shipped_cell("floor-wall"))
}

/// A session of `n` rows of `kind`, random layout, simulated on `truth` with `seed`, written
/// against the reported cell `reported`.
fn kind_session_n(
    dir: &Path,
    truth: &Cell,
    reported: &Cell,
    kind: SimKind,
    n: usize,
    seed: u64,
) -> PathBuf {
    let spec = SessionSpec::new(n, Layout::Random, crate::support::RANDOM_SPREAD_M);
    let name = format!("{kind:?}-{n}-{seed}.csv");
    write_kind_session(dir, &name, (truth, reported), &spec, kind, seed)
}

/// The false alarm of stop 34 (`check20`): a mixed session of 84 rows of the docs' example
/// truth, whose model is healthy (the truth is within what it represents), lost all its
/// corrections to one region's 14 plane rows at ×1.055 (t −2.06) judged at t −2. Judged at
/// the session's Šidák thresholds, the full model is exported.
#[test]
fn a_healthy_mixed_session_of_84_rows_exports_the_full_model() {
    let tmp = tempfile::tempdir().unwrap();
    let (truth, reported_path) = example_truth();
    let reported = Cell::from_toml_file(&reported_path).unwrap();
    let csv = kind_session_n(tmp.path(), &truth, &reported, SimKind::Mixed, 84, 4);
    let h = default_export(&reported_path, &csv, &tmp.path().join("out"));
    assert_eq!(h["design"], "joint_regions", "{h}");
    assert!(h["withheld"].as_array().unwrap().is_empty(), "{h}");
    assert_ne!(h["exported"], "placement", "{h}");
    // Every comparison's threshold is Student's quantile at the session's Šidák level.
    let alpha = h["alpha_each"].as_f64().unwrap();
    let m = h["comparisons"].as_f64().unwrap();
    assert!((1.0 - (1.0 - alpha).powf(m) - 0.05).abs() < 1e-9, "{h}");
}

/// Sessions per kind of the false-alarm benchmark.
const BENCH_SESSIONS: u64 = 20;

/// Fresh coincident handclasps over the workspace (random layout, [`RANDOM_SPREAD_M`]) that
/// label a benchmark session by its truth, as `tools/bench/harm_truth.py` does.
const WORKSPACE_PAIRS: usize = 100;

/// Seed offset of the workspace pairs (session seed + this), apart from every session's seed.
const WORKSPACE_SEED: u64 = 90_000;

/// The false-alarm rate the judge states per session (`calib_core::selection::HARM_FALSE_ALARM`).
const STATED_FALSE_ALARM: f64 = 0.05;

/// Chance the bound of [`false_alarm_bound`] may be exceeded by a judge that keeps its rate.
const BOUND_TAIL: f64 = 1e-3;

/// The most false alarms a judge at [`STATED_FALSE_ALARM`] per session gives in `n` sessions
/// but in [`BOUND_TAIL`] of benchmarks: the smallest `k` with `P(Binomial(n, 5 %) > k) ≤ 0.1 %`
/// (5 of 20, as the benchmark asked before it was labelled by the truth).
fn false_alarm_bound(n: usize) -> usize {
    let p = STATED_FALSE_ALARM;
    let mut term = (1.0 - p).powi(n as i32); // P(X = 0)
    let mut below = 0.0;
    for k in 0..=n {
        below += term;
        if 1.0 - below <= BOUND_TAIL {
            return k;
        }
        term *= (n - k) as f64 / (k + 1) as f64 * p / (1.0 - p);
    }
    n
}

/// One benchmark session judged, and labelled by its truth.
struct Judged {
    /// Something withheld by the judge (`do_no_harm.withheld` not empty).
    withheld: bool,
    /// The full model (`--force`) is worse than the placement only over the workspace: its
    /// rms on [`WORKSPACE_PAIRS`] fresh handclasps is above the placement's.
    harmful: bool,
    /// The full model's workspace rms over the placement's.
    ratio: f64,
    /// The export the judge wrote (no `--force`), its workspace rms over the placement's.
    export_ratio: f64,
}

/// Judges the session `csv` of `truth` (reported as `reported_path`, scored against the
/// nominal cell `nominal_path`) with `calibrate --cell … --export` and `model` flags, and
/// labels it by the truth: the full model (the same flags and `--force`) and the placement
/// only (`--model placement --force`) exported and scored by `validate` on
/// [`WORKSPACE_PAIRS`] fresh handclasps of the truth over the workspace. `Err`: a run failed
/// (the judged one, e.g. the result check refused the fit; or a labelling export; an exported
/// placement off robot 2's declared mount no longer fails: harm36b), with its first `error` line.
#[allow(clippy::too_many_arguments)]
fn judge_against_truth(
    dir: &Path,
    (truth, reported): (&Cell, &Cell),
    reported_path: &Path,
    nominal_path: &Path,
    csv: &Path,
    model: &[&str],
    seed: u64,
) -> Result<Judged, String> {
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let out_arg = out.display().to_string();
        let mut args = vec!["--export", &out_arg, "--json"];
        args.extend_from_slice(extra);
        let o = handclasp(&cell_session_args("calibrate", reported_path, csv, &args));
        (o, out.join("cell.toml"))
    };
    let ok = |stage: &str, o: &std::process::Output| {
        if o.status.success() {
            return Ok(());
        }
        let e = String::from_utf8_lossy(&o.stderr);
        let first = e.lines().find(|l| l.starts_with("error")).unwrap_or("");
        Err(format!("{stage} run: {first}"))
    };
    let (judged, judged_cell) = run("judged", model);
    ok("judged", &judged)?;
    let h = stdout_json(&judged)["do_no_harm"].clone();
    let withheld = h["withheld"].as_array().is_none_or(|w| !w.is_empty());
    let mut full_args = model.to_vec();
    full_args.push("--force");
    let (full, full_cell) = run("full", &full_args);
    ok("full-model labelling", &full)?;
    let (placement, placement_cell) = run("placement", &["--model", "placement", "--force"]);
    ok("placement labelling", &placement)?;
    let pairs = kind_session_n(
        dir,
        truth,
        reported,
        SimKind::Coincident,
        WORKSPACE_PAIRS,
        WORKSPACE_SEED + seed,
    );
    let rms = |cell: &Path| validate_rms_mm(cell, &pairs, nominal_path).0;
    let base = rms(&placement_cell);
    let ratio = rms(&full_cell) / base;
    Ok(Judged {
        withheld,
        harmful: ratio > 1.0,
        ratio,
        export_ratio: rms(&judged_cell) / base,
    })
}

/// Benchmark (not a timed test; `cargo test -p handclasp --test e2e -- --ignored
/// do_no_harm::false_alarm_and_detection_benchmark --nocapture`): the judge against each
/// session's **workspace truth** (as `tools/bench/harm_truth.py`): a session is *truly
/// harmful* when its full model is worse than the placement only on [`WORKSPACE_PAIRS`] fresh
/// handclasps over the workspace. Cases: healthy sessions (the docs' example truth reported as
/// the floor–wall cell: the model represents the truth) of tracker rows (40), plane rows (40)
/// and mixed rows (84), [`BENCH_SESSIONS`] seeds each (100…); sessions with the unmodelled sag
/// (clustered: handclasps and tracker rows, 40 each, `--model kinematic`), half as many (1…).
/// Prints every session and each case's counts.
///
/// Targets (fixed in stop 36, `harm36`, before the benchmark was run with this labelling):
/// - **false alarms**, healthy cases: sessions truly harmless yet withheld at most
///   [`false_alarm_bound`] of the truly harmless ones (5 of 20) per case;
/// - **detection**, sag cases: at least half of the truly harmful sessions withheld per case.
///
/// Not asserted, printed: detection in the healthy cases, and withholding in truly harmless
/// sag sessions (a sag model better than the placement on average can still be worse in one
/// region of joint space, which the region-wise rule exists to withhold: the workspace average
/// does not make it a false alarm of the judge's 5 %); and how many exports (the judge's, no
/// `--force`) are worse than the placement over the workspace.
#[test]
#[ignore = "benchmark: 80 sessions of 3 calibrations and 3 validations, minutes"]
fn false_alarm_and_detection_benchmark() {
    let tmp = tempfile::tempdir().unwrap();
    let (example, reported_path) = example_truth();
    let reported = Cell::from_toml_file(&reported_path).unwrap();
    let sag_path = write_cell(tmp.path(), "sag.toml", true);
    let sag = Cell::from_toml_file(&sag_path).unwrap();
    let nominal_path = write_cell(tmp.path(), "nominal.toml", false);
    let kinematic: &[&str] = &["--model", "kinematic", "--accept-mm", ACCEPT_MM];
    // (name, truth, reported, reported file, kind, rows, layout, seeds, model flags, healthy)
    let cases = [
        (
            "healthy Tracker",
            &example,
            &reported,
            &reported_path,
            SimKind::Tracker,
            40,
            Layout::Random,
            100..100 + BENCH_SESSIONS,
            &[][..],
            true,
        ),
        (
            "healthy Plane",
            &example,
            &reported,
            &reported_path,
            SimKind::Plane,
            40,
            Layout::Random,
            100..100 + BENCH_SESSIONS,
            &[][..],
            true,
        ),
        (
            "healthy Mixed",
            &example,
            &reported,
            &reported_path,
            SimKind::Mixed,
            84,
            Layout::Random,
            100..100 + BENCH_SESSIONS,
            &[][..],
            true,
        ),
        (
            "sag Coincident",
            &sag,
            &sag,
            &sag_path,
            SimKind::Coincident,
            ROWS,
            Layout::Clustered,
            1..1 + BENCH_SESSIONS / 2,
            kinematic,
            false,
        ),
        (
            "sag Tracker",
            &sag,
            &sag,
            &sag_path,
            SimKind::Tracker,
            ROWS,
            Layout::Clustered,
            1..1 + BENCH_SESSIONS / 2,
            kinematic,
            false,
        ),
    ];
    let mut failures = Vec::new();
    for (name, truth, rep, rep_path, kind, n, layout, seeds, model, healthy) in cases {
        let (mut harmful, mut harmless) = (0, 0);
        let (mut caught, mut alarms, mut export_harms, mut refused) = (0, 0, 0, 0);
        for seed in seeds {
            let dir = tmp.path().join(format!("{name}-{seed}").replace(' ', "-"));
            std::fs::create_dir_all(&dir).unwrap();
            let spec = SessionSpec::new(
                n,
                layout,
                if healthy {
                    crate::support::RANDOM_SPREAD_M
                } else {
                    SPREAD_M
                },
            );
            let csv = write_kind_session(&dir, "session.csv", (truth, rep), &spec, kind, seed);
            let j = match judge_against_truth(
                &dir,
                (truth, rep),
                rep_path,
                &nominal_path,
                &csv,
                model,
                seed,
            ) {
                Ok(j) => j,
                Err(e) => {
                    println!("{name} seed {seed}: not counted: {e}");
                    refused += 1;
                    continue;
                }
            };
            println!(
                "{name} seed {seed}: full model ×{:.2} the placement over the workspace ({}); \
                 judge: {}; export ×{:.2}",
                j.ratio,
                if j.harmful { "harmful" } else { "harmless" },
                if j.withheld { "withheld" } else { "exported" },
                j.export_ratio
            );
            if j.harmful {
                harmful += 1;
                caught += usize::from(j.withheld);
            } else {
                harmless += 1;
                alarms += usize::from(j.withheld);
            }
            export_harms += usize::from(j.export_ratio > 1.0);
        }
        println!(
            "== {name} ×{n}: truly harmful {harmful}, withheld {caught}; truly harmless \
             {harmless}, withheld {alarms}; exports worse than the placement {export_harms}; \
             {refused} not counted (a run failed)"
        );
        if healthy && alarms > false_alarm_bound(harmless) {
            failures.push(format!(
                "{name}: {alarms} of {harmless} truly harmless sessions withheld (bound {})",
                false_alarm_bound(harmless)
            ));
        }
        if !healthy && 2 * caught < harmful {
            failures.push(format!(
                "{name}: {caught} of {harmful} truly harmful sessions withheld (target half)"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
