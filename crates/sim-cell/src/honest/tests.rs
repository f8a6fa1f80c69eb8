//! The honest-predictions check: a small seeded test and the larger benchmark
//! (`cargo test --release -p sim-cell --lib honest::tests::benchmark -- --ignored --nocapture`).

use super::*;
use std::path::Path;

/// The alignment noise of the check, per axis (the cells' own), m.
const SIGMA_M: f64 = 3e-4;

/// Handclasps per session.
const POSES: usize = 40;

fn shipped(name: &str) -> Cell {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    Cell::from_toml_file(&root.join(format!("{name}.toml"))).expect("shipped cell loads")
}

/// Trials on each of `cells` for seeds `seeds`, printing each.
fn trials(cells: &[&str], seeds: std::ops::Range<u64>) -> Vec<HonestTrial> {
    let mut out = Vec::new();
    for name in cells {
        let cell = shipped(name);
        for seed in seeds.clone() {
            let Some(t) = honest_trial(&cell, POSES, SIGMA_M, seed) else {
                println!("| {name} | {seed} | no trial (session or fit failed) |");
                continue;
            };
            println!(
                "| {name} | {seed} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {} | {} |",
                t.predicted_rms_m * 1e3,
                t.data_rms_m * 1e3,
                t.prior_rms_m * 1e3,
                t.model_error_rms_m * 1e3,
                t.bound95_m * 1e3,
                t.actual_rms_m * 1e3,
                t.ratio(),
                if t.covered() { "yes" } else { "no" },
                t.prior_scale
            );
            out.push(t);
        }
    }
    out
}

const HEADER: &str = "| cell | seed | predicted rms, mm | data part | prior part | model part | 95 % bound | actual rms | predicted / actual | bound covers | prior scale |\n|---|---|---|---|---|---|---|---|---|---|---|";

/// Small seeded check on two robot pairs (floor–wall, floor–ceiling) × 3 seeds: every trial
/// runs, the parts' squares sum to the total, the median predicted / actual lies in
/// [`RATIO_BAND`] and the 95 % bound covers at least [`MIN_COVERAGE`] of the cells (with six
/// cells: all six).
#[test]
fn predictions_are_honest_on_drawn_truths() {
    println!("{HEADER}");
    let t = trials(&["floor-wall", "floor-ceiling"], 1..4);
    assert_eq!(t.len(), 6, "every trial runs");
    for x in &t {
        let parts =
            (x.data_rms_m.powi(2) + x.prior_rms_m.powi(2) + x.model_error_rms_m.powi(2)).sqrt();
        // rms² = data² + prior² + model² exactly; round-off of the traces only.
        assert!(
            (parts - x.predicted_rms_m).abs() <= 1e-9 * x.predicted_rms_m,
            "{x:?}"
        );
    }
    let s = HonestSummary::of(&t).unwrap();
    println!("{s:?}");
    assert!(s.honest(), "{s:?}");
}

/// The benchmark of BENCHMARKS.md ("Honest predictions"): the three shipped robot pairs ×
/// `HONEST_SEEDS` seeds (default 10), 40 handclasps at σ 0.3 mm, errors on every joint drawn
/// from the cells' tolerances; prints each trial and the summary.
#[test]
#[ignore = "benchmark: run in release with --ignored --nocapture"]
fn benchmark() {
    let seeds: u64 = std::env::var("HONEST_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10);
    println!("{HEADER}");
    let t = trials(
        &["floor-floor", "floor-wall", "floor-ceiling"],
        1..seeds + 1,
    );
    let s = HonestSummary::of(&t).unwrap();
    let fired = t.iter().filter(|x| x.model_error_rms_m > 0.0).count();
    println!(
        "cells {}: median predicted / actual {:.2} (range {:.2}–{:.2}), 95 % bound covers {:.0} % ; honest: {}; model-error term added in {fired} of {} cells",
        s.cells,
        s.median_ratio,
        s.ratio_range[0],
        s.ratio_range[1],
        s.coverage * 100.0,
        s.honest(),
        s.cells
    );
}
