//! Hidden-effect tests of the whole-cell diagnosis (`diagnose::diagnose_cell_session`) on mixed
//! sessions simulated by `sim_cell::generate_kind_session` (coincident, contact, tracker and plane
//! rows in turn) on the shipped floor–wall cell: one hidden effect must be the only family named,
//! with its true value inside the reported 95 % interval; a noise-only session names nothing.
//!
//! The simulated session has one group per kind; like real sessions (one tracker frame or
//! plane per recorded file) the rows of each kind are spread over [`GROUPS_PER_KIND`] groups in
//! turn, so the held-out criterion has whole groups to hold out.

use diagnose::{diagnose_cell_session, CellDiagnoseOptions, CellDiagnoseReport};
use kinematics::{Axis, ErrorParam};
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
    let spec = SessionSpec::new(N_ROWS, Layout::Random, SPREAD_M);
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
    let nominal = Cell::default_floor_wall();
    let s = session(truth, seed);
    diagnose_cell_session(&nominal, &s, &CellDiagnoseOptions::default(), &mut |_| {})
        .expect("diagnosis")
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
