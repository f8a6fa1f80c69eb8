//! The MAP fit: the whitened data residuals plus the prior rows as a least-squares problem
//! ([`assemble`]), minimised by the crate's one Levenberg–Marquardt solver
//! ([`crate::LmOptions`], schedule [`LmOptions::whole_cell`]).

use std::sync::Arc;

use nalgebra::{DMatrix, DVector, Isometry3};
use rayon::prelude::*;
use serde::Serialize;

use super::{
    initial_estimate, CellEstimate, CellFitError, CellParam, CellProblem, Evaluator, ParamLayout,
};
use crate::lm::{minimize, LeastSquaresProblem, Linearised};
use crate::{LmOptions, StopReason};

/// Eigenvalues of the Jacobi-scaled `JᵀJ` at or below this fraction of the largest are dropped
/// from the posterior covariance (pseudo-inverse) and flag the fit [`CellFit::singular`].
const COVARIANCE_REL_EIGEN_TOL: f64 = 1e-14;

/// Observations per rayon task when [`assemble`] linearises in parallel (tens of µs each with
/// the Jacobian: a task of ~0.5 ms, far above rayon's scheduling cost).
const OBSERVATIONS_PER_TASK: usize = 16;

/// Solver settings. Every default is documented on its field.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SolveOptions {
    /// The Levenberg–Marquardt settings, checked when set (default [`LmOptions::whole_cell`]:
    /// 100 iterations, cost tolerance 1e-10 on the relative and the predicted decrease, initial
    /// damping 1e-3).
    pub lm: LmOptions,
    /// Starting `b1_from_b2`; default `None`: a rigid fit of the coincident rows at nominal.
    pub initial_b1_from_b2: Option<Isometry3<f64>>,
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
    /// The linearisation at the optimum, kept so that the statistics and fits that start from
    /// this estimate do not evaluate the robots again. Checked against the fit's estimate,
    /// layout and active observations before each use: a fit changed by hand is linearised
    /// again.
    pub(crate) at_optimum: Option<Arc<AtOptimum>>,
}

/// The whitened data rows (unweighted, `W_i·r_i` and `W_i·J_i`) of some observations at one
/// estimate and layout: what [`assemble`] scales by the IRLS weights and stacks over the prior.
#[derive(Debug)]
pub(crate) struct DataRows {
    /// The observations (indices into the problem's), in row order.
    pub observations: Vec<usize>,
    /// Row offset of each observation's block.
    pub block_start: Vec<usize>,
    /// Whitened residuals (the system's prior rows may follow the data rows: read the blocks
    /// by their offsets).
    pub r: DVector<f64>,
    /// Whitened Jacobian, same rows (none when only the residuals were evaluated).
    pub j: DMatrix<f64>,
    /// Whether `j` holds the Jacobian.
    pub jacobian: bool,
}

/// A fit's linearisation at its optimum ([`CellFit::at_optimum`]).
#[derive(Debug)]
pub(crate) struct AtOptimum {
    /// The estimate it was taken at.
    estimate: CellEstimate,
    /// The layout's columns it was taken with.
    params: Vec<CellParam>,
    /// The layout's prior rows `R_p` (part of `information`).
    prior_sqrt_info: DMatrix<f64>,
    /// The unweighted data rows of the fit's active observations, with the Jacobian.
    pub rows: DataRows,
    /// `JᵀJ` of the unweighted system (data and prior rows) at the optimum, whose inverse is
    /// the fit's covariance; `None` for an IRLS-weighted fit (its system was another).
    information: Option<DMatrix<f64>>,
}

impl AtOptimum {
    /// Whether these rows are the ones a linearisation at `est` with `layout`'s columns gives.
    pub fn matches(&self, layout: &ParamLayout, est: &CellEstimate) -> bool {
        self.params == layout.params && self.estimate == *est
    }
}

impl CellFit {
    /// The unweighted `JᵀJ` at the optimum (data and prior rows, as [`assemble`] with no weights
    /// stacks them), from the fit's own linearisation when it has one.
    pub(crate) fn information(&self, problem: &CellProblem) -> Result<DMatrix<f64>, CellFitError> {
        match self.at_optimum.as_deref() {
            Some(AtOptimum {
                information: Some(h),
                prior_sqrt_info,
                ..
            }) if self.at_optimum_matches() && *prior_sqrt_info == self.layout.prior_sqrt_info => {
                Ok(h.clone())
            }
            _ => {
                let sys = assemble(
                    problem,
                    &self.layout,
                    &self.estimate,
                    &self.active,
                    None,
                    true,
                )?;
                Ok(sys.j.transpose() * &sys.j)
            }
        }
    }

