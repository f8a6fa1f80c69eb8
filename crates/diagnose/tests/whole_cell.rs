//! Hidden-effect tests of the whole-cell diagnosis (`diagnose::diagnose_cell_session`) on mixed
//! sessions simulated by `sim_cell::generate_kind_session` (coincident, contact, tracker and plane
//! rows in turn) on the shipped floor–wall cell: one hidden effect must be the only family named,
//! with its true value inside the reported 95 % interval (joint offsets, a tool tip, a
//! joint-periodic error, a tracker scale, a tracker drift); a noise-only session names nothing.
//!
//! The simulated session has one group per kind; like real sessions (one tracker frame or
//! plane per recorded file) the rows of each kind are spread over [`GROUPS_PER_KIND`] groups in
//! turn, so the held-out criterion has whole groups to hold out.

use std::collections::HashMap;

use diagnose::{diagnose_cell_session, CellDiagnoseOptions, CellDiagnoseReport};
use kinematics::{Axis, ErrorParam};
use nalgebra::{Point3, Vector3};
use sim_cell::{
    generate_kind_session, trial_rng, Cell, KindSpec, Layout, Session, SessionKind, SessionSpec,
    SimKind,
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
    s
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
