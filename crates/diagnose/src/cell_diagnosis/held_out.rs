//! The held-out criterion of the selection: the units and folds, the fit of a model on the
//! training rows, each held-out unit's score (its own nuisance refitted on half its rows), the
//! cross-validation of the candidates in parallel, and the test that a gain is significant.

use calib_core::selection::one_sample_t;
use calib_core::stats::f_sf;
use calib_core::whole_cell::{
    fit_cell_with, held_out_pieces, initial_estimate, score_held_out, CellEstimate, CellFit,
    CellFitError, CellProblem, Evaluator, GroupKind, ObservationKind, ParamLayout, MIN_SPLIT_ROWS,
};
use nalgebra::DVector;
use rayon::prelude::*;

use super::families::{model_layout, model_problem, Family};
use super::CellDiagnoseOptions;

/// At most this many held-out units are cut from the coincident rows (in row order, at least
/// [`MIN_UNIT_ROWS`] rows each).
pub const COINCIDENT_UNITS: usize = 4;
/// Fewest rows of a coincident unit.
pub const MIN_UNIT_ROWS: usize = 6;
/// Fewest rows of a group that is held out and scored, per group kind
/// ([`GroupKind::index`]: contact, tracker, plane): each half must fit the group's nuisance (a
/// distance from 1 row, a tracker frame or a plane from 3).
pub const MIN_SCORED_GROUP_ROWS: [usize; GroupKind::ALL.len()] = MIN_SPLIT_ROWS;
/// Fewest rows of a block cut from a group when the session has fewer than 3 units.
pub const MIN_GROUP_BLOCK_ROWS: usize = 12;

/// The sub-problem of the observations `rows`, its groups renumbered (calib-core's, shared with
/// `calibrate --cell`'s do-no-harm check and `validate`).
pub(super) use calib_core::whole_cell::sub_problem;

pub(super) fn coincident_count(problem: &CellProblem, rows: &[usize]) -> usize {
    rows.iter()
        .filter(|&&i| {
            matches!(
                problem.observations[i].kind,
                ObservationKind::Coincident { .. }
            )
        })
        .count()
}

/// Fits `model` on the observations `rows` of `problem` (a sub-problem of them), starting from
/// the robot corrections and placement of `start` when given. Returns the sub-problem and fit.
pub(super) fn fit_model(
    problem: &CellProblem,
    model: &[Family],
    rows: &[usize],
    start: Option<&CellEstimate>,
    options: &CellDiagnoseOptions,
    cell_b1_from_b2: nalgebra::Isometry3<f64>,
) -> Result<(CellProblem, CellFit), CellFitError> {
    let sub = sub_problem(&model_problem(problem, model), rows);
    let layout = model_layout(&sub, model);
    let all: Vec<usize> = (0..sub.observations.len()).collect();
    let placement = match start {
        Some(s) => Some(s.b1_from_b2),
        None if coincident_count(&sub, &all) < 3 => Some(cell_b1_from_b2),
        None => options.solve.initial_b1_from_b2,
    };
    let mut est = initial_estimate(&sub, placement, &all)?;
    if let Some(s) = start {
        est.robot1 = s.robot1.clone();
        est.robot2 = s.robot2.clone();
    }
    let fit = fit_cell_with(&sub, layout, &all, Some(&est), &options.solve)?;
    Ok((sub, fit))
}

/// One scored residual block: the observation's kind, its raw residual (m) and its whitened
/// residual.
#[derive(Debug, Clone)]
pub(crate) struct ScoredRow {
    pub(crate) kind: &'static str,
    pub(crate) raw_m: DVector<f64>,
    pub(crate) whitened: DVector<f64>,
    /// Stated σ of each residual, m (`sqrt diag (WᵀW)⁻¹`).
    pub(crate) sigma_m: DVector<f64>,
    /// Index of the observation in its problem.
    pub(crate) index: usize,
}

/// Residuals of `rows` of `problem` at `est` under `layout`.
pub(crate) fn residuals_at(
    problem: &CellProblem,
    layout: &ParamLayout,
    est: &CellEstimate,
    rows: &[usize],
) -> Result<Vec<ScoredRow>, CellFitError> {
    let ev = Evaluator::new(problem, layout);
    rows.iter()
        .map(|&i| {
            let o = &problem.observations[i];
            let l = ev.linearise(o, est, false)?;
            let w = &l.whitening;
            let sigma_m = match (w.transpose() * w).try_inverse() {
                Some(cov) => cov.diagonal().map(|v| v.max(0.0).sqrt()),
                None => DVector::from_element(w.nrows(), f64::NAN),
            };
            Ok(ScoredRow {
                kind: o.kind.name(),
                whitened: w * &l.residual,
                raw_m: l.residual,
                sigma_m,
                index: i,
            })
        })
        .collect()
}

