//! Hidden-effect tests of the whole-cell diagnosis (`diagnose::diagnose_cell_session`) on mixed
//! sessions simulated by `sim_cell::generate_kind_session` (coincident, contact, tracker and plane
//! rows in turn) on the shipped floor–wall cell: one hidden effect must be the only family named,
//! with its true value inside the reported 95 % interval (joint offsets, a tool tip, a
//! joint-periodic error, a tracker scale, a tracker drift); a noise-only session names nothing.
//!
//! The export (`diagnose::export_cell_diagnosis`) must write a cell whose FK reproduces the
//! hidden truth on fresh poses better than the input cell; a rejected family must report its
//! value with an interval that covers the truth.
//!
//! The simulated session has one group per kind; like real sessions (one tracker frame or
//! plane per recorded file) the rows of each kind are spread over [`GROUPS_PER_KIND`] groups in
//! turn, so the held-out criterion has whole groups to hold out.

use std::collections::HashMap;

use diagnose::{
    diagnose_cell_session, export_cell_diagnosis, CellDiagnoseOptions, CellDiagnoseReport,
};
use handclasp_cell::{Cell, CellRobot};
use handclasp_cell::{Session, SessionKind};
use kinematics::{true_base_from_tip, Axis, ErrorParam};
use nalgebra::{Point3, Vector3};
use sim_cell::{
    generate_kind_session, generate_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind,
};

/// Rows per session (60 observations, 10 of each of the 6 kinds in turn).
const N_ROWS: usize = 60;
/// Side of the random teach cube, m.
const SPREAD_M: f64 = 0.7;
/// Nuisance groups per kind (tracker frames, planes, contact distances).
const GROUPS_PER_KIND: usize = 2;

/// A mixed session of the floor–wall cell with `truth`'s errors hidden (the CSV-level session
/// says what the nominal cell believes), its groups spread as in the module documentation.
fn session(truth: &Cell, seed: u64) -> Session {
    session_of(truth, N_ROWS, seed)
}

/// [`session`] with `n` rows.
fn session_of(truth: &Cell, n: usize, seed: u64) -> Session {
    let spec = SessionSpec::new(n, Layout::Random, SPREAD_M);
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        ..KindSpec::default()
    };
    let (mut s, _) = generate_kind_session(truth, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .expect("session");
    spread_groups(&mut s);
    s
}

/// Spreads each kind's rows over [`GROUPS_PER_KIND`] groups in turn (module documentation).
fn spread_groups(s: &mut Session) {
    let mut count = [0usize; 3];
    for o in &mut s.observations {
        let (k, group) = match &mut o.kind {
            SessionKind::Contact { group, .. } => (0, group),
            SessionKind::Tracker { group, .. } => (1, group),
            SessionKind::Plane { group, .. } => (2, group),
            _ => continue,
        };
        // Pairs of rows: tracker and plane rows alternate robots 1 and 2, and a group that
        // sees both robots ties the two bases (a group of one robot is anchored at its base).
        group.push_str(&format!("_{}", (count[k] / 2) % GROUPS_PER_KIND));
        count[k] += 1;
    }
}

fn diagnose(truth: &Cell, seed: u64) -> CellDiagnoseReport {
    diagnose_session(&session(truth, seed))
}

fn diagnose_session(s: &Session) -> CellDiagnoseReport {
    let nominal = Cell::default_floor_wall();
    diagnose_cell_session(&nominal, s, &CellDiagnoseOptions::default(), &|_| {}).expect("diagnosis")
}

/// Rows of the tracker-nuisance sessions: 40 tracker rows, 20 per group, so that each half of
/// a held-out group (10 rows, 30 residuals) fits its frame, scale and drift (10 unknowns).
const N_TRACKER_ROWS: usize = 120;

