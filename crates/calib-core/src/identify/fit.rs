//! The joint Levenberg–Marquardt fit of `b1_from_b2` and error parameters, and its covariance
//! (see the measurement model in [`crate::identify`]). The solver is the crate's one
//! Levenberg–Marquardt loop ([`crate::LmOptions`], schedule [`LmOptions::identify`]); this file
//! gives it the problem: the stacked (whitened) residuals, their Jacobian and the manifold update.

use super::model::{IdentifyError, TipEval, TipModel};
use crate::lm::{minimize, LeastSquaresProblem, Linearised, COST_FLOOR};
use crate::stats::t_quantile;
use crate::stop::StopReason;
use crate::{LmOptions, Robot};
use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3,
};
use rayon::prelude::*;

/// Eigenvalues of the Jacobi-scaled `JᵀJ` at or below this fraction of the largest are dropped
/// from the covariance (pseudo-inverse) and flag the fit [`IdentFit::singular`].
pub(super) const COVARIANCE_REL_EIGEN_TOL: f64 = 1e-12;

/// Result of a joint fit of `b1_from_b2` and error parameters.
#[derive(Debug, Clone)]
pub struct IdentFit {
    /// Estimated `b1_from_b2`.
    pub b1_from_b2: Isometry3<f64>,
    /// Parameters fitted (catalogue indices).
    pub params: Vec<usize>,
    /// Their estimates, in the model's parameter units.
    pub values: Vec<f64>,
    /// Points used (indices into the model).
    pub points: Vec<usize>,
    /// Residuals `f1 − b1_from_b2·f2` at the solution (unweighted), m, one per point in `points`.
    pub residuals: Vec<Vector3<f64>>,
    /// Weighted residual sum of squares `Σ‖W_i·r_i‖²` (m²; the plain RSS for unit weights):
    /// what the fit minimises and the tests use.
    pub rss: f64,
    /// Degrees of freedom `3n − 6 − k`.
    pub dof: usize,
    /// `σ̂ = sqrt(RSS/dof)`, m (NaN when dof = 0).
    pub sigma_hat: f64,
    /// Covariance of `[ρ (m); φ (rad); θ]` (`σ̂²·(JᵀJ)⁻¹`, pseudo-inverse if singular).
    pub covariance: DMatrix<f64>,
    /// Whether `JᵀJ` was numerically singular (some direction not determined by the data).
    pub singular: bool,
    /// LM iterations used.
    pub iterations: usize,
    /// Why LM stopped: [`StopReason::Converged`] (relative RSS decrease below
    /// [`LmOptions::cost_tolerance`]), [`StopReason::StepTooSmall`] (step norm below
    /// [`LmOptions::step_tolerance`]), [`StopReason::NoDescent`] (no damped step lowers the RSS),
    /// [`StopReason::NonFinite`] (a trial step's RSS overflowed) or [`StopReason::IterationCap`]
    /// ([`LmOptions::max_iterations`] reached).
    pub stopped: StopReason,
}

impl IdentFit {
    /// Whether LM stopped at a (numerical) minimum rather than at its iteration cap
    /// ([`StopReason::converged`]).
    pub fn converged(&self) -> bool {
        self.stopped.converged()
    }

    /// Residual RMS over points of the unweighted residuals, `sqrt(Σ‖r_i‖²/n)`, m (3-D distance
    /// per point).
    pub fn rms(&self) -> f64 {
        let raw: f64 = self.residuals.iter().map(|r| r.norm_squared()).sum();
        (raw / self.points.len().max(1) as f64).sqrt()
    }

    /// Standard error of fitted parameter `k` (position in `params`), model units.
    pub fn std_error(&self, k: usize) -> f64 {
        self.covariance[(6 + k, 6 + k)].max(0.0).sqrt()
    }

    /// Two-sided `level` (e.g. 0.95) confidence interval of fitted parameter `k`, t quantile with
    /// `dof` degrees of freedom. Returns `(NaN, NaN)` when dof = 0.
    pub fn interval(&self, k: usize, level: f64) -> (f64, f64) {
        let t = t_quantile(0.5 + level / 2.0, self.dof);
        let half = t * self.std_error(k);
        (self.values[k] - half, self.values[k] + half)
    }