/// Held-out residuals of one unit (rows of `problem`, all of one nuisance group or none) given a
/// training estimate: the unit's nuisance fitted on one half with the training kinematics and
/// placement held, the other half scored, and back ([`calib_core::whole_cell::score_held_out`],
/// the implementation `calibrate --cell --export`'s do-no-harm check and `validate` share).
fn score_unit(
    problem: &CellProblem,
    unit: &[usize],
    train: &CellEstimate,
    options: &CellDiagnoseOptions,
) -> Result<Vec<ScoredRow>, CellFitError> {
    Ok(score_held_out(problem, unit, train, &options.solve)?
        .into_iter()
        .map(|r| ScoredRow {
            kind: r.kind.name(),
            raw_m: r.raw_m,
            whitened: r.whitened,
            sigma_m: r.sigma_m,
            index: r.index,
        })
        .collect())
}

/// The held-out units of the rows `rows`: one per named group of at least
/// [`MIN_SCORED_GROUP_ROWS`] rows (in order of first appearance; smaller groups are never held
/// out), the coincident rows cut into up to [`COINCIDENT_UNITS`] units in row order.
pub(crate) fn held_out_units(problem: &CellProblem, rows: &[usize]) -> Vec<Vec<usize>> {
    let mut keys: Vec<(GroupKind, usize)> = Vec::new();
    let mut units: Vec<Vec<usize>> = Vec::new();
    let mut coincident = Vec::new();
    for &i in rows {
        match problem.observations[i].kind.group() {
            Some(key) => match keys.iter().position(|k| *k == key) {
                Some(u) => units[u].push(i),
                None => {
                    keys.push(key);
                    units.push(vec![i]);
                }
            },
            None => coincident.push(i),
        }
    }
    // A group too small to fit its nuisance on half its rows is never held out (it trains
    // every fold and is not scored).
    let mut units: Vec<Vec<usize>> = units
        .into_iter()
        .zip(&keys)
        .filter(|(u, (kind, _))| u.len() >= MIN_SCORED_GROUP_ROWS[kind.index()])
        .map(|(u, _)| u)
        .collect();
    if !coincident.is_empty() {
        let parts = (coincident.len() / MIN_UNIT_ROWS).clamp(1, COINCIDENT_UNITS);
        let size = coincident.len().div_ceil(parts);
        units.extend(coincident.chunks(size).map(<[usize]>::to_vec));
    }
    if units.len() < 3 {
        // Too few units to hold any out: cut each into contiguous blocks (recording order) of
        // at least 2·MIN_GROUP_BLOCK_ROWS rows; each block's nuisance is refitted when it is
        // scored, so no held-out row is predicted by a nuisance fitted on it.
        units = units
            .into_iter()
            .flat_map(|u| {
                let parts = (u.len() / MIN_GROUP_BLOCK_ROWS).clamp(1, COINCIDENT_UNITS);
                let size = u.len().div_ceil(parts);
                u.chunks(size).map(<[usize]>::to_vec).collect::<Vec<_>>()
            })
            .collect();
    }
    units
}

/// Fewest rows of a joint-space region of the `--cv-folds regions` design
/// ([`super::FoldDesign::JointRegions`]): the workspace's one value.
pub use calib_core::selection::regions::MIN_REGION_ROWS;

/// One fold of a design, as the report names it.
#[derive(Debug, Clone)]
pub(crate) struct FoldInfo {
    /// Rows of the fold (held out together).
    pub(crate) rows: usize,
    /// Held-out units of the fold (its rows split by nuisance group).
    pub(crate) units: usize,
    /// Rows of the fold that stay in training: pieces of a group too small to refit its
    /// nuisance on half of them.
    pub(crate) kept_in_training: usize,
    /// Mean joint vector of each robot over the fold's rows that use it, rad (empty: none).
    pub(crate) mean_q: [Vec<f64>; 2],
}

