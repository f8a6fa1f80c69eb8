//! The study: σ̂ per cell and method, one σ for all cells (likelihood-ratio test), whether both
//! methods share σ (parametric bootstrap), and each published value beside its simulated band.

use calib_core::stats::chi2_sf;
use nalgebra::Isometry3;
use rayon::prelude::*;
use serde::Serialize;

use super::experiments::{table1_experiments, truths_of, Experiment, PaperCell, PaperMethod};
use super::render::study_notes;
use super::sigma_fit::{fit_sigma, fit_sigma_opt, Band, Group, SigmaFit};
use super::simulate::{build_sims, synthetic_experiments, CellSim, PlantedEffects};
use super::{PaperError, DEFAULT_BOOTSTRAP, DEFAULT_SEED, DEFAULT_TRIALS, MIN_TRIALS};

/// Options of the paper study and diagnosis (also the command-line flags of
/// `handclasp paper diagnose` and `sim-cell paper`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct StudyOptions {
    /// Seed of every Monte Carlo draw (same seed, same report; trial `k` of a cell uses
    /// `trial_rng(seed, …)`).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_SEED))]
    pub seed: u64,
    /// Simulated experiments per cell (at least 200, `MIN_TRIALS`).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_TRIALS))]
    pub trials: usize,
    /// Parametric-bootstrap replicates for the "both methods share σ" test (0 skips it).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_BOOTSTRAP))]
    pub bootstrap: usize,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            seed: DEFAULT_SEED,
            trials: DEFAULT_TRIALS,
            bootstrap: DEFAULT_BOOTSTRAP,
        }
    }
}

impl StudyOptions {
    /// Checks the options.
    pub fn validate(&self) -> Result<(), PaperError> {
        if self.trials < MIN_TRIALS {
            return Err(PaperError::Option {
                option: "trials",
                message: format!(
                    "{} trials per cell are too few for the kernel density and the 5–95 % band; use at least {MIN_TRIALS} (default {DEFAULT_TRIALS})",
                    self.trials
                ),
            });
        }
        if self.trials > 1_000_000 {
            return Err(PaperError::Option {
                option: "trials",
                message: format!(
                    "{} trials per cell would take very long; use at most 1000000",
                    self.trials
                ),
            });
        }
        if self.bootstrap > 10_000 {
            return Err(PaperError::Option {
                option: "bootstrap",
                message: format!(
                    "{} replicates would take very long; use at most 10000",
                    self.bootstrap
                ),
            });
        }
        Ok(())
    }
}

/// σ̂ of one cell and method.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CellSigma {
    /// The cell.
    pub cell: PaperCell,
    /// The method.
    pub method: PaperMethod,
    /// The fit on this cell's 5 published pairs.
    pub fit: SigmaFit,
}

/// Likelihood-ratio test of one σ for all cells against one σ per cell, for one method.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CommonSigmaTest {
    /// The method.
    pub method: PaperMethod,
    /// σ̂ shared by the three cells.
    pub common: SigmaFit,
    /// Sum of the per-cell maximised log-likelihoods.
    pub loglik_per_cell: f64,
    /// `2·(ℓ_per_cell − ℓ_common)`.
    pub statistic: f64,
    /// Degrees of freedom (2).
    pub df: usize,
    /// p-value (χ²).
    pub p_value: f64,
}

/// Parametric-bootstrap test that both methods share σ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MethodsShareSigma {
    /// `ln(σ̂_constrained / σ̂_generic)` on the published table.
    pub log_ratio: f64,
    /// Its 5–95 % band under the isotropic model at the generic σ̂ (bootstrap).
    pub band: Band,
    /// Two-sided bootstrap p-value.
    pub p_value: f64,
    /// Replicates used.
    pub replicates: usize,
}

/// One published experiment and method beside the simulation at the method's common σ̂.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StudyRow {
    /// Experiment number.
    pub experiment: u32,
    /// The cell.
    pub cell: PaperCell,
    /// The method.
    pub method: PaperMethod,
    /// Published e_tran, mm.
    pub e_tran_mm: f64,
    /// Published e_rot, degrees.
    pub e_rot_deg: f64,
    /// Simulated e_tran at σ̂ (the method's common σ), mm.
    pub sim_e_tran_mm: Band,
    /// Simulated e_rot at σ̂, degrees.
    pub sim_e_rot_deg: Band,
    /// The published e_tran lies outside the 5–95 % band.
    pub e_tran_outside: bool,
    /// The published e_rot lies outside the 5–95 % band.
    pub e_rot_outside: bool,
}

/// The simulation beside Table 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaperStudy {
    /// Options used.
    pub options: StudyOptions,
    /// σ̂ per cell and method.
    pub per_cell: Vec<CellSigma>,
    /// One σ per method for all cells, with the test against one per cell.
    pub common: Vec<CommonSigmaTest>,
    /// Whether both methods share σ (absent when `bootstrap = 0`).
    pub methods_share_sigma: Option<MethodsShareSigma>,
    /// Published vs simulated, per experiment and method.
    pub rows: Vec<StudyRow>,
    /// Number of published values outside their 5–95 % band (of `2·rows.len()`); about 10 % are
    /// expected by chance.
    pub outside_band: usize,
    /// What 5 experiments per cell can and cannot show.
    pub notes: Vec<String>,
}

