//! The prior-scale benchmark (issue 20, item 4; `sim-cell oracle`): how close the whole-cell
//! fit's evidence-chosen prior scales come to a MAP fit that knows the true prior (the oracle),
//! and how it compares with the placement-only fit, on simulated sessions of any cell.
//!
//! Per cell and seed: the cell's stated tolerances are set to `tol` (joint offsets, origin xyz,
//! tips; origin rpy off, as the truth draws none); the truth's errors are drawn from
//! `U(±truth_factor·tol)` ([`crate::plan::draw_kinematic_errors`]); a session of `points`
//! random handclasps (spread cube around the cell's teach centre, alignment σ `noise_mm`) is
//! simulated; four fits of it are scored by their cooperative rms over `EVAL_PAIRS` held-out
//! pairs drawn on the nominal cell (the same for every seed of a cell):
//! - `evidence`: `calibrate_cell` then `widen_prior` (the evidence chooses the scales,
//!   1e-3 … 100; what `calibrate --cell` does on a session its result check does not refuse —
//!   the check itself is not run here: the sessions are simulated from the cell's own model);
//! - `oracle`: `calibrate_cell_with` the scale fixed at `truth_factor` (the true prior: the
//!   truth is drawn from exactly the tolerances × that factor);
//! - `held`: the scale fixed at 1 (the stated tolerances held);
//! - `placement`: the placement-only fit (`FitModel::Placement`, what `--method lsq` fits from
//!   the same rows, weighted by the same σ).

use calib_core::whole_cell::{
    calibrate_cell_with, measure_cooperative_error, widen_prior, CellCalibration, ConfigPair,
    ScaleMethod, ScreenOptions, SolveOptions, Tolerance,
};
use handclasp_cell::cell::Cell;
use handclasp_cell::problem::{cell_problem, truth_estimate, FitModel};
use nalgebra::Vector3;

use crate::error::SimError;
use crate::layout::Layout;
use crate::plan::{draw_kinematic_errors, nominal_cell, reachable_handclasps, share_trunk_errors};
use crate::simulate::{generate_session, SessionSpec};
use crate::trial_rng;

/// Held-out configuration pairs per cell.
pub const EVAL_PAIRS: usize = 200;

/// The benchmark's settings.
#[derive(Debug, Clone)]
pub struct OracleOptions {
    /// Seeds per cell (trials `0..seeds` of the master seed).
    pub seeds: usize,
    /// Master seed.
    pub seed: u64,
    /// Handclasps per session.
    pub points: usize,
    /// Alignment σ per axis, mm.
    pub noise_mm: f64,
    /// Side of the teach cube around the cell's teach centre, mm.
    pub spread_mm: f64,
    /// Stated joint-offset tolerance, degrees (half-width).
    pub joint_deg: f64,
    /// Stated origin-xyz and tip tolerance, mm (half-width).
    pub origin_mm: f64,
    /// The truth is drawn from `U(±truth_factor·tolerance)` (1: the tolerances are right).
    pub truth_factor: f64,
}

impl Default for OracleOptions {
    /// Issue 20's realistic cell: 40 points at σ 0.3 mm, joints ±0.05°, origins and tips
    /// ±0.5 mm, a 700 mm cube, 20 seeds.
    fn default() -> Self {
        OracleOptions {
            seeds: 20,
            seed: 1,
            points: 40,
            noise_mm: 0.3,
            spread_mm: 700.0,
            joint_deg: 0.05,
            origin_mm: 0.5,
            truth_factor: 1.0,
        }
    }
}

/// One trial's cooperative rms over the held-out pairs, m, and the evidence's choice.
#[derive(Debug, Clone)]
pub struct OracleTrial {
    /// The trial (seed index).
    pub trial: usize,
    /// The evidence-chosen fit.
    pub evidence_m: f64,
    /// The fit at the true prior.
    pub oracle_m: f64,
    /// The fit at the stated tolerances (scale 1).
    pub held_m: f64,
    /// The placement-only fit.
    pub placement_m: f64,
    /// The evidence's scales, e.g. `1` or `joint_offset ×4, origin_xyz ×1, tip ×1`.
    pub scales: String,
}

