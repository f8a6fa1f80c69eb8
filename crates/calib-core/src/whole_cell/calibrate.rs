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
//! 4. `choose_prior_scale` (`evidence.rs`): the prior scales (one common scale or one per
//!    family, 1e-3 … 1 at the stated tolerances, or the caller's fixed scale) from the evidence
//!    of the MAP problem linearised at the screened estimate, a refit at those scales
//!    (relinearised once), and the error covariance under the reference prior (up to the
//!    stated tolerances, as far as the evidence does not reject them).
//!    [`widen_prior`] (a separate call, after the caller's result check) redoes steps 1–4 at
//!    tolerances the evidence widened (up to ×100 in all).
//! 5. A placement-only model whose residuals exceed the stated noise: the data's σ in its
//!    covariance are scaled (a placement prior's are not: `scaled_data_covariance`) and the
//!    model-error term set (`mean_noise_var`).
//! 6. [`CellCalibration::report`] (`report.rs`): the report in file units.

use nalgebra::DMatrix;

use super::blunders::{fit_screened, RejectedRow, ScreenOptions, ScreenedFit};
use super::evidence::{
    self, format_scale, LinearModel, PriorScaleChoice, ScaleMethod, MAX_PRIOR_SCALE, PRIOR_SCALES,
};
use super::reduce::{reduce, Reduction};
use super::solve::{fit_cell_from, CellFit, SolveOptions};
use super::{initial_estimate, CellFitError, CellProblem};

/// Result of [`calibrate_cell`].
#[derive(Debug, Clone)]
pub struct CellCalibration {
    /// The MAP fit on the reduced unknowns without the rejected rows.
    pub fit: CellFit,
    /// What the data cannot determine (dropped or merged) and why.
    pub reduction: Reduction,
    /// Rejected blunders.
    pub rejected: Vec<RejectedRow>,
    /// The prior scales applied (the session's own evidence's choice, or the caller's) and why.
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
/// depends on its noise and geometry. On the screened rows the prior σ of every kinematic
/// family is multiplied by a scale from [`PRIOR_SCALES`] of at most 1 (1e-3, the
/// placement-only limit, … 1): the common scale of largest Laplace evidence (type-II maximum
/// likelihood; the marginal likelihood of the data, of the MAP problem linearised at the
/// screened fit), then one scale per family (joint offsets, origin xyz, origin rpy, tool tips,
/// other terms) where the evidence separates them by a margin
/// ([`super::FAMILY_EVIDENCE_MARGIN`] nats per family); the formulas are in `evidence.rs`
/// ([`PriorScaleChoice`]). When the data cannot support the kinematic parameters, the evidence
/// prefers the smallest scale, whose fit is the placement-only fit to within 1e-6 of the
/// tolerances. The fit is then redone at the chosen scales from the screened estimate (and the
/// choice repeated once at that fit). The reported covariance is the error covariance of the
/// chosen estimator under a reference prior: the stated tolerances where the data cannot tell
/// (so the predicted cooperative accuracy includes the kinematic error the shrunk fit may
/// leave), narrower where the evidence rejects them by more than
/// [`super::REFERENCE_EVIDENCE_MARGIN`] nats (`evidence.rs`). Tolerances the robots exceed are widened by
/// [`widen_prior`], after the caller's check of this fit; [`calibrate_cell_with`] fixes the
/// scale instead.
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
///     shared_joints: 0,
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
///     other_arm_q: Default::default(),
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
    calibrate_cell_with(problem, solve, screen, None)
}