/// The region-held-out design of the rows `used`: seeded k-means++ regions of the rows' joint
/// vectors ([`calib_core::selection::regions::joint_regions`], at least [`MIN_REGION_ROWS`]
/// rows each, at most `max_folds`), one fold per region; a region's rows are split into units by
/// nuisance group (the coincident and other group-free rows form one unit), and a unit of a
/// group with fewer than its kind's [`MIN_SCORED_GROUP_ROWS`] rows is not held out (it trains
/// every fold). `None` when fewer than [`calib_core::selection::regions::MIN_REGIONS`] regions
/// with a scored unit remain.
pub(super) fn region_design(
    problem: &CellProblem,
    used: &[usize],
    max_folds: usize,
    seed: u64,
) -> Option<(Folds, Vec<FoldInfo>)> {
    use calib_core::selection::regions::{joint_features, joint_regions, MIN_REGIONS};
    let features = joint_features(problem, used);
    let regions = joint_regions(&features, MIN_REGION_ROWS, max_folds, seed)?;
    let mut folds = Vec::new();
    let mut info = Vec::new();
    for region in 0..regions.sizes.len() {
        let rows: Vec<usize> = used
            .iter()
            .zip(&regions.labels)
            .filter(|(_, &l)| l == region)
            .map(|(&i, _)| i)
            .collect();
        // A piece is held out when its half can refit the nuisance and the group's rows left
        // in training are none or enough to start the training fit's nuisance (calib-core's
        // rule, shared with `calibrate --cell`'s do-no-harm check).
        let (scored, kept) = held_out_pieces(problem, used, &rows);
        if scored.is_empty() {
            continue;
        }
        let mut mean_q: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
        for (r, robot) in [calib_core::Robot::One, calib_core::Robot::Two]
            .into_iter()
            .enumerate()
        {
            let qs: Vec<&[f64]> = rows
                .iter()
                .flat_map(|&i| problem.observations[i].kind.joints())
                .filter(|(rb, _)| *rb == robot)
                .map(|(_, q)| q)
                .collect();
            if let Some(first) = qs.first() {
                mean_q[r] = (0..first.len())
                    .map(|j| qs.iter().map(|q| q[j]).sum::<f64>() / qs.len() as f64)
                    .collect();
            }
        }
        info.push(FoldInfo {
            rows: rows.len(),
            units: scored.len(),
            kept_in_training: kept.len(),
            mean_q,
        });
        folds.push(scored);
    }
    if folds.len() < MIN_REGIONS {
        return None;
    }
    let n_units = folds.iter().map(Vec::len).sum();
    Some((
        Folds {
            used: used.to_vec(),
            folds,
            n_units,
        },
        info,
    ))
}

/// The held-out result of one model.
#[derive(Debug, Clone)]
pub(crate) struct HeldOut {
    /// Held-out χ² of each unit (whitened residual sum of squares).
    pub(crate) unit_chi2: Vec<f64>,
    /// Each unit's scored rows' whitened χ² (one value per observation), in scoring order (the
    /// same order for every model of one design, so two models' values pair row by row).
    pub(crate) unit_e2: Vec<Vec<f64>>,
    /// Scored residual blocks.
    pub(crate) rows: Vec<ScoredRow>,
    /// Each fold's training estimate (fold order): where the next step's linearised
    /// prediction ([`Training::Predict`]) starts.
    pub(crate) fold_estimates: Vec<CellEstimate>,
}

impl HeldOut {
    pub(crate) fn total(&self) -> f64 {
        self.unit_chi2.iter().sum()
    }
}

/// The held-out design: the rows used and their units, grouped into folds.
#[derive(Debug, Clone)]
pub(crate) struct Folds {
    /// Rows (observation indices) used, after the blunder screen.
    pub(crate) used: Vec<usize>,
    /// Each fold's units (each a list of rows).
    pub(crate) folds: Vec<Vec<Vec<usize>>>,
    /// Number of units over all folds.
    pub(crate) n_units: usize,
}

/// One fold's training estimate, and each unit's held-out χ² and scored rows in the fold's
/// unit order.
type FoldHeldOut = (CellEstimate, Vec<(f64, Vec<ScoredRow>)>);

/// Levenberg–Marquardt iterations of a training fit of the linearised held-out prediction
/// (`CellDiagnoseOptions::refit_every_candidate = false`): damped Gauss–Newton steps from the
/// current model's fold optimum, the first with the candidate's columns (at zero) bordered onto
/// its normal equations. One
/// step mispredicted the held-out χ² by up to 12.7 % of the current χ² on the hidden-effect
/// sessions, three by at most 2.1 % (`HELD_OUT_SLACK_ABS` in `cell_diagnosis`).
pub const PREDICTION_ITERATIONS: usize = 3;