    /// The fit's linearisation at its optimum: its own when it has one, else the unweighted
    /// data rows of its active observations evaluated now (with the Jacobian).
    pub(crate) fn linearisation(
        &self,
        problem: &CellProblem,
    ) -> Result<Arc<AtOptimum>, CellFitError> {
        match &self.at_optimum {
            Some(a) if self.at_optimum_matches() => Ok(Arc::clone(a)),
            _ => {
                let rows =
                    linearise_rows(problem, &self.layout, &self.estimate, &self.active, None)?;
                Ok(Arc::new(AtOptimum {
                    estimate: self.estimate.clone(),
                    params: self.layout.params.clone(),
                    prior_sqrt_info: self.layout.prior_sqrt_info.clone(),
                    rows,
                    information: None,
                }))
            }
        }
    }

    /// Whether [`CellFit::at_optimum`] is still the linearisation at this fit's estimate and
    /// layout (a caller may have changed them).
    fn at_optimum_matches(&self) -> bool {
        self.at_optimum.as_ref().is_some_and(|a| {
            a.matches(&self.layout, &self.estimate)
                && a.rows.observations == self.active
                && a.rows.jacobian
        })
    }
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
    /// The observations of the data rows, in row order.
    observations: Vec<usize>,
    /// Row offset of each observation's block.
    pub block_start: Vec<usize>,
    /// The data rows before the IRLS weights (residuals, Jacobian) of a weighted system; `None`
    /// without weights (they are then the first `data_rows` rows of `r` and `j`).
    unweighted: Option<(DVector<f64>, DMatrix<f64>)>,
    /// Whether `j` holds the Jacobian.
    jacobian: bool,
}

impl System {
    /// The unweighted data rows of this system (the prior rows may follow them in `r` and `j`:
    /// blocks are read by their offsets).
    fn into_rows(self) -> DataRows {
        let jacobian = self.jacobian;
        let (r, j) = self.unweighted.unwrap_or((self.r, self.j));
        DataRows {
            observations: self.observations,
            block_start: self.block_start,
            r,
            j,
            jacobian,
        }
    }
}

/// One observation's whitened residuals `W·r` and, when asked for, Jacobian rows `W·J`.
type Whitened = (DVector<f64>, Option<DMatrix<f64>>);

/// The unweighted whitened rows of `observations` at `est` (with the Jacobian): each block
/// copied from `reuse` when it holds that observation (taken at the same estimate and layout
/// columns: the caller's promise), else linearised, in parallel on rayon's current pool.
/// Errors: the first in the order of `observations`, as a sequential loop would return it.
pub(crate) fn linearise_rows(
    problem: &CellProblem,
    layout: &ParamLayout,
    est: &CellEstimate,
    observations: &[usize],
    reuse: Option<&DataRows>,
) -> Result<DataRows, CellFitError> {
    linearise_rows_with(problem, layout, est, observations, reuse, true)
}

