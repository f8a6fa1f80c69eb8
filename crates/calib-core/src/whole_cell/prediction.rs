//! The predicted cooperative error: one definition for `calibrate --cell`, `plan` and the report
//! page, over a named set of configuration pairs, split into what the data determined, what the
//! prior asserts and what the model misses.
//!
//! 1. [`PredictionSplit`]: the error covariance of the estimate in two parts whose sum is the
//!    fit's (or the design's) error covariance `Σ`, plus a model-error variance:
//!    - a calibration ([`PredictionSplit::of_calibration`]): the estimator with prior
//!      information `Λ_s` (the tolerances at the evidence's scale `s`, `Λ_s = Λ/s²`) has
//!      information `H = H_d + Λ_s` and, for a truth drawn from the tolerance prior, error
//!      covariance `Σ = H⁻¹·H_d·H⁻¹ + H⁻¹·(Λ_s/s²)·H⁻¹`. The first term is the **data part**
//!      (the noise the data leave); the second is the **prior part** (the truth's spread along
//!      the directions the data do not determine, and what the shrinkage to the prior leaves:
//!      right only if the robots really are as far off as their tolerances). The prior part is
//!      taken as `Σ − data part`, so the parts sum to the fit's own covariance whatever its
//!      scale (a placement-only fit whose residuals exceed the noise: its data part is scaled
//!      with it).
//!    - a design ([`super::design_split`]): the same at nominal, for a chosen prior scale.
//! 2. The **model-error term** ([`ModelError`]): the placement-only fit's residual variance
//!    factor when it set one; else from the **region-held-out** residuals of the fit's rows
//!    (linearised): the rows are clustered into regions in joint space ([`region_labels`]) and
//!    each region `c` is held out in turn. Its residuals `r_c` (whitened) have, under the model
//!    and the fit's own prior, covariance `M_cc = I − J_c·H⁻¹·J_cᵀ` (the block of
//!    `M = (I + J·Λ⁻¹·Jᵀ)⁻¹`), so `t_c² = r_cᵀ·M_cc⁺·r_c` (the held-out prediction error
//!    against what the rest of the data and the posterior predict) has mean `rank(M_cc)`. The
//!    regions' `t_c²` are correlated (they share one fit), so `Σ t_c²` is tested against its own
//!    mean and variance under the model (`2·tr((D·M)²)`, `D = blockdiag(M_cc⁺)`), not against a
//!    χ² with `Σ dim` degrees of freedom (which fires far more often than its level when the
//!    model is right). When its upper tail is below [`MODEL_ERROR_ALPHA`], the excess over the
//!    test's critical value `c` (its `1 − α` quantile under the model),
//!    `(Σt² − c)/Σ tr(M_cc) · σ̄²` (σ̄² the mean stated noise variance per residual row), is the
//!    variance per b1 axis the model does not represent: the smallest the held-out residuals
//!    prove, so the term is 0 whenever the test does not fire and small when it barely does. A design has none (it
//!    assumes the model).
//! 3. [`predict_error`]: over pairs `(q1, q2)` of a [`PairSet`], the cooperative vector
//!    `v = f1(q1) − b1_from_b2·f2(q2)` (m, b1 axes) has error covariance
//!    `J_v·(D + P)·J_vᵀ + m·I` (`D`, `P` the parts, `m` the model-error variance); the rms of
//!    each part is `sqrt(mean_k trace)`, and `rms² = data² + prior² + model²` exactly. The p95
//!    of ‖δv‖ and its interval come from [`summarise_covariances`]; the 95 % bound of the rms
//!    over the pairs ([`PredictedError::rms_bound95_m`]) from [`BOUND_DRAWS`] seeded draws of
//!    one parameter error (shared by every pair, as a calibration's error is) and the
//!    model-error term per pair.
//! 4. [`workspace_pairs`]: seeded reachable handclasps over the whole common workspace (robot 1
//!    drawn within its joint limits, robot 2 meeting its tip head-on by inverse kinematics).

use kinematics::{base_from_tip, ik_tip_position, IkOptions};
use nalgebra::{DMatrix, Isometry3, Point3, Unit};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::Serialize;

use super::accuracy::{summarise_covariances, ConfigPair};
use super::calibrate::CellCalibration;
use super::solve::sym_inverse;
use super::{CellEstimate, CellFitError, CellProblem, Evaluator, ParamLayout};
use crate::selection::regions::{joint_features, joint_regions, REGION_SEED};
use crate::stats::{chi2_quantile_real, chi2_sf_real, quantile, trial_rng};

/// Significance of the region-held-out residuals' excess over what the fit predicts below
/// which a model-error term is added (upper tail of `Σ_c t_c²` under the model).
pub const MODEL_ERROR_ALPHA: f64 = 0.05;

/// Regions the model-error test holds out in turn at most ([`region_labels`]): clusters in
/// joint space, as issue 20's region-held-out cross-validation holds them out. Five: the
/// README's 40-row session gives five regions of about eight observations, each far enough
/// from the rest that holding it out measures extrapolation, while each still leaves four
/// fifths of the data to predict it (more regions tend to leave-one-out, which measures
/// interpolation; fewer leave blocks whose prediction rests on too little data).
pub const HELD_OUT_REGIONS: usize = 5;

/// Fewest observations in a held-out region ([`joint_regions`]' minimum size): four
/// observations are at least 12 residual rows (a coincident row has 3), enough for the
/// region's `M_cc` to carry several directions the rest of the data predict; a session with
/// fewer than [`crate::selection::regions::MIN_REGIONS`] such regions holds out each
/// observation alone.
pub const MIN_OBSERVATIONS_PER_REGION: usize = 4;

/// Relative eigenvalue of a held-out region's `M_cc` below which its direction is not
/// predicted by the rest of the data (dropped from the test; round-off level).
const HELD_OUT_EIGEN_FLOOR: f64 = 1e-9;