/// Hides a tracker scale error `scale` (ratio) and a drift `drift_m` (m over the whole
/// recording, tracker axes) in every tracker row, as the library's model has them:
/// `p' = (1 + s)·(p + u·δ)`, `u = (point − first)/(last − first) − ½` over the group's rows.
fn hide_tracker_nuisance(s: &mut Session, scale: f64, drift_m: Vector3<f64>) {
    let mut span: HashMap<String, (usize, usize)> = HashMap::new();
    for o in &s.observations {
        if let SessionKind::Tracker { group, .. } = &o.kind {
            let e = span.entry(group.clone()).or_insert((o.point, o.point));
            *e = (e.0.min(o.point), e.1.max(o.point));
        }
    }
    for o in &mut s.observations {
        if let SessionKind::Tracker {
            group, p_tracker, ..
        } = &mut o.kind
        {
            let (first, last) = span[group.as_str()];
            let u = (o.point - first) as f64 / (last - first) as f64 - 0.5;
            *p_tracker = Point3::from((p_tracker.coords + drift_m * u) * (1.0 + scale));
        }
    }
}

/// The parameters of the one effect whose name ends with `suffix`, in report units:
/// (name, value, [low, high]); one per tracker group.
fn params_ending(r: &CellDiagnoseReport, suffix: &str) -> Vec<(String, f64, [f64; 2])> {
    r.effects[0]
        .parameters
        .iter()
        .filter(|p| p.name.ends_with(suffix))
        .map(|p| (p.name.clone(), p.value, p.ci95()))
        .collect()
}

fn named(r: &CellDiagnoseReport) -> Vec<String> {
    r.effects.iter().map(|e| e.family.name.clone()).collect()
}

/// The one parameter `name` of the one effect, in report units: (value, [low, high]).
fn param(r: &CellDiagnoseReport, name: &str) -> (f64, [f64; 2]) {
    let p = r.effects[0]
        .parameters
        .iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("no parameter `{name}` in {:?}", r.effects[0].parameters));
    (p.value, p.ci95())
}

#[test]
fn hidden_joint_offset_of_robot_1_is_the_one_effect_named_and_covered() {
    // 2 mrad on robot 1's joint 2 (a shoulder joint: seen by every kind).
    let truth_mrad = 2.0;
    for seed in [1, 2] {
        let mut truth = Cell::default_floor_wall();
        truth
            .robot1
            .errors
            .set(ErrorParam::JointOffset { joint: 1 }, truth_mrad * 1e-3);
        let r = diagnose(&truth, seed);
        assert_eq!(
            named(&r),
            ["robot 1 joint offsets"],
            "seed {seed}: {}",
            diagnose::render_cell_text(&r)
        );
        // A healthy session: the do-no-harm rule withholds nothing (it is no blanket refusal).
        assert!(
            !r.do_no_harm.withholds() && r.do_no_harm.exported_families == named(&r),
            "seed {seed}: {}",
            diagnose::render_cell_text(&r)
        );
        // The fits behind the exported and the full model are the ones their estimates come
        // from (what the verdict at the work site is predicted from).
        assert_eq!(
            r.export_model.fit.estimate.b1_from_b2,
            r.export_estimate.b1_from_b2
        );
        assert_eq!(
            r.full_model.fit.estimate.b1_from_b2,
            r.final_estimate.b1_from_b2
        );
        assert_eq!(
            r.full_model.fit.layout.len(),
            r.full_model.fit.covariance.nrows()
        );
        let (v, [lo, hi]) = param(&r, "robot 1 joint_offset joint 2");
        assert!(
            lo <= truth_mrad && truth_mrad <= hi,
            "seed {seed}: {v} mrad, 95 % [{lo}, {hi}] misses {truth_mrad}"
        );
        // Named for what it explains on held-out data: the tracker rows gain most.
        let tracker = r.effects[0]
            .held_out_by_kind
            .iter()
            .find(|k| k.kind == "tracker")
            .expect("tracker rows");
        assert!(
            tracker.rms_mm_after < 0.7 * tracker.rms_mm_before,
            "{tracker:?}"
        );
    }
}