/// [`linearise_rows`], with the Jacobian or without (`want_jac`; `reuse` is then ignored).
fn linearise_rows_with(
    problem: &CellProblem,
    layout: &ParamLayout,
    est: &CellEstimate,
    observations: &[usize],
    reuse: Option<&DataRows>,
    want_jac: bool,
) -> Result<DataRows, CellFitError> {
    let ev = Evaluator::new(problem, layout);
    let at = ev.at(est);
    let n = layout.len();
    // Where each observation's block is in `reuse` (indexed by observation).
    let mut reused: Vec<Option<usize>> = Vec::new();
    if let Some(old) = reuse.filter(|old| want_jac && old.jacobian) {
        reused = vec![None; problem.observations.len()];
        for (b, &i) in old.observations.iter().enumerate() {
            if let Some(slot) = reused.get_mut(i) {
                *slot = Some(old.block_start[b]);
            }
        }
    }
    let fresh: Vec<usize> = observations
        .iter()
        .copied()
        .filter(|&i| reused.get(i).copied().flatten().is_none())
        .collect();
    // Each observation whitened on the thread that linearised it (`W·r`, `W·J`).
    let lins: Vec<Result<Whitened, CellFitError>> = fresh
        .par_iter()
        .with_min_len(OBSERVATIONS_PER_TASK)
        .map(|&i| {
            let l = ev.linearise_at(&problem.observations[i], &at, want_jac)?;
            let j = want_jac.then(|| &l.whitening * &l.jacobian);
            Ok((&l.whitening * &l.residual, j))
        })
        .collect();
    let mut lins = lins.into_iter();
    let total: usize = observations
        .iter()
        .map(|&i| problem.observations[i].kind.rows())
        .sum();
    let mut rows = DataRows {
        observations: observations.to_vec(),
        block_start: Vec::with_capacity(observations.len()),
        r: DVector::zeros(total),
        j: DMatrix::zeros(if want_jac { total } else { 0 }, n),
        jacobian: want_jac,
    };
    let mut row = 0;
    for &i in observations {
        let k = problem.observations[i].kind.rows();
        rows.block_start.push(row);
        match (reuse, reused.get(i).copied().flatten()) {
            (Some(old), Some(at)) => {
                rows.r.rows_mut(row, k).copy_from(&old.r.rows(at, k));
                rows.j.rows_mut(row, k).copy_from(&old.j.rows(at, k));
            }
            _ => {
                // The first error in the order of `observations` (the fresh ones keep it).
                let (r, j) = lins
                    .next()
                    .expect("one linearisation per fresh observation")?;
                rows.r.rows_mut(row, k).copy_from(&r);
                if let Some(j) = j {
                    rows.j.rows_mut(row, k).copy_from(&j);
                }
            }
        }
        row += k;
    }
    Ok(rows)
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
    let rows = linearise_rows_with(problem, layout, est, active, None, want_jac)?;
    Ok(stack(problem, layout, est, rows, weights))
}

/// The system of [`assemble`] from the unweighted data rows at `est`: each block scaled by
/// `sqrt(weight)` (`weights` one per block of `rows`), then the layout's prior rows and the
/// placement prior's.
fn stack(
    problem: &CellProblem,
    layout: &ParamLayout,
    est: &CellEstimate,
    rows: DataRows,
    weights: Option<&[f64]>,
) -> System {
    let n = layout.len();
    let want_jac = rows.jacobian;
    let data_rows: usize = rows
        .observations
        .iter()
        .map(|&i| problem.observations[i].kind.rows())
        .sum();
    let p = layout.prior_sqrt_info.nrows();
    let placement = problem
        .placement_prior
        .map(|pp| pp.linearise(&est.b1_from_b2));
    let pl_rows = placement.as_ref().map_or(0, |(r, _)| r.len());
    let m = data_rows + p + pl_rows;
    let mut r = DVector::zeros(m);
    let mut j = DMatrix::zeros(if want_jac { m } else { 0 }, n);
    match weights {
        None => {
            r.rows_mut(0, data_rows)
                .copy_from(&rows.r.rows(0, data_rows));
            if want_jac {
                j.rows_mut(0, data_rows)
                    .copy_from(&rows.j.rows(0, data_rows));
            }
        }
        Some(weights) => {
            for (b, &start) in rows.block_start.iter().enumerate() {
                let w = weights[b].sqrt();
                let k = problem.observations[rows.observations[b]].kind.rows();
                r.rows_mut(start, k).copy_from(&(rows.r.rows(start, k) * w));
                if want_jac {
                    j.rows_mut(start, k).copy_from(&(rows.j.rows(start, k) * w));
                }
            }
        }
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
    let unweighted = weights.map(|_| (rows.r, rows.j));
    System {
        r,
        j,
        data_rows,
        observations: rows.observations,
        block_start: rows.block_start,
        unweighted,
        jacobian: want_jac,
    }
}

/// Inverse of a symmetric positive semi-definite matrix by a Jacobi-scaled eigen-decomposition;
/// pseudo-inverse (and `true`) when the scaled condition exceeds 1e14
/// ([`COVARIANCE_REL_EIGEN_TOL`]).
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
        if e > COVARIANCE_REL_EIGEN_TOL * emax && e > 0.0 {
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

impl Linearised for System {
    fn residuals(&self) -> &DVector<f64> {
        &self.r
    }

    fn jacobian(&self) -> &DMatrix<f64> {
        &self.j
    }
}

/// The MAP fit as a least-squares problem for the crate's solver: the active observations
/// (IRLS-weighted if `weights`) and the prior rows of `layout`; the step has one entry per
/// column of `layout`, applied by [`ParamLayout::apply`].
struct MapProblem<'a> {
    problem: &'a CellProblem,
    layout: &'a ParamLayout,
    active: &'a [usize],
    weights: Option<&'a [f64]>,
    /// A linearisation at the start (another fit's optimum): its rows are reused where it has
    /// the observation and it was taken at the start with these columns.
    start_rows: Option<&'a AtOptimum>,
}

impl MapProblem<'_> {
    /// [`assemble`] at `at`, with the Jacobian or without.
    fn at(&self, at: &CellEstimate, want_jac: bool) -> Result<System, CellFitError> {
        let (problem, layout) = (self.problem, self.layout);
        assemble(problem, layout, at, self.active, self.weights, want_jac)
    }
}