/// Seeded draws of the parameter error behind [`PredictedError::rms_bound95_m`].
pub const BOUND_DRAWS: usize = 400;

/// Configuration pairs per rayon task when [`predict_error`] evaluates the pairs' Jacobians
/// (tens of µs each: a task of ~0.5 ms, far above rayon's scheduling cost).
const PAIRS_PER_TASK: usize = 16;

/// Reachable handclasps over the whole workspace that `calibrate --cell` and `plan` predict
/// over ([`workspace_pairs`]).
pub const WORKSPACE_POSES: usize = 100;

/// Draws of robot 1's joints per wanted workspace pose before giving up.
pub const WORKSPACE_ATTEMPTS_PER_POSE: usize = 10;

/// Seed of the workspace poses of `calibrate --cell` and `plan` (the same poses for both).
pub const WORKSPACE_SEED: u64 = 1;

/// Which configuration pairs a prediction is over; serialised snake_case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum PairSet {
    /// The session's own meeting pairs (coincident and contact rows): where the data are.
    MeetingPairs,
    /// Handclasps at the user's work points.
    WorkPoints,
    /// Seeded reachable handclasps over the whole common workspace ([`workspace_pairs`]).
    Workspace,
    /// Held-out reachable handclasps in the cube the session's (or the plan's) poses were drawn
    /// in: `plan`'s evaluation set, and the honest-predictions check's.
    HeldOutHandclasps,
}

impl PairSet {
    /// What the set is, for people.
    pub fn describe(self) -> &'static str {
        match self {
            PairSet::MeetingPairs => {
                "the session's meeting pairs (q1_i, q2_i) of its coincident and contact rows"
            }
            PairSet::WorkPoints => "handclasps placed head-on at the work points",
            PairSet::Workspace => {
                "seeded reachable handclasps over the whole common workspace (robot 1 within its \
                 joint limits, robot 2 meeting it head-on)"
            }
            PairSet::HeldOutHandclasps => {
                "held-out reachable handclasps in the cube the poses were drawn in"
            }
        }
    }
}

/// Where the model-error term comes from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "source")]
#[non_exhaustive]
pub enum ModelError {
    /// None assumed (a design, or a fit with no residual to hold out).
    Assumed,
    /// The placement-only fit's residual variance factor ([`super::CellFit::model_error_var_m2`]).
    PlacementResiduals {
        /// Variance per b1 axis, m².
        var_m2: f64,
    },
    /// The region-held-out residuals of the fit's rows.
    HeldOut {
        /// `Σ_c t_c² / E[Σ_c t_c²]`: 1 when the held-out residuals are as the stated noise and
        /// the posterior predict.
        ratio: f64,
        /// Upper-tail probability of `Σ_c t_c²` under the model (two-moment approximation of
        /// its exact distribution).
        p_value: f64,
        /// How many regions were held out in turn.
        regions: usize,
        /// Variance per b1 axis added (0 unless `p_value` < [`MODEL_ERROR_ALPHA`]; the excess
        /// beyond the test's critical value), m².
        var_m2: f64,
    },
}

impl ModelError {
    /// The variance per b1 axis it adds, m².
    pub fn var_m2(&self) -> f64 {
        match *self {
            ModelError::Assumed => 0.0,
            ModelError::PlacementResiduals { var_m2 } | ModelError::HeldOut { var_m2, .. } => {
                var_m2
            }
        }
    }
}

/// The error covariance of an estimate in parts (see the module documentation), over the
/// layout's columns, SI units.
#[derive(Debug, Clone)]
pub struct PredictionSplit {
    /// The part the data determined (the noise they leave).
    pub data: DMatrix<f64>,
    /// The part the prior asserts (tolerances of what the data do not determine).
    pub prior: DMatrix<f64>,
    /// The model-error term.
    pub model_error: ModelError,
}

impl PredictionSplit {
    /// The split of a calibration of `problem` (see the module documentation).
    ///
    /// Errors: the models reject an observation of the fit.
    pub fn of_calibration(
        problem: &CellProblem,
        cal: &CellCalibration,
    ) -> Result<Self, CellFitError> {
        Self::of_fit(problem, &cal.fit, cal.noise_scale)
    }

    /// The split of a fit of `problem` that is not a [`CellCalibration`] (e.g. one model of
    /// a diagnosis): as [`PredictionSplit::of_calibration`], `noise_scale` the blunder
    /// screen's noise scale of a placement-only fit ([`CellCalibration::noise_scale`]; 1 when
    /// the problem's σ are already the ones to trust).
    ///
    /// Errors: the models reject an observation of the fit.
    pub fn of_fit(
        problem: &CellProblem,
        fit: &super::CellFit,
        noise_scale: f64,
    ) -> Result<Self, CellFitError> {
        let h = fit.information(problem)?;
        let lin = fit.linearisation(problem)?;
        let rows = &lin.rows;
        let data_rows: usize = fit
            .active
            .iter()
            .map(|&i| problem.observations[i].kind.rows())
            .sum();
        let jd = rows.j.rows(0, data_rows.min(rows.j.nrows()));
        let hd = jd.transpose() * jd;
        let (h_inv, _) = sym_inverse(&h);
        let placement_only = fit.layout.prior_sqrt_info.nrows() == 0;
        let noise2 = if placement_only && noise_scale > 1.0 {
            noise_scale * noise_scale
        } else {
            1.0
        };
        let data = sym(&(&h_inv * hd * &h_inv * noise2));
        let prior = sym(&(&fit.covariance - &data));
        let model_error = if fit.model_error_var_m2 > 0.0 {
            ModelError::PlacementResiduals {
                var_m2: fit.model_error_var_m2,
            }
        } else {
            held_out_model_error(problem, fit, &h_inv)?
        };
        Ok(PredictionSplit {
            data,
            prior,
            model_error,
        })
    }