/// The trials of one cell.
#[derive(Debug, Clone)]
pub struct OracleCell {
    /// The cell's name (its file stem).
    pub name: String,
    /// Its trials (sessions that could not be simulated or fitted are left out and counted).
    pub trials: Vec<OracleTrial>,
    /// Trials left out.
    pub skipped: usize,
}

fn fit_error(what: &str, e: impl std::fmt::Display) -> SimError {
    SimError::InvalidInput(format!("{what}: {e}"))
}

/// Runs the benchmark on `cell` (named `name`).
pub fn run_cell(name: &str, cell: &Cell, o: &OracleOptions) -> Result<OracleCell, SimError> {
    let tol = Tolerance {
        joint_offset_rad: o.joint_deg.to_radians(),
        origin_xyz_m: o.origin_mm * 1e-3,
        origin_rpy_rad: 0.0,
        tip_m: o.origin_mm * 1e-3,
        ..Tolerance::default()
    };
    let mut stated = nominal_cell(cell);
    stated.robot1.tolerance = tol;
    stated.robot2.tolerance = tol;
    stated.noise = cell.noise;
    stated.noise.alignment_m = Vector3::repeat(o.noise_mm * 1e-3);
    let spread_m = o.spread_mm * 1e-3;
    let mut setup = trial_rng(o.seed, u64::MAX);
    let nominal = nominal_cell(&stated);
    let (held_out, _) = reachable_handclasps(
        &nominal,
        &nominal.centre_b1,
        spread_m,
        EVAL_PAIRS,
        20 * EVAL_PAIRS,
        &mut setup,
        &mut |_, _| {},
    );
    if held_out.len() < EVAL_PAIRS {
        return Err(SimError::InvalidInput(format!(
            "{name}: only {} of {EVAL_PAIRS} held-out pairs reachable in the {:.0} mm cube; \
             reduce --spread-mm",
            held_out.len(),
            o.spread_mm
        )));
    }
    let pairs: Vec<ConfigPair> = held_out
        .into_iter()
        .map(|p| ConfigPair {
            q1: p.q1,
            q2: p.q2,
            tool1: 0,
            tool2: 0,
        })
        .collect();
    let mut trials = Vec::new();
    let mut skipped = 0;
    for t in 0..o.seeds {
        let mut rng = trial_rng(o.seed, t as u64);
        let mut truth = stated.clone();
        let draw = Tolerance {
            joint_offset_rad: tol.joint_offset_rad * o.truth_factor,
            origin_xyz_m: tol.origin_xyz_m * o.truth_factor,
            tip_m: tol.tip_m * o.truth_factor,
            ..tol
        };
        for r in [&mut truth.robot1, &mut truth.robot2] {
            r.tolerance = draw;
            draw_kinematic_errors(r, &mut rng);
            r.tolerance = tol;
        }
        share_trunk_errors(&mut truth);
        let spec = SessionSpec::new(o.points, Layout::Random, spread_m);
        let Ok(session) = generate_session(&truth, &spec, &mut rng) else {
            skipped += 1;
            continue;
        };
        let problem = cell_problem(&truth, &session, FitModel::Kinematic);
        let truth_est = truth_estimate(&truth, &problem);
        let fit =
            |scale: Option<f64>, model: FitModel| -> Result<(f64, CellCalibration), SimError> {
                let p = cell_problem(&truth, &session, model);
                let (solve, screen) = (SolveOptions::default(), ScreenOptions::default());
                let mut cal = calibrate_cell_with(&p, &solve, &screen, scale)
                    .map_err(|e| fit_error(name, e))?;
                if scale.is_none() {
                    if let Some(wide) =
                        widen_prior(&p, &cal, &solve, &screen).map_err(|e| fit_error(name, e))?
                    {
                        cal = wide;
                    }
                }
                let e = measure_cooperative_error(&problem, &cal.fit.estimate, &truth_est, &pairs)
                    .map_err(|e| fit_error(name, e))?;
                Ok((e.rms_m, cal))
            };
        let run = || -> Result<OracleTrial, SimError> {
            let (evidence_m, cal) = fit(None, FitModel::Kinematic)?;
            let (oracle_m, _) = fit(Some(o.truth_factor), FitModel::Kinematic)?;
            let (held_m, _) = fit(Some(1.0), FitModel::Kinematic)?;
            let (placement_m, _) = fit(None, FitModel::Placement)?;
            let c = &cal.prior_scale;
            let scales = match c.method {
                ScaleMethod::EvidencePerFamily => c
                    .families
                    .iter()
                    .map(|f| {
                        format!(
                            "{} ×{}",
                            f.family,
                            calib_core::whole_cell::format_scale(f.scale)
                        )
                    })
                    .collect::<Vec<_>>()
                    .join(", "),
                _ => calib_core::whole_cell::format_scale(c.scale),
            };
            Ok(OracleTrial {
                trial: t,
                evidence_m,
                oracle_m,
                held_m,
                placement_m,
                scales,
            })
        };
        match run() {
            Ok(trial) => trials.push(trial),
            Err(_) => skipped += 1,
        }
    }
    Ok(OracleCell {
        name: name.to_string(),
        trials,
        skipped,
    })
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    calib_core::stats::quantile(v, 0.5)
}