/// [`calibrate_cell`] with the prior scale fixed at `tolerance_scale` (every prior σ of every
/// family multiplied by it: `calibrate --cell --tolerance-scale X`) instead of the evidence's
/// choice; `None` is [`calibrate_cell`]. The covariance is the fit's error covariance under
/// the reference prior `max(scale, 1)`, as there.
///
/// Errors: those of [`calibrate_cell`], and a scale that is not finite or outside
/// `[1e-3, 100]` ([`PRIOR_SCALES`]' range), named with the accepted range.
pub fn calibrate_cell_with(
    problem: &CellProblem,
    solve: &SolveOptions,
    screen: &ScreenOptions,
    tolerance_scale: Option<f64>,
) -> Result<CellCalibration, CellFitError> {
    if let Some(s) = tolerance_scale {
        if !(s.is_finite() && (MIN_PRIOR_SCALE..=MAX_PRIOR_SCALE).contains(&s)) {
            return Err(CellFitError::InvalidInput(format!(
                "tolerance scale {s}: give a number from {MIN_PRIOR_SCALE} (the placement-only \
                 limit) to {MAX_PRIOR_SCALE} (the tolerances ×100); 1 keeps the stated tolerances"
            )));
        }
    }
    problem.check()?;
    let ones = FamilyFactors::ones();
    let (reduction, screened, fit, prior_scale) = match tolerance_scale {
        // A fixed widening: reduce, screen and fit at the widened tolerances.
        Some(x) if x > 1.0 => {
            let wide = FamilyFactors::all(x);
            let (red, scr, fit, mut choice) = one_pass(
                &wide.apply(problem),
                solve,
                screen,
                Some(1.0),
                &wide,
                &|_| 1.0,
            )?;
            choice.rescale(&wide);
            choice.scale = x;
            for c in &mut choice.log_evidence {
                c.0 *= x;
            }
            choice.why = format!(
                "fixed at {} by the caller (--tolerance-scale): reduction, blunder screen and fit \
                 at the tolerances ×{}",
                format_scale(x),
                format_scale(x)
            );
            (red, scr, fit, choice)
        }
        Some(x) => one_pass(problem, solve, screen, Some(x), &ones, &|_| 1.0)?,
        // The stated tolerances: the evidence may shrink them, not widen them.
        None => one_pass(problem, solve, screen, None, &ones, &|_| 1.0)?,
    };
    finish(problem, reduction, screened, fit, prior_scale)
}

/// The widening of a calibration at the stated tolerances (`stated`, from [`calibrate_cell`]
/// with the same `problem`, `solve` and `screen`): `None` when the evidence, linearised at the
/// stated fit over the whole range of [`PRIOR_SCALES`] (up to ×[`MAX_PRIOR_SCALE`]), widens no
/// family, or when `stated`'s scale was fixed or it has no prior.
///
/// Otherwise the families the evidence widened get their tolerances × its scales, and the
/// calibration is redone at them (reduction, blunder screen, the evidence's choice relative to
/// the widened tolerances, the refit): the reduction and the screen of the stated pass were made
/// at tolerances too narrow (rows the robots' real errors move were screened as blunders,
/// parameters the data see were dropped as decided by the prior). A family the new choice
/// widens again is widened again, for at most `WIDENING_PASSES − 1` passes. The product of all
/// the scale changes of a family never exceeds ×[`MAX_PRIOR_SCALE`] (each choice is capped at
/// what is left of it). The covariance is the error covariance under the widened prior
/// ([`calibrate_cell`]).
///
/// **Widen only a fit that stands.** A wrong model (a joint's sign flipped, a tip's sign, two
/// joints swapped) also looks like "the robots are further off than stated", and a prior wide
/// enough lets the kinematic terms absorb it: call this only after the result check of `stated`
/// has found no likely mistake and no refusal (`cli_support::cell_report` does).
///
/// Errors: those of [`calibrate_cell`].
pub fn widen_prior(
    problem: &CellProblem,
    stated: &CellCalibration,
    solve: &SolveOptions,
    screen: &ScreenOptions,
) -> Result<Option<CellCalibration>, CellFitError> {
    let c = &stated.prior_scale;
    if !matches!(
        c.method,
        ScaleMethod::EvidenceCommon | ScaleMethod::EvidencePerFamily
    ) {
        return Ok(None);
    }
    let fit = &stated.fit;
    let unscale = nalgebra::DVector::from_iterator(
        fit.layout.len(),
        fit.layout
            .params
            .iter()
            .map(|p| evidence::prior_family(p).map_or(1.0, |f| 1.0 / c.family_scale(f))),
    );
    let base = evidence::scaled_layout(&fit.layout, &unscale);
    let model = LinearModel::new(problem, &base, fit)?;
    let Some(first) = evidence::choose(&model, &|_| MAX_PRIOR_SCALE) else {
        return Ok(None);
    };
    let mut further = FamilyFactors::widening(&first);
    if further.is_ones() {
        return Ok(None);
    }
    let curve = first.log_evidence.clone();
    let mut why = format!(
        "at the stated tolerances, {}; over the whole range (up to ×{MAX_PRIOR_SCALE}), {}",
        c.why, first.why
    );
    let mut wide = FamilyFactors::ones();
    let mut current = None;
    for _ in 1..WIDENING_PASSES {
        wide = wide.times(&further).capped(MAX_PRIOR_SCALE);
        let cap = |f: &str| MAX_PRIOR_SCALE / wide.get(f);
        let (red, scr, fit, mut again) =
            one_pass(&wide.apply(problem), solve, screen, None, &wide, &cap)?;
        further = FamilyFactors::widening(&again);
        again.rescale(&wide);
        why = format!(
            "{why}; refitted at the widened tolerances ({}; reduction and blunder screen \
             redone), where, relative to those, {}",
            wide.describe(&again),
            again.why
        );
        current = Some((red, scr, fit, again));
        if further.is_ones() {
            break;
        }
    }
    let Some((reduction, screened, fit, mut choice)) = current else {
        return Ok(None);
    };
    choice.log_evidence = curve;
    choice.why = why;
    finish(problem, reduction, screened, fit, choice).map(Some)
}