    /// The split of a design's posterior: information `hd` from the data (with the weak
    /// prior of the unpenalised columns), `lambda` the tolerance prior's, estimated at prior
    /// scale `scale` (see the module documentation). No model error.
    pub(crate) fn of_information(hd: &DMatrix<f64>, lambda: &DMatrix<f64>, scale: f64) -> Self {
        let s2 = scale * scale;
        let h = hd + lambda / s2;
        let (h_inv, _) = sym_inverse(&h);
        PredictionSplit {
            data: sym(&(&h_inv * hd * &h_inv)),
            prior: sym(&(&h_inv * (lambda / (s2 * s2)) * &h_inv)),
            model_error: ModelError::Assumed,
        }
    }
}

/// `(m + mᵀ)/2`.
fn sym(m: &DMatrix<f64>) -> DMatrix<f64> {
    (m + m.transpose()) * 0.5
}

/// The model-error term from the fit's region-held-out residuals (see the module
/// documentation); `h_inv` the estimator's own posterior `H⁻¹`.
fn held_out_model_error(
    problem: &CellProblem,
    fit: &super::CellFit,
    h_inv: &DMatrix<f64>,
) -> Result<ModelError, CellFitError> {
    let lin = fit.linearisation(problem)?;
    let sys = &lin.rows;
    let labels = region_labels(problem, &fit.active);
    // Each region's rows of the data system, in block order.
    let regions = labels.iter().copied().max().map_or(0, |m| m + 1);
    let mut blocks: Vec<Vec<usize>> = vec![Vec::new(); regions];
    for (b, &i) in fit.active.iter().enumerate() {
        let s = sys.block_start[b];
        blocks[labels[b]].extend(s..s + problem.observations[i].kind.rows());
    }
    let data_rows: usize = blocks.iter().map(Vec::len).sum();
    let q = held_out_statistic(
        &sys.j.rows(0, data_rows).into_owned(),
        &sys.r.rows(0, data_rows).into_owned(),
        h_inv,
        &blocks,
    );
    if q.mean == 0.0 {
        return Ok(ModelError::Assumed);
    }
    let ratio = q.t2 / q.mean;
    let p_value = quadratic_form_sf(q.t2, q.mean, q.var);
    // Only the excess beyond the test's critical value: the smallest model error the held-out
    // residuals prove at level MODEL_ERROR_ALPHA (0 whenever the test does not fire).
    let critical = quadratic_form_quantile(1.0 - MODEL_ERROR_ALPHA, q.mean, q.var);
    let var_m2 = if q.t2 > critical && q.trace_m > 0.0 {
        (q.t2 - critical) / q.trace_m * super::calibrate::mean_noise_var(problem, fit)?
    } else {
        0.0
    };
    Ok(ModelError::HeldOut {
        ratio,
        p_value,
        regions,
        var_m2,
    })
}

/// The region-held-out statistic of whitened data residuals `r` (Jacobian `j`, the posterior
/// `h_inv`), `blocks` the rows of each region: `Σ_c r_cᵀ·M_cc⁺·r_c` with its mean and variance
/// under the model (see the module documentation).
fn held_out_statistic(
    j: &DMatrix<f64>,
    r: &nalgebra::DVector<f64>,
    h_inv: &DMatrix<f64>,
    blocks: &[Vec<usize>],
) -> HeldOutStatistic {
    let n = h_inv.nrows();
    let mut q = HeldOutStatistic::default();
    let mut k_total = DMatrix::zeros(n, n);
    let mut own_sq = 0.0;
    for idx in blocks.iter().filter(|b| !b.is_empty()) {
        let jc = j.select_rows(idx);
        let rc = r.select_rows(idx);
        let b = if idx.len() > n {
            held_out_block_low_rank(&jc, &rc, h_inv)
        } else {
            held_out_block_dense(&jc, &rc, h_inv)
        };
        q.t2 += b.t2;
        q.mean += b.rank as f64;
        q.trace_m += b.trace_m;
        let a = h_inv * &b.k;
        own_sq += (&a * &a).trace();
        k_total += b.k;
    }
    let a = h_inv * k_total;
    // Var[rᵀDr] = 2·tr((D·M)²) for r ~ N(0, M): the blocks' own terms give their ranks, the
    // cross terms `tr((H⁻¹K)²) − Σ_c tr((H⁻¹K_c)²)`.
    q.var = 2.0 * (q.mean + ((&a * &a).trace() - own_sq).max(0.0));
    q
}

/// One region's terms of [`held_out_statistic`]: with `M = I − J_c·H⁻¹·J_cᵀ` and `D = M⁺` on
/// the eigenvalues above [`HELD_OUT_EIGEN_FLOOR`] (relative to the largest, at least 1).
struct HeldOutBlock {
    /// `r_cᵀ·D·r_c`.
    t2: f64,
    /// The number of eigenvalues kept (the rank of `D`).
    rank: usize,
    /// `tr(M)`.
    trace_m: f64,
    /// `J_cᵀ·D·J_c` (columns × columns).
    k: DMatrix<f64>,
}

/// [`HeldOutBlock`] from the eigendecomposition of the rows × rows `M` (O(rows³): for blocks of
/// no more rows than columns).
fn held_out_block_dense(
    jc: &DMatrix<f64>,
    rc: &nalgebra::DVector<f64>,
    h_inv: &DMatrix<f64>,
) -> HeldOutBlock {
    let rows = jc.nrows();
    let m = sym(&(DMatrix::identity(rows, rows) - jc * h_inv * jc.transpose()));
    let trace_m = m.trace();
    // `M_cc⁺` on the directions the rest of the data predict (eigenvalues above the floor).
    let eig = m.symmetric_eigen();
    let top = eig.eigenvalues.amax();
    let mut d = DMatrix::zeros(rows, rows);
    let mut rank = 0usize;
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        if l > HELD_OUT_EIGEN_FLOOR * top.max(1.0) {
            let v = eig.eigenvectors.column(k);
            d += v * v.transpose() / l;
            rank += 1;
        }
    }
    HeldOutBlock {
        t2: rc.dot(&(&d * rc)),
        rank,
        trace_m,
        k: jc.transpose() * &d * jc,
    }
}

