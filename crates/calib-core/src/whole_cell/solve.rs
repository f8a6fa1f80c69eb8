//! The MAP solver: Levenberg–Marquardt on the whitened data residuals plus the prior rows.

use nalgebra::{DMatrix, DVector, Isometry3};
use serde::Serialize;

use super::{
    initial_estimate, CellEstimate, CellFitError, CellParam, CellProblem, Evaluator,
    ObservationLinearisation, ParamLayout,
};

/// Solver settings. Every default is documented on its field.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveOptions {
    /// Iteration cap (default 100; a well-posed cell converges in 3–10).
    pub max_iterations: usize,
    /// Converged when an accepted step lowers the cost by less than this fraction, or the
    /// predicted decrease `gᵀH⁻¹g/2` is below this fraction of the cost (default 1e-10).
    pub cost_tolerance: f64,
    /// Initial damping relative to `diag(H)` (default 1e-3).
    pub initial_damping: f64,
    /// Starting `b1_from_b2`; default `None`: a rigid fit of the coincident rows at nominal.
    pub initial_b1_from_b2: Option<Isometry3<f64>>,
}

impl Default for SolveOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            cost_tolerance: 1e-10,
            initial_damping: 1e-3,
            initial_b1_from_b2: None,
        }
    }
}

impl SolveOptions {
    fn check(&self) -> Result<(), CellFitError> {
        if self.max_iterations == 0 {
            return Err(CellFitError::InvalidInput(
                "solver option `max_iterations` must be at least 1".into(),
            ));
        }
        for (f, v) in [
            ("cost_tolerance", self.cost_tolerance),
            ("initial_damping", self.initial_damping),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(CellFitError::InvalidInput(format!(
                    "solver option `{f}` is {v}; it must be finite and > 0"
                )));
            }
        }
        Ok(())
    }
}

/// Why the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum StopReason {
    /// The cost stopped decreasing (relative change or predicted decrease below tolerance).
    Converged,
    /// `max_iterations` reached first.
    IterationCap,
    /// No damped step lowers the cost although the predicted decrease is not negligible.
    StepTooSmall,
    /// A residual or Jacobian became non-finite (the iterate diverged).
    NonFinite,
}

impl StopReason {
    /// `"converged"`, `"iteration_cap"`, `"step_too_small"` or `"non_finite"`.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::IterationCap => "iteration_cap",
            StopReason::StepTooSmall => "step_too_small",
            StopReason::NonFinite => "non_finite",
        }
    }
}

/// A MAP fit of the cell.
#[derive(Debug, Clone)]
pub struct CellFit {
    /// The estimate at the optimum.
    pub estimate: CellEstimate,
    /// The unknowns (columns of `covariance`) and their prior.
    pub layout: ParamLayout,
    /// Posterior covariance `(JᵀJ)⁻¹` of the unknowns (whitened data rows and prior rows), in
    /// their SI units; the placement and tracker columns are left perturbations (m, rad).
    /// Pseudo-inverse when singular.
    pub covariance: DMatrix<f64>,
    /// Whether `JᵀJ` was numerically singular (some direction determined by neither data nor
    /// prior).
    pub singular: bool,
    /// Data part of the cost `Σ‖W_i·r_i‖²` (dimensionless, χ²-like).
    pub data_chi2: f64,
    /// Prior part of the cost `‖R_p·θ‖²` plus the placement prior's (if any).
    pub prior_chi2: f64,
    /// Residual rows (scalars) of the data used.
    pub residual_rows: usize,
    /// Indices (into the problem's observations) of the observations used.
    pub active: Vec<usize>,
    /// Iterations used.
    pub iterations: usize,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// Variance per b1 axis (m²) of the error the model does not represent, added to every
    /// predicted cooperative covariance ([`super::predict_cooperative_accuracy`]): 0 from the
    /// solver; set by [`super::calibrate_cell`] for a placement-only model from the excess of
    /// its residuals over the stated noise (the robots' unmodelled kinematic error).
    pub model_error_var_m2: f64,
}

impl CellFit {
    /// Posterior standard deviation of column `j`, its unit.
    pub fn std_error(&self, j: usize) -> f64 {
        self.covariance[(j, j)].max(0.0).sqrt()
    }

    /// The fitted value of each unknown with its prior and posterior σ (SI units; the
    /// placement's prior σ is the problem's [`super::PlacementPrior`], if any).
    pub fn parameters(&self, problem: &CellProblem) -> Vec<FittedParam> {
        let values = self.layout.values(&self.estimate);
        self.layout
            .params
            .iter()
            .enumerate()
            .map(|(j, p)| FittedParam {
                param: p.clone(),
                name: p.describe(problem),
                value: values[j],
                prior_sigma: match (p, &problem.placement_prior) {
                    (CellParam::PlacementTranslation { .. }, Some(pp)) => pp.sigma_m,
                    (CellParam::PlacementRotation { .. }, Some(pp)) => pp.sigma_rad,
                    _ => self.layout.prior_sigma(j),
                },
                posterior_sigma: self.std_error(j),
            })
            .collect()
    }
}

