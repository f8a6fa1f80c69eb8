//! Greedy experiment design: choose observations that minimise the predicted cooperative error
//! (A-optimal) or maximise the information volume (D-optimal), by rank-k Woodbury updates.

use nalgebra::DMatrix;
use serde::Serialize;

use super::accuracy::ConfigPair;
use super::{CellEstimate, CellFitError, CellProblem, Evaluator, Observation, ParamLayout};

/// σ of the weak prior put on the unpenalised unknowns (placement, nuisances) so that the
/// design's information matrix is invertible before any observation: 10 (m or rad). Its
/// information, 0.01, is negligible next to a single observation's.
pub const WEAK_PRIOR_SIGMA: f64 = 10.0;

/// The design criterion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum DesignCriterion {
    /// A-optimal for cooperative accuracy: minimise the predicted mean cooperative variance
    /// `mean_k trace(J_v,k·Σ·J_v,kᵀ)` over the evaluation pairs (m²).
    CooperativeA,
    /// D-optimal: maximise `log det` of the posterior information.
    D,
}

/// Result of [`greedy_design`].
#[derive(Debug, Clone, Serialize)]
pub struct DesignResult {
    /// Chosen candidate indices, in the order chosen.
    pub chosen: Vec<usize>,
    /// The criterion at the chosen set: for A, the predicted cooperative rms
    /// `sqrt(mean trace Σ_v)`, m; for D, `log det A` of the information (dimensionless).
    pub criterion: f64,
    /// The criterion after each pick (same unit).
    pub history: Vec<f64>,
}

struct DesignSetup {
    /// Whitened Jacobian block of each candidate.
    blocks: Vec<DMatrix<f64>>,
    /// Prior information (with the weak prior).
    info0: DMatrix<f64>,
    /// `M = mean_k J_v,kᵀ·J_v,k`.
    m: DMatrix<f64>,
}

fn setup(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    eval_pairs: &[ConfigPair],
) -> Result<DesignSetup, CellFitError> {
    if candidates.is_empty() {
        return Err(CellFitError::InvalidInput(
            "design: no candidate observations".into(),
        ));
    }
    let ev = Evaluator::new(problem, layout);
    let n = layout.len();
    let blocks = candidates
        .iter()
        .map(|c| {
            let l = ev.linearise(c, at, true)?;
            Ok(&l.whitening * &l.jacobian)
        })
        .collect::<Result<Vec<_>, CellFitError>>()?;
    let mut info0 = layout.prior_sqrt_info.transpose() * &layout.prior_sqrt_info;
    for j in 0..n {
        if layout.prior_sigma(j) == 0.0 {
            info0[(j, j)] += 1.0 / (WEAK_PRIOR_SIGMA * WEAK_PRIOR_SIGMA);
        }
    }
    let mut m = DMatrix::zeros(n, n);
    for pair in eval_pairs {
        let (_, jv) = ev.cooperative_vector(at, pair, true)?;
        m += jv.transpose() * &jv;
    }
    m /= eval_pairs.len().max(1) as f64;
    Ok(DesignSetup { blocks, info0, m })
}

fn criterion_value(
    crit: DesignCriterion,
    sigma: &DMatrix<f64>,
    info: &DMatrix<f64>,
    m: &DMatrix<f64>,
) -> f64 {
    match crit {
        DesignCriterion::CooperativeA => (m * sigma).trace().max(0.0).sqrt(),
        DesignCriterion::D => info
            .clone()
            .cholesky()
            .map(|c| 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>())
            .unwrap_or(f64::NEG_INFINITY),
    }
}