/// The calibration from its last pass: a placement-only model whose residuals exceed the
/// stated noise gets its data's σ scaled and the model-error term (module docs, step 5).
fn finish(
    problem: &CellProblem,
    reduction: Reduction,
    screened: ScreenedFit,
    mut fit: CellFit,
    prior_scale: PriorScaleChoice,
) -> Result<CellCalibration, CellFitError> {
    let noise_scale = screened.noise_scale;
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
    let at = ev.at(&fit.estimate);
    let (mut sum, mut rows) = (0.0, 0usize);
    for &i in &fit.active {
        let l = ev.linearise_at(&problem.observations[i], &at, false)?;
        let w = &l.whitening;
        if let Some(inv) = (w.transpose() * w).try_inverse() {
            sum += inv.trace();
            rows += w.nrows();
        }
    }
    Ok(if rows == 0 { 0.0 } else { sum / rows as f64 })
}

/// Passes of the calibration at most, the first at the stated tolerances and each further one
/// at the tolerances the evidence widened in the pass before.
const WIDENING_PASSES: usize = 4;

/// The smallest prior scale (the placement-only limit), the last of [`PRIOR_SCALES`].
const MIN_PRIOR_SCALE: f64 = PRIOR_SCALES[PRIOR_SCALES.len() - 1];