    /// Predicted 1-σ translation error of `b1_from_b2`, m: `sqrt(trace Σ_ρ)` (covariance based,
    /// about the left-perturbed origin).
    pub fn predicted_translation_error(&self) -> f64 {
        (0..3)
            .map(|i| self.covariance[(i, i)].max(0.0))
            .sum::<f64>()
            .sqrt()
    }

    /// Predicted 1-σ rotation error of `b1_from_b2`, rad: `sqrt(trace Σ_φ)`.
    pub fn predicted_rotation_error(&self) -> f64 {
        (3..6)
            .map(|i| self.covariance[(i, i)].max(0.0))
            .sum::<f64>()
            .sqrt()
    }

    /// Bayesian information criterion `N·ln(RSS/N) + p·ln(N)`, `N = 3n` residuals, `p = 6 + k`.
    pub fn bic(&self) -> f64 {
        let n_obs = 3.0 * self.points.len() as f64;
        let p = (6 + self.params.len()) as f64;
        n_obs * (self.rss.max(COST_FLOOR) / n_obs).ln() + p * n_obs.ln()
    }
}

/// Smallest number of points for fitting `b1_from_b2` plus `params` parameters with at least 10
/// residual degrees of freedom (and never fewer than 4 points).
pub fn min_points(params: usize) -> usize {
    (6 + params + 10).div_ceil(3).max(4)
}

pub(super) fn check_params(model: &dyn TipModel, params: &[usize]) -> Result<(), IdentifyError> {
    for &p in params {
        if p >= model.n_params() {
            return Err(IdentifyError::BadParam {
                index: p,
                len: model.n_params(),
            });
        }
    }
    Ok(())
}

/// Residuals and (optionally) the stacked Jacobian `[∂r/∂ρ, ∂r/∂φ, ∂r/∂θ_params, ∂r/∂θ_extra]` at a
/// state. `extra` are extra parameter columns evaluated at the state (for screening).
pub(super) struct Linearisation {
    pub(super) residuals: DVector<f64>,
    pub(super) jacobian: DMatrix<f64>,
    /// Weighted residual sum of squares (whitened residuals), m².
    pub(super) rss: f64,
    /// Unweighted residuals `f1 − X·f2`, m, one per point.
    pub(super) raw: Vec<Vector3<f64>>,
    /// Unweighted residual sum of squares, m².
    pub(super) raw_rss: f64,
    /// The points' whitening matrices ([`TipModel::weight`]).
    pub(super) weights: Vec<Matrix3<f64>>,
    /// Robot 1's tips in b1, m (one per point).
    pub(super) p1_b1: Vec<Vector3<f64>>,
    /// Robot 2's tips in b2, m (one per point).
    pub(super) p2_b2: Vec<Point3<f64>>,
}

/// Points per rayon task when the tip model is evaluated in parallel (a few µs per point: about
/// 0.1 ms per task, far above rayon's scheduling cost).
const POINTS_PER_TASK: usize = 32;

/// `model.eval` at every point of `points` (in parallel on rayon's current pool), one result per
/// point in the order of `points`. Each result is the one a sequential call would give, so what
/// [`assemble`] builds from them does not depend on the thread count.
fn eval_points(
    model: &dyn TipModel,
    points: &[usize],
    params: &[usize],
    values: &[f64],
    jac_params: &[usize],
) -> Vec<Result<TipEval, IdentifyError>> {
    points
        .par_iter()
        .with_min_len(POINTS_PER_TASK)
        .map(|&i| model.eval(i, params, values, jac_params))
        .collect()
}

#[allow(clippy::too_many_arguments)]
pub(super) fn linearise(
    model: &dyn TipModel,
    points: &[usize],
    b1_from_b2: &Isometry3<f64>,
    params: &[usize],
    values: &[f64],
    extra: &[usize],
    want_jacobian: bool,
) -> Result<Linearisation, IdentifyError> {
    let mut jac_params: Vec<usize> = Vec::new();
    if want_jacobian {
        jac_params.extend_from_slice(params);
        jac_params.extend_from_slice(extra);
    }
    let evals = eval_points(model, points, params, values, &jac_params);
    assemble(model, points, b1_from_b2, &jac_params, want_jacobian, evals)
}