#[test]
fn hidden_tip_offset_of_robot_2_is_the_one_effect_named_and_covered() {
    let truth_mm = 1.5;
    let mut truth = Cell::default_floor_wall();
    truth
        .robot2
        .errors
        .set(ErrorParam::Tip { axis: Axis::X }, truth_mm * 1e-3);
    let r = diagnose(&truth, 3);
    assert_eq!(
        named(&r),
        ["robot 2 tool `tip` tip"],
        "{}",
        diagnose::render_cell_text(&r)
    );
    let (v, [lo, hi]) = param(&r, "robot 2 tool `tip` tip x");
    assert!(
        lo <= truth_mm && truth_mm <= hi,
        "{v} mm, 95 % [{lo}, {hi}] misses {truth_mm}"
    );
}

#[test]
fn noise_only_mixed_sessions_name_nothing() {
    for seed in [1, 2, 3] {
        let r = diagnose(&Cell::default_floor_wall(), seed);
        assert!(
            r.effects.is_empty(),
            "seed {seed}: {}",
            diagnose::render_cell_text(&r)
        );
        // The baseline residuals match the stated σ of each kind of many rows (the tracker's
        // and the coincident rows': a median of ≥ 30 whitened residuals; the 10 contact rows'
        // median is too noisy to check): no noise scale above 1.5.
        assert!(
            r.baseline
                .iter()
                .filter(|k| k.residual_rows >= 30)
                .all(|k| k.noise_scale < 1.5),
            "{:?}",
            r.baseline
        );
    }
}

#[test]
fn hidden_tracker_scale_is_the_one_effect_named_and_covered() {
    // 300 ppm: 0.1 mm over the ±0.35 m teach cube, twice the tracker's σ.
    let truth_ppm = 300.0;
    let mut s = session_of(&Cell::default_floor_wall(), N_TRACKER_ROWS, 5);
    hide_tracker_nuisance(&mut s, truth_ppm * 1e-6, Vector3::zeros());
    let r = diagnose_session(&s);
    assert_eq!(
        named(&r),
        ["tracker scales"],
        "{}",
        diagnose::render_cell_text(&r)
    );
    let scales = params_ending(&r, " scale");
    assert_eq!(scales.len(), GROUPS_PER_KIND, "{scales:?}");
    for (name, v, [lo, hi]) in scales {
        assert!(
            lo <= truth_ppm && truth_ppm <= hi,
            "{name}: {v} ppm, 95 % [{lo}, {hi}] misses {truth_ppm}"
        );
    }
    let tracker = r.effects[0]
        .held_out_by_kind
        .iter()
        .find(|k| k.kind == "tracker")
        .expect("tracker rows");
    assert!(tracker.rms_mm_after < tracker.rms_mm_before, "{tracker:?}");
}

#[test]
fn hidden_tracker_drift_is_the_one_effect_named_and_covered() {
    // 0.5 mm along the tracker's x over each group's recording (±0.25 mm at its ends).
    let truth_mm = Vector3::new(0.5, 0.0, 0.0);
    let mut s = session_of(&Cell::default_floor_wall(), N_TRACKER_ROWS, 6);
    hide_tracker_nuisance(&mut s, 0.0, truth_mm * 1e-3);
    let r = diagnose_session(&s);
    assert_eq!(
        named(&r),
        ["tracker drifts"],
        "{}",
        diagnose::render_cell_text(&r)
    );
    let drifts: Vec<_> = [" drift x", " drift y", " drift z"]
        .iter()
        .map(|a| params_ending(&r, a))
        .collect();
    for (axis, per_group) in drifts.iter().enumerate() {
        assert_eq!(per_group.len(), GROUPS_PER_KIND, "{per_group:?}");
        for (name, v, [lo, hi]) in per_group {
            let truth = truth_mm[axis];
            assert!(
                *lo <= truth && truth <= *hi,
                "{name}: {v} mm, 95 % [{lo}, {hi}] misses {truth}"
            );
        }
    }
}

#[test]
fn noise_only_sessions_of_many_tracker_rows_name_nothing() {
    // The tracker-nuisance sessions without a hidden effect: neither a scale nor a drift (nor
    // anything else) is named.
    for seed in [5, 6] {
        let r = diagnose_session(&session_of(
            &Cell::default_floor_wall(),
            N_TRACKER_ROWS,
            seed,
        ));
        assert!(
            r.effects.is_empty(),
            "seed {seed}: {}",
            diagnose::render_cell_text(&r)
        );
    }
}