pub(super) fn groups_for<'a>(
    sims: &'a [CellSim],
    exps: &[Experiment],
    method: PaperMethod,
    cells: &[PaperCell],
) -> Vec<Group<'a>> {
    cells
        .iter()
        .map(|&c| Group {
            sim: &sims[c.index()],
            method,
            obs: exps
                .iter()
                .filter(|e| e.cell == c)
                .map(|e| (e.e_tran_mm[method.index()], e.e_rot_deg[method.index()]))
                .collect(),
        })
        .collect()
}

/// Runs the study on Table 1.
///
/// # Examples
/// ```no_run
/// let study = sim_cell::paper::run_paper_study(&sim_cell::paper::StudyOptions::default()).unwrap();
/// println!("{}", sim_cell::paper::study_text(&study));
/// ```
pub fn run_paper_study(opts: &StudyOptions) -> Result<PaperStudy, PaperError> {
    study_experiments(&table1_experiments()?, opts)
}

/// Runs the study on any set of experiments (Table 1 or synthetic), ≥ 2 per cell.
pub fn study_experiments(
    exps: &[Experiment],
    opts: &StudyOptions,
) -> Result<PaperStudy, PaperError> {
    opts.validate()?;
    let truths = truths_of(exps)?;
    let sims = build_sims(&truths, opts.seed, opts.trials);
    Ok(study_with(exps, opts, &sims, &truths))
}

pub(super) fn study_with(
    exps: &[Experiment],
    opts: &StudyOptions,
    sims: &[CellSim],
    truths: &[Isometry3<f64>; 3],
) -> PaperStudy {
    let mut per_cell = Vec::new();
    let mut common = Vec::new();
    let mut rows = Vec::new();
    let mut common_sigma = [0.0; 2];
    for method in PaperMethod::ALL {
        let mut ll_cells = 0.0;
        for cell in PaperCell::ALL {
            let fit = fit_sigma(&groups_for(sims, exps, method, &[cell]));
            ll_cells += fit.loglik;
            per_cell.push(CellSigma { cell, method, fit });
        }
        let fit = fit_sigma(&groups_for(sims, exps, method, &PaperCell::ALL));
        common_sigma[method.index()] = fit.sigma_mm;
        let statistic = (2.0 * (ll_cells - fit.loglik)).max(0.0);
        common.push(CommonSigmaTest {
            method,
            common: fit,
            loglik_per_cell: ll_cells,
            statistic,
            df: 2,
            p_value: chi2_sf(statistic, 2),
        });
        for cell in PaperCell::ALL {
            let sim = sims[cell.index()].errors_at(method, fit.sigma_mm);
            let bt = Band::of(sim.iter().map(|x| x.0));
            let br = Band::of(sim.iter().map(|x| x.1));
            for e in exps.iter().filter(|e| e.cell == cell) {
                let (t, r) = (e.e_tran_mm[method.index()], e.e_rot_deg[method.index()]);
                rows.push(StudyRow {
                    experiment: e.number,
                    cell,
                    method,
                    e_tran_mm: t,
                    e_rot_deg: r,
                    sim_e_tran_mm: bt,
                    sim_e_rot_deg: br,
                    e_tran_outside: bt.outside(t),
                    e_rot_outside: br.outside(r),
                });
            }
        }
    }
    rows.sort_by_key(|r| (r.experiment, r.method.index()));
    let methods_share_sigma = (opts.bootstrap > 0).then(|| {
        let observed = (common_sigma[1] / common_sigma[0]).ln();
        let per_cell_n: usize = PaperCell::ALL
            .iter()
            .map(|&c| exps.iter().filter(|e| e.cell == c).count())
            .max()
            .unwrap_or(5);
        let ratios: Vec<f64> = (0..opts.bootstrap)
            .into_par_iter()
            .map(|b| {
                let syn = synthetic_experiments(
                    opts.seed
                        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                        .wrapping_add(b as u64 + 1),
                    per_cell_n,
                    common_sigma[0],
                    &PlantedEffects::default(),
                    truths,
                );
                let s1 = fit_sigma_opt(
                    &groups_for(sims, &syn, PaperMethod::Generic, &PaperCell::ALL),
                    false,
                );
                let s2 = fit_sigma_opt(
                    &groups_for(sims, &syn, PaperMethod::Constrained, &PaperCell::ALL),
                    false,
                );
                (s2.sigma_mm / s1.sigma_mm).ln()
            })
            .collect();
        let band = Band::of(ratios.iter().copied());
        let below = ratios.iter().filter(|&&r| r <= observed).count() as f64;
        let above = ratios.iter().filter(|&&r| r >= observed).count() as f64;
        let n = ratios.len() as f64;
        let p_value = (2.0 * ((below + 1.0) / (n + 1.0)).min((above + 1.0) / (n + 1.0))).min(1.0);
        MethodsShareSigma {
            log_ratio: observed,
            band,
            p_value,
            replicates: ratios.len(),
        }
    });
    let outside_band = rows
        .iter()
        .map(|r| r.e_tran_outside as usize + r.e_rot_outside as usize)
        .sum();
    let notes = study_notes();
    PaperStudy {
        options: *opts,
        per_cell,
        common,
        methods_share_sigma,
        rows,
        outside_band,
        notes,
    }
}
