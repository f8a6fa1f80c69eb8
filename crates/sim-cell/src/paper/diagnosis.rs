//! The diagnosis on signed errors.
//!
//! The signed error of the generic estimate is `y = (T_est − T_true [mm], log(R_est·R_trueᵀ) [mrad])`
//! in b1 axes (all six components for floor–wall; translation and yaw for the other two cells). The
//! baseline model is `y ~ N(0, σ²·Σ_cell)` with `Σ_cell` the simulated covariance at σ = 1 mm.
//! Candidate extended models ([`Candidate`]) add a mean `J·β` (exact, layout-independent effects of
//! a physical cause on the estimate: a tip length error along the approach axis, a contact bias per
//! cell, robot 1's or robot 2's joint-1 offset) and/or change the covariance (anisotropic alignment
//! noise, one σ per cell, a wider or narrower layout on [`super::SPREAD_GRID_M`], a contact offset constant
//! within an experiment). Each is fitted by maximum likelihood (generalised least squares for β, closed
//! form for σ², golden section for the anisotropy), and scored by the likelihood ratio against the
//! baseline, AIC, and leave-one-experiment-out held-out log-likelihood (refit on the other 14
//! experiments — 4 of the held-out one's cell — and score the held-out one). Forward selection
//! accepts a candidate when its likelihood-ratio p-value is below 0.05 / (number of candidates
//! tried) and its AIC is below the current model's, choosing among those the best held-out score
//! (which must beat the current model's); it stops when none qualifies.

use calib_core::stats::{chi2_sf, quantile};
use nalgebra::DVector;
use serde::Serialize;

use super::candidates::{observations, Candidate, Obs};
use super::experiments::{table1_experiments, truths_of, Experiment, PaperCell, PaperMethod};
use super::model_fit::{candidate_result, CandidateResult};
use super::render::conclusions;
use super::sigma_fit::Band;
use super::simulate::{build_sims, CellSim};
use super::study::{study_with, PaperStudy, StudyOptions};
use super::{PaperError, ALPHA, MRAD_PER_RAD};

/// Signed errors of one published experiment (generic estimate).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignedRow {
    /// Experiment number.
    pub experiment: u32,
    /// The cell.
    pub cell: PaperCell,
    /// `T_est − T_true`, mm, b1 axes.
    pub dt_mm: [f64; 3],
    /// `log(R_est·R_trueᵀ)`, degrees, b1 axes (floor–floor/ceiling: only z is published faithfully).
    pub rot_deg: [f64; 3],
}

/// What the isotropic model gets wrong about one cell's signed errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellFinding {
    /// The cell.
    pub cell: PaperCell,
    /// Names of the observed components (`dx_mm`, …, `wz_deg`).
    pub components: Vec<String>,
    /// Mean signed error per component (mm or degrees).
    pub mean: Vec<f64>,
    /// Mean / its standard error under the baseline σ̂ (|z| > 2 suggests a bias).
    pub z: Vec<f64>,
    /// Experiments sharing the majority sign, per component (5 of 5 has p = 1/16 by chance).
    pub same_sign: Vec<usize>,
    /// Test of a zero mean: `n·ȳᵀ(σ̂²Σ)⁻¹ȳ` ~ χ²(components).
    pub mean_chi2: f64,
    /// Its p-value.
    pub mean_p_value: f64,
    /// Published median e_rot1/e_tran1, degrees per mm.
    pub ratio_published: f64,
    /// Simulated band of the median of 5 ratios at σ̂ (isotropic model).
    pub ratio_sim: Band,
    /// Published mean gain of the constrained method, e_tran1 − e_tran2, mm.
    pub gain_tran_published_mm: f64,
    /// Simulated band of the mean of 5 at σ̂, mm.
    pub gain_tran_sim_mm: Band,
    /// Published mean gain, e_rot1 − e_rot2, degrees.
    pub gain_rot_published_deg: f64,
    /// Simulated band of the mean of 5 at σ̂, degrees.
    pub gain_rot_sim_deg: Band,
}