#[test]
fn hidden_joint_periodic_error_of_robot_1_is_the_one_effect_named_and_covered() {
    // A first harmonic of 2 mrad·sin(q2) on robot 1's shoulder joint (an error of the joint
    // offset's size that no constant offset holds: q2 spans both signs over the teach cube).
    let truth_mrad = 2.0;
    let mut truth = Cell::default_floor_wall();
    truth
        .robot1
        .errors
        .set(ErrorParam::PeriodicSin { joint: 1 }, truth_mrad * 1e-3);
    let r = diagnose(&truth, 1);
    assert_eq!(
        named(&r),
        ["robot 1 joint-periodic errors"],
        "{}",
        diagnose::render_cell_text(&r)
    );
    let (v, [lo, hi]) = param(&r, "robot 1 periodic_sin joint 2");
    assert!(
        lo <= truth_mrad && truth_mrad <= hi,
        "{v} mrad, 95 % [{lo}, {hi}] misses {truth_mrad}"
    );
}

/// Fresh poses of the FK checks: a new seed's coincident session (both robots within their
/// limits, over the same teach cube as the diagnosed session).
const FRESH_POSES: usize = 100;

/// RMS over the fresh poses of `robot`'s tip (robot 1: its base; robot 2: in b1 through each
/// cell's `b1_from_b2`) of `model` against `truth`, m: what `handclasp fk --cell` computes
/// (`true_base_from_tip` with the cell's `[robotN.errors]` and gravity).
fn tip_rms_m(truth: &Cell, model: &Cell, robot: u8) -> f64 {
    let poses = generate_session(
        truth,
        &SessionSpec::new(FRESH_POSES, Layout::Random, SPREAD_M),
        &mut trial_rng(99, 0),
    )
    .expect("fresh poses");
    let tip = |cell: &Cell, q: &[f64]| {
        let r: &CellRobot = if robot == 1 {
            &cell.robot1
        } else {
            &cell.robot2
        };
        let base_from_tip =
            true_base_from_tip(&r.model, &r.errors, q, &r.flange_from_tip, &r.g_base).expect("fk");
        if robot == 1 {
            base_from_tip.translation.vector
        } else {
            (cell.b1_from_b2 * base_from_tip).translation.vector
        }
    };
    let ss: f64 = poses
        .points
        .iter()
        .map(|p| {
            let q = if robot == 1 { &p.q1 } else { &p.q2 };
            (tip(truth, q) - tip(model, q)).norm_squared()
        })
        .sum();
    (ss / poses.points.len() as f64).sqrt()
}

/// The nominal floor–wall cell with the report's fitted corrections applied in memory (robot
/// errors, tool-0 tips, placement): what the export must write.
fn fitted_cell(r: &CellDiagnoseReport) -> Cell {
    let mut c = Cell::default_floor_wall();
    let e = &r.final_estimate;
    c.b1_from_b2 = e.b1_from_b2;
    for (robot, fit) in [(&mut c.robot1, &e.robot1), (&mut c.robot2, &e.robot2)] {
        robot.errors = fit.errors.clone();
        robot.flange_from_tip += fit.tool_tip_m[0];
    }
    c
}