/// One fitted unknown, for reports. Values in the parameter's SI unit (m, rad, ratio,
/// rad/(N·m)); perturbation columns (placement, tracker, plane normal) report 0 as value.
#[derive(Debug, Clone, Serialize)]
pub struct FittedParam {
    /// Which unknown.
    pub param: CellParam,
    /// Readable name.
    pub name: String,
    /// Value, SI.
    pub value: f64,
    /// Prior σ, SI (0: unpenalised).
    pub prior_sigma: f64,
    /// Posterior σ, SI.
    pub posterior_sigma: f64,
}

/// The stacked whitened system at an estimate.
pub(crate) struct System {
    /// Whitened residuals, data rows, then the layout's prior rows, then the placement prior's.
    pub r: DVector<f64>,
    /// Whitened Jacobian, same rows.
    pub j: DMatrix<f64>,
    /// Number of data rows.
    pub data_rows: usize,
    /// Row offset of each active observation's block.
    pub block_start: Vec<usize>,
}

/// Linearises every active observation (rows scaled by `sqrt(weight)`) and appends the prior.
pub(crate) fn assemble(
    problem: &CellProblem,
    layout: &ParamLayout,
    est: &CellEstimate,
    active: &[usize],
    weights: Option<&[f64]>,
    want_jac: bool,
) -> Result<System, CellFitError> {
    let ev = Evaluator::new(problem, layout);
    let n = layout.len();
    let lins: Vec<ObservationLinearisation> = active
        .iter()
        .map(|&i| ev.linearise(&problem.observations[i], est, want_jac))
        .collect::<Result<_, _>>()?;
    let data_rows: usize = lins.iter().map(|l| l.residual.len()).sum();
    let p = layout.prior_sqrt_info.nrows();
    let placement = problem
        .placement_prior
        .map(|pp| pp.linearise(&est.b1_from_b2));
    let pl_rows = placement.as_ref().map_or(0, |(r, _)| r.len());
    let m = data_rows + p + pl_rows;
    let mut r = DVector::zeros(m);
    let mut j = DMatrix::zeros(if want_jac { m } else { 0 }, n);
    let mut block_start = Vec::with_capacity(active.len());
    let mut row = 0;
    for (k, l) in lins.iter().enumerate() {
        let w = weights.map_or(1.0, |w| w[k]).sqrt();
        let rows = l.residual.len();
        block_start.push(row);
        r.rows_mut(row, rows)
            .copy_from(&(&l.whitening * &l.residual * w));
        if want_jac {
            j.rows_mut(row, rows)
                .copy_from(&(&l.whitening * &l.jacobian * w));
        }
        row += rows;
    }
    let theta = layout.values(est);
    r.rows_mut(data_rows, p)
        .copy_from(&(&layout.prior_sqrt_info * theta));
    if want_jac {
        j.rows_mut(data_rows, p).copy_from(&layout.prior_sqrt_info);
    }
    // The placement prior (columns 0..6 are the placement's left perturbation); not scaled by
    // IRLS weights or the prior scale, not a data row for the blunder screen.
    if let Some((pr, pj)) = placement {
        for (k, (rv, jv)) in pr.iter().zip(&pj).enumerate() {
            r[data_rows + p + k] = *rv;
            if want_jac {
                for (c, v) in jv.iter().enumerate() {
                    j[(data_rows + p + k, c)] = *v;
                }
            }
        }
    }
    Ok(System {
        r,
        j,
        data_rows,
        block_start,
    })
}

/// Inverse of a symmetric positive semi-definite matrix by a Jacobi-scaled eigen-decomposition;
/// pseudo-inverse (and `true`) when the scaled condition exceeds 1e14.
pub(crate) fn sym_inverse(h: &DMatrix<f64>) -> (DMatrix<f64>, bool) {
    let m = h.nrows();
    let d = DVector::from_iterator(
        m,
        (0..m).map(|i| {
            let v = h[(i, i)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                1.0
            }
        }),
    );
    let scaled = DMatrix::from_fn(m, m, |a, b| h[(a, b)] * d[a] * d[b]);
    let eig = scaled.symmetric_eigen();
    let emax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut singular = false;
    let inv_diag = eig.eigenvalues.map(|e| {
        if e > 1e-14 * emax && e > 0.0 {
            1.0 / e
        } else {
            singular = true;
            0.0
        }
    });
    let v = &eig.eigenvectors;
    let mut inv = v * DMatrix::from_diagonal(&inv_diag) * v.transpose();
    for a in 0..m {
        for b in 0..m {
            inv[(a, b)] *= d[a] * d[b];
        }
    }
    (inv, singular)
}