/// [`linearise`] with the Jacobian (no extra columns) at the state `previous` was linearised at
/// without it: the tips are taken from `previous` and only the Jacobian columns are evaluated
/// ([`TipModel::eval_jacobian`]), so the tips are not computed twice. The result is the one
/// `linearise(…, &[], true)` gives at that state, bit for bit.
pub(super) fn relinearise_with_jacobian(
    model: &dyn TipModel,
    points: &[usize],
    b1_from_b2: &Isometry3<f64>,
    params: &[usize],
    values: &[f64],
    previous: &Linearisation,
) -> Result<Linearisation, IdentifyError> {
    let evals: Vec<Result<TipEval, IdentifyError>> = points
        .par_iter()
        .zip(previous.p1_b1.par_iter().zip(&previous.p2_b2))
        .with_min_len(POINTS_PER_TASK)
        .map(|(&i, (p1, p2))| {
            model
                .eval_jacobian(i, params, values, params)
                .map(|jacobian| TipEval {
                    p1_b1: Point3::from(*p1),
                    p2_b2: *p2,
                    jacobian,
                })
        })
        .collect();
    assemble(model, points, b1_from_b2, params, true, evals)
}

/// The linearisation from the tip evaluations `evals` (one per point of `points`, in order),
/// checked point by point in order (the first failing point's error is returned, as a
/// sequential evaluation would).
fn assemble(
    model: &dyn TipModel,
    points: &[usize],
    b1_from_b2: &Isometry3<f64>,
    jac_params: &[usize],
    want_jacobian: bool,
    evals: Vec<Result<TipEval, IdentifyError>>,
) -> Result<Linearisation, IdentifyError> {
    let n = points.len();
    let cols = if want_jacobian {
        6 + jac_params.len()
    } else {
        0
    };
    let mut residuals = DVector::zeros(3 * n);
    let mut jacobian = DMatrix::zeros(if want_jacobian { 3 * n } else { 0 }, cols);
    let r_x = b1_from_b2.rotation.to_rotation_matrix().into_inner();
    // Each point's rows on rayon's current pool (the arithmetic a sequential pass does, point by
    // point), then copied into place in point order, where the first failing point's error is
    // returned.
    let rows: Vec<Result<PointRows, IdentifyError>> = points
        .par_iter()
        .zip(evals.into_par_iter())
        .with_min_len(POINTS_PER_TASK)
        .map(|(&i, e)| point_rows(model, i, b1_from_b2, &r_x, jac_params, want_jacobian, e?))
        .collect();
    let mut p1_b1 = Vec::with_capacity(n);
    let mut p2_b2 = Vec::with_capacity(n);
    let mut raw = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for (row, rows) in rows.into_iter().enumerate() {
        let PointRows {
            p1_b1: p1,
            p2_b2: p2,
            raw: r,
            weight: w,
            residual,
            jacobian: block,
        } = rows?;
        p1_b1.push(p1);
        raw.push(r);
        weights.push(w);
        residuals.fixed_rows_mut::<3>(3 * row).copy_from(&residual);
        if want_jacobian {
            jacobian.view_mut((3 * row, 0), (3, cols)).copy_from(&block);
        }
        p2_b2.push(p2);
    }
    let rss = residuals.norm_squared();
    let raw_rss = raw.iter().map(|r| r.norm_squared()).sum();
    Ok(Linearisation {
        residuals,
        jacobian,
        rss,
        raw,
        raw_rss,
        weights,
        p1_b1,
        p2_b2,
    })
}

/// One point's part of a [`Linearisation`] ([`point_rows`]).
struct PointRows {
    /// Robot 1's tip, b1, m.
    p1_b1: Vector3<f64>,
    /// Robot 2's tip, b2, m.
    p2_b2: Point3<f64>,
    /// The unweighted residual `p1 − X·p2`, b1, m.
    raw: Vector3<f64>,
    /// The point's whitening matrix.
    weight: Matrix3<f64>,
    /// The weighted residual (3 rows).
    residual: Vector3<f64>,
    /// The weighted Jacobian rows (3 × (6 + parameters); empty without a Jacobian).
    jacobian: DMatrix<f64>,
}

