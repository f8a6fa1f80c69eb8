//! Hidden-effect tests of `sim_cell::diagnose` on sessions simulated from the project's URDFs:
//! a random effect of the catalogue (random robot, joint, axis, realistic magnitude and sign)
//! hidden among the alignment noise must be named and covered by its 95% interval; noise-only
//! sessions must come back clean; two simultaneous effects must both be found.
//!
//! CI runs a small seeded set; `cargo test -p sim-cell --release --test diagnose_hidden --
//! --ignored --nocapture` runs the larger study.

use std::path::PathBuf;

use kinematics::KinematicErrors;
use rand::Rng;
use sim_cell::diagnose::{
    self, Candidate, DiagnoseCell, DiagnoseOptions, DiagnoseReport, EffectKind,
};

/// Points per session (the issue's typical 20–60).
const N_POINTS: usize = 40;
/// Half size of the teach box around the bases' midpoint, m.
const HALF_SIZE_M: f64 = 0.5;

fn cell() -> DiagnoseCell {
    let robots = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("cell.toml");
    let toml = format!(
        r#"[robot1]
urdf = "{}"
mount = "floor"
tip_mm = [0.0, 0.0, 150.0]
[robot2]
urdf = "{}"
mount = "floor"
tip_mm = [0.0, 0.0, 120.0]
[b1_from_b2]
xyz_mm = [1800.0, 50.0, 0.0]
zyz_deg = [180.0, 0.0, 0.0]
[noise]
alignment_mm = 0.1
"#,
        robots.join("va1400.urdf").display(),
        robots.join("hp20.urdf").display()
    );
    std::fs::write(&path, toml).expect("write cell");
    diagnose::load_cell(&path).expect("the test cell loads")
}

/// Realistic magnitude (SI) of a kind, random sign: offsets/tilts 0.05–0.3°, lengths 0.5–3 mm,
/// compliance 0.05–0.3 deg/(kN·m), scale 2e-4–1e-3.
fn magnitude(kind: EffectKind, rng: &mut impl Rng) -> f64 {
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let out = match kind {
        EffectKind::JointOffset | EffectKind::MountTilt => rng.random_range(0.05..0.3),
        EffectKind::LinkLength | EffectKind::TipOffset => rng.random_range(0.5..3.0),
        EffectKind::Compliance => rng.random_range(0.05..0.3),
        EffectKind::JointScale => rng.random_range(2e-4..1e-3),
    };
    sign * out / kind.to_output()
}

fn inject(cell: &DiagnoseCell, hidden: &[(Candidate, f64)]) -> (KinematicErrors, KinematicErrors) {
    let mut e1 = KinematicErrors::zero(cell.robot1.model.dof());
    let mut e2 = KinematicErrors::zero(cell.robot2.model.dof());
    for (c, v) in hidden {
        if c.robot == 1 {
            e1.set(c.param, *v);
        } else {
            e2.set(c.param, *v);
        }
    }
    (e1, e2)
}

fn run(cell: &DiagnoseCell, hidden: &[(Candidate, f64)], seed: u64) -> DiagnoseReport {
    let (e1, e2) = inject(cell, hidden);
    let session = diagnose::simulate_session(cell, &e1, &e2, N_POINTS, HALF_SIZE_M, seed)
        .expect("simulated session");
    let options = DiagnoseOptions {
        seed,
        trials: 100,
        ..DiagnoseOptions::default()
    };
    diagnose::diagnose(cell, &session, &options).expect("diagnosis runs")
}

fn unidentifiable(report: &DiagnoseReport, c: &Candidate) -> bool {
    let label = c.label();
    report
        .families
        .iter()
        .any(|f| f.confounded_with_base.contains(&label) || f.no_effect.contains(&label))
}

