//! `diagnose::diagnose_cell_session` (the whole-cell diagnosis of sessions with contact,
//! tracker and plane rows) on sessions simulated from fuzz bytes, so the engine itself runs:
//! baseline, noise scaling, blunder screen, group-wise held-out selection, intervals, report.
//!
//! The session: a shipped floor-mounted cell with optional hidden kinematic errors on either
//! robot, simulated by `sim_cell::generate_kind_session` (kind, row count, layout, spread and
//! seed from the bytes), its rows spread over 1–3 nuisance groups per kind as real sessions have
//! one tracker frame or plane per file. The diagnosis runs with a small budget. Invariant: no
//! panic (degenerate sessions get a typed error) and the text report renders.
#![no_main]

use handclasp_fuzz as common;

use arbitrary::Arbitrary;
use diagnose::{diagnose_cell_session, render_cell_text, CellDiagnoseOptions};
use handclasp_cell::SessionKind;
use kinematics::{Axis, ErrorParam};
use libfuzzer_sys::fuzz_target;
use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

#[derive(Debug, Arbitrary)]
struct HiddenError {
    robot2: bool,
    joint: u8,
    /// 0 offset, 1–3 origin xyz, 4 tip x, 5 periodic sin.
    kind: u8,
    /// × 1e-4 (m or rad).
    value: i8,
}

#[derive(Debug, Arbitrary)]
struct Input {
    cell: u8,
    kind: u8,
    rows: u8,
    layout: u8,
    spread_cm: u8,
    groups: u8,
    seed: u64,
    errors: Vec<HiddenError>,
    max_steps: u8,
    max_folds: u8,
    screen: bool,
}

const KINDS: [SimKind; 4] = [
    SimKind::Contact,
    SimKind::Tracker,
    SimKind::Plane,
    SimKind::Mixed,
];
const LAYOUTS: [Layout; 4] = [
    Layout::Tetrahedron,
    Layout::Random,
    Layout::Planar,
    Layout::Clustered,
];
const AXES: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

fn param(e: &HiddenError, dof: usize) -> ErrorParam {
    let joint = usize::from(e.joint) % dof;
    match e.kind % 6 {
        0 => ErrorParam::JointOffset { joint },
        k @ 1..=3 => ErrorParam::OriginXyz {
            joint,
            axis: AXES[usize::from(k - 1)],
        },
        4 => ErrorParam::Tip { axis: Axis::X },
        _ => ErrorParam::PeriodicSin { joint },
    }
}

fuzz_target!(|input: Input| {
    if input.errors.len() > 4 {
        return;
    }
    // The three floor-mounted shipped cells (the CTU cell's real sessions are covered by the
    // CTU e2e tests).
    let cells = &common::cells()[..3];
    let nominal = &cells[usize::from(input.cell) % cells.len()];
    let mut truth = nominal.clone();
    for e in &input.errors {
        let robot = if e.robot2 {
            &mut truth.robot2
        } else {
            &mut truth.robot1
        };
        let p = param(e, robot.model.dof());
        robot.errors.set(p, f64::from(e.value) * 1e-4);
    }
    let n = 4 + usize::from(input.rows % 45);
    let spread = 0.05 + f64::from(input.spread_cm) * 0.01;
    let spec = SessionSpec::new(n, LAYOUTS[usize::from(input.layout) % 4], spread);
    let kinds = KindSpec {
        kind: KINDS[usize::from(input.kind) % KINDS.len()],
        ..KindSpec::default()
    };
    let Ok((mut session, _)) =
        generate_kind_session(&truth, &spec, &kinds, None, &mut trial_rng(input.seed, 0))
    else {
        return; // unreachable layouts are the generator's typed error, not the engine's
    };
    let groups = 1 + usize::from(input.groups % 3);
    let mut count = [0usize; 3];
    for o in &mut session.observations {
        let (k, group) = match &mut o.kind {
            SessionKind::Contact { group, .. } => (0, group),
            SessionKind::Tracker { group, .. } => (1, group),
            SessionKind::Plane { group, .. } => (2, group),
            _ => continue,
        };
        group.push_str(&format!("_{}", (count[k] / 2) % groups));
        count[k] += 1;
    }
    let mut options = CellDiagnoseOptions {
        max_steps: 1 + usize::from(input.max_steps % 2),
        max_folds: 2 + usize::from(input.max_folds % 3),
        screen_blunders: input.screen,
        ..CellDiagnoseOptions::default()
    };
    options.solve.lm = options
        .solve
        .lm
        .with_max_iterations(30)
        .expect("30 iterations is a valid cap");
    let Ok(report) = diagnose_cell_session(nominal, &session, &options, &|_| {}) else {
        return; // typed errors (too few rows, degenerate groups) are the expected outcome
    };
    // The text report renders whatever the engine found (a kind without held-out rows has a
    // NaN held-out rms by design, so finiteness is not asserted here).
    let _ = render_cell_text(&report);
});