/// Point `i`'s rows of [`assemble`]'s linearisation from its tip evaluation `e` (`r_x`: the
/// rotation of `b1_from_b2`), checked in the order a sequential pass checks them.
fn point_rows(
    model: &dyn TipModel,
    i: usize,
    b1_from_b2: &Isometry3<f64>,
    r_x: &Matrix3<f64>,
    jac_params: &[usize],
    want_jacobian: bool,
    e: TipEval,
) -> Result<PointRows, IdentifyError> {
    let y = b1_from_b2 * e.p2_b2;
    let r = e.p1_b1 - y;
    if !r.iter().all(|v| v.is_finite()) {
        return Err(IdentifyError::NonFinite { point: i });
    }
    let w = model.weight(i);
    let unit = w == Matrix3::identity();
    let residual = if unit { r } else { w * r };
    let cols = if want_jacobian {
        6 + jac_params.len()
    } else {
        0
    };
    let mut block = DMatrix::zeros(if want_jacobian { 3 } else { 0 }, cols);
    if want_jacobian {
        if e.jacobian.ncols() != jac_params.len() {
            return Err(IdentifyError::JacobianShape {
                point: i,
                columns: e.jacobian.ncols(),
                requested: jac_params.len(),
            });
        }
        block
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(-Matrix3::identity()));
        block
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&y.coords.cross_matrix());
        for (c, &p) in jac_params.iter().enumerate() {
            let col: Vector3<f64> = e.jacobian.column(c).into_owned();
            if !col.iter().all(|v| v.is_finite()) {
                return Err(IdentifyError::NonFinite { point: i });
            }
            let d = match model.param_robot(p) {
                Robot::One => col,
                Robot::Two => -(r_x * col),
            };
            block.fixed_view_mut::<3, 1>(0, 6 + c).copy_from(&d);
        }
        if !unit {
            let b = block.clone_owned();
            block.copy_from(&(w * b));
        }
    }
    Ok(PointRows {
        p1_b1: e.p1_b1.coords,
        p2_b2: e.p2_b2,
        raw: r,
        weight: w,
        residual,
        jacobian: block,
    })
}

impl Linearisation {
    /// The same linearisation with only the Jacobian columns `columns` (in that order): the
    /// start of a fit whose parameters are a subset of those this one was taken with, at the
    /// same state (a parameter not fitted is zero either way).
    pub(super) fn with_columns(&self, columns: &[usize]) -> Linearisation {
        let jacobian = DMatrix::from_fn(self.jacobian.nrows(), columns.len(), |r, c| {
            self.jacobian[(r, columns[c])]
        });
        Linearisation {
            residuals: self.residuals.clone(),
            jacobian,
            rss: self.rss,
            raw: self.raw.clone(),
            raw_rss: self.raw_rss,
            weights: self.weights.clone(),
            p1_b1: self.p1_b1.clone(),
            p2_b2: self.p2_b2.clone(),
        }
    }
}

/// The iterate of the identification fit: the placement and the fitted parameters' values.
struct IdentPoint {
    b1_from_b2: Isometry3<f64>,
    values: Vec<f64>,
}

/// The identification fit as a least-squares problem for the crate's solver: the tip model on
/// `points` with `params` fitted; the step is `[ρ (m); φ (rad); δθ]`.
struct IdentProblem<'a> {
    model: &'a dyn TipModel,
    points: &'a [usize],
    params: &'a [usize],
    /// The linearisation at the starting point when the caller already has it (taken by the
    /// solver's first [`LeastSquaresProblem::linearise`], the only one it makes).
    start: std::cell::Cell<Option<Linearisation>>,
}

impl Linearised for Linearisation {
    fn residuals(&self) -> &DVector<f64> {
        &self.residuals
    }

    fn jacobian(&self) -> &DMatrix<f64> {
        &self.jacobian
    }
}

impl IdentProblem<'_> {
    /// [`linearise`] at `at`, with the Jacobian or without.
    fn at(&self, at: &IdentPoint, want_jacobian: bool) -> Result<Linearisation, IdentifyError> {
        let (x, values) = (&at.b1_from_b2, &at.values);
        linearise(
            self.model,
            self.points,
            x,
            self.params,
            values,
            &[],
            want_jacobian,
        )
    }
}

