//! The one-call whole-cell calibration a CLI needs: starting values, base-parameter reduction,
//! MAP fit with blunder screening; its report in file units is `report.rs`.
//!
//! The steps of [`calibrate_cell`], in order (each MAP fit is [`fit_cell_with`], the crate's
//! Levenberg–Marquardt solver on the problem of `solve.rs`):
//! 1. [`CellProblem::check`], then [`initial_estimate`] (`start.rs`): the starting placement and
//!    nuisances.
//! 2. [`reduce`] (`reduce.rs`): the unknowns the data can determine at the start (the layout).
//! 3. [`fit_screened`] (`blunders.rs`): a Huber IRLS start, then the studentised screen that
//!    drops the worst blunder and refits, one at a time.
//! 4. `choose_prior_scale`: a refit at every scale of [`PRIOR_SCALES`] from the screened
//!    estimate, scored by `log_evidence`; the largest evidence wins and gets the error
//!    covariance under the scale-1 prior.
//! 5. A placement-only model whose residuals exceed the stated noise: the data's σ in its
//!    covariance are scaled (a placement prior's are not: `scaled_data_covariance`) and the
//!    model-error term set (`mean_noise_var`).
//! 6. [`CellCalibration::report`] (`report.rs`): the report in file units.

use nalgebra::DMatrix;
use serde::Serialize;

use super::blunders::{fit_screened, RejectedRow, ScreenOptions};
use super::reduce::{reduce, Reduction};
use super::solve::{fit_cell_from, sym_inverse, CellFit, SolveOptions};
use super::{initial_estimate, CellFitError, CellProblem, ParamLayout};

/// Prior scales `s` [`calibrate_cell`] compares (every prior σ multiplied by `s`): the
/// tolerances as given (1), halved down to 1/16, and 1e-3, the placement-only limit (the
/// kinematic parameters held at their nominal values by a prior 1000 times tighter than the
/// tolerances; the same columns, so the evidence and the error covariance stay comparable).
pub const PRIOR_SCALES: [f64; 6] = [1.0, 0.5, 0.25, 0.125, 0.0625, 1e-3];

/// The prior scale [`calibrate_cell`] chose and why.
#[derive(Debug, Clone, Serialize)]
pub struct PriorScaleChoice {
    /// The chosen scale `s` (prior σ = `s`·tolerance/√3).
    pub scale: f64,
    /// `(s, log evidence)` for every scale of [`PRIOR_SCALES`] that fitted (natural log, up to
    /// a constant common to all scales).
    pub log_evidence: Vec<(f64, f64)>,
}

/// Result of [`calibrate_cell`].
#[derive(Debug, Clone)]
pub struct CellCalibration {
    /// The MAP fit on the reduced unknowns without the rejected rows.
    pub fit: CellFit,
    /// What the data cannot determine (dropped or merged) and why.
    pub reduction: Reduction,
    /// Rejected blunders.
    pub rejected: Vec<RejectedRow>,
    /// The prior scale chosen from the session's own evidence.
    pub prior_scale: PriorScaleChoice,
    /// The blunder screen's noise scale ([`super::ScreenedFit::noise_scale`]): 1, or for a
    /// placement-only model `sqrt` of its a-posteriori variance factor (then also applied to the
    /// data's σ in the covariance, not to a placement prior's, and its excess over 1 is the
    /// fit's model-error term,
    /// [`CellFit::model_error_var_m2`]).
    pub noise_scale: f64,
}