/// The summary table of `cells` (markdown), one row per cell and one for all: median and worst
/// ratio of the evidence fit to the oracle, the medians in mm, and the trials where the evidence
/// fit is more than 5 % worse than the placement-only fit.
pub fn render_table(cells: &[OracleCell], o: &OracleOptions) -> String {
    let mut s = format!(
        "truth U(±{}·tol), tol: joints ±{}°, origins and tips ±{} mm; {} points, σ {} mm, {} mm cube, {} held-out pairs\n\n",
        o.truth_factor, o.joint_deg, o.origin_mm, o.points, o.noise_mm, o.spread_mm, EVAL_PAIRS
    );
    s.push_str("| cell | trials | evidence/oracle median | worst | evidence mm (median) | oracle mm | held (scale 1) mm | placement mm | evidence > 1.05 × placement | scales chosen |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
    let mut all: Vec<&OracleTrial> = Vec::new();
    let row = |name: &str, t: &[&OracleTrial], scales: String| {
        let mut ratio: Vec<f64> = t.iter().map(|x| x.evidence_m / x.oracle_m).collect();
        let worst = ratio.iter().cloned().fold(0.0, f64::max);
        let worse = t
            .iter()
            .filter(|x| x.evidence_m > 1.05 * x.placement_m)
            .count();
        let med = |f: &dyn Fn(&OracleTrial) -> f64| {
            let mut v: Vec<f64> = t.iter().map(|x| f(x)).collect();
            median(&mut v) * 1e3
        };
        format!(
            "| {name} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {worse}/{} | {scales} |\n",
            t.len(),
            median(&mut ratio),
            worst,
            med(&|x| x.evidence_m),
            med(&|x| x.oracle_m),
            med(&|x| x.held_m),
            med(&|x| x.placement_m),
            t.len()
        )
    };
    for c in cells {
        let t: Vec<&OracleTrial> = c.trials.iter().collect();
        let mut counts: Vec<(String, usize)> = Vec::new();
        for x in &t {
            match counts.iter_mut().find(|(k, _)| *k == x.scales) {
                Some(e) => e.1 += 1,
                None => counts.push((x.scales.clone(), 1)),
            }
        }
        counts.sort_by_key(|c| std::cmp::Reverse(c.1));
        let scales = counts
            .iter()
            .map(|(k, n)| format!("{k} ({n})"))
            .collect::<Vec<_>>()
            .join("; ");
        s.push_str(&row(&c.name, &t, scales));
        all.extend(t);
    }
    s.push_str(&row("all", &all, String::new()));
    let skipped: usize = cells.iter().map(|c| c.skipped).sum();
    if skipped > 0 {
        s.push_str(&format!(
            "\n{skipped} trial(s) left out (session unreachable or a fit failed)\n"
        ));
    }
    s
}