/// Diagnoses `truth`'s hidden effect on the nominal floor–wall cell, checks that `family` is the
/// one named, exports, checks that the exported cell is the fitted model (both robots, robot 2
/// through the placement) and that it predicts the truth better than the input cell; returns
/// the loaded exported cell and the report.
fn diagnose_export_and_check(
    truth: &Cell,
    family: &str,
    dir: &std::path::Path,
) -> (Cell, CellDiagnoseReport) {
    let nominal = Cell::default_floor_wall();
    let r = diagnose(truth, 1);
    assert_eq!(named(&r), [family], "{}", diagnose::render_cell_text(&r));
    assert!(
        r.placement_fitted,
        "coincident and contact rows tie the bases"
    );
    let written = export_cell_diagnosis(&nominal, &r, dir).expect("export");
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "robot1_corrected.urdf",
            "robot2_corrected.urdf",
            "cell_corrected.toml",
            "effects.json",
            "report.json",
            "report.txt"
        ]
    );
    let exported = Cell::from_toml_file(&dir.join("cell_corrected.toml")).expect("loads");
    let fitted = fitted_cell(&r);
    for robot in [1, 2] {
        let d = tip_rms_m(&fitted, &exported, robot);
        assert!(
            d < kinematics::PATCH_TOLERANCE_M,
            "robot {robot}: exported cell {d:e} m off the fitted model"
        );
    }
    let (before, after) = (
        tip_rms_m(truth, &nominal, 1),
        tip_rms_m(truth, &exported, 1),
    );
    assert!(
        after < EXPORT_GAIN * before,
        "robot 1 tip rms vs truth: input cell {:.3} mm, exported {:.3} mm",
        before * 1e3,
        after * 1e3
    );
    (exported, r)
}

/// The exported cell must at least halve robot 1's error against the truth on fresh poses.
/// What it reaches is the fit's accuracy (measured: 2 mrad joint offset 0.05×, 2 mrad periodic
/// term 0.20×, as the 14 free periodic amplitudes carry the noise of 60 rows); the export's own
/// exactness is checked separately, to `kinematics::PATCH_TOLERANCE_M`.
const EXPORT_GAIN: f64 = 0.5;

#[test]
fn exported_cell_reproduces_a_hidden_joint_offset_on_fresh_poses() {
    let mut truth = Cell::default_floor_wall();
    truth
        .robot1
        .errors
        .set(ErrorParam::JointOffset { joint: 1 }, 2e-3);
    let dir = tempfile::tempdir().expect("tempdir");
    let (exported, _) = diagnose_export_and_check(&truth, "robot 1 joint offsets", dir.path());
    // The offset is a URDF term: it is in the corrected URDF, not in [robot1.errors].
    assert!(
        exported.robot1.errors.is_zero(),
        "{:?}",
        exported.robot1.errors
    );
    let urdf = std::fs::read_to_string(dir.path().join("robot1_corrected.urdf")).expect("urdf");
    assert!(
        urdf.contains("<calibration rising="),
        "offsets are calibrations"
    );
}

#[test]
fn exported_cell_reproduces_a_hidden_joint_periodic_error_through_its_errors_table() {
    let mut truth = Cell::default_floor_wall();
    truth
        .robot1
        .errors
        .set(ErrorParam::PeriodicSin { joint: 1 }, 2e-3);
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, r) = diagnose_export_and_check(&truth, "robot 1 joint-periodic errors", dir.path());
    // A URDF cannot hold a periodic term: it is in [robot1.errors].
    let text = std::fs::read_to_string(dir.path().join("cell_corrected.toml")).expect("cell");
    assert!(text.contains("periodic_sin_deg"), "{text}");
    // The report files are the report.
    let json = std::fs::read_to_string(dir.path().join("report.json")).expect("report.json");
    let v: serde_json::Value = serde_json::from_str(&json).expect("json");
    assert_eq!(v["effects"][0]["family"]["name"], named(&r)[0].as_str());
    let txt = std::fs::read_to_string(dir.path().join("report.txt")).expect("report.txt");
    assert_eq!(txt, diagnose::render_cell_text(&r));
}