/// Calibrates the whole cell: starting values ([`initial_estimate`]), base-parameter reduction
/// at the start ([`reduce`]), the screened MAP fit ([`fit_screened`]) on the reduced
/// unknowns, then the prior scale chosen from the session's own data.
///
/// **Prior scale.** The tolerances bound the errors; how much of them a session can resolve
/// depends on its noise and geometry. On the screened rows the fit is repeated with every prior
/// σ multiplied by each `s` of [`PRIOR_SCALES`], and the scale of largest Laplace evidence
/// (type-II maximum likelihood; the linearised marginal likelihood of the data)
/// `log Z(s) = −C(s)/2 − log det H(s)/2 + log det(R_p,s·R_p,sᵀ)/2` is kept (`C` the MAP cost,
/// `H = JᵀJ` over data and prior rows at the optimum, `R_p,s = R_p/s`; the unpenalised
/// unknowns' flat prior adds the same constant to every `s`). When the data cannot support the
/// kinematic parameters, the evidence prefers the smallest scale, whose fit is the placement-only
/// fit to within 1e-6 of the tolerances. The reported covariance is then the error covariance of
/// the chosen estimator under the tolerance prior (`s = 1`):
/// `H⁻¹·(H − Λ_s + Λ_s/s²)·H⁻¹`, `Λ_s = R_p,sᵀR_p,s` (equal to `H⁻¹` at `s = 1`), so the
/// predicted cooperative accuracy includes the kinematic error the shrunk fit leaves.
///
/// Errors: invalid input, no starting placement, model failures, or too few rows after
/// rejecting blunders (naming the rows to re-record).
///
/// # Examples
/// Two identical 3-joint arms, robot 2's base 1.4 m along robot 1's x axis and turned by π
/// about z. Robot 2 visits 12 configurations; robot 1 meets each tip (inverse kinematics),
/// so the rows are noise-free handclasps of nominal robots. The fit recovers the placement.
/// ```
/// use calib_core::whole_cell::{
///     calibrate_cell, CellProblem, CellRobot, Noise3, Observation, ObservationKind,
///     ScreenOptions, SolveOptions, Tolerance, Tool,
/// };
/// use calib_core::StopReason;
/// use kinematics::{base_from_tip, ik_tip_position, IkOptions, RobotModel};
/// use nalgebra::{Isometry3, Point3, Vector3};
///
/// const ARM: &str = r#"<robot name="arm">
///   <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool0"/>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
///     <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
///   <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
///     <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
///   <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
///     <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
///   <joint name="l3-tool0" type="fixed"><parent link="l3"/><child link="tool0"/>
///     <origin xyz="0.4 0 0"/></joint>
/// </robot>"#;
///
/// let model = RobotModel::from_urdf_str(ARM, "tool0")?;
/// let tool = Tool { name: "tip".into(), flange_from_tip: Vector3::new(0.0, 0.0, 0.1) };
/// let robot = |g_base| CellRobot {
///     model: model.clone(),
///     tools: vec![tool.clone()],
///     g_base,
///     tolerance: Tolerance::default(),
/// };
/// let b1_from_b2 = Isometry3::new(Vector3::new(1.4, 0.0, 0.0), Vector3::new(0.0, 0.0, std::f64::consts::PI));
/// let g_b1 = Vector3::new(0.0, 0.0, -9.81);
///
/// let mut observations = Vec::new();
/// for a in [-0.3, 0.0, 0.3] {
///     for (b, c) in [(-0.4, 0.3), (-0.4, 0.9), (0.2, 0.3), (0.2, 0.9)] {
///         let q2 = vec![a, b, c];
///         let p_b2 = base_from_tip(&model, &q2, &tool.flange_from_tip)?.translation.vector;
///         let p_b1 = b1_from_b2 * Point3::from(p_b2);
///         let sol = ik_tip_position(&model, &p_b1, &tool.flange_from_tip, &IkOptions::default())?;
///         assert!(sol.reachable());
///         observations.push(Observation {
///             row: observations.len() + 1,
///             kind: ObservationKind::Coincident {
///                 q1: sol.q,
///                 q2,
///                 tool1: 0,
///                 tool2: 0,
///                 noise: Noise3::Isotropic { sigma_m: 1e-4 },
///             },
///         });
///     }
/// }
/// let problem = CellProblem {
///     robot1: robot(g_b1),
///     robot2: robot(b1_from_b2.rotation.inverse() * g_b1),
///     observations,
///     trackers: vec![],
///     planes: vec![],
///     contacts: vec![],
///     placement_prior: None,
/// };
///
/// let cal = calibrate_cell(&problem, &SolveOptions::default(), &ScreenOptions::default())?;
/// assert_eq!(cal.fit.stopped, StopReason::Converged);
/// assert!(cal.rejected.is_empty());
/// let fitted = cal.fit.estimate.b1_from_b2;
/// // Noise-free data: the placement is recovered to well below the stated σ (0.1 mm).
/// assert!((fitted.translation.vector - b1_from_b2.translation.vector).norm() < 1e-6);
/// assert!(fitted.rotation.angle_to(&b1_from_b2.rotation) < 1e-6);
/// println!("{} parameters dropped or merged", cal.reduction.dropped.len());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn calibrate_cell(
    problem: &CellProblem,
    solve: &SolveOptions,
    screen: &ScreenOptions,
) -> Result<CellCalibration, CellFitError> {
    problem.check()?;
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let start = initial_estimate(problem, solve.initial_b1_from_b2, &all)?;
    let reduction = reduce(problem, &start, &all)?;
    let screened = fit_screened(problem, Some(reduction.layout.clone()), solve, screen)?;
    let noise_scale = screened.noise_scale;
    let (mut fit, prior_scale) = choose_prior_scale(problem, screened.fit, solve)?;
    let placement_only = fit.layout.prior_sqrt_info.nrows() == 0;
    if placement_only && noise_scale > 1.0 {
        // The residuals carry error the model does not represent: scale the placement's
        // covariance by the variance factor (the data's own noise level), and predict
        // the unmodelled part at any configuration pair from its variance at the handclasps.
        let s2 = noise_scale * noise_scale;
        fit.covariance = scaled_data_covariance(problem, &fit, s2);
        fit.model_error_var_m2 = (s2 - 1.0) * mean_noise_var(problem, &fit)?;
    }
    Ok(CellCalibration {
        fit,
        reduction,
        rejected: screened.rejected,
        prior_scale,
        noise_scale,
    })
}