/// The prior scales of `screened` (a fit at scale 1): the evidence's choice (or `fixed`) at the
/// screened estimate, a refit there, the choice repeated once at the refit (refitted again if it
/// changed), and the error covariance under the reference prior (see [`calibrate_cell`]).
fn choose_prior_scale(
    problem: &CellProblem,
    screened: CellFit,
    solve: &SolveOptions,
    fixed: Option<f64>,
    widened: &FamilyFactors,
    cap: &dyn Fn(&str) -> f64,
) -> Result<(CellFit, PriorScaleChoice), CellFitError> {
    if screened.layout.prior_sqrt_info.nrows() == 0 {
        return Ok((screened, PriorScaleChoice::none()));
    }
    let base = screened.layout.clone();
    let choose = |fit: &CellFit| -> Result<Option<PriorScaleChoice>, CellFitError> {
        let model = LinearModel::new(problem, &base, fit)?;
        Ok(match fixed {
            Some(s) => Some(evidence::fixed(&model, s)),
            None => evidence::choose(&model, cap),
        })
    };
    let Some(mut choice) = choose(&screened)? else {
        return Ok((screened, PriorScaleChoice::none()));
    };
    let column_scales = |c: &PriorScaleChoice| {
        nalgebra::DVector::from_iterator(
            base.len(),
            base.params
                .iter()
                .map(|p| evidence::prior_family(p).map_or(1.0, |f| c.family_scale(f))),
        )
    };
    let mut s = column_scales(&choice);
    let refit = |s: &nalgebra::DVector<f64>| {
        fit_cell_from(
            problem,
            evidence::scaled_layout(&base, s),
            &screened.active,
            None,
            &screened,
            solve,
        )
    };
    let mut fit = if s.iter().all(|&v| v == 1.0) {
        screened.clone()
    } else {
        refit(&s)?
    };
    if fixed.is_none() && s.iter().any(|&v| v != 1.0) {
        // Relinearise at the fit of the chosen scales (widening moves the estimate by more than
        // the scale-1 fit did) and choose again; refit if the choice changed.
        if let Some(again) = choose(&fit)? {
            let s2 = column_scales(&again);
            if s2 != s {
                fit = if s2.iter().all(|&v| v == 1.0) {
                    screened.clone()
                } else {
                    refit(&s2)?
                };
                s = s2;
            }
            choice = again;
        }
    }
    // The reference prior: the stated tolerances (`1 / widened` relative to this layout) where
    // the scales shrank them; for the evidence's choice, only as far up as the evidence does not
    // reject (a family the data show near nominal keeps a reference near its scale).
    let upper = |f: &str| choice.family_scale(f).max(1.0 / widened.get(f));
    let s_ref = if s
        .iter()
        .zip(base.params.iter())
        .all(|(v, p)| evidence::prior_family(p).is_none_or(|f| *v >= upper(f)))
    {
        s.clone()
    } else if fixed.is_some() {
        column_scales_of(&base, &upper)
    } else {
        let model = LinearModel::new(problem, &base, &fit)?;
        let chosen: Vec<f64> = model
            .families
            .iter()
            .map(|(f, _)| choice.family_scale(f))
            .collect();
        let uppers: Vec<f64> = model.families.iter().map(|(f, _)| upper(f)).collect();
        model.column_scales(&evidence::reference_scales(&model, &chosen, &uppers))
    };
    fit.covariance = evidence::reference_covariance(problem, &fit, &s, &s_ref)?;
    Ok((fit, choice))
}

/// Per-column scales of `layout` from a scale per family (1 on unpenalised columns).
fn column_scales_of(
    layout: &super::ParamLayout,
    family: &dyn Fn(&str) -> f64,
) -> nalgebra::DVector<f64> {
    nalgebra::DVector::from_iterator(
        layout.len(),
        layout
            .params
            .iter()
            .map(|p| evidence::prior_family(p).map_or(1.0, family)),
    )
}

/// One pass of the calibration at `problem`'s tolerances: start, reduction, blunder screen,
/// then the prior scales (`widened`: the factors the tolerances already carry, for the
/// reference covariance).
fn one_pass(
    problem: &CellProblem,
    solve: &SolveOptions,
    screen: &ScreenOptions,
    fixed: Option<f64>,
    widened: &FamilyFactors,
    cap: &dyn Fn(&str) -> f64,
) -> Result<(Reduction, ScreenedFit, CellFit, PriorScaleChoice), CellFitError> {
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let start = initial_estimate(problem, solve.initial_b1_from_b2, &all)?;
    let reduction = reduce(problem, &start, &all)?;
    let screened = fit_screened(problem, Some(reduction.layout.clone()), solve, screen)?;
    let (fit, choice) =
        choose_prior_scale(problem, screened.fit.clone(), solve, fixed, widened, cap)?;
    Ok((reduction, screened, fit, choice))
}

