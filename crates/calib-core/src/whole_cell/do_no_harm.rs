//! The do-no-harm check of a calibration (issue 20): is the fitted model worse than the nominal
//! model (the placement and nuisances alone, both robots nominal) on rows it was not fitted
//! to? `calibrate --cell --export` runs it before exporting; `diagnose --export` applies the
//! same test ([`region_harm`], [`HARM_T`]) to its own folds.
//!
//! 1. **Held-out rows**: the fit's rows without a nuisance group (coincident handclasps). A
//!    tracker, plane or contact group's rows always train: scoring them held out would need
//!    their nuisance refitted on half of them, as `diagnose` does.
//! 2. **Folds** ([`HarmDesign`]): regions of joint space ([`joint_regions`] on
//!    [`joint_features`], at least [`MIN_HARM_REGION_ROWS`] rows each, at most one region per
//!    `2·MIN_HARM_REGION_ROWS` rows (3 to 6), seed [`REGION_SEED`], the clustering `diagnose
//!    --cv-folds regions` uses); a session too small for
//!    [`MIN_REGIONS`] regions falls back to blocks of rows in row order (at most
//!    [`FALLBACK_BLOCKS`] of at least [`MIN_BLOCK_ROWS`], as `diagnose` cuts its coincident
//!    rows), which measure interpolation, and says so; fewer than two blocks: not checked.
//! 3. **Fits per fold** ([`fold_e2`]): the model (the calibration's own layout: its unknowns and
//!    its prior at the scales the evidence chose, not chosen again per fold) and the nominal
//!    model are both fitted on the other rows ([`fit_cell_with`]), and each held-out row's
//!    whitened squared residual is taken under each.
//! 4. **Verdict**: [`region_harm`] per fold at [`HARM_T`]: harmful where the model's held-out
//!    rms is above nominal's and the paired t of the per-row gains is `≤ −HARM_T`.
//!
//! Cost: two fits per fold, at most `2 ·` [`crate::selection::regions::MAX_REGIONS`].

use serde::Serialize;

use super::{
    fit_cell_with, initial_estimate, CellCalibration, CellFitError, CellProblem, Evaluator,
    ParamLayout, SolveOptions, Tolerance,
};
use crate::selection::regions::{
    joint_features, joint_regions, MAX_REGIONS, MIN_REGIONS, REGION_SEED,
};
use crate::selection::{region_harm, FoldHarm, HARM_T};

/// Fewest handclasp rows of a held-out region. `diagnose`'s regions need
/// [`crate::selection::regions::MIN_REGION_ROWS`] (12) because a region's piece of a tracker
/// or plane group must refit its frame on half of it; a handclasp has no nuisance to refit, so
/// a region needs only enough rows for the paired t of [`region_harm`]: eight handclasps, 24
/// residuals.
pub const MIN_HARM_REGION_ROWS: usize = 8;

/// Most blocks of the row-order fallback (as `diagnose` cuts its coincident rows into at most
/// four units).
pub const FALLBACK_BLOCKS: usize = 4;

/// Fewest rows of a block of the row-order fallback (as `diagnose`'s coincident units): six
/// handclasps are 18 residuals, enough for the paired t of [`region_harm`] to mean something.
pub const MIN_BLOCK_ROWS: usize = 6;

/// How the check's folds were made; serialised snake_case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum HarmDesign {
    /// Regions of joint space: a fold measures extrapolation to postures the fit did not see.
    JointRegions,
    /// Blocks of rows in row order (a session too small for regions): interpolation.
    RowBlocks,
    /// Too few held-out rows for two blocks: nothing was checked.
    NotChecked,
}

/// One fold of the check: its held-out rows and the verdict.
#[derive(Debug, Clone, Serialize)]
pub struct HarmFold {
    /// Held-out rows (observations) of the fold.
    pub rows: usize,
    /// The model against nominal in the fold (name `region k` or `block k`).
    #[serde(flatten)]
    pub harm: FoldHarm,
}

/// The do-no-harm check of a calibration (see the module documentation).
#[derive(Debug, Clone, Serialize)]
pub struct HarmCheck {
    /// How the folds were made.
    pub design: HarmDesign,
    /// The same in words (and why, on a fallback).
    pub how: String,
    /// The one-sided t below which a loss is significant ([`HARM_T`]).
    pub harm_t: f64,
    /// Each fold's verdict (empty when not checked).
    pub folds: Vec<HarmFold>,
    /// Rows of the fit that were never held out (rows of a nuisance group: they train every
    /// fold).
    pub kept_in_training: usize,
}