/// How the training fits of a cross-validation are made.
#[derive(Debug, Clone, Copy)]
pub(super) enum Training<'a> {
    /// Fitted to convergence ([`fit_model`]) from this estimate's robot corrections and
    /// placement (the reference: what the report's held-out figures are).
    Refit(&'a CellEstimate),
    /// [`PREDICTION_ITERATIONS`] iterations from each fold's training estimate of the current
    /// model (one per fold, in fold order; the candidate's new parameters start at zero): the
    /// linearised prediction of the refit's held-out result, a fraction of its cost.
    Predict(&'a [CellEstimate]),
}

/// The [`Training::Predict`] fit of `model` on `rows` of `problem` from `start`.
fn predict_fit(
    problem: &CellProblem,
    model: &[Family],
    rows: &[usize],
    start: &CellEstimate,
    options: &CellDiagnoseOptions,
) -> Result<CellEstimate, CellFitError> {
    let sub = sub_problem(&model_problem(problem, model), rows);
    let layout = model_layout(&sub, model);
    let all: Vec<usize> = (0..sub.observations.len()).collect();
    let mut solve = options.solve.clone();
    // PREDICTION_ITERATIONS ≥ 1 is always a valid iteration count.
    if let Ok(lm) = solve.lm.with_max_iterations(PREDICTION_ITERATIONS) {
        solve.lm = lm;
    }
    Ok(fit_cell_with(&sub, layout, &all, Some(start), &solve)?.estimate)
}

/// One fold of the held-out criterion: `model` fitted on the used rows outside fold `fold` of
/// `design` (starting from `start`), then each of the fold's units scored on `scoring_problem`
/// (`problem` under `model`). Returns each unit's held-out χ² and scored rows, in the fold's
/// unit order.
#[allow(clippy::too_many_arguments)]
fn fold_held_out(
    problem: &CellProblem,
    scoring_problem: &CellProblem,
    model: &[Family],
    design: &Folds,
    fold: usize,
    training: Training<'_>,
    options: &CellDiagnoseOptions,
    cell_b1_from_b2: nalgebra::Isometry3<f64>,
) -> Result<FoldHeldOut, CellFitError> {
    let units = &design.folds[fold];
    let held: Vec<usize> = units.iter().flatten().copied().collect();
    let train: Vec<usize> = design
        .used
        .iter()
        .copied()
        .filter(|i| !held.contains(i))
        .collect();
    let estimate = match training {
        Training::Refit(start) => {
            fit_model(
                problem,
                model,
                &train,
                Some(start),
                options,
                cell_b1_from_b2,
            )?
            .1
            .estimate
        }
        Training::Predict(starts) => predict_fit(problem, model, &train, &starts[fold], options)?,
    };
    let scores = units
        .iter()
        .map(|unit| {
            let scored = score_unit(scoring_problem, unit, &estimate, options)?;
            let chi2 = scored.iter().map(|s| s.whitened.norm_squared()).sum();
            Ok((chi2, scored))
        })
        .collect::<Result<Vec<_>, CellFitError>>()?;
    Ok((estimate, scores))
}

/// Cross-validates each of `models` over `design`'s folds, the training fits made as
/// `training` says. The (model, fold) fits run in parallel (rayon's current pool) and are assembled in
/// model order, then fold order, then unit order; each fit depends only on its own inputs, so
/// the results, and the error returned (the first in that order), are those of running the fits
/// one after another, whatever the thread count. `on_fit(m)` is called (from any thread) after
/// each finished fit of model `m`.
#[allow(clippy::too_many_arguments)]
pub(super) fn cross_validate_all(
    problem: &CellProblem,
    models: &[Vec<Family>],
    design: &Folds,
    training: Training<'_>,
    options: &CellDiagnoseOptions,
    cell_b1_from_b2: nalgebra::Isometry3<f64>,
    on_fit: &(dyn Fn(usize) + Sync),
) -> Result<Vec<HeldOut>, CellFitError> {
    let scoring: Vec<CellProblem> = models.iter().map(|m| model_problem(problem, m)).collect();
    let n_folds = design.folds.len();
    let jobs: Vec<(usize, usize)> = (0..models.len())
        .flat_map(|m| (0..n_folds).map(move |f| (m, f)))
        .collect();
    let results: Vec<Result<FoldHeldOut, CellFitError>> = jobs
        .par_iter()
        .map(|&(m, f)| {
            let r = fold_held_out(
                problem,
                &scoring[m],
                &models[m],
                design,
                f,
                training,
                options,
                cell_b1_from_b2,
            );
            on_fit(m);
            r
        })
        .collect();
    let mut results = results.into_iter();
    let mut out = Vec::with_capacity(models.len());
    for _ in models {
        let mut unit_chi2 = Vec::with_capacity(design.n_units);
        let mut unit_e2 = Vec::with_capacity(design.n_units);
        let mut rows = Vec::new();
        let mut fold_estimates = Vec::with_capacity(n_folds);
        for fold in results.by_ref().take(n_folds) {
            let (estimate, scores) = fold?;
            fold_estimates.push(estimate);
            for (chi2, scored) in scores {
                unit_chi2.push(chi2);
                unit_e2.push(scored.iter().map(|r| r.whitened.norm_squared()).collect());
                rows.extend(scored);
            }
        }
        out.push(HeldOut {
            unit_chi2,
            unit_e2,
            rows,
            fold_estimates,
        });
    }
    Ok(out)
}

/// Whether `after` gains enough over `before` (see the [`cell_diagnosis`](crate::cell_diagnosis)
/// documentation); returns the t statistic of the relative gains of the units the family is
/// `involved` in (∞ or 0 with fewer than 3 such units).
pub(super) fn significant(
    before: &HeldOut,
    after: &HeldOut,
    involved: &[bool],
    options: &CellDiagnoseOptions,
) -> (bool, f64) {
    let rel: Vec<f64> = before
        .unit_chi2
        .iter()
        .zip(&after.unit_chi2)
        .zip(involved)
        .filter(|(_, inv)| **inv)
        .map(|((b, a), _)| if *b > 0.0 { (b - a) / b } else { 0.0 })
        .collect();
    let total_before = before.total();
    let relative = if total_before > 0.0 {
        (total_before - after.total()) / total_before
    } else {
        0.0
    };
    let t = if rel.len() < 3 {
        if rel.iter().all(|r| *r >= options.min_relative_gain) {
            f64::INFINITY
        } else {
            0.0
        }
    } else {
        one_sample_t(&rel)
    };
    (
        relative >= options.min_relative_gain && t >= options.min_gain_t,
        t,
    )
}

/// The in-sample nested-model F test of a candidate family (step 5 of the
/// [`cell_diagnosis`](crate::cell_diagnosis) documentation): the fit of the current model
/// (`before`) against the fit with the family added (`after`), both on all screened rows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NestedF {
    /// `F = (Δ/k)/(χ²_after/d₂)`, `Δ` the drop of the penalised cost (data χ² plus prior).
    pub(crate) f: f64,
    /// `k`: the family's columns (the added unknowns).
    pub(crate) k: usize,
    /// `d₂`: residual rows less the unknowns of `after`.
    pub(crate) dof: usize,
    /// `P(F(k, d₂) > F)` (1 when `k` or `d₂` is 0: an untestable family is not accepted).
    pub(crate) p: f64,
    /// The p-value it must not exceed: the Šidák level [`sidak_level`] over the step's
    /// candidates.
    pub(crate) p_needed: f64,
}

