//! Cooperative accuracy: the error of the predicted vector from tip 2 to tip 1 in base 1,
//! predicted from the posterior and measured against a known truth.

use nalgebra::{DMatrix, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use super::solve::CellFit;
use super::{CellEstimate, CellFitError, CellProblem, Evaluator, ParamLayout};
use crate::stats::{quantile, quantile_ci};

/// A pair of joint configurations of the two robots (rad, chain order) and the tools whose
/// tips form the cooperative vector `v = f1(q1) − b1_from_b2·f2(q2)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigPair {
    /// Robot 1's joints, rad.
    pub q1: Vec<f64>,
    /// Robot 2's joints, rad.
    pub q2: Vec<f64>,
    /// Robot 1's tool.
    pub tool1: usize,
    /// Robot 2's tool.
    pub tool2: usize,
}

/// Draws per pair used for the predicted p95 (seeded; see [`predict_cooperative_accuracy`]).
pub const P95_DRAWS_PER_PAIR: usize = 200;

/// Predicted cooperative accuracy of a fit over configuration pairs.
#[derive(Debug, Clone, Serialize)]
pub struct CooperativePrediction {
    /// `sqrt(mean_k trace Σ_v,k)`: the predicted rms of ‖δv‖ over the pairs, m (exact).
    pub predicted_rms_m: f64,
    /// Predicted 95th percentile of ‖δv‖ over the pairs, m (seeded Monte Carlo draw of
    /// [`P95_DRAWS_PER_PAIR`] Gaussian errors per pair from `N(0, Σ_v,k)`).
    pub predicted_p95_m: f64,
    /// Distribution-free 95 % interval of that p95 from the same draws
    /// ([`crate::stats::quantile_ci`]), m: how far the seeded draw leaves the p95 uncertain.
    pub predicted_p95_ci_m: [f64; 2],
    /// `sqrt(trace Σ_v,k)` per pair, m.
    pub per_pair_rms_m: Vec<f64>,
}

/// Covariances `Σ_v,k = J_v,k·Σ·J_v,kᵀ` (3×3, m², b1 axes) of the cooperative vector at each pair,
/// from a parameter covariance `covariance` over `layout`'s columns, linearised at `estimate`.
pub fn cooperative_covariances(
    problem: &CellProblem,
    layout: &ParamLayout,
    estimate: &CellEstimate,
    covariance: &DMatrix<f64>,
    pairs: &[ConfigPair],
) -> Result<Vec<nalgebra::Matrix3<f64>>, CellFitError> {
    let ev = Evaluator::new(problem, layout);
    let at = ev.at(estimate);
    pairs
        .iter()
        .map(|pair| {
            let (_, j) = ev.cooperative_vector_at(&at, pair, true)?;
            let c = &j * covariance * j.transpose();
            Ok(nalgebra::Matrix3::from_fn(|a, b| c[(a, b)]))
        })
        .collect()
}

/// Predicted cooperative accuracy of `fit` over `pairs`: the error `δv` of the predicted
/// `v = f1(q1) − b1_from_b2·f2(q2)` (m, b1 axes) has covariance `J_v·Σ·J_vᵀ` with `Σ` the
/// posterior covariance of every unknown (the prior-regularised ones included), plus the fit's
/// unmodelled-error variance `fit.model_error_var_m2·I` (placement-only fits). rms exact from
/// the traces; p95 from a seeded draw (`seed`; identical on any machine and thread count).
///
/// Errors: no pairs, or a pair the models reject (its 0-based index is in the message).
pub fn predict_cooperative_accuracy(
    problem: &CellProblem,
    fit: &CellFit,
    pairs: &[ConfigPair],
    seed: u64,
) -> Result<CooperativePrediction, CellFitError> {
    if pairs.is_empty() {
        return Err(CellFitError::InvalidInput(
            "cooperative accuracy needs at least one configuration pair".into(),
        ));
    }
    let mut covs =
        cooperative_covariances(problem, &fit.layout, &fit.estimate, &fit.covariance, pairs)?;
    for c in &mut covs {
        *c += nalgebra::Matrix3::identity() * fit.model_error_var_m2;
    }
    Ok(summarise_covariances(&covs, seed))
}