#[test]
fn a_rejected_family_reports_its_value_and_interval() {
    // A 300 ppm tracker scale (named by the default criterion, see above) with a criterion no
    // family can pass: every candidate is rejected at step 1, and the scale's value, fitted
    // with it added to the (nominal) final model, still covers the truth.
    let truth_ppm = 300.0;
    let mut s = session_of(&Cell::default_floor_wall(), N_TRACKER_ROWS, 5);
    hide_tracker_nuisance(&mut s, truth_ppm * 1e-6, Vector3::zeros());
    let options = CellDiagnoseOptions {
        min_relative_gain: 0.9,
        ..CellDiagnoseOptions::default()
    };
    let r = diagnose_cell_session(&Cell::default_floor_wall(), &s, &options, &|_| {})
        .expect("diagnosis");
    assert!(r.effects.is_empty());
    assert_eq!(r.rejected_families.len(), r.candidates.len());
    let scale = r
        .rejected_families
        .iter()
        .find(|f| f.family.name == "tracker scales")
        .expect("the scale is a rejected family");
    assert!(scale.gain.relative_gain > 0.0, "{:?}", scale.gain);
    assert!(
        scale.reason.contains("a decrease of ≥ 90.0 % is needed"),
        "{}",
        scale.reason
    );
    assert_eq!(scale.parameters.len(), GROUPS_PER_KIND);
    for p in &scale.parameters {
        let [lo, hi] = p.ci95();
        assert_eq!(p.unit.suffix(), "ppm");
        assert!(
            lo <= truth_ppm && truth_ppm <= hi,
            "{}: {} ppm, 95 % [{lo}, {hi}] misses {truth_ppm}",
            p.name,
            p.value
        );
    }
    let text = diagnose::render_cell_text(&r);
    assert!(text.contains("Rejected families"), "{text}");
    assert!(
        text.contains("tracker scales: held-out χ² -"),
        "a held-out χ² that fell, signed: {text}"
    );
    // JSON: the added fields, the old ones unchanged.
    let v = serde_json::to_value(&r).expect("json");
    let json_scale = v["rejected_families"]
        .as_array()
        .expect("rejected_families")
        .iter()
        .find(|f| f["family"]["name"] == "tracker scales")
        .expect("in the JSON");
    let p0 = &json_scale["parameters"][0];
    assert_eq!(p0["ci95_ppm"].as_array().map(Vec::len), Some(2), "{p0}");
    assert!(p0["value_ppm"].is_f64() && json_scale["gain"]["relative_gain"].is_f64());
    assert!(v["stopped_at"].is_object() && v["stopped_candidates_held_out_chi2"].is_array());
}

#[test]
fn noise_only_tracker_scale_is_rejected_with_an_interval_around_zero() {
    let r = diagnose_session(&session_of(&Cell::default_floor_wall(), N_TRACKER_ROWS, 5));
    assert!(r.effects.is_empty(), "{}", diagnose::render_cell_text(&r));
    let scale = r
        .rejected_families
        .iter()
        .find(|f| f.family.name == "tracker scales")
        .expect("the scale is a rejected family");
    for p in &scale.parameters {
        let [lo, hi] = p.ci95();
        assert!(lo <= 0.0 && 0.0 <= hi, "{}: 95 % [{lo}, {hi}] ppm", p.name);
    }
}

/// Compliance of robot 1's joints 2 and 3 (rad/(N·m)) in the region-limited test: about 2 mrad
/// at the session's largest gravity torques, which change along the session's regions.
const TRUTH_COMPLIANCE: f64 = 1.5e-5;

/// A region-limited mixed session of `truth`: `per_cluster` teach points in each of four small
/// clusters (±3 cm) at the corners of a 0.5 m square about the cell's centre, so that each
/// joint-space region is one posture family and a model fitted without it extrapolates to it.
fn clustered_session(truth: &Cell, per_cluster: usize, seed: u64) -> Session {
    fn jitter<R: rand::Rng>(rng: &mut R) -> f64 {
        0.03 * (2.0 * rng.random::<f64>() - 1.0)
    }
    let mut rng = trial_rng(seed, 1);
    let c = truth.centre_b1;
    let mut points = Vec::new();
    for _ in 0..per_cluster {
        for (dx, dz) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
            points.push(Point3::new(
                c.x + dx + jitter(&mut rng),
                c.y + jitter(&mut rng),
                c.z + dz + jitter(&mut rng),
            ));
        }
    }
    let spec = SessionSpec {
        points_b1: Some(points),
        ..SessionSpec::new(4 * per_cluster, Layout::Random, SPREAD_M)
    };
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        ..KindSpec::default()
    };
    let (mut s, _) = generate_kind_session(truth, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .expect("clustered session");
    spread_groups(&mut s);
    s
}

