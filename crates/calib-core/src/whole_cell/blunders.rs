//! Blunder screening: a robust start, studentised residuals per observation block with a
//! Bonferroni threshold, rejection and refit (see the module documentation of
//! [`crate::whole_cell`]).

use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::solve::{fit_cell_from, fit_cell_with, CellFit, SolveOptions};
use super::{CellFitError, CellProblem, ParamLayout};

/// Screening settings. Every default is documented on its field.
#[derive(Debug, Clone, PartialEq)]
pub struct ScreenOptions {
    /// Family-wise false-rejection probability over all blocks (Bonferroni), default 0.01: with
    /// clean data, a fit rejects anything with probability ≤ 1 %.
    pub alpha: f64,
    /// IRLS rounds of the Huber start (default 8).
    pub irls_rounds: usize,
    /// Rejection/re-admission rounds after the robust start (default 20).
    pub max_rounds: usize,
    /// Residual rows that must remain beyond the unpenalised unknowns (default 6); fewer is
    /// [`CellFitError::TooFewRows`].
    pub min_redundancy: usize,
    /// Reject rows at all (default true). False keeps every row: the fit on all of them, no
    /// rejection (`calibrate --cell --screen off`, and `auto` when the rejections are a model
    /// misfit, [`super::classify_rejections`]).
    pub reject: bool,
}

impl Default for ScreenOptions {
    fn default() -> Self {
        Self {
            alpha: 0.01,
            irls_rounds: 8,
            max_rounds: 20,
            min_redundancy: 6,
            reject: true,
        }
    }
}

/// One rejected observation.
#[derive(Debug, Clone, Serialize)]
pub struct RejectedRow {
    /// 1-based source row.
    pub row: usize,
    /// Observation kind.
    pub kind: &'static str,
    /// Its deletion-studentised statistic against the final fit, `sqrt(r̃ᵀ(I + H)⁻¹r̃)`, in σ.
    pub size_sigma: f64,
    /// The residual against the final fit, m (norm for 3-row kinds).
    pub residual_m: f64,
}

/// A MAP fit after blunder screening.
#[derive(Debug, Clone)]
pub struct ScreenedFit {
    /// The fit without the rejected observations.
    pub fit: CellFit,
    /// What was rejected (by row).
    pub rejected: Vec<RejectedRow>,
    /// The rejection threshold, in σ (`sqrt` of the χ² quantile for 3-row blocks).
    pub threshold_sigma_3: f64,
    /// The threshold for 1-row blocks, in σ.
    pub threshold_sigma_1: f64,
    /// The noise scale the screen used, relative to the stated noise: 1, or for a
    /// placement-only model (no penalised unknown) `sqrt` of the a-posteriori variance factor
    /// `χ²/(rows − unknowns)` of its fit on every row when above 1 (the robots' unmodelled
    /// kinematic error is not a blunder). Sizes and thresholds above are in units of the
    /// scaled σ.
    pub noise_scale: f64,
}

/// Blocks per rayon task in [`block_stats`] (a block's statistic is a few µs of small matrix
/// products with the fit's covariance).
const BLOCKS_PER_TASK: usize = 64;

struct BlockStats {
    /// Studentised statistic t² per active block (internal: `(I − H)⁻¹`).
    internal: Vec<f64>,
}

/// Studentised statistic of each active block at a fit: `r̃ᵀ(I − H_ii)⁻¹r̃`.
fn block_stats(problem: &CellProblem, fit: &CellFit) -> Result<BlockStats, CellFitError> {
    // The fit's own linearisation at its optimum (the unweighted rows of its active blocks).
    let lin = fit.linearisation(problem)?;
    let sys = &lin.rows;
    // The blocks are independent: on rayon's current pool (the same values as one loop).
    let internal = fit
        .active
        .par_iter()
        .enumerate()
        .with_min_len(BLOCKS_PER_TASK)
        .map(|(b, &i)| {
            let rows = problem.observations[i].kind.rows();
            let s = sys.block_start[b];
            let j = sys.j.rows(s, rows);
            let r = sys.r.rows(s, rows);
            let h = j * &fit.covariance * j.transpose();
            let m = DMatrix::identity(rows, rows) - h;
            match m.clone().cholesky() {
                Some(c) => r.dot(&c.solve(&r.into_owned())),
                None => f64::INFINITY,
            }
        })
        .collect();
    Ok(BlockStats { internal })
}