impl NestedF {
    /// Whether the family's in-sample χ² drop is significant at the step's level.
    pub(crate) fn passes(&self) -> bool {
        self.p <= self.p_needed
    }
}

/// The per-test level `1 − (1 − false_alarm)^(1/n_tests)` that keeps the chance that any of
/// `n_tests` independent null tests rejects at `false_alarm` (Šidák).
pub fn sidak_level(false_alarm: f64, n_tests: usize) -> f64 {
    1.0 - (1.0 - false_alarm).powf(1.0 / n_tests.max(1) as f64)
}

/// The nested F test of `after` (the current model with one family added) against `before`
/// (the current model), both fitted on the same rows, at a step of `n_candidates` candidates
/// and a per-step level `false_alarm` ([`NestedF`]; step 5 of the
/// [`cell_diagnosis`](crate::cell_diagnosis) documentation).
pub(crate) fn nested_f(
    before: &CellFit,
    after: &CellFit,
    n_candidates: usize,
    false_alarm: f64,
) -> NestedF {
    let k = after.layout.len().saturating_sub(before.layout.len());
    let dof = after.residual_rows.saturating_sub(after.layout.len());
    let drop = (before.data_chi2 + before.prior_chi2) - (after.data_chi2 + after.prior_chi2);
    let f = if k > 0 && dof > 0 && after.data_chi2 > 0.0 {
        (drop / k as f64) / (after.data_chi2 / dof as f64)
    } else {
        f64::NAN
    };
    NestedF {
        f,
        k,
        dof,
        p: f_sf(f, k, dof),
        p_needed: sidak_level(false_alarm, n_candidates),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell_diagnosis::tests::mixed_session;
    use crate::cell_diagnosis::{diagnosis_problem, CellDiagnoseOptions};
    use handclasp_cell::Cell;

    /// Šidák's per-test level reproduces the family level exactly; it lies just above
    /// Bonferroni's `α/m`.
    #[test]
    fn sidak_level_keeps_the_step_level() {
        assert!((sidak_level(0.05, 1) - 0.05).abs() < 1e-15);
        assert_eq!(sidak_level(0.05, 0), sidak_level(0.05, 1));
        let per = sidak_level(0.05, 18);
        assert!(((1.0 - per).powi(18) - 0.95).abs() < 1e-12, "{per}");
        assert!(per > 0.05 / 18.0 && per < 0.05 / 17.0, "{per}");
    }

    /// The nested F test on a mixed session of the floor–wall cell whose robot 1 has a hidden
    /// joint-2 offset of 2 mrad: the true family "robot 1 joint offsets" passes at the step's
    /// level with 19 candidates, the F statistic is the drop per added column over the larger
    /// model's residual variance, and a family added to the true model (robot 2's offsets,
    /// which the truth lacks) has `k` its columns and does not pass.
    #[test]
    fn nested_f_passes_a_true_family_and_not_a_spurious_one() {
        use kinematics::ErrorParam;
        let nominal = Cell::default_floor_wall();
        let mut truth = nominal.clone();
        truth
            .robot1
            .errors
            .set(ErrorParam::JointOffset { joint: 1 }, 2e-3);
        let session = mixed_session(&truth, 36, 5);
        let options = CellDiagnoseOptions::default();
        let p = diagnosis_problem(&nominal, &session, &options).unwrap();
        let all: Vec<usize> = (0..p.observations.len()).collect();
        let families = crate::cell_diagnosis::candidate_families(&p);
        let family = |name: &str| {
            families
                .iter()
                .find(|f| f.name == name)
                .unwrap_or_else(|| panic!("{name} is a candidate"))
                .clone()
        };
        let r1 = family("robot 1 joint offsets");
        let r2 = family("robot 2 joint offsets");
        let fit = |model: &[Family], start: Option<&CellEstimate>| {
            fit_model(&p, model, &all, start, &options, nominal.b1_from_b2).unwrap()
        };
        let base = fit(&[], None);
        let with_r1 = fit(std::slice::from_ref(&r1), Some(&base.1.estimate));
        let nf = nested_f(&base.1, &with_r1.1, families.len(), options.false_alarm);
        assert!(nf.passes(), "{nf:?}");
        assert_eq!(nf.k, with_r1.1.layout.len() - base.1.layout.len());
        let drop =
            (base.1.data_chi2 + base.1.prior_chi2) - (with_r1.1.data_chi2 + with_r1.1.prior_chi2);
        let expected = (drop / nf.k as f64) / (with_r1.1.data_chi2 / nf.dof as f64);
        assert!((nf.f - expected).abs() <= 1e-12 * expected.abs(), "{nf:?}");
        let both = fit(&[r1, r2], Some(&with_r1.1.estimate));
        let spurious = nested_f(&with_r1.1, &both.1, families.len() - 1, options.false_alarm);
        assert!(spurious.k > 0 && !spurious.passes(), "{spurious:?}");
    }

    #[test]
    fn sub_problem_renumbers_groups_and_units_cover_every_row_once() {
        let cell = Cell::default_floor_wall();
        let session = mixed_session(&cell, 36, 3);
        let p = diagnosis_problem(&cell, &session, &CellDiagnoseOptions::default()).unwrap();
        p.check().unwrap();
        let all: Vec<usize> = (0..p.observations.len()).collect();
        let units = held_out_units(&p, &all);
        let mut seen: Vec<usize> = units.iter().flatten().copied().collect();
        seen.sort_unstable();
        assert_eq!(seen, all);
        for unit in &units {
            let groups: Vec<_> = unit
                .iter()
                .map(|&i| p.observations[i].kind.group())
                .collect();
            assert!(
                groups.windows(2).all(|w| w[0] == w[1]),
                "one group per unit"
            );
            let sub = sub_problem(&p, unit);
            sub.check().unwrap();
            assert_eq!(
                sub.contacts.len() + sub.trackers.len() + sub.planes.len(),
                usize::from(groups[0].is_some())
            );
        }
    }
}