impl HarmCheck {
    /// Whether the model is worse than nominal, with significance, in any fold.
    pub fn harmful(&self) -> bool {
        self.folds.iter().any(|f| f.harm.harmful)
    }

    /// The folds where it is.
    pub fn harmful_folds(&self) -> Vec<&HarmFold> {
        self.folds.iter().filter(|f| f.harm.harmful).collect()
    }
}

/// The do-no-harm check of `cal`, a calibration of `problem` (see the module documentation);
/// `solve` the solver settings of the fits. `None` when the calibration has no kinematic
/// unknown (a placement-only fit is the nominal model: nothing to check).
///
/// # Errors
/// A training fit fails (too few rows for its unknowns, a model failure at an observation).
pub fn region_harm_check(
    problem: &CellProblem,
    cal: &CellCalibration,
    solve: &SolveOptions,
) -> Result<Option<HarmCheck>, CellFitError> {
    let fit = &cal.fit;
    if fit.layout.prior_sqrt_info.nrows() == 0 {
        return Ok(None);
    }
    let (scorable, kept): (Vec<usize>, Vec<usize>) = fit
        .active
        .iter()
        .partition(|&&i| problem.observations[i].kind.group().is_none());
    let features = joint_features(problem, &scorable);
    // At most one region per 2·MIN_HARM_REGION_ROWS rows: regions of twice the minimum on
    // average leave k-means room to follow the postures, the minimum-size assignment of
    // `joint_regions` binding only on stragglers (with one region per MIN_HARM_REGION_ROWS rows
    // every region would be cut to exactly the minimum, whatever the postures).
    let max_regions = (scorable.len() / (2 * MIN_HARM_REGION_ROWS)).clamp(MIN_REGIONS, MAX_REGIONS);
    let (design, how, folds): (HarmDesign, String, Vec<Vec<usize>>) =
        match joint_regions(&features, MIN_HARM_REGION_ROWS, max_regions, REGION_SEED) {
            Some(regions) => {
                let folds = (0..regions.sizes.len())
                    .map(|c| {
                        scorable
                            .iter()
                            .zip(&regions.labels)
                            .filter(|(_, &l)| l == c)
                            .map(|(&i, _)| i)
                            .collect()
                    })
                    .collect::<Vec<Vec<usize>>>();
                let how = format!(
                    "{} regions of joint space (natural clusters, else seeded k-means++, \
                     seed {REGION_SEED}; on the handclasps' joint vectors normalised by the \
                     joint limits, at least \
                     {MIN_HARM_REGION_ROWS} rows each), each held out in turn",
                    folds.len()
                );
                (HarmDesign::JointRegions, how, folds)
            }
            None => {
                let parts = (scorable.len() / MIN_BLOCK_ROWS).min(FALLBACK_BLOCKS);
                if parts < 2 {
                    let how = format!(
                        "not checked: {} handclasp rows are too few for {MIN_REGIONS} joint-space \
                         regions of {MIN_HARM_REGION_ROWS} rows or 2 blocks of {MIN_BLOCK_ROWS}",
                        scorable.len()
                    );
                    return Ok(Some(HarmCheck {
                        design: HarmDesign::NotChecked,
                        how,
                        harm_t: HARM_T,
                        folds: Vec::new(),
                        kept_in_training: kept.len(),
                    }));
                }
                let size = scorable.len().div_ceil(parts);
                let folds: Vec<Vec<usize>> = scorable.chunks(size).map(<[usize]>::to_vec).collect();
                let how = format!(
                    "{} blocks of rows in row order: {} handclasp rows do not cut into \
                     {MIN_REGIONS} joint-space regions of at least {MIN_HARM_REGION_ROWS} rows \
                     (the check measures interpolation, not extrapolation)",
                    folds.len(),
                    scorable.len()
                );
                (HarmDesign::RowBlocks, how, folds)
            }
        };
    let prefix = match design {
        HarmDesign::JointRegions => "region",
        _ => "block",
    };
    let mut nominal = problem.clone();
    nominal.robot1.tolerance = Tolerance::none();
    nominal.robot2.tolerance = Tolerance::none();
    let nominal_layout = ParamLayout::new(&nominal, &[]);
    let mut out = Vec::with_capacity(folds.len());
    for (k, held) in folds.iter().enumerate() {
        let train: Vec<usize> = fit
            .active
            .iter()
            .copied()
            .filter(|i| !held.contains(i))
            .collect();
        let model_e2 = fold_e2(problem, &fit.layout, cal, &train, held, solve)?;
        let nominal_e2 = fold_e2(&nominal, &nominal_layout, cal, &train, held, solve)?;
        let harm = region_harm(&nominal_e2, &model_e2, HARM_T).map_err(|e| {
            CellFitError::InvalidInput(format!("do-no-harm check, {prefix} {}: {e}", k + 1))
        })?;
        out.push(HarmFold {
            rows: held.len(),
            harm: FoldHarm::new(&format!("{prefix} {}", k + 1), &harm),
        });
    }
    Ok(Some(HarmCheck {
        design,
        how,
        harm_t: HARM_T,
        folds: out,
        kept_in_training: kept.len(),
    }))
}