/// Greedily chooses `n` of `candidates` (linearised at `at`, normally the nominal cell at its
/// nominal placement) for the criterion, with rank-k Woodbury updates of the posterior
/// covariance (see the module documentation). `eval_pairs` are the configuration pairs of the
/// cooperative criterion (A); D ignores them.
///
/// Errors: `n` larger than the candidate count, no candidates, no evaluation pairs for A, or a
/// candidate the models reject.
pub fn greedy_design(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    eval_pairs: &[ConfigPair],
    n: usize,
    criterion: DesignCriterion,
) -> Result<DesignResult, CellFitError> {
    if n > candidates.len() {
        return Err(CellFitError::InvalidInput(format!(
            "design: {n} observations asked from {} candidates; give more candidates or a smaller n",
            candidates.len()
        )));
    }
    if criterion == DesignCriterion::CooperativeA && eval_pairs.is_empty() {
        return Err(CellFitError::InvalidInput(
            "design: the cooperative criterion needs evaluation pairs".into(),
        ));
    }
    let s = setup(problem, layout, at, candidates, eval_pairs)?;
    let (mut sigma, _) = super::solve::sym_inverse(&s.info0);
    let mut info = s.info0.clone();
    let mut chosen: Vec<usize> = Vec::with_capacity(n);
    let mut taken = vec![false; candidates.len()];
    let mut history = Vec::with_capacity(n);
    for _ in 0..n {
        // G = Σ·M·Σ for the A criterion.
        let g = match criterion {
            DesignCriterion::CooperativeA => Some(&sigma * &s.m * &sigma),
            DesignCriterion::D => None,
        };
        let mut best: Option<(usize, f64)> = None;
        for (c, b) in s.blocks.iter().enumerate() {
            if taken[c] {
                continue;
            }
            let bs = b * &sigma;
            let k = b.nrows();
            let smat = DMatrix::identity(k, k) + &bs * b.transpose();
            let Some(chol) = smat.clone().cholesky() else {
                continue;
            };
            let gain = match &g {
                // Decrease of trace(M·Σ): trace(S⁻¹·B·G·Bᵀ).
                Some(g) => (chol.solve(&(b * g * b.transpose()))).trace(),
                // Increase of log det: log det S.
                None => 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>(),
            };
            if best.is_none_or(|(_, bg)| gain > bg) {
                best = Some((c, gain));
            }
        }
        let Some((c, _)) = best else { break };
        let b = &s.blocks[c];
        let bs = b * &sigma;
        let k = b.nrows();
        let smat = DMatrix::identity(k, k) + &bs * b.transpose();
        let chol = smat.cholesky().ok_or_else(|| {
            CellFitError::InvalidInput("design: information update is not positive definite".into())
        })?;
        // Σ' = Σ − (BΣ)ᵀ·S⁻¹·(BΣ).
        sigma -= bs.transpose() * chol.solve(&bs);
        sigma = (&sigma + sigma.transpose()) * 0.5;
        info += b.transpose() * b;
        taken[c] = true;
        chosen.push(c);
        history.push(criterion_value(criterion, &sigma, &info, &s.m));
    }
    let criterion_now = history
        .last()
        .copied()
        .unwrap_or_else(|| criterion_value(criterion, &sigma, &info, &s.m));
    Ok(DesignResult {
        chosen,
        criterion: criterion_now,
        history,
    })
}

/// The criterion of a given subset `chosen` of `candidates` (for comparing a design with, e.g.,
/// random subsets): A: predicted cooperative rms, m; D: `log det` of the information.
///
/// Errors: an index out of range, or as [`greedy_design`].
pub fn design_criterion(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    chosen: &[usize],
    eval_pairs: &[ConfigPair],
    criterion: DesignCriterion,
) -> Result<f64, CellFitError> {
    if let Some(&bad) = chosen.iter().find(|&&c| c >= candidates.len()) {
        return Err(CellFitError::InvalidInput(format!(
            "design: candidate index {bad} is out of range ({} candidates)",
            candidates.len()
        )));
    }
    let picked: Vec<Observation> = chosen.iter().map(|&c| candidates[c].clone()).collect();
    let s = setup(problem, layout, at, &picked, eval_pairs)?;
    let mut info = s.info0.clone();
    for b in &s.blocks {
        info += b.transpose() * b;
    }
    let (sigma, _) = super::solve::sym_inverse(&info);
    Ok(criterion_value(criterion, &sigma, &info, &s.m))
}