/// [`HeldOutBlock`] through the thin QR `J_c = Q·R` (Q rows × columns, orthonormal): `M` is the
/// identity on the rows' directions outside `Q`'s span (eigenvalue 1, kept) and `I − S` on it
/// (`S = R·H⁻¹·Rᵀ`, columns × columns), so only `S` is decomposed: O(rows·columns²) where the
/// dense form is O(rows³) (a region of 1,500 rows: ~0.2 ms against ~1 s). The same quantities
/// as [`held_out_block_dense`] up to round-off (unit test).
fn held_out_block_low_rank(
    jc: &DMatrix<f64>,
    rc: &nalgebra::DVector<f64>,
    h_inv: &DMatrix<f64>,
) -> HeldOutBlock {
    let rows = jc.nrows();
    let qr = jc.clone().qr();
    let (q, r) = (qr.q(), qr.r());
    let span = q.ncols();
    let s_mat = sym(&(&r * h_inv * r.transpose()));
    let trace_m = rows as f64 - s_mat.trace();
    let eig = s_mat.symmetric_eigen();
    // Eigenvalues of M: 1 − λ on Q's span, 1 on the other `rows − span` directions.
    let inside: Vec<f64> = eig.eigenvalues.iter().map(|l| 1.0 - l).collect();
    let top = inside
        .iter()
        .copied()
        .fold(if rows > span { 1.0f64 } else { 0.0 }, f64::max);
    let floor = HELD_OUT_EIGEN_FLOOR * top.max(1.0);
    // r_c's coordinates in Q's span and what lies outside it (eigenvalue 1: weight 1).
    let qr_c = q.transpose() * rc;
    let mut t2 = (rc.norm_squared() - qr_c.norm_squared()).max(0.0);
    let mut rank = rows - span;
    // `J_cᵀ·D·J_c = Rᵀ·(Σ_kept v·vᵀ/(1 − λ))·R`: outside Q's span `J_c` has no component.
    let mut inner = DMatrix::zeros(span, span);
    for (k, &l) in inside.iter().enumerate() {
        if l > floor {
            let v = eig.eigenvectors.column(k);
            let c = v.dot(&qr_c);
            t2 += c * c / l;
            inner += v * v.transpose() / l;
            rank += 1;
        }
    }
    HeldOutBlock {
        t2,
        rank,
        trace_m,
        k: r.transpose() * inner * r,
    }
}

/// The region-held-out test's sums over the regions.
#[derive(Debug, Default)]
struct HeldOutStatistic {
    /// `Σ_c r_cᵀ·M_cc⁺·r_c`.
    t2: f64,
    /// Its mean under the model, `Σ_c rank(M_cc)`.
    mean: f64,
    /// `Σ_c tr(M_cc)`: how much of a model error in the held-out rows their residuals carry.
    trace_m: f64,
    /// The variance of `t2` under the model, `2·tr((D·M)²)`.
    var: f64,
}

/// Upper tail `P(T > t)` of a positive quadratic form `T` of a Gaussian vector with mean
/// `mean` and variance `var`, by Satterthwaite's two-moment approximation `T ≈ g·χ²_h`
/// (`g = var/(2·mean)`, `h = 2·mean²/var`): exact when the form is a χ², and the usual test of
/// a sum of correlated χ² terms. 1 when undefined.
fn quadratic_form_sf(t: f64, mean: f64, var: f64) -> f64 {
    if !(mean > 0.0 && var > 0.0 && t.is_finite()) {
        return 1.0;
    }
    let g = var / (2.0 * mean);
    let h = 2.0 * mean * mean / var;
    chi2_sf_real(t / g, h)
}

/// Quantile `p` of the quadratic form of [`quadratic_form_sf`] (the same approximation); +∞
/// when undefined (nothing exceeds it).
fn quadratic_form_quantile(p: f64, mean: f64, var: f64) -> f64 {
    if !(mean > 0.0 && var > 0.0) {
        return f64::INFINITY;
    }
    let g = var / (2.0 * mean);
    let h = 2.0 * mean * mean / var;
    let x = g * chi2_quantile_real(p, h);
    if x.is_nan() {
        f64::INFINITY
    } else {
        x
    }
}

/// The region of each of `active`'s observations (in `active`'s order), `0..k`: the regions of
/// region-held-out cross-validation ([`joint_regions`] on [`joint_features`], the one
/// clustering `diagnose --cv-folds regions` uses), at most [`HELD_OUT_REGIONS`] of at least
/// [`MIN_OBSERVATIONS_PER_REGION`] observations each, seed [`REGION_SEED`]. A session too
/// small (or too alike) for [`crate::selection::regions::MIN_REGIONS`] such regions holds out
/// each observation alone (leave-one-out).
pub(crate) fn region_labels(problem: &CellProblem, active: &[usize]) -> Vec<usize> {
    let features = joint_features(problem, active);
    match joint_regions(
        &features,
        MIN_OBSERVATIONS_PER_REGION,
        HELD_OUT_REGIONS,
        REGION_SEED,
    ) {
        Some(regions) => regions.labels,
        None => (0..active.len()).collect(),
    }
}