/// rms and seeded p95 of ‖δv‖ for Gaussian errors with the given 3×3 covariances.
pub fn summarise_covariances(covs: &[nalgebra::Matrix3<f64>], seed: u64) -> CooperativePrediction {
    let per_pair_rms_m: Vec<f64> = covs.iter().map(|c| c.trace().max(0.0).sqrt()).collect();
    let ms = per_pair_rms_m.iter().map(|r| r * r).sum::<f64>() / covs.len().max(1) as f64;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut norms = Vec::with_capacity(covs.len() * P95_DRAWS_PER_PAIR);
    for c in covs {
        // Symmetric square root through the eigen-decomposition (PSD up to round-off).
        let eig = c.symmetric_eigen();
        let s = eig.eigenvalues.map(|e| e.max(0.0).sqrt());
        let l = eig.eigenvectors * nalgebra::Matrix3::from_diagonal(&s);
        for _ in 0..P95_DRAWS_PER_PAIR {
            let z = Vector3::from_fn(|_, _| StandardNormal.sample(&mut rng));
            norms.push((l * z).norm());
        }
    }
    // Unstable: values equal under `total_cmp` are the same bits, so the order is the same.
    norms.sort_unstable_by(f64::total_cmp);
    let p95 = quantile_ci(&norms, 0.95);
    CooperativePrediction {
        predicted_rms_m: ms.sqrt(),
        predicted_p95_m: p95.value,
        predicted_p95_ci_m: [p95.lower, p95.upper],
        per_pair_rms_m,
    }
}

/// Measured cooperative error of a fitted cell against the truth.
#[derive(Debug, Clone, Serialize)]
pub struct CooperativeError {
    /// rms of ‖v_fit − v_true‖ over the pairs, m.
    pub rms_m: f64,
    /// 95th percentile, m.
    pub p95_m: f64,
    /// Largest, m.
    pub max_m: f64,
    /// ‖v_fit − v_true‖ per pair, m.
    pub per_pair_m: Vec<f64>,
}

/// The actual cooperative error of `fitted` against `truth` (both [`CellEstimate`]s of the same
/// problem: placement and both robots' corrections) over `pairs`: `‖v_fit − v_true‖` with
/// `v = f1(q1) − b1_from_b2·f2(q2)` (m, b1 axes) under each estimate.
///
/// Errors: no pairs, or a pair the models reject.
pub fn measure_cooperative_error(
    problem: &CellProblem,
    fitted: &CellEstimate,
    truth: &CellEstimate,
    pairs: &[ConfigPair],
) -> Result<CooperativeError, CellFitError> {
    if pairs.is_empty() {
        return Err(CellFitError::InvalidInput(
            "cooperative error needs at least one configuration pair".into(),
        ));
    }
    fitted.check_robots(problem)?;
    truth.check_robots(problem)?;
    let layout = ParamLayout::new(problem, &[]);
    let ev = Evaluator::new(problem, &layout);
    let mut per_pair_m = Vec::with_capacity(pairs.len());
    for pair in pairs {
        let (vf, _) = ev.cooperative_vector(fitted, pair, false)?;
        let (vt, _) = ev.cooperative_vector(truth, pair, false)?;
        per_pair_m.push((vf - vt).norm());
    }
    let ms = per_pair_m.iter().map(|e| e * e).sum::<f64>() / pairs.len() as f64;
    let mut sorted = per_pair_m.clone();
    sorted.sort_by(f64::total_cmp);
    Ok(CooperativeError {
        rms_m: ms.sqrt(),
        p95_m: quantile(&sorted, 0.95),
        max_m: sorted[sorted.len() - 1],
        per_pair_m,
    })
}