impl LeastSquaresProblem for MapProblem<'_> {
    type Point = CellEstimate;
    type System = System;
    type Error = CellFitError;

    /// At the start: the rows of [`MapProblem::start_rows`] where they apply (the same values
    /// a new linearisation gives), the others linearised.
    fn linearise(&self, at: &CellEstimate) -> Result<System, CellFitError> {
        match self.start_rows.filter(|s| s.matches(self.layout, at)) {
            Some(start) => {
                let rows = linearise_rows(
                    self.problem,
                    self.layout,
                    at,
                    self.active,
                    Some(&start.rows),
                )?;
                Ok(stack(self.problem, self.layout, at, rows, self.weights))
            }
            None => self.at(at, true),
        }
    }

    /// A non-finite residual or a kinematics failure at a trial estimate means the step
    /// diverged (`None`: the solver stops with [`StopReason::NonFinite`]); other errors are
    /// errors.
    ///
    /// The trial is linearised with the Jacobian: most trial steps of these fits are accepted
    /// (2,000-row session: every one of the screen's), and an accepted trial's system is then
    /// the next iteration's ([`MapProblem::relinearise`]) instead of a second pass over the
    /// robots. The residuals are the same values as without the Jacobian (one walk of each
    /// chain gives both, [`kinematics::true_tip_with_error_jacobian`]). A trial whose
    /// linearisation fails is evaluated again without the Jacobian and judged on that, as
    /// before, so that the solver's decisions and errors do not change.
    fn evaluate(&self, at: &CellEstimate) -> Result<Option<System>, CellFitError> {
        match self.at(at, true) {
            Ok(s) => Ok(Some(s)),
            Err(_) => match self.at(at, false) {
                Ok(s) => Ok(Some(s)),
                Err(CellFitError::NonFinite { .. } | CellFitError::Kinematics { .. }) => Ok(None),
                Err(e) => Err(e),
            },
        }
    }

    /// The evaluated trial itself when it holds the Jacobian ([`MapProblem::evaluate`]), else
    /// linearised now.
    fn relinearise(&self, at: &CellEstimate, evaluated: System) -> Result<System, CellFitError> {
        if evaluated.jacobian {
            Ok(evaluated)
        } else {
            self.at(at, true)
        }
    }

    fn retract(&self, at: &CellEstimate, step: &DVector<f64>) -> CellEstimate {
        self.layout.apply(at, step)
    }
}

/// Fits the cell by MAP on all observations. See [`fit_cell_with`] for the options.
///
/// A complete two-robot example (problem built from an inline URDF, then fitted) is on
/// [`super::calibrate_cell`]; `fit_cell(&problem, &SolveOptions::default())` fits the same
/// problem without reduction or screening.
pub fn fit_cell(problem: &CellProblem, options: &SolveOptions) -> Result<CellFit, CellFitError> {
    let active: Vec<usize> = (0..problem.observations.len()).collect();
    let layout = ParamLayout::new(problem, &[]);
    fit_cell_with(problem, layout, &active, None, options)
}