/// The predicted cooperative error over a [`PairSet`] (m): its rms split into parts, its p95
/// and the 95 % bound of its rms.
#[derive(Debug, Clone, Serialize)]
pub struct PredictedError {
    /// Which pairs.
    pub pair_set: PairSet,
    /// How many.
    pub pairs: usize,
    /// Predicted rms of ‖δv‖ over the pairs, m: `sqrt(data² + prior² + model²)`.
    pub rms_m: f64,
    /// The part the data determined, m.
    pub data_rms_m: f64,
    /// The part the prior asserts, m.
    pub prior_rms_m: f64,
    /// The model-error part, m.
    pub model_error_rms_m: f64,
    /// The model-error term's source.
    pub model_error: ModelError,
    /// Predicted p95 of ‖δv‖ over the pairs, m.
    pub p95_m: f64,
    /// Its distribution-free 95 % interval from the seeded draws, m.
    pub p95_ci_m: [f64; 2],
    /// 95 % upper bound of the rms over these pairs (one parameter error shared by the pairs:
    /// the 95th percentile over [`BOUND_DRAWS`] seeded draws), m.
    pub rms_bound95_m: f64,
    /// `sqrt(trace)` of each pair's total covariance, m.
    pub per_pair_rms_m: Vec<f64>,
}

/// The predicted cooperative error over `pairs` (of `pair_set`), linearised at `estimate`
/// with `layout`'s columns (those of `split`): see the module documentation. `seed` seeds the
/// p95 and the bound's draws (identical on any machine and thread count).
///
/// Errors: no pairs, a split whose size is not the layout's, or a pair the models reject.
pub fn predict_error(
    problem: &CellProblem,
    layout: &ParamLayout,
    estimate: &CellEstimate,
    split: &PredictionSplit,
    pairs: &[ConfigPair],
    pair_set: PairSet,
    seed: u64,
) -> Result<PredictedError, CellFitError> {
    let n = layout.len();
    if pairs.is_empty() {
        return Err(CellFitError::InvalidInput(format!(
            "predicted error over {}: no configuration pair",
            pair_set.describe()
        )));
    }
    if split.data.nrows() != n || split.prior.nrows() != n {
        return Err(CellFitError::InvalidInput(format!(
            "predicted error: the covariance has {} columns, the layout {n}",
            split.data.nrows()
        )));
    }
    let ev = Evaluator::new(problem, layout);
    let at = ev.at(estimate);
    let m = split.model_error.var_m2();
    // Every pair's Jacobian `J_k` (in parallel on rayon's current pool; the first error in
    // pair order), stacked (3·pairs × n), so that `J_k·D` and `J_k·P` are two matrix products
    // over all pairs instead of 3 × n by n × n products pair by pair.
    let jacobians: Vec<Result<DMatrix<f64>, CellFitError>> = pairs
        .par_iter()
        .with_min_len(PAIRS_PER_TASK)
        .map(|pair| ev.cooperative_vector_at(&at, pair, true).map(|(_, j)| j))
        .collect();
    let mut stacked = DMatrix::zeros(3 * pairs.len(), n);
    for (k, j) in jacobians.into_iter().enumerate() {
        stacked.rows_mut(3 * k, 3).copy_from(&j?);
    }
    let jd_all = &stacked * &split.data;
    let jp_all = &stacked * &split.prior;
    let (mut data_ms, mut prior_ms) = (0.0, 0.0);
    let mut covs = Vec::with_capacity(pairs.len());
    for k in 0..pairs.len() {
        let j = stacked.rows(3 * k, 3);
        let c_data = jd_all.rows(3 * k, 3) * j.transpose();
        let c_prior = jp_all.rows(3 * k, 3) * j.transpose();
        data_ms += c_data.trace().max(0.0);
        prior_ms += c_prior.trace().max(0.0);
        // `J·(D + P)·Jᵀ`, the total covariance.
        let c = c_data + c_prior;
        covs.push(nalgebra::Matrix3::from_fn(|a, b| c[(a, b)]) + nalgebra::Matrix3::identity() * m);
    }
    let k = pairs.len() as f64;
    let summary = summarise_covariances(&covs, seed);
    let total = &split.data + &split.prior;
    let rms_bound95_m = rms_bound(&stacked, pairs.len(), &total, m, seed);
    Ok(PredictedError {
        pair_set,
        pairs: pairs.len(),
        rms_m: summary.predicted_rms_m,
        data_rms_m: (data_ms / k).sqrt(),
        prior_rms_m: (prior_ms / k).sqrt(),
        model_error_rms_m: (3.0 * m).sqrt(),
        model_error: split.model_error,
        p95_m: summary.predicted_p95_m,
        p95_ci_m: summary.predicted_p95_ci_m,
        rms_bound95_m,
        per_pair_rms_m: summary.per_pair_rms_m,
    })
}

/// The 95th percentile over [`BOUND_DRAWS`] draws (generator `trial_rng(seed, draw)`) of the
/// rms over the `pairs` pairs of `J_k·δθ + ε_k`, `δθ ~ N(0, cov)` shared by the pairs and
/// `ε_k ~ N(0, model_var·I)` per pair; `stacked` the pairs' Jacobians `J_k` (3·pairs × n).
///
/// Each draw takes its `n` normals of `δθ = L·z` (`L` the root of `cov`), then one normal per
/// row for `ε`. Without a model error, the draw's sum of squares is the quadratic form
/// `zᵀ·(Lᵀ·JᵀJ·L)·z` (n × n: the rows are summed once, not per draw); with one, all draws'
/// `J·L·z` are one matrix product.
fn rms_bound(
    stacked: &DMatrix<f64>,
    pairs: usize,
    cov: &DMatrix<f64>,
    model_var: f64,
    seed: u64,
) -> f64 {
    let n = cov.nrows();
    let eig = cov.clone().symmetric_eigen();
    let root =
        &eig.eigenvectors * DMatrix::from_diagonal(&eig.eigenvalues.map(|e| e.max(0.0).sqrt()));
    let model_sd = model_var.max(0.0).sqrt();
    let draws: Vec<_> = (0..BOUND_DRAWS)
        .map(|d| {
            let mut rng = trial_rng(seed, d as u64);
            let z = nalgebra::DVector::from_fn(n, |_, _| StandardNormal.sample(&mut rng));
            (rng, z)
        })
        .collect();
    let mut rms: Vec<f64> = if model_sd == 0.0 {
        // `(v + 0·ε)² = v²`: the model-error normals change nothing.
        let gram = root.tr_mul(&stacked.tr_mul(stacked)) * &root;
        draws
            .iter()
            .map(|(_, z)| (z.dot(&(&gram * z)).max(0.0) / pairs as f64).sqrt())
            .collect()
    } else {
        let z_all =
            DMatrix::from_columns(&draws.iter().map(|(_, z)| z.clone()).collect::<Vec<_>>());
        let e_all = stacked * (root * z_all);
        draws
            .into_iter()
            .enumerate()
            .map(|(d, (mut rng, _))| {
                let ms = e_all
                    .column(d)
                    .iter()
                    .map(|v| {
                        let noise: f64 = StandardNormal.sample(&mut rng);
                        (v + model_sd * noise).powi(2)
                    })
                    .sum::<f64>()
                    / pairs as f64;
                ms.sqrt()
            })
            .collect()
    };
    rms.sort_by(f64::total_cmp);
    quantile(&rms, 0.95)
}