impl LeastSquaresProblem for IdentProblem<'_> {
    type Point = IdentPoint;
    type System = Linearisation;
    type Error = IdentifyError;

    fn linearise(&self, at: &IdentPoint) -> Result<Linearisation, IdentifyError> {
        match self.start.take() {
            Some(start) => Ok(start),
            None => self.at(at, true),
        }
    }

    /// Every model failure (a non-finite tip included) is an error of the fit, not a stop.
    fn evaluate(&self, at: &IdentPoint) -> Result<Option<Linearisation>, IdentifyError> {
        self.at(at, false).map(Some)
    }

    fn relinearise(
        &self,
        at: &IdentPoint,
        evaluated: Linearisation,
    ) -> Result<Linearisation, IdentifyError> {
        relinearise_with_jacobian(
            self.model,
            self.points,
            &at.b1_from_b2,
            self.params,
            &at.values,
            &evaluated,
        )
    }

    /// `X ← Translation(ρ)·Rotation(φ)·X`, `θ ← θ + δθ` ([`retract`]).
    fn retract(&self, at: &IdentPoint, step: &DVector<f64>) -> IdentPoint {
        let (b1_from_b2, values) = retract(&at.b1_from_b2, &at.values, step);
        IdentPoint { b1_from_b2, values }
    }
}

/// The state moved by the step `[ρ (m); φ (rad); δθ]` of the identification fit:
/// `X ← Translation(ρ)·Rotation(φ)·X`, `θ ← θ + δθ` (the left perturbation the Jacobian's
/// columns of [`linearise`] are taken in).
pub(super) fn retract(
    b1_from_b2: &Isometry3<f64>,
    values: &[f64],
    step: &DVector<f64>,
) -> (Isometry3<f64>, Vec<f64>) {
    let rho = Vector3::new(step[0], step[1], step[2]);
    let phi = Vector3::new(step[3], step[4], step[5]);
    let x = Isometry3::from_parts(Translation3::from(rho), UnitQuaternion::identity())
        * Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_scaled_axis(phi),
        )
        * b1_from_b2;
    let values = values
        .iter()
        .enumerate()
        .map(|(c, v)| v + step[6 + c])
        .collect();
    (x, values)
}

/// Fits `b1_from_b2` and the parameters `params` (starting from `initial_values`, or zeros) on
/// all points by Levenberg–Marquardt. `b1_from_b2` starts from the rigid fit of the tips at the
/// initial parameters unless `initial_b1_from_b2` is given.
///
/// Failure cases: too few points ([`min_points`] with zero redundancy check: `3n ≥ 6 + k + 1`),
/// bad parameter indices, model failures, non-finite values.
pub fn fit(
    model: &dyn TipModel,
    params: &[usize],
    initial_values: Option<&[f64]>,
    initial_b1_from_b2: Option<Isometry3<f64>>,
    options: &LmOptions,
) -> Result<IdentFit, IdentifyError> {
    let points: Vec<usize> = (0..model.n_points()).collect();
    fit_points(
        model,
        &points,
        params,
        initial_values,
        initial_b1_from_b2,
        options,
    )
}

/// [`fit`] on a subset of the points (used for cross-validation).
pub fn fit_points(
    model: &dyn TipModel,
    points: &[usize],
    params: &[usize],
    initial_values: Option<&[f64]>,
    initial_b1_from_b2: Option<Isometry3<f64>>,
    options: &LmOptions,
) -> Result<IdentFit, IdentifyError> {
    fit_points_from(
        model,
        points,
        params,
        initial_values,
        initial_b1_from_b2,
        None,
        options,
    )
}

/// [`fit`] on every point from `b1_from_b2` and `values` (one per parameter of `params`), whose
/// linearisation `start` (residuals and the Jacobian columns `[b1_from_b2; params]`, e.g. from
/// [`Linearisation::with_columns`]) the caller already has: the fit does not evaluate it again.
/// The result is [`fit`]'s from that start, bit for bit, when `start` is what [`linearise`]
/// gives there. Failure cases: as [`fit`].
pub(super) fn fit_from_linearisation(
    model: &dyn TipModel,
    params: &[usize],
    values: &[f64],
    b1_from_b2: Isometry3<f64>,
    start: Linearisation,
    options: &LmOptions,
) -> Result<IdentFit, IdentifyError> {
    let points: Vec<usize> = (0..model.n_points()).collect();
    let start = (values.len() == params.len()
        && start.residuals.len() == 3 * points.len()
        && start.jacobian.ncols() == 6 + params.len())
    .then_some(start);
    fit_points_from(
        model,
        &points,
        params,
        Some(values),
        Some(b1_from_b2),
        start,
        options,
    )
}