/// A factor per parameter family (1 for a family not named), applied to the tolerances.
#[derive(Debug, Clone, PartialEq)]
struct FamilyFactors(Vec<(&'static str, f64)>);

impl FamilyFactors {
    fn ones() -> Self {
        FamilyFactors(Vec::new())
    }

    /// `x` for every family.
    fn all(x: f64) -> Self {
        FamilyFactors(
            [
                "joint_offset",
                "origin_xyz",
                "origin_rpy",
                "tip",
                "joint_scale",
                "compliance",
                "periodic",
                "lumped_compliance",
            ]
            .iter()
            .map(|f| (*f, x))
            .collect(),
        )
    }

    /// The families `choice` widened (scale > 1), with their scales.
    fn widening(choice: &PriorScaleChoice) -> Self {
        FamilyFactors(
            choice
                .families
                .iter()
                .filter(|f| f.scale > 1.0)
                .map(|f| (f.family, f.scale))
                .collect(),
        )
    }

    /// The product of two factor sets, family by family.
    fn times(&self, other: &FamilyFactors) -> Self {
        let mut out = self.clone();
        for &(f, x) in &other.0 {
            match out.0.iter_mut().find(|(g, _)| *g == f) {
                Some(e) => e.1 *= x,
                None => out.0.push((f, x)),
            }
        }
        out
    }

    /// Each factor at most `max`.
    fn capped(mut self, max: f64) -> Self {
        for e in &mut self.0 {
            e.1 = e.1.min(max);
        }
        self
    }

    fn is_ones(&self) -> bool {
        self.0.iter().all(|(_, x)| *x == 1.0)
    }

    fn get(&self, family: &str) -> f64 {
        self.0
            .iter()
            .find(|(f, _)| *f == family)
            .map_or(1.0, |(_, x)| *x)
    }

    /// `problem` with each robot's tolerance of each family × its factor.
    fn apply(&self, problem: &CellProblem) -> CellProblem {
        let mut p = problem.clone();
        for t in [&mut p.robot1.tolerance, &mut p.robot2.tolerance] {
            t.joint_offset_rad *= self.get("joint_offset");
            t.origin_xyz_m *= self.get("origin_xyz");
            t.origin_rpy_rad *= self.get("origin_rpy");
            t.tip_m *= self.get("tip");
            t.joint_scale = t.joint_scale.map(|v| v * self.get("joint_scale"));
            t.compliance_rad_per_nm = t.compliance_rad_per_nm.map(|v| v * self.get("compliance"));
            t.periodic_rad = t.periodic_rad.map(|v| v * self.get("periodic"));
            t.lumped_compliance_rad = t
                .lumped_compliance_rad
                .map(|v| v * self.get("lumped_compliance"));
        }
        p
    }

    /// `joint_offset ×8, tip ×8` (the families `choice` lists that carry a factor).
    fn describe(&self, choice: &PriorScaleChoice) -> String {
        choice
            .families
            .iter()
            .filter(|f| self.get(f.family) != 1.0)
            .map(|f| format!("{} ×{}", f.family, format_scale(self.get(f.family))))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl PriorScaleChoice {
    /// Scales relative to tolerances widened by `w` → relative to the stated tolerances.
    fn rescale(&mut self, w: &FamilyFactors) {
        for f in &mut self.families {
            f.scale *= w.get(f.family);
        }
        let first = self.families.first().map(|f| f.scale);
        let common = first.filter(|s| self.families.iter().all(|f| f.scale == *s));
        match common {
            Some(c) => {
                self.scale = c;
                if self.method == ScaleMethod::EvidencePerFamily {
                    self.method = ScaleMethod::EvidenceCommon;
                }
            }
            None => {
                if self.method == ScaleMethod::EvidenceCommon {
                    self.method = ScaleMethod::EvidencePerFamily;
                }
            }
        }
    }
}