/// `handclasp paper diagnose`: the study, what the isotropic simulation gets wrong, the candidates and
/// the named cause.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaperDiagnosis {
    /// The σ fit and published-vs-simulated rows.
    pub study: PaperStudy,
    /// Signed errors of the generic estimates.
    pub signed: Vec<SignedRow>,
    /// Per-cell findings under the baseline.
    pub cells: Vec<CellFinding>,
    /// The baseline (isotropic σ, no bias) on the signed errors.
    pub baseline: CandidateResult,
    /// Each candidate alone.
    pub candidates: Vec<CandidateResult>,
    /// The model forward selection ends with (equal to the baseline when nothing is selected).
    pub selected: CandidateResult,
    /// The named cause: candidate names joined by " + ", or "none significant".
    pub cause: String,
    /// Plain statements of what can and cannot be concluded.
    pub conclusions: Vec<String>,
}

/// Runs the diagnosis on Table 1.
pub fn run_paper_diagnosis(opts: &StudyOptions) -> Result<PaperDiagnosis, PaperError> {
    diagnose_experiments(&table1_experiments()?, opts)
}

pub(super) const COMPONENT_NAMES: [&str; 6] =
    ["dx_mm", "dy_mm", "dz_mm", "wx_deg", "wy_deg", "wz_deg"];

/// Runs the diagnosis on any set of experiments (≥ 2 per cell).
pub fn diagnose_experiments(
    exps: &[Experiment],
    opts: &StudyOptions,
) -> Result<PaperDiagnosis, PaperError> {
    opts.validate()?;
    let truths = truths_of(exps)?;
    let sims = build_sims(&truths, opts.seed, opts.trials);
    let study = study_with(exps, opts, &sims, &truths);
    let data = observations(exps, &sims);
    let deg = |mrad: f64| mrad / MRAD_PER_RAD * 180.0 / std::f64::consts::PI;
    let signed = exps
        .iter()
        .map(|e| {
            let y = e.signed_generic();
            SignedRow {
                experiment: e.number,
                cell: e.cell,
                dt_mm: [y[0], y[1], y[2]],
                rot_deg: [deg(y[3]), deg(y[4]), deg(y[5])],
            }
        })
        .collect();
    let fail = || {
        PaperError::Experiments(
            "the baseline model could not be fitted (degenerate covariance)".into(),
        )
    };
    let (baseline, base_fit) = candidate_result(&[], &data, None).ok_or_else(fail)?;
    let base_held = baseline.heldout_loglik;
    let mut baseline = baseline;
    baseline.description = "isotropic alignment noise, one σ, no bias".into();

    // Per-cell findings under the baseline σ̂.
    let sigma_base = base_fit.sigma2[0].sqrt();
    let generic_sigma = study
        .common
        .iter()
        .find(|t| t.method == PaperMethod::Generic)
        .map(|t| t.common.sigma_mm)
        .unwrap_or(sigma_base);
    let cells: Vec<CellFinding> = PaperCell::ALL
        .iter()
        .map(|&cell| {
            cell_finding(
                cell,
                exps,
                &data,
                &sims[cell.index()],
                sigma_base,
                generic_sigma,
            )
        })
        .collect();

    let candidates: Vec<CandidateResult> = Candidate::ALL
        .iter()
        .filter_map(|&c| candidate_result(&[c], &data, Some((&base_fit, base_held))).map(|r| r.0))
        .collect();

    // Forward selection.
    let mut chosen: Vec<Candidate> = Vec::new();
    let mut current = (baseline.clone(), base_fit.clone());
    loop {
        let remaining: Vec<Candidate> = Candidate::ALL
            .iter()
            .copied()
            .filter(|c| chosen.iter().all(|d| d.family() != c.family()))
            .collect();
        if remaining.is_empty() {
            break;
        }
        let alpha = ALPHA / remaining.len() as f64;
        let best = remaining
            .iter()
            .filter_map(|&c| {
                let mut set = chosen.clone();
                set.push(c);
                let (r, m) =
                    candidate_result(&set, &data, Some((&current.1, current.0.heldout_loglik)))?;
                (r.lr_p_value < alpha && r.heldout_loglik > current.0.heldout_loglik)
                    .then_some((c, r, m))
            })
            .filter(|(_, r, _)| r.aic < current.0.aic)
            .max_by(|a, b| a.1.heldout_loglik.total_cmp(&b.1.heldout_loglik));
        let Some((c, r, m)) = best else { break };
        if r.aic >= current.0.aic {
            break;
        }
        chosen.push(c);
        current = (r, m);
    }
    // Report the selected model's LR and held-out gain against the baseline.
    let selected = if chosen.is_empty() {
        baseline.clone()
    } else {
        candidate_result(&chosen, &data, Some((&base_fit, base_held)))
            .map(|r| r.0)
            .unwrap_or_else(|| current.0.clone())
    };
    let cause = if chosen.is_empty() {
        "none significant".to_string()
    } else {
        chosen
            .iter()
            .map(|c| c.name())
            .collect::<Vec<_>>()
            .join(" + ")
    };
    let conclusions = conclusions(&study, &cells, &selected, baseline.aic, &cause);
    Ok(PaperDiagnosis {
        study,
        signed,
        cells,
        baseline,
        candidates,
        selected,
        cause,
        conclusions,
    })
}