/// Issue 20's seeded case: the truth is gravity compliance of robot 1, the session covers four
/// small regions. Joint offsets fitted in some regions absorb the sag there and mispredict the
/// others; the region-held-out criterion must pick the physical term, or the do-no-harm rule
/// must withhold the offsets. Either way what `--export` writes is no worse than nominal on
/// fresh poses of the whole teach cube. (Measured: the regions pick robot 1's compliance, 0.27–
/// 0.75 of nominal's held-out rms in each of the 3 regions; `--cv-folds groups` picks it too on
/// this session.)
#[test]
fn region_limited_compliance_truth_exports_no_offsets_that_extrapolate_badly() {
    let mut truth = Cell::default_floor_wall();
    for joint in [1, 2] {
        truth
            .robot1
            .errors
            .set(ErrorParam::Compliance { joint }, TRUTH_COMPLIANCE);
    }
    let nominal = Cell::default_floor_wall();
    let s = clustered_session(&truth, 18, 7);
    let options = CellDiagnoseOptions {
        folds: diagnose::FoldDesign::JointRegions,
        ..CellDiagnoseOptions::default()
    };
    let r = diagnose_cell_session(&nominal, &s, &options, &|_| {}).expect("diagnosis");
    let text = diagnose::render_cell_text(&r);
    assert_eq!(r.folds.design, diagnose::FoldDesign::JointRegions, "{text}");
    let exported = &r.do_no_harm.exported_families;
    let withheld: Vec<&str> = r
        .do_no_harm
        .withheld
        .iter()
        .map(|w| w.family.as_str())
        .collect();
    let offsets = "robot 1 joint offsets";
    let compliance = "robot 1 joint compliance";
    assert!(
        exported.iter().any(|f| f == compliance)
            || (withheld.contains(&offsets) && !exported.iter().any(|f| f == offsets)),
        "neither the physical term exported nor the offsets withheld: {text}"
    );
    // What the export writes does no harm on the whole teach cube.
    let mut written = Cell::default_floor_wall();
    let e = &r.export_estimate;
    written.b1_from_b2 = e.b1_from_b2;
    written.robot1.errors = e.robot1.errors.clone();
    written.robot1.flange_from_tip += e.robot1.tool_tip_m[0];
    let (before, after) = (
        tip_rms_m(&truth, &nominal, 1),
        tip_rms_m(&truth, &written, 1),
    );
    assert!(
        after <= before,
        "robot 1 tip rms vs truth on fresh poses: nominal {:.3} mm, export {:.3} mm\n{text}",
        before * 1e3,
        after * 1e3
    );
}

/// Every effect's candidate list without the two fields that differ by design between the
/// linearised prediction and cross-validating every candidate: `(cross-validated, ruled out)`.
fn take_candidate_lists(report: &mut serde_json::Value) -> Vec<(ChiList, ChiList)> {
    let list = |v: serde_json::Value| -> ChiList {
        serde_json::from_value(v).expect("a list of (family, χ²) pairs")
    };
    report["effects"]
        .as_array_mut()
        .expect("effects")
        .iter_mut()
        .map(|e| {
            let e = e.as_object_mut().expect("an effect");
            let tried = list(e.remove("candidates_held_out_chi2").expect("tried"));
            let ruled = list(e.remove("candidates_ruled_out").expect("ruled out"));
            (tried, ruled)
        })
        .collect()
}

/// `(family, held-out χ²)` pairs of a report's candidate lists.
type ChiList = Vec<(String, f64)>;