/// Fits the cell by MAP on all observations. See [`fit_cell_with`] for the options.
///
/// A complete two-robot example (problem built from an inline URDF, then fitted) is on
/// [`super::calibrate_cell`]; `fit_cell(&problem, &SolveOptions::default())` fits the same
/// problem without reduction or screening.
pub fn fit_cell(problem: &CellProblem, options: &SolveOptions) -> Result<CellFit, CellFitError> {
    let active: Vec<usize> = (0..problem.observations.len()).collect();
    let layout = ParamLayout::new(problem, &[]);
    fit_cell_with(problem, layout, &active, None, None, options)
}

/// MAP fit with a given layout (e.g. after [`super::reduce`]), a subset of the observations,
/// optional per-observation weights (IRLS) and an optional starting estimate.
///
/// Minimises `Σ_i w_i‖W_i·r_i‖² + ‖R_p·θ‖²` by Levenberg–Marquardt. Errors: invalid input
/// (see [`CellProblem::check`]), no starting placement, or model failures at an observation.
/// Non-convergence is reported in [`CellFit::stopped`].
pub fn fit_cell_with(
    problem: &CellProblem,
    layout: ParamLayout,
    active: &[usize],
    weights: Option<&[f64]>,
    start: Option<&CellEstimate>,
    options: &SolveOptions,
) -> Result<CellFit, CellFitError> {
    problem.check()?;
    options.check()?;
    if let Some(w) = weights {
        if w.len() != active.len() || !w.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(CellFitError::InvalidInput(
                "weights: one finite weight ≥ 0 per active observation is needed".into(),
            ));
        }
    }
    let mut est = match start {
        Some(s) => {
            s.check(problem)?;
            s.clone()
        }
        None => initial_estimate(problem, options.initial_b1_from_b2, active)?,
    };
    let mut sys = assemble(problem, &layout, &est, active, weights, true)?;
    let mut cost = sys.r.norm_squared();
    let mut lambda = options.initial_damping;
    let mut iterations = 0;
    let mut stopped = StopReason::IterationCap;
    while iterations < options.max_iterations {
        iterations += 1;
        let jt = sys.j.transpose();
        let h = &jt * &sys.j;
        let g = &jt * &sys.r;
        let dmax = (0..h.nrows()).map(|i| h[(i, i)]).fold(0.0, f64::max);
        let floor = 1e-12 * dmax.max(1e-300);
        // Predicted decrease of the undamped Gauss–Newton step.
        let predicted = match h.clone().cholesky() {
            Some(c) => g.dot(&c.solve(&g)),
            None => f64::INFINITY,
        };
        if predicted.is_finite() && predicted < options.cost_tolerance * cost.max(1e-300) {
            stopped = StopReason::Converged;
            break;
        }
        let mut accepted = false;
        let mut non_finite = false;
        while lambda <= 1e10 {
            let mut a = h.clone();
            for i in 0..a.nrows() {
                a[(i, i)] += lambda * h[(i, i)].max(floor);
            }
            let Some(c) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step = -c.solve(&g);
            let trial = layout.apply(&est, &step);
            let trial_sys = match assemble(problem, &layout, &trial, active, weights, false) {
                Ok(s) => s,
                Err(CellFitError::NonFinite { .. } | CellFitError::Kinematics { .. }) => {
                    non_finite = true;
                    break;
                }
                Err(e) => return Err(e),
            };
            let trial_cost = trial_sys.r.norm_squared();
            if !trial_cost.is_finite() {
                non_finite = true;
                break;
            }
            if trial_cost <= cost {
                let rel = (cost - trial_cost) / cost.max(1e-300);
                est = trial;
                sys = assemble(problem, &layout, &est, active, weights, true)?;
                cost = trial_cost;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                if rel < options.cost_tolerance {
                    stopped = StopReason::Converged;
                }
                break;
            }
            lambda *= 10.0;
        }
        if non_finite {
            stopped = StopReason::NonFinite;
            break;
        }
        if !accepted {
            stopped = StopReason::StepTooSmall;
            break;
        }
        if stopped == StopReason::Converged {
            break;
        }
    }
    let h = sys.j.transpose() * &sys.j;
    let (covariance, singular) = sym_inverse(&h);
    let data_chi2 = sys.r.rows(0, sys.data_rows).norm_squared();
    let prior_chi2 = cost - data_chi2;
    Ok(CellFit {
        estimate: est,
        layout,
        covariance,
        singular,
        data_chi2,
        prior_chi2,
        residual_rows: sys.data_rows,
        active: active.to_vec(),
        iterations,
        stopped,
        model_error_var_m2: 0.0,
    })
}