pub(super) fn cell_finding(
    cell: PaperCell,
    exps: &[Experiment],
    data: &[Obs],
    sim: &CellSim,
    sigma_base: f64,
    generic_sigma: f64,
) -> CellFinding {
    let dims = cell.observed_dims();
    let obs: Vec<&Obs> = data.iter().filter(|o| o.cell == cell).collect();
    let n = obs.len().max(1) as f64;
    let d = dims.len();
    let mut mean = DVector::zeros(d);
    for o in &obs {
        mean += &o.y;
    }
    mean /= n;
    let cov = (&obs[0].cov_perp + &obs[0].cov_along) * (sigma_base * sigma_base);
    let chi2 = cov
        .clone()
        .cholesky()
        .map(|ch| n * mean.dot(&ch.solve(&mean)))
        .unwrap_or(f64::NAN);
    let to_unit = |k: usize, v: f64| {
        if dims[k] >= 3 {
            v / MRAD_PER_RAD * 180.0 / std::f64::consts::PI
        } else {
            v
        }
    };
    let z = (0..d).map(|k| mean[k] / (cov[(k, k)] / n).sqrt()).collect();
    let same_sign = (0..d)
        .map(|k| {
            let pos = obs.iter().filter(|o| o.y[k] > 0.0).count();
            pos.max(obs.len() - pos)
        })
        .collect();
    // Ratio and gain: published vs simulated statistics of 5 at the generic common σ̂.
    let mine: Vec<&Experiment> = exps.iter().filter(|e| e.cell == cell).collect();
    let k = mine.len().max(1);
    let mut ratios: Vec<f64> = mine
        .iter()
        .map(|e| e.e_rot_deg[0] / e.e_tran_mm[0])
        .collect();
    ratios.sort_by(f64::total_cmp);
    let ratio_published = quantile(&ratios, 0.5);
    let g = sim.errors_at(PaperMethod::Generic, generic_sigma);
    let c = sim.errors_at(PaperMethod::Constrained, generic_sigma);
    let groups = g.len() / k;
    // Groups of k consecutive trials (independent draws).
    let mut med = Vec::with_capacity(groups);
    let mut gt = Vec::with_capacity(groups);
    let mut gr = Vec::with_capacity(groups);
    for gi in 0..groups {
        let idx = gi * k..(gi + 1) * k;
        let mut r: Vec<f64> = idx.clone().map(|i| g[i].1 / g[i].0).collect();
        r.sort_by(f64::total_cmp);
        med.push(quantile(&r, 0.5));
        gt.push(idx.clone().map(|i| g[i].0 - c[i].0).sum::<f64>() / k as f64);
        gr.push(idx.map(|i| g[i].1 - c[i].1).sum::<f64>() / k as f64);
    }
    let kf = k as f64;
    CellFinding {
        cell,
        components: dims
            .iter()
            .map(|&i| COMPONENT_NAMES[i].to_string())
            .collect(),
        mean: (0..d).map(|i| to_unit(i, mean[i])).collect(),
        z,
        same_sign,
        mean_chi2: chi2,
        mean_p_value: chi2_sf(chi2, d),
        ratio_published,
        ratio_sim: Band::of(med),
        gain_tran_published_mm: mine
            .iter()
            .map(|e| e.e_tran_mm[0] - e.e_tran_mm[1])
            .sum::<f64>()
            / kf,
        gain_tran_sim_mm: Band::of(gt),
        gain_rot_published_deg: mine
            .iter()
            .map(|e| e.e_rot_deg[0] - e.e_rot_deg[1])
            .sum::<f64>()
            / kf,
        gain_rot_sim_deg: Band::of(gr),
    }
}