/// The linearised held-out criterion (`CellDiagnoseOptions::refit_every_candidate = false`: a
/// candidate is cross-validated only when a few Gauss–Newton steps per fold from the current
/// model's fold fits cannot rule it out) gives the report of cross-validating every candidate,
/// on the hidden-effect sessions of this file (a joint offset, seeds 1 and 2; a tool tip; a
/// joint-periodic error; a tracker scale; a tracker drift; noise only, seeds 1 and 5) and the
/// 84-row mixed session of the example truth (`sim-cell session --cell docs/examples/truth.toml
/// --kind mixed --n 84 --seed 4`, its groups spread): byte-identical JSON except each named
/// effect's candidate lists, where the pruned run lists a subset of the candidates with the
/// same held-out χ², and each candidate it ruled out has a cross-validated χ² at or above the
/// lower end of its prediction and above the chosen family's.
#[test]
fn predicted_candidates_choose_what_cross_validating_every_candidate_chooses() {
    let floor_wall = Cell::default_floor_wall();
    let with = |robot: u8, param: ErrorParam, value: f64| {
        let mut truth = floor_wall.clone();
        let errors = if robot == 1 {
            &mut truth.robot1.errors
        } else {
            &mut truth.robot2.errors
        };
        errors.set(param, value);
        truth
    };
    let offset = with(1, ErrorParam::JointOffset { joint: 1 }, 2e-3);
    let mut scale = session_of(&floor_wall, N_TRACKER_ROWS, 5);
    hide_tracker_nuisance(&mut scale, 300e-6, Vector3::zeros());
    let mut drift = session_of(&floor_wall, N_TRACKER_ROWS, 6);
    hide_tracker_nuisance(&mut drift, 0.0, Vector3::new(0.5e-3, 0.0, 0.0));
    let example_truth = Cell::from_toml_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/examples/truth.toml"),
    )
    .expect("the example truth");
    let sessions = [
        ("joint offset, seed 1", session(&offset, 1)),
        ("joint offset, seed 2", session(&offset, 2)),
        (
            "tool tip",
            session(&with(2, ErrorParam::Tip { axis: Axis::X }, 1.5e-3), 3),
        ),
        (
            "joint-periodic",
            session(&with(1, ErrorParam::PeriodicSin { joint: 1 }, 2e-3), 1),
        ),
        ("tracker scale", scale),
        ("tracker drift", drift),
        ("noise only, seed 1", session(&floor_wall, 1)),
        (
            "noise only, tracker rows",
            session_of(&floor_wall, N_TRACKER_ROWS, 5),
        ),
        ("example truth, 84 rows", session_of(&example_truth, 84, 4)),
    ];
    let mut ruled_out = 0;
    let mut named = 0;
    for (name, s) in &sessions {
        let run = |every: bool| {
            let options = CellDiagnoseOptions {
                refit_every_candidate: every,
                ..CellDiagnoseOptions::default()
            };
            let r = diagnose_cell_session(&floor_wall, s, &options, &|_| {}).expect("diagnosis");
            (serde_json::to_value(&r).expect("json"), r)
        };
        let ((mut pruned, report), (mut every, _)) = (run(false), run(true));
        let lists = take_candidate_lists(&mut pruned).into_iter();
        for (effect, ((tried, ruled), (all, none))) in
            lists.zip(take_candidate_lists(&mut every)).enumerate()
        {
            assert!(
                none.is_empty(),
                "{name}: nothing is ruled out when every candidate is cross-validated"
            );
            assert_eq!(
                tried.len() + ruled.len(),
                all.len(),
                "{name}, effect {effect}"
            );
            let chosen = report.effects[effect].gain.held_out_chi2_after;
            let full = |f: &str| all.iter().find(|a| a.0 == f).map(|a| a.1);
            for (f, chi2) in &tried {
                assert_eq!(full(f), Some(*chi2), "{name}, effect {effect}: {f}");
            }
            for (f, low) in &ruled {
                let chi2 = full(f).expect("every candidate is listed");
                assert!(
                    chi2 >= *low && chi2 > chosen,
                    "{name}, effect {effect}: {f} ruled out at ≥ {low}, cross-validated {chi2}, chosen {chosen}"
                );
            }
            ruled_out += ruled.len();
        }
        assert_eq!(
            pruned,
            every,
            "{name}: {}",
            diagnose::render_cell_text(&report)
        );
        named += report.effects.len();
    }
    // The sessions exercise accepted steps, and the prediction rules candidates out there.
    assert!(
        named >= 6 && ruled_out > 0,
        "{named} effects named, {ruled_out} candidates ruled out"
    );
}