/// The covariance of `fit` with the data's σ multiplied by `sqrt(s2)` and the placement prior
/// as stated: `(H_data/s² + Λ_p)⁻¹ = s²·(H + (s² − 1)·Λ_p)⁻¹` with `H = Σ⁻¹` the fit's
/// information and `Λ_p` the placement prior's ([`super::PlacementPrior`], columns 0..6), so a
/// placement held by a tight prior keeps a σ at most its prior's (scaling the whole covariance
/// would inflate the prior too). Without a placement prior (or when `Σ` cannot be inverted)
/// this is `s²·Σ`.
fn scaled_data_covariance(problem: &CellProblem, fit: &CellFit, s2: f64) -> DMatrix<f64> {
    let scaled = &fit.covariance * s2;
    let Some(pp) = &problem.placement_prior else {
        return scaled;
    };
    let (_, rows) = pp.linearise(&fit.estimate.b1_from_b2);
    let n = fit.covariance.nrows();
    if rows.is_empty() || n < 6 {
        return scaled;
    }
    let Some(mut h) = fit.covariance.clone().cholesky().map(|c| c.inverse()) else {
        return scaled;
    };
    for row in &rows {
        for a in 0..6 {
            for b in 0..6 {
                h[(a, b)] += (s2 - 1.0) * row[a] * row[b];
            }
        }
    }
    match h.cholesky() {
        Some(c) => c.inverse() * s2,
        None => scaled,
    }
}

/// Mean stated noise variance per residual row (m²) over the fit's active observations.
pub(super) fn mean_noise_var(problem: &CellProblem, fit: &CellFit) -> Result<f64, CellFitError> {
    let ev = super::Evaluator::new(problem, &fit.layout);
    let (mut sum, mut rows) = (0.0, 0usize);
    for &i in &fit.active {
        let l = ev.linearise(&problem.observations[i], &fit.estimate, false)?;
        let w = &l.whitening;
        if let Some(inv) = (w.transpose() * w).try_inverse() {
            sum += inv.trace();
            rows += w.nrows();
        }
    }
    Ok(if rows == 0 { 0.0 } else { sum / rows as f64 })
}

/// The layout with every prior σ multiplied by `scale`.
fn scaled_layout(layout: &ParamLayout, scale: f64) -> ParamLayout {
    let mut l = layout.clone();
    l.prior_sqrt_info /= scale;
    l
}

/// Laplace log evidence of a converged fit (see [`calibrate_cell`]); `None` when `H` or the
/// prior rows are singular.
fn log_evidence(problem: &CellProblem, fit: &CellFit) -> Result<Option<f64>, CellFitError> {
    let h = fit.information(problem)?;
    let logdet = |m: DMatrix<f64>| {
        m.cholesky()
            .map(|c| 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>())
    };
    let rp = &fit.layout.prior_sqrt_info;
    let prior = if rp.nrows() == 0 {
        Some(0.0)
    } else {
        logdet(rp * rp.transpose())
    };
    Ok(match (logdet(h), prior) {
        (Some(lh), Some(lp)) => Some(-0.5 * (fit.data_chi2 + fit.prior_chi2) - 0.5 * lh + 0.5 * lp),
        _ => None,
    })
}

/// Refits `screened` (a fit at scale 1) at every scale of [`PRIOR_SCALES`] on its rows, keeps
/// the one of largest evidence and gives it the error covariance under the scale-1 prior.
fn choose_prior_scale(
    problem: &CellProblem,
    screened: CellFit,
    solve: &SolveOptions,
) -> Result<(CellFit, PriorScaleChoice), CellFitError> {
    let penalised = screened.layout.prior_sqrt_info.nrows() > 0;
    let Some(base_evidence) = log_evidence(problem, &screened)?.filter(|_| penalised) else {
        return Ok((
            screened,
            PriorScaleChoice {
                scale: 1.0,
                log_evidence: Vec::new(),
            },
        ));
    };
    let base_layout = screened.layout.clone();
    let mut log_ev = vec![(1.0, base_evidence)];
    let mut best = (1.0, base_evidence, screened.clone());
    for &s in &PRIOR_SCALES[1..] {
        let fit = fit_cell_from(
            problem,
            scaled_layout(&base_layout, s),
            &screened.active,
            None,
            &screened,
            solve,
        )?;
        if let Some(ev) = log_evidence(problem, &fit)? {
            log_ev.push((s, ev));
            if ev > best.1 {
                best = (s, ev, fit);
            }
        }
    }
    let (scale, _, mut fit) = best;
    if scale != 1.0 {
        let h = fit.information(problem)?;
        let rp = &fit.layout.prior_sqrt_info;
        let lambda = rp.transpose() * rp;
        let (h_inv, _) = sym_inverse(&h);
        let middle = &h - &lambda + lambda / (scale * scale);
        fit.covariance = &h_inv * middle * &h_inv;
    }
    Ok((
        fit,
        PriorScaleChoice {
            scale,
            log_evidence: log_ev,
        },
    ))
}