/// MAP fit with a given layout (e.g. after [`super::reduce`]) on the observations `active`
/// (indices into `problem.observations`), from `start` (`None`: [`initial_estimate`] with
/// [`SolveOptions::initial_b1_from_b2`]).
///
/// Minimises `Σ_i ‖W_i·r_i‖² + ‖R_p·θ‖²` by Levenberg–Marquardt ([`SolveOptions::lm`]). Errors:
/// invalid input (see [`CellProblem::check`]), no starting placement, or model failures at an
/// observation. Non-convergence is reported in [`CellFit::stopped`].
pub fn fit_cell_with(
    problem: &CellProblem,
    layout: ParamLayout,
    active: &[usize],
    start: Option<&CellEstimate>,
    options: &SolveOptions,
) -> Result<CellFit, CellFitError> {
    fit_cell_weighted(problem, layout, active, None, start, options)
}

/// [`fit_cell_with`] with per-observation weights `w_i` (one finite weight ≥ 0 per active
/// observation; the blunder screen's IRLS): minimises `Σ_i w_i‖W_i·r_i‖² + ‖R_p·θ‖²`.
pub(crate) fn fit_cell_weighted(
    problem: &CellProblem,
    layout: ParamLayout,
    active: &[usize],
    weights: Option<&[f64]>,
    start: Option<&CellEstimate>,
    options: &SolveOptions,
) -> Result<CellFit, CellFitError> {
    fit_cell_start(problem, layout, active, weights, start, None, options)
}

/// [`fit_cell_weighted`] from another fit's optimum (`from.estimate`): its linearisation there
/// is reused for the start (the observations it holds, when `layout` has its columns), so the
/// fit does not evaluate the robots again where `from` already did.
pub(crate) fn fit_cell_from(
    problem: &CellProblem,
    layout: ParamLayout,
    active: &[usize],
    weights: Option<&[f64]>,
    from: &CellFit,
    options: &SolveOptions,
) -> Result<CellFit, CellFitError> {
    let start_rows = from.at_optimum.as_deref();
    fit_cell_start(
        problem,
        layout,
        active,
        weights,
        Some(&from.estimate),
        start_rows,
        options,
    )
}

/// The fits' one body: [`fit_cell_weighted`] with a linearisation at the start to reuse.
fn fit_cell_start(
    problem: &CellProblem,
    layout: ParamLayout,
    active: &[usize],
    weights: Option<&[f64]>,
    start: Option<&CellEstimate>,
    start_rows: Option<&AtOptimum>,
    options: &SolveOptions,
) -> Result<CellFit, CellFitError> {
    problem.check()?;
    if let Some(w) = weights {
        if w.len() != active.len() || !w.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(CellFitError::InvalidInput(
                "weights: one finite weight ≥ 0 per active observation is needed".into(),
            ));
        }
    }
    let est = match start {
        Some(s) => {
            s.check(problem)?;
            s.clone()
        }
        None => initial_estimate(problem, options.initial_b1_from_b2, active)?,
    };
    let map = MapProblem {
        problem,
        layout: &layout,
        active,
        weights,
        start_rows,
    };
    let min = minimize(&map, est, &options.lm)?;
    let sys = min.system;
    // `JᵀJ` of the final system: the solver's own when its last iteration formed it there.
    let h = match min.information {
        Some(h) => h,
        None => sys.j.transpose() * &sys.j,
    };
    let (covariance, singular) = sym_inverse(&h);
    let data_chi2 = sys.r.rows(0, sys.data_rows).norm_squared();
    let prior_chi2 = min.cost - data_chi2;
    let residual_rows = sys.data_rows;
    let at_optimum = AtOptimum {
        estimate: min.point.clone(),
        params: layout.params.clone(),
        prior_sqrt_info: layout.prior_sqrt_info.clone(),
        rows: sys.into_rows(),
        information: weights.is_none().then_some(h),
    };
    Ok(CellFit {
        estimate: min.point,
        layout,
        covariance,
        singular,
        data_chi2,
        prior_chi2,
        residual_rows,
        active: active.to_vec(),
        iterations: min.iterations,
        stopped: min.stopped,
        model_error_var_m2: 0.0,
        at_optimum: Some(Arc::new(at_optimum)),
    })
}