/// [`fit_points`], the solver's first linearisation `start` when given (it must be the one at
/// the starting state: the caller checks its shape).
fn fit_points_from(
    model: &dyn TipModel,
    points: &[usize],
    params: &[usize],
    initial_values: Option<&[f64]>,
    initial_b1_from_b2: Option<Isometry3<f64>>,
    start: Option<Linearisation>,
    options: &LmOptions,
) -> Result<IdentFit, IdentifyError> {
    check_params(model, params)?;
    let k = params.len();
    let n = points.len();
    if 3 * n < 6 + k + 1 || n < 3 {
        return Err(IdentifyError::TooFewPoints {
            n,
            params: k,
            needed: min_points(k),
        });
    }
    let values: Vec<f64> = match initial_values {
        Some(v) if v.len() == k => v.to_vec(),
        _ => vec![0.0; k],
    };
    let x = match initial_b1_from_b2 {
        Some(x) => x,
        None => {
            let mut p1 = Vec::with_capacity(n);
            let mut p2 = Vec::with_capacity(n);
            for &i in points {
                let e = model.eval(i, params, &values, &[])?;
                p1.push(e.p1_b1);
                p2.push(e.p2_b2);
            }
            crate::rigid_fit_fast(&p1, &p2).unwrap_or_else(Isometry3::identity)
        }
    };
    let problem = IdentProblem {
        model,
        points,
        params,
        start: std::cell::Cell::new(start),
    };
    let min = minimize(
        &problem,
        IdentPoint {
            b1_from_b2: x,
            values,
        },
        options,
    )?;
    let IdentPoint {
        b1_from_b2: x,
        values,
    } = min.point;
    let lin = min.system;
    let dof = (3 * n).saturating_sub(6 + k);
    let sigma_hat = if dof > 0 {
        (lin.rss / dof as f64).sqrt()
    } else {
        f64::NAN
    };
    let h = lin.jacobian.transpose() * &lin.jacobian;
    let (inv, singular) = sym_inverse(&h, COVARIANCE_REL_EIGEN_TOL);
    let covariance = inv * (sigma_hat * sigma_hat);
    let residuals = lin.raw.clone();
    Ok(IdentFit {
        b1_from_b2: x,
        params: params.to_vec(),
        values,
        points: points.to_vec(),
        residuals,
        rss: lin.rss,
        dof,
        sigma_hat,
        covariance,
        singular,
        iterations: min.iterations,
        stopped: min.stopped,
    })
}

/// Inverse of a symmetric positive semi-definite matrix by scaled eigen-decomposition; pseudo-inverse
/// (and `true`) when eigenvalues of the scaled matrix are at or below `rel_eigen_tol` times the
/// largest.
pub(super) fn sym_inverse(h: &DMatrix<f64>, rel_eigen_tol: f64) -> (DMatrix<f64>, bool) {
    let m = h.nrows();
    let d: Vec<f64> = (0..m)
        .map(|i| {
            let v = h[(i, i)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                1.0
            }
        })
        .collect();
    let dm = DMatrix::from_diagonal(&DVector::from_vec(d));
    let scaled = &dm * h * &dm;
    let eig = scaled.symmetric_eigen();
    let emax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut singular = false;
    let mut inv_diag = DVector::zeros(m);
    for i in 0..m {
        let e = eig.eigenvalues[i];
        if e > rel_eigen_tol * emax && e > 0.0 {
            inv_diag[i] = 1.0 / e;
        } else {
            singular = true;
        }
    }
    let inv_scaled =
        &eig.eigenvectors * DMatrix::from_diagonal(&inv_diag) * eig.eigenvectors.transpose();
    (&dm * inv_scaled * &dm, singular)
}