/// A reachable handclasp over the workspace: its pair and robot 1's tip in b1 (m).
#[derive(Debug, Clone, PartialEq)]
pub struct WorkspacePose {
    /// The configuration pair (tool 0 of each robot).
    pub pair: ConfigPair,
    /// Robot 1's nominal tip, m, b1.
    pub p_b1: Point3<f64>,
}

/// Up to `count` seeded reachable handclasps over the whole common workspace of `problem`'s
/// nominal robots with the placement `b1_from_b2`: draw `a` (generator `trial_rng(seed, a)`,
/// so each can be replayed alone) draws robot 1's joints uniformly within its limits
/// (continuous joints ±π); robot 2 meets robot 1's tool-0 tip head-on with its tool 0
/// (position, and its flange z axis opposite robot 1's) by inverse kinematics within its
/// limits (on a shared trunk, with the trunk's joints held at robot 1's); draws robot 2 does not
/// reach are skipped, at most
/// [`WORKSPACE_ATTEMPTS_PER_POSE`]`·count` are drawn.
pub fn workspace_pairs(
    problem: &CellProblem,
    b1_from_b2: &Isometry3<f64>,
    count: usize,
    seed: u64,
) -> Vec<WorkspacePose> {
    let r1 = &problem.robot1;
    let r2 = &problem.robot2;
    let (Some(tool1), Some(tool2)) = (r1.tools.first(), r2.tools.first()) else {
        return Vec::new();
    };
    let limits: Vec<(f64, f64)> = r1
        .model
        .joints()
        .iter()
        .map(|j| {
            if j.lower.is_finite() && j.upper.is_finite() {
                (j.lower, j.upper)
            } else {
                (-std::f64::consts::PI, std::f64::consts::PI)
            }
        })
        .collect();
    let b2_from_b1 = b1_from_b2.inverse();
    let trunk = r2
        .model
        .chain_joints()
        .iter()
        .take(r2.shared_joints)
        .filter(|j| !j.is_coupled())
        .count();
    let mut out = Vec::with_capacity(count);
    for a in 0..WORKSPACE_ATTEMPTS_PER_POSE * count {
        if out.len() == count {
            break;
        }
        let mut rng = trial_rng(seed, a as u64);
        let q1: Vec<f64> = limits
            .iter()
            .map(|&(lo, hi)| rng.random_range(lo..=hi))
            .collect();
        let Ok(b1_from_tip1) = base_from_tip(&r1.model, &q1, &tool1.flange_from_tip) else {
            continue;
        };
        let p_b1 = Point3::from(b1_from_tip1.translation.vector);
        let z1 = b1_from_tip1.rotation * nalgebra::Vector3::z();
        let options = IkOptions {
            tool_axis_base: Some(Unit::new_normalize(b2_from_b1.rotation * -z1)),
            restarts: 4,
            ..IkOptions::default()
        };
        let p_b2 = b2_from_b1 * p_b1;
        // A shared trunk: robot 2 stands on robot 1's trunk posture.
        let held;
        let model2 = if trunk > 0 {
            match r2.model.with_joints_held(&q1[..trunk]) {
                Ok(m) => {
                    held = m;
                    &held
                }
                Err(_) => continue,
            }
        } else {
            &r2.model
        };
        match ik_tip_position(model2, &p_b2, &tool2.flange_from_tip, &options) {
            Ok(sol) if sol.reachable() => out.push(WorkspacePose {
                pair: ConfigPair {
                    q1,
                    q2: sol.q,
                    tool1: 0,
                    tool2: 0,
                },
                p_b1,
            }),
            _ => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{sim_cell, Cell};
    use super::super::{
        calibrate_cell, design_prediction, design_split, predict_cooperative_accuracy, Observation,
        ScreenOptions, SolveOptions, Tolerance,
    };
    use super::*;

    /// Two evaluations of the same covariance through different products: round-off only.
    const SAME_REL: f64 = 1e-9;

    /// The calibration's parts sum to its covariance; with no model error, the predicted rms
    /// is `predict_cooperative_accuracy`'s, and `rms² = data² + prior² + model²`; the bound is
    /// at least the rms (the rms of one shared draw is below its 95th percentile on average).
    #[test]
    fn calibration_parts_sum_to_the_fit() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        p.observations = sc.coincident(30, 3e-4, 0.8, 4);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let split = PredictionSplit::of_calibration(&p, &cal).unwrap();
        let sum = &split.data + &split.prior;
        assert!((&sum - &cal.fit.covariance).amax() <= SAME_REL * cal.fit.covariance.amax());
        let pairs = sc.eval_pairs(20, 0.8, 5);
        let e = predict_error(
            &p,
            &cal.fit.layout,
            &cal.fit.estimate,
            &split,
            &pairs,
            PairSet::HeldOutHandclasps,
            1,
        )
        .unwrap();
        let parts =
            (e.data_rms_m.powi(2) + e.prior_rms_m.powi(2) + e.model_error_rms_m.powi(2)).sqrt();
        assert!((parts - e.rms_m).abs() <= SAME_REL * e.rms_m);
        if split.model_error.var_m2() == 0.0 {
            let old = predict_cooperative_accuracy(&p, &cal.fit, &pairs, 1).unwrap();
            assert!((old.predicted_rms_m - e.rms_m).abs() <= SAME_REL * e.rms_m);
        }
        assert!(e.rms_bound95_m >= e.rms_m, "{e:?}");
        assert!(matches!(split.model_error, ModelError::HeldOut { .. }));
        let err = predict_error(
            &p,
            &cal.fit.layout,
            &cal.fit.estimate,
            &split,
            &[],
            PairSet::Workspace,
            1,
        )
        .unwrap_err();
        assert!(err.to_string().contains("no configuration pair"), "{err}");
    }

    /// A design's split at scale 1 gives the design's own predicted rms; at the placement-only
    /// limit the prior part grows (the corrections are not estimated).
    #[test]
    fn design_split_at_scale_one_is_the_design_prediction() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let p = sc.problem();
        let cands: Vec<Observation> = sc.coincident(24, 3e-4, 0.8, 6);
        let eval = sc.eval_pairs(20, 0.8, 7);
        let layout = ParamLayout::new(&p, &[]);
        let at = CellEstimate::nominal(&p, sc.truth.b1_from_b2);
        let chosen: Vec<usize> = (0..24).collect();
        let d = design_prediction(&p, &layout, &at, &cands, &chosen, &eval, 1).unwrap();
        let split = design_split(&p, &layout, &at, &cands, &chosen, 1.0).unwrap();
        let e = predict_error(
            &p,
            &layout,
            &at,
            &split,
            &eval,
            PairSet::HeldOutHandclasps,
            1,
        )
        .unwrap();
        assert!((e.rms_m - d.cooperative_rms_m).abs() <= SAME_REL * d.cooperative_rms_m);
        let limit = design_split(&p, &layout, &at, &cands, &chosen, 1e-3).unwrap();
        let l = predict_error(
            &p,
            &layout,
            &at,
            &limit,
            &eval,
            PairSet::HeldOutHandclasps,
            1,
        )
        .unwrap();
        assert!(l.prior_rms_m > e.prior_rms_m, "{l:?} {e:?}");
        assert!(design_split(&p, &layout, &at, &cands, &chosen, 0.0).is_err());
    }

    /// The low-rank form of a region's held-out terms equals the dense eigendecomposition's on
    /// the regions of a real fit (120 coincident points: more rows per region than columns) and
    /// on a block whose Jacobian has a repeated and a zero column (rank-deficient `R`): the same
    /// rank, and `t2`, `tr(M)` and `J_cᵀ·D·J_c` to `LOW_RANK_REL_TOL` (round-off of two
    /// decompositions of well-separated eigenvalues).
    #[test]
    fn low_rank_held_out_block_equals_the_dense_one() {
        const LOW_RANK_REL_TOL: f64 = 1e-8;
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= LOW_RANK_REL_TOL * scale.max(1.0);
        let same = |jc: &DMatrix<f64>, rc: &nalgebra::DVector<f64>, h_inv: &DMatrix<f64>| {
            assert!(jc.nrows() > jc.ncols());
            let fast = held_out_block_low_rank(jc, rc, h_inv);
            let dense = held_out_block_dense(jc, rc, h_inv);
            assert_eq!(fast.rank, dense.rank);
            assert!(
                close(fast.t2, dense.t2, dense.t2.abs()),
                "{} {}",
                fast.t2,
                dense.t2
            );
            assert!(close(fast.trace_m, dense.trace_m, dense.trace_m.abs()));
            let scale = dense.k.amax();
            for (a, b) in fast.k.iter().zip(dense.k.iter()) {
                assert!(close(*a, *b, scale), "{a} {b}");
            }
        };
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        p.observations = sc.coincident(120, 3e-4, 0.8, 4);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let fit = &cal.fit;
        let lin = fit.linearisation(&p).unwrap();
        let sys = &lin.rows;
        let labels = region_labels(&p, &fit.active);
        let mut blocks = vec![Vec::new(); labels.iter().copied().max().unwrap() + 1];
        for (b, &i) in fit.active.iter().enumerate() {
            let s = sys.block_start[b];
            blocks[labels[b]].extend(s..s + p.observations[i].kind.rows());
        }
        let (h_inv, _) = sym_inverse(&fit.information(&p).unwrap());
        let mut tested = 0;
        for idx in blocks.iter().filter(|b| b.len() > h_inv.nrows()) {
            same(&sys.j.select_rows(idx), &sys.r.select_rows(idx), &h_inv);
            tested += 1;
        }
        assert!(tested >= 2, "{tested} regions with more rows than columns");
        // A rank-deficient block: 30 rows, 5 columns, column 3 = column 1, column 4 zero.
        let mut rng = trial_rng(12, 0);
        let mut jc = DMatrix::<f64>::from_fn(30, 5, |_, _| StandardNormal.sample(&mut rng));
        let c1 = jc.column(1).into_owned();
        jc.set_column(3, &c1);
        jc.column_mut(4).fill(0.0);
        let rc = nalgebra::DVector::from_fn(30, |_, _| StandardNormal.sample(&mut rng));
        let a = DMatrix::<f64>::from_fn(5, 5, |_, _| StandardNormal.sample(&mut rng));
        let h_inv = (&a * a.transpose() + DMatrix::identity(5, 5)) * 0.01;
        same(&jc, &rc, &h_inv);
    }

    /// Under the model (whitened residuals `r ~ N(0, M)`, `M = I − J·H⁻¹·Jᵀ` of a real fit), the
    /// region-held-out statistic has the mean and variance the test assumes, and the test fires
    /// at about its level: seeded draws.
    #[test]
    fn held_out_test_is_calibrated_under_the_model() {
        /// Draws of the residual vector.
        const DRAWS: usize = 1500;
        /// Binomial 3σ of a 5 % rate over the draws, and the moments' sampling error.
        const RATE_TOL: f64 = 0.017;
        const MOMENT_REL_TOL: f64 = 0.12;
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        p.observations = sc.coincident(40, 3e-4, 0.8, 4);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let fit = &cal.fit;
        let lin = fit.linearisation(&p).unwrap();
        let sys = &lin.rows;
        let labels = region_labels(&p, &fit.active);
        let k = labels.iter().copied().max().unwrap() + 1;
        assert_eq!(k, HELD_OUT_REGIONS);
        let mut blocks = vec![Vec::new(); k];
        for (b, &i) in fit.active.iter().enumerate() {
            let s = sys.block_start[b];
            blocks[labels[b]].extend(s..s + p.observations[i].kind.rows());
        }
        let rows: usize = blocks.iter().map(Vec::len).sum();
        let j = sys.j.rows(0, rows).into_owned();
        let (h_inv, _) = sym_inverse(&fit.information(&p).unwrap());
        let m = sym(&(DMatrix::identity(rows, rows) - &j * &h_inv * j.transpose()));
        let eig = m.clone().symmetric_eigen();
        let root =
            &eig.eigenvectors * DMatrix::from_diagonal(&eig.eigenvalues.map(|e| e.max(0.0).sqrt()));
        let (mut sum, mut sum2, mut fired) = (0.0, 0.0, 0usize);
        let mut q0 = None;
        for d in 0..DRAWS {
            let mut rng = trial_rng(11, d as u64);
            let z = nalgebra::DVector::from_fn(rows, |_, _| StandardNormal.sample(&mut rng));
            let r = &root * z;
            let q = held_out_statistic(&j, &r, &h_inv, &blocks);
            sum += q.t2;
            sum2 += q.t2 * q.t2;
            if quadratic_form_sf(q.t2, q.mean, q.var) < MODEL_ERROR_ALPHA {
                fired += 1;
            }
            q0.get_or_insert(q);
        }
        let q0 = q0.unwrap();
        let n = DRAWS as f64;
        let mean = sum / n;
        let var = sum2 / n - mean * mean;
        assert!(
            (mean / q0.mean - 1.0).abs() < MOMENT_REL_TOL,
            "{mean} {q0:?}"
        );
        assert!(
            (var / q0.var - 1.0).abs() < 2.0 * MOMENT_REL_TOL,
            "{var} {q0:?}"
        );
        let rate = fired as f64 / n;
        assert!((rate - MODEL_ERROR_ALPHA).abs() < RATE_TOL, "{rate}");
    }

    /// Workspace pairs meet at the nominal cell (the cooperative vector is ~0: IK tolerance),
    /// and the same seed gives the same poses.
    #[test]
    fn workspace_pairs_meet_and_replay() {
        /// IK position tolerance 1e-10 m per robot, with margin.
        const MEET_TOL_M: f64 = 1e-6;
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let p = sc.problem();
        let x = sc.truth.b1_from_b2;
        let poses = workspace_pairs(&p, &x, 8, 2);
        assert!(poses.len() >= 4, "{}", poses.len());
        let layout = ParamLayout::new(&p, &[]);
        let ev = Evaluator::new(&p, &layout);
        let nominal = CellEstimate::nominal(&p, x);
        for pose in &poses {
            let (v, _) = ev.cooperative_vector(&nominal, &pose.pair, false).unwrap();
            assert!(v.norm() < MEET_TOL_M, "{v:?}");
        }
        assert_eq!(poses, workspace_pairs(&p, &x, 8, 2));
    }

    /// The rms bound's two forms (the quadratic form without a model error, one product over
    /// all draws with one) give what drawing `J·L·z` pair by pair gives (the form before
    /// either), on random Jacobians and a random covariance of rank 4 of 6.
    #[test]
    fn rms_bound_equals_the_per_draw_sums() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (pairs, n) = (40, 6);
        let stacked = DMatrix::from_fn(3 * pairs, n, |_, _| rng.random_range(-1.0f64..1.0));
        let a = DMatrix::from_fn(n, 4, |_, _| rng.random_range(-1.0f64..1.0));
        let cov = &a * a.transpose() * 1e-6;
        for model_var in [0.0f64, 4e-8] {
            // The per-draw form.
            let eig = cov.clone().symmetric_eigen();
            let root = &eig.eigenvectors
                * DMatrix::from_diagonal(&eig.eigenvalues.map(|e| e.max(0.0).sqrt()));
            let mapped = &stacked * root;
            let mut rms: Vec<f64> = (0..BOUND_DRAWS)
                .map(|d| {
                    let mut rng = trial_rng(3, d as u64);
                    let z = nalgebra::DVector::from_fn(n, |_, _| StandardNormal.sample(&mut rng));
                    let e = &mapped * z;
                    let ms = e
                        .iter()
                        .map(|v| {
                            let noise: f64 = StandardNormal.sample(&mut rng);
                            (v + model_var.sqrt() * noise).powi(2)
                        })
                        .sum::<f64>()
                        / pairs as f64;
                    ms.sqrt()
                })
                .collect();
            rms.sort_by(f64::total_cmp);
            let expected = quantile(&rms, 0.95);
            let got = rms_bound(&stacked, pairs, &cov, model_var, 3);
            assert!(
                (got - expected).abs() <= SAME_REL * expected,
                "model variance {model_var}: {got} vs {expected}"
            );
        }
    }
}