/// The whitened squared residual `‖W·r‖²` of each row of `held` under `layout`'s model of
/// `problem` fitted on the rows `train` (starting from `cal`'s placement, robots nominal).
fn fold_e2(
    problem: &CellProblem,
    layout: &ParamLayout,
    cal: &CellCalibration,
    train: &[usize],
    held: &[usize],
    solve: &SolveOptions,
) -> Result<Vec<f64>, CellFitError> {
    let start = initial_estimate(problem, Some(cal.fit.estimate.b1_from_b2), train)?;
    let fit = fit_cell_with(problem, layout.clone(), train, Some(&start), solve)?;
    let ev = Evaluator::new(problem, layout);
    held.iter()
        .map(|&i| {
            let l = ev.linearise(&problem.observations[i], &fit.estimate, false)?;
            Ok((&l.whitening * &l.residual).norm_squared())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{sim_cell, Cell};
    use super::super::{calibrate_cell, ScreenOptions};
    use super::*;

    /// A healthy session (the truth within the tolerances, rows over the cube): the fitted
    /// model harms no region; the same session with the kinematics fitted is judged region by
    /// region, and a placement-only calibration is not checked at all.
    #[test]
    fn a_healthy_session_harms_no_region() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        p.observations = sc.coincident(40, 3e-4, 0.8, 4);
        let solve = SolveOptions::default();
        let cal = calibrate_cell(&p, &solve, &ScreenOptions::default()).unwrap();
        let check = region_harm_check(&p, &cal, &solve).unwrap().unwrap();
        assert_eq!(check.design, HarmDesign::JointRegions, "{}", check.how);
        assert!(check.folds.len() >= MIN_REGIONS);
        assert_eq!(
            check.folds.iter().map(|f| f.rows).sum::<usize>(),
            cal.fit.active.len()
        );
        assert!(!check.harmful(), "{check:?}");
        let mut placement = p.clone();
        placement.robot1.tolerance = Tolerance::none();
        placement.robot2.tolerance = Tolerance::none();
        let cal0 = calibrate_cell(&placement, &solve, &ScreenOptions::default()).unwrap();
        assert!(region_harm_check(&placement, &cal0, &solve)
            .unwrap()
            .is_none());
    }

    /// Too few rows for regions: blocks in row order, and the reason says so; fewer still:
    /// not checked.
    #[test]
    fn a_small_session_falls_back_to_blocks_then_to_no_check() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        // 20 rows afford 2 regions of 8 (fewer than MIN_REGIONS): 3 blocks of at least 6.
        p.observations = sc.coincident(20, 3e-4, 0.8, 5);
        let solve = SolveOptions::default();
        let cal = calibrate_cell(&p, &solve, &ScreenOptions::default()).unwrap();
        let check = region_harm_check(&p, &cal, &solve).unwrap().unwrap();
        assert_eq!(check.design, HarmDesign::RowBlocks, "{}", check.how);
        assert_eq!(check.folds.len(), 20 / MIN_BLOCK_ROWS);
        assert!(check.how.contains("interpolation"), "{}", check.how);
        p.observations = sc.coincident(11, 3e-4, 0.8, 6);
        let cal = calibrate_cell(&p, &solve, &ScreenOptions::default()).unwrap();
        let check = region_harm_check(&p, &cal, &solve).unwrap().unwrap();
        assert_eq!(check.design, HarmDesign::NotChecked, "{}", check.how);
        assert!(check.folds.is_empty() && !check.harmful());
    }
}