/// Outcome of one hidden-effect session: (detectable, found, covered). An identifiable effect
/// counts as detectable when its true magnitude is at least 1.5× the report's minimum detectable
/// value (80% power at 1×, ≈ 99% at 1.5×); weaker ones are not required to be named.
fn hidden_trial(cell: &DiagnoseCell, seed: u64) -> (bool, bool, bool) {
    let cands = diagnose::catalogue(cell.robot1.model.dof(), cell.robot2.model.dof());
    let mut rng = diagnose::trial_rng(seed, 0);
    let c = cands[rng.random_range(0..cands.len())];
    let v = magnitude(c.kind, &mut rng);
    let report = run(cell, &[(c, v)], seed);
    if unidentifiable(&report, &c) {
        // Provably confounded under this design: it must be reported as such, never fitted.
        assert!(
            report
                .effects
                .iter()
                .all(|e| !e.confounded_with.contains(&c.label())),
            "seed {seed}: {} fitted although unidentifiable",
            c.label()
        );
        return (false, false, false);
    }
    let label = c.label();
    let mde = report
        .min_detectable
        .iter()
        .find(|d| d.label == label)
        .map_or(f64::INFINITY, |d| d.value);
    if (v * c.kind.to_output()).abs() < 1.5 * mde {
        return (false, false, false);
    }
    let hit = report
        .effects
        .iter()
        .find(|e| e.confounded_with.contains(&label));
    let covered = hit.is_some_and(|e| {
        let exact = e.kind == c.kind
            && e.robot == c.robot
            && e.joint == c.joint.map(|j| j + 1)
            && e.axis == c.axis.map(|a| a.name());
        let truth = v * c.kind.to_output();
        !exact || (e.ci95[0] <= truth && truth <= e.ci95[1])
    });
    if hit.is_none() {
        eprintln!(
            "seed {seed}: missed {label} = {:.4} {}: {:?}",
            v * c.kind.to_output(),
            c.kind.unit(),
            report.steps
        );
    }
    (true, hit.is_some(), covered)
}

#[test]
fn noise_only_sessions_come_back_clean() {
    let cell = cell();
    // 10 seeded sessions at a 5% family-wise level: ≥ 3 false alarms has probability ≈ 1%.
    let alarms = (0..10)
        .filter(|&s| !run(&cell, &[], 1000 + s).effects.is_empty())
        .count();
    assert!(
        alarms <= 2,
        "{alarms} false alarms in 10 noise-only sessions"
    );
}

#[test]
fn a_hidden_effect_is_named_and_covered() {
    let cell = cell();
    let (mut ident, mut found, mut covered) = (0, 0, 0);
    for seed in 0..12 {
        let (i, f, c) = hidden_trial(&cell, 2000 + seed);
        ident += i as usize;
        found += f as usize;
        covered += c as usize;
    }
    // Small effects on short levers may be honestly below detection: require 80% named and
    // 80% of the named ones covered (95% intervals).
    assert!(ident >= 4, "only {ident} detectable draws");
    assert!(found * 5 >= ident * 4, "named {found} of {ident}");
    assert!(covered * 5 >= found * 4, "covered {covered} of {found}");
}

#[test]
fn two_simultaneous_effects_are_both_found() {
    let cell = cell();
    let cands = diagnose::catalogue(cell.robot1.model.dof(), cell.robot2.model.dof());
    let pick = |robot: u8, kind: EffectKind, joint: usize| {
        *cands
            .iter()
            .find(|c| c.robot == robot && c.kind == kind && c.joint == Some(joint))
            .expect("in catalogue")
    };
    // Robot 2 joint-3 offset 0.2° and robot 1 joint-2 offset −0.15°.
    let hidden = [
        (pick(2, EffectKind::JointOffset, 2), 0.2f64.to_radians()),
        (pick(1, EffectKind::JointOffset, 1), (-0.15f64).to_radians()),
    ];
    for seed in 0..3 {
        let report = run(&cell, &hidden, 3000 + seed);
        for (c, _) in &hidden {
            assert!(
                report
                    .effects
                    .iter()
                    .any(|e| e.confounded_with.contains(&c.label())),
                "seed {seed}: {} not found: {:?}\n{:#?}",
                c.label(),
                report.steps,
                report
                    .effects
                    .iter()
                    .map(|e| (&e.confounded_with, e.value))
                    .collect::<Vec<_>>()
            );
        }
        assert!(report.heldout_rms_after_mm < report.heldout_rms_before_mm);
    }
}

#[test]
#[ignore]
fn many_seeds_false_alarms_and_detection() {
    let cell = cell();
    let trials = 200;
    let alarms = (0..trials)
        .filter(|&s| !run(&cell, &[], 10_000 + s).effects.is_empty())
        .count();
    let rate = alarms as f64 / trials as f64;
    println!("noise-only false-alarm rate: {rate:.3} ({alarms}/{trials})");
    let (mut ident, mut found, mut covered) = (0, 0, 0);
    for seed in 0..trials {
        let (i, f, c) = hidden_trial(&cell, 20_000 + seed);
        ident += i as usize;
        found += f as usize;
        covered += c as usize;
    }
    println!("hidden effects: identifiable {ident}/{trials}, named {found}, covered {covered}");
    assert!(rate <= 0.05);
}