/// Deletion statistic of an observation not in the fit, `r̃ᵀ(I + J̃·Σ·J̃ᵀ)⁻¹r̃`, and its residual
/// norm (m).
fn deletion_stat(
    problem: &CellProblem,
    fit: &CellFit,
    i: usize,
) -> Result<(f64, f64), CellFitError> {
    let ev = super::Evaluator::new(problem, &fit.layout);
    let lin = ev.linearise(&problem.observations[i], &fit.estimate, true)?;
    let rw = &lin.whitening * &lin.residual;
    let jw = &lin.whitening * &lin.jacobian;
    let rows = rw.len();
    let m = DMatrix::identity(rows, rows) + &jw * &fit.covariance * jw.transpose();
    let t2 = m
        .cholesky()
        .map(|c| rw.dot(&c.solve(&rw)))
        .unwrap_or(f64::INFINITY);
    Ok((t2, lin.residual.norm()))
}

/// MAP fit with blunder screening (see the module documentation): robust Huber start, then
/// studentised residuals against the Bonferroni threshold `χ²_dim(1 − α/B)`, rejecting the worst
/// block and re-admitting cleared ones until stable; then the final fit without the rejected
/// rows. `layout`: the unknowns (e.g. from [`super::reduce`]); `None`: all from the tolerances.
///
/// Errors: as [`fit_cell_with`], and [`CellFitError::TooFewRows`] (naming the rejected rows) when
/// fewer than `unpenalised unknowns + min_redundancy` residual rows remain.
pub fn fit_screened(
    problem: &CellProblem,
    layout: Option<ParamLayout>,
    solve: &SolveOptions,
    screen: &ScreenOptions,
) -> Result<ScreenedFit, CellFitError> {
    if !(screen.alpha > 0.0 && screen.alpha < 1.0) {
        return Err(CellFitError::InvalidInput(format!(
            "screening option `alpha` is {}; give a probability in (0, 1), e.g. 0.01",
            screen.alpha
        )));
    }
    let layout = layout.unwrap_or_else(|| ParamLayout::new(problem, &[]));
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let blocks = all.len().max(1) as f64;
    let quant = |dim: usize| -> f64 {
        ChiSquared::new(dim as f64)
            .map(|d| d.inverse_cdf(1.0 - screen.alpha / blocks))
            .unwrap_or(f64::INFINITY)
    };
    let mut weights = vec![1.0; all.len()];
    let mut fit = fit_cell_with(problem, layout.clone(), &all, None, solve)?;
    // The screen's noise scale: 1 (the stated noise) when the model has kinematic unknowns;
    // for a placement-only model (no penalised unknown), whose residuals also carry the robots'
    // unmodelled kinematic error, the a-posteriori variance factor when it exceeds 1.
    let placement_only = (0..layout.len()).all(|j| layout.prior_sigma(j) == 0.0);
    let scale2 = if placement_only {
        variance_factor(&fit)
    } else {
        1.0
    };
    let thr = [quant(1) * scale2, quant(3) * scale2];
    if !screen.reject {
        return Ok(ScreenedFit {
            fit,
            rejected: Vec::new(),
            threshold_sigma_3: (thr[1] / scale2).sqrt(),
            threshold_sigma_1: (thr[0] / scale2).sqrt(),
            noise_scale: scale2.sqrt(),
        });
    }
    let thr_of = |i: usize| {
        if problem.observations[i].kind.rows() == 3 {
            thr[1]
        } else {
            thr[0]
        }
    };
    // The Huber threshold of a block of 1 and of 3 rows (blocks have no other size): two χ²
    // quantiles, computed once here rather than for every block in every IRLS round (statrs'
    // incomplete gamma was 1.5 % of a 2,000-row kinematic calibration's profile).
    let huber_k_of_dim = |dim: f64| {
        ChiSquared::new(dim)
            .map(|d| d.inverse_cdf(0.95).sqrt())
            .unwrap_or(2.0)
            * scale2.sqrt()
    };
    let huber_k_by_rows = [huber_k_of_dim(1.0), huber_k_of_dim(3.0)];
    let huber_k = |i: usize| match problem.observations[i].kind.rows() {
        1 => huber_k_by_rows[0],
        3 => huber_k_by_rows[1],
        rows => huber_k_of_dim(rows as f64),
    };
    // Robust start: Huber IRLS on the whitened block norms (each fit's unweighted rows at its
    // optimum, over `all`).
    for _ in 0..screen.irls_rounds {
        let lin = fit.linearisation(problem)?;
        let sys = &lin.rows;
        let mut changed = 0.0f64;
        for (b, &i) in all.iter().enumerate() {
            let rows = problem.observations[i].kind.rows();
            let s = sys.r.rows(sys.block_start[b], rows).norm();
            let k = huber_k(i);
            let w = if s <= k { 1.0 } else { k / s };
            changed = changed.max((w - weights[b]).abs());
            weights[b] = w;
        }
        fit = fit_cell_from(problem, layout.clone(), &all, Some(&weights), &fit, solve)?;
        if changed < 1e-3 {
            break;
        }
    }
    // Initial rejection at the robust fit: blocks whose whitened norm² exceeds the threshold
    // (the robust fit has down-weighted them, so its hat matrix understates their leverage;
    // the refits below re-test everything properly).
    let lin = fit.linearisation(problem)?;
    let sys = &lin.rows;
    let mut active: Vec<usize> = Vec::new();
    let mut rejected: Vec<usize> = Vec::new();
    for (b, &i) in all.iter().enumerate() {
        let rows = problem.observations[i].kind.rows();
        let s2 = sys.r.rows(sys.block_start[b], rows).norm_squared();
        if s2 > thr_of(i) {
            rejected.push(i);
        } else {
            active.push(i);
        }
    }
    let unpen = (0..layout.len())
        .filter(|&j| layout.prior_sigma(j) == 0.0)
        .count();
    let needed = unpen + screen.min_redundancy;
    let too_few = |active: &[usize], rejected: &[usize]| {
        let remaining: usize = active
            .iter()
            .map(|&i| problem.observations[i].kind.rows())
            .sum();
        if remaining < needed {
            let mut rows: Vec<usize> = rejected
                .iter()
                .map(|&i| problem.observations[i].row)
                .collect();
            rows.sort_unstable();
            Some(CellFitError::TooFewRows {
                remaining,
                needed,
                rejected_rows: rows,
            })
        } else {
            None
        }
    };
    if let Some(e) = too_few(&active, &rejected) {
        return Err(e);
    }
    let mut fit = fit_cell_from(problem, layout.clone(), &active, None, &fit, solve)?;
    for _ in 0..screen.max_rounds {
        let mut changed = false;
        // Re-admit rejected blocks that the current fit explains.
        let mut readmit = Vec::new();
        for &i in &rejected {
            let (t2, _) = deletion_stat(problem, &fit, i)?;
            if t2 <= thr_of(i) {
                readmit.push(i);
            }
        }
        if !readmit.is_empty() {
            rejected.retain(|i| !readmit.contains(i));
            active.extend(readmit);
            active.sort_unstable();
            changed = true;
        } else {
            // Reject the worst active block above its threshold.
            let stats = block_stats(problem, &fit)?;
            let worst = fit
                .active
                .iter()
                .enumerate()
                .map(|(b, &i)| (i, stats.internal[b] / thr_of(i)))
                .filter(|&(_, ratio)| ratio > 1.0)
                .max_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((i, _)) = worst {
                active.retain(|&a| a != i);
                rejected.push(i);
                changed = true;
            }
        }
        if !changed {
            break;
        }
        if let Some(e) = too_few(&active, &rejected) {
            return Err(e);
        }
        fit = fit_cell_from(problem, layout.clone(), &active, None, &fit, solve)?;
    }
    rejected.sort_unstable();
    let mut out = Vec::with_capacity(rejected.len());
    for &i in &rejected {
        let (t2, res) = deletion_stat(problem, &fit, i)?;
        out.push(RejectedRow {
            row: problem.observations[i].row,
            kind: problem.observations[i].kind.name(),
            size_sigma: (t2 / scale2).sqrt(),
            residual_m: res,
        });
    }
    Ok(ScreenedFit {
        fit,
        rejected: out,
        threshold_sigma_3: (thr[1] / scale2).sqrt(),
        threshold_sigma_1: (thr[0] / scale2).sqrt(),
        noise_scale: scale2.sqrt(),
    })
}

/// Squared noise scale of a fit's residuals, the a-posteriori variance factor
/// `σ̂₀² = χ²_data / (rows − unknowns)` of the least-squares fit on every row (as Pope's τ test
/// estimates the noise when the stated one is not trusted), never below 1 (the screen never
/// tightens below the stated noise). A blunder inflates it only by its share of the total
/// χ², so a gross error still stands out against it.
fn variance_factor(fit: &CellFit) -> f64 {
    let dof = fit.residual_rows.saturating_sub(fit.layout.len());
    if dof == 0 {
        1.0
    } else {
        (fit.data_chi2 / dof as f64).max(1.0)
    }
}
