//! The do-no-harm export decision, family by family (issue 20): which error families of a
//! calibration an export keeps and which it withholds, so that the exported model is not
//! worse than the nominal model (placement alone) on any held-out region of joint space.
//!
//! **Families** ([`ErrorFamily`]): a robot's unknowns whose prior comes from one field of its
//! tolerances ([`FamilyKind`]: joint offsets, joint scales, origin positions, origin angles,
//! tool tips, compliance, joint-periodic errors, lumped compliance). Withholding a family is
//! zeroing that field ([`ErrorFamily::withhold_from`]): the model without it is what the same
//! calibration gives when the cell states that part of the robot nominal. (A prismatic joint's
//! zero offset takes its prior from the origin-position tolerance, so it is in that family.
//! Robot 2's shared-trunk joints are robot 1's columns, so they are in robot 1's families.)
//!
//! **The rule** (written down before it was run on the sessions that test it):
//! 1. The full model is checked against nominal ([`super::region_harm_check`]: the same
//!    joint-space regions, each held out in turn, and [`judge_harm`](crate::selection::judge_harm)
//!    at [`HARM_FALSE_ALARM`](crate::selection::HARM_FALSE_ALARM) per session). Harmless in
//!    every region: every family is kept.
//! 2. Otherwise, **ranking**: for each family `F`, the model without `F` (the other families'
//!    unknowns, their prior as the calibration's) is fitted without each region and judged
//!    against nominal on the same regions; its **margin** is the smallest `t + t_harm` over all
//!    its comparisons (negative: harmful). Families are ranked by that margin, largest first
//!    (the family whose removal relieves the worst region most comes first), ties in family
//!    order.
//! 3. **Nested withholding** (the rule `diagnose --export` applies to its accepted steps: the
//!    largest model of a nested sequence that harms no region): for `j = 1, 2, …` the model
//!    without the first `j` ranked families is judged (`j = 1` is the ranking's own trial); the
//!    first that harms no region is the export, the `j` families withheld. All withheld: the
//!    placement only (the nominal model, harmless by definition, not judged). Both rules are
//!    [`largest_harmless`], over this nested sequence.
//! 4. The export is a **refit** of the session without the withheld families (the caller's
//!    whole calibration, screen and prior-scale choice included, on the problem with those
//!    tolerances zeroed: `cli_support::do_no_harm`), not the full fit with entries zeroed.
//!
//! **What it controls and what it does not.** Anything is withheld only when the full model is
//! judged harmful (step 1), so a harmless model loses a family in at most
//! [`HARM_FALSE_ALARM`](crate::selection::HARM_FALSE_ALARM) (5 %) of sessions: the judge's
//! stated false-alarm rate keeps its meaning, and the family-by-family steps add no test that
//! could withhold anything from a harmless model. Once the full model is harmful, each reduced
//! model is judged at the same 5 % per session, but the sequence of them is not corrected as a
//! family, and the ranking is chosen on the same held-out regions that judge the nested
//! models: a reduced model that does not harm may still be called harmful (one more family
//! withheld than needed: at most 5 % per judged model, not controlled over the sequence), and
//! one that harms is exported whenever the judge misses it (the judge's detection power, not
//! controlled by any rate). The per-region fits carry the calibration's prior scales (as the
//! full check does); the export's refit chooses its own.
//!
//! Cost: nothing beyond [`super::region_harm_check`] when the full model harms no region;
//! otherwise one fit per region for each family (ranking) and each nested model judged, at most
//! `2 · families` fits per region.

use rayon::prelude::*;
use serde::Serialize;

use super::do_no_harm::{has_checked_unknowns, layout_without, HarmFolds};
use super::{CellCalibration, CellFitError, CellParam, CellProblem, SolveOptions, Tolerance};
use super::{HarmCheck, HarmFold};
use crate::Robot;

/// The kind of an error family: the tolerance field its unknowns' prior comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum FamilyKind {
    /// Joint zero offsets of revolute joints (`joint_offset_rad`).
    JointOffset,
    /// Joint scale (gear ratio) errors (`joint_scale`).
    JointScale,
    /// Joint origin positions, and prismatic joints' zero offsets (`origin_xyz_m`).
    OriginXyz,
    /// Joint origin angles (`origin_rpy_rad`).
    OriginRpy,
    /// Tool tip offsets, every tool of the robot (`tip_m`).
    Tip,
    /// Joint compliance under gravity (`compliance_rad_per_nm`).
    Compliance,
    /// Joint-angle-periodic errors (`periodic_rad`).
    Periodic,
    /// Lumped gravity compliance (`lumped_compliance_rad`).
    LumpedCompliance,
}

impl FamilyKind {
    /// Every kind, in the order families are listed.
    pub const ALL: [FamilyKind; 8] = [
        FamilyKind::JointOffset,
        FamilyKind::JointScale,
        FamilyKind::OriginXyz,
        FamilyKind::OriginRpy,
        FamilyKind::Tip,
        FamilyKind::Compliance,
        FamilyKind::Periodic,
        FamilyKind::LumpedCompliance,
    ];

    /// In words, plural: `joint offsets`, `origin positions`, …
    pub fn words(self) -> &'static str {
        match self {
            FamilyKind::JointOffset => "joint offsets",
            FamilyKind::JointScale => "joint scales",
            FamilyKind::OriginXyz => "origin positions",
            FamilyKind::OriginRpy => "origin angles",
            FamilyKind::Tip => "tool tips",
            FamilyKind::Compliance => "compliance",
            FamilyKind::Periodic => "joint-periodic errors",
            FamilyKind::LumpedCompliance => "lumped compliance",
        }
    }

    /// `tolerance` with this kind's field zeroed (nothing of the kind fitted).
    pub fn withheld(self, tolerance: &Tolerance) -> Tolerance {
        let mut t = *tolerance;
        match self {
            FamilyKind::JointOffset => t.joint_offset_rad = 0.0,
            FamilyKind::JointScale => t.joint_scale = None,
            FamilyKind::OriginXyz => t.origin_xyz_m = 0.0,
            FamilyKind::OriginRpy => t.origin_rpy_rad = 0.0,
            FamilyKind::Tip => t.tip_m = 0.0,
            FamilyKind::Compliance => t.compliance_rad_per_nm = None,
            FamilyKind::Periodic => t.periodic_rad = None,
            FamilyKind::LumpedCompliance => t.lumped_compliance_rad = None,
        }
        t
    }
}

/// An error family of one robot (see the module documentation). Serialised as
/// `{"robot": 1, "kind": "joint_offset", "name": "robot 1 joint offsets"}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorFamily {
    /// The robot.
    pub robot: Robot,
    /// The kind.
    pub kind: FamilyKind,
}

impl Serialize for ErrorFamily {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("ErrorFamily", 3)?;
        s.serialize_field("robot", &self.robot)?;
        s.serialize_field("kind", &self.kind)?;
        s.serialize_field("name", &self.name())?;
        s.end()
    }
}

impl ErrorFamily {
    /// `robot 1 joint offsets`.
    pub fn name(&self) -> String {
        format!("{} {}", self.robot, self.kind.words())
    }

    /// Whether unknown `p` of `problem` is in the family: a robot unknown of this robot whose
    /// prior the family's tolerance field gives (zeroing that field leaves it no prior).
    pub fn contains(&self, problem: &CellProblem, p: &CellParam) -> bool {
        let robot = problem.robot(self.robot);
        match p {
            CellParam::Kinematic { robot: r, param } if *r == self.robot => {
                let mut without = robot.clone();
                without.tolerance = self.kind.withheld(&robot.tolerance);
                robot.prior_sigma(*param) > 0.0 && without.prior_sigma(*param) == 0.0
            }
            // Unknown tips (tools started at one tip) are the nominal reference's nuisances,
            // not a family (`do_no_harm`'s module documentation).
            CellParam::ToolTip { robot: r, .. } if *r == self.robot => {
                self.kind == FamilyKind::Tip && robot.tolerance.tip_m > 0.0 && !robot.tips_unknown()
            }
            _ => false,
        }
    }

    /// Withholds the family from `problem`: its tolerance field zeroed, so nothing of it is
    /// fitted (a calibration of the result is the refit without the family).
    pub fn withhold_from(&self, problem: &mut CellProblem) {
        let robot = match self.robot {
            Robot::One => &mut problem.robot1,
            Robot::Two => &mut problem.robot2,
        };
        robot.tolerance = self.kind.withheld(&robot.tolerance);
    }
}

/// The families with at least one unknown in the calibration `cal` of `problem`, robot 1's
/// first, each robot's in [`FamilyKind::ALL`] order.
pub fn error_families(problem: &CellProblem, cal: &CellCalibration) -> Vec<ErrorFamily> {
    Robot::BOTH
        .into_iter()
        .flat_map(|robot| FamilyKind::ALL.map(|kind| ErrorFamily { robot, kind }))
        .filter(|f| cal.fit.layout.params.iter().any(|p| f.contains(problem, p)))
        .collect()
}

/// A model without some families, judged against nominal on the check's regions.
#[derive(Debug, Clone, Serialize)]
pub struct FamilyTrial {
    /// The families it withholds.
    pub withheld: Vec<ErrorFamily>,
    /// Harmful in some region (some comparison's `t ≤ −t_harm`).
    pub harmful: bool,
    /// The smallest `t + t_harm` over its comparisons (negative: harmful; `inf` when none
    /// could be judged).
    pub margin: f64,
    /// Comparisons judged (the Šidák family of this model).
    pub comparisons: usize,
    /// Each region's verdict.
    pub folds: Vec<HarmFold>,
}

impl FamilyTrial {
    fn of(withheld: Vec<ErrorFamily>, check: HarmCheck) -> Self {
        let margin = check_margin(&check);
        FamilyTrial {
            withheld,
            harmful: check.harmful(),
            margin,
            comparisons: check.comparisons,
            folds: check.folds,
        }
    }
}

/// The smallest `t + t_harm` over the check's comparisons (`inf` when there is none with a
/// finite t).
pub fn check_margin(check: &HarmCheck) -> f64 {
    check
        .folds
        .iter()
        .flat_map(|f| &f.harm.kinds)
        .map(|k| k.t + k.t_harm)
        .filter(|m| m.is_finite())
        .fold(f64::INFINITY, f64::min)
}

/// One family's verdict.
#[derive(Debug, Clone, Serialize)]
pub struct FamilyVerdict {
    /// The family.
    pub family: ErrorFamily,
    /// Kept in the export.
    pub kept: bool,
    /// Its rank (1 = withheld first), when the ranking ran (the full model harmed a region).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rank: Option<usize>,
    /// The margin of the model without it alone (the ranking's trial), when the ranking ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub margin_without: Option<f64>,
    /// Whether the model without it alone still harms a region, when the ranking ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harmful_without: Option<bool>,
    /// Why it is withheld: the regions where the model still holding it (every family ranked
    /// before it withheld) is worse than nominal with significance (empty when kept).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub harmful_in: Vec<HarmFold>,
}

/// The decision of [`decide_families`] (see the module documentation).
#[derive(Debug, Clone, Serialize)]
pub struct FamilyDecision {
    /// The full model's check against nominal.
    pub check: HarmCheck,
    /// Each family of the model, in family order, kept or withheld, with the figures that
    /// ranked it.
    pub families: Vec<FamilyVerdict>,
    /// The families withheld, in the order withheld (empty: the full model is exported).
    pub withheld: Vec<ErrorFamily>,
    /// The models judged after the full one, in order: the ranking's (one family withheld
    /// each), then the nested ones beyond the first (empty when the full model harms no region).
    pub trials: Vec<FamilyTrial>,
    /// The nested model exported, as its trial (`None`: the full model, or the placement only
    /// when every family is withheld).
    pub exported_trial: Option<FamilyTrial>,
}

impl FamilyDecision {
    /// Whether anything is withheld.
    pub fn withholds(&self) -> bool {
        !self.withheld.is_empty()
    }

    /// Whether every family is withheld (the export is the placement only).
    pub fn placement_only(&self) -> bool {
        self.withholds() && self.families.iter().all(|f| !f.kept)
    }

    /// The families kept.
    pub fn kept(&self) -> Vec<ErrorFamily> {
        self.families
            .iter()
            .filter(|f| f.kept)
            .map(|f| f.family)
            .collect()
    }
}

/// The do-no-harm rule over a nested sequence of models `0..=n` (model `j` holds the first `j`
/// families of an order; model 0, the nominal model, is harmless by definition): the largest `j`
/// whose model `harmful(j)` says harms no region, judged from `n` down, so the models above the
/// answer are the only ones judged. `diagnose --export` applies it to its accepted steps (`j`
/// steps), [`decide_families`] to the families in reverse withholding order.
///
/// # Errors
/// The first error of `harmful`.
pub fn largest_harmless<E>(
    n: usize,
    mut harmful: impl FnMut(usize) -> Result<bool, E>,
) -> Result<usize, E> {
    for j in (1..=n).rev() {
        if !harmful(j)? {
            return Ok(j);
        }
    }
    Ok(0)
}

/// The do-no-harm decision for `cal`, a calibration of `problem` (see the module
/// documentation): which families to keep and which to withhold. `None` when the calibration
/// has no kinematic unknown (nothing to check).
///
/// # Errors
/// A training fit fails (too few rows for its unknowns, a model failure at an observation).
pub fn decide_families(
    problem: &CellProblem,
    cal: &CellCalibration,
    solve: &SolveOptions,
) -> Result<Option<FamilyDecision>, CellFitError> {
    decide(problem, cal, solve, true)
}

/// Step 1 of the rule alone (the full model judged against nominal), every family kept: the
/// decision when the full model is exported whatever the verdict (the CLI's `--force`), so
/// the ranking and the nested models, which could only withhold, are not fitted. `None` as
/// for [`decide_families`].
///
/// # Errors
/// A training fit fails (too few rows for its unknowns, a model failure at an observation).
pub fn judge_full_model(
    problem: &CellProblem,
    cal: &CellCalibration,
    solve: &SolveOptions,
) -> Result<Option<FamilyDecision>, CellFitError> {
    decide(problem, cal, solve, false)
}

/// [`decide_families`], or with `rank` off [`judge_full_model`].
fn decide(
    problem: &CellProblem,
    cal: &CellCalibration,
    solve: &SolveOptions,
    rank: bool,
) -> Result<Option<FamilyDecision>, CellFitError> {
    if !has_checked_unknowns(problem, cal) {
        return Ok(None);
    }
    let folds = HarmFolds::new(problem, cal, solve)?;
    let check = folds.judge(problem, cal, &cal.fit.layout, solve)?;
    let families = error_families(problem, cal);
    let verdict = |family: ErrorFamily| FamilyVerdict {
        family,
        kept: true,
        rank: None,
        margin_without: None,
        harmful_without: None,
        harmful_in: Vec::new(),
    };
    if !rank || !check.harmful() || families.is_empty() {
        return Ok(Some(FamilyDecision {
            check,
            families: families.into_iter().map(verdict).collect(),
            withheld: Vec::new(),
            trials: Vec::new(),
            exported_trial: None,
        }));
    }
    let judge_without = |withheld: &[ErrorFamily]| -> Result<FamilyTrial, CellFitError> {
        let layout = layout_without(&cal.fit.layout, problem, &|p| {
            withheld.iter().any(|f| f.contains(problem, p))
        });
        let c = folds.judge(problem, cal, &layout, solve)?;
        Ok(FamilyTrial::of(withheld.to_vec(), c))
    };
    // Ranking: each family withheld alone (in parallel, assembled in family order).
    let ranking: Vec<FamilyTrial> = families
        .par_iter()
        .map(|f| judge_without(&[*f]))
        .collect::<Result<_, _>>()?;
    let mut order: Vec<usize> = (0..families.len()).collect();
    // Largest margin first; `sort_by` is stable, so ties keep family order.
    order.sort_by(|&a, &b| ranking[b].margin.total_cmp(&ranking[a].margin));
    let mut trials = ranking.clone();
    let mut exported_trial = None;
    // Per family (family order): the harmful regions of the model it was withheld from.
    let mut why: Vec<Vec<HarmFold>> = vec![Vec::new(); families.len()];
    let mut harming: Vec<HarmFold> = check.harmful_folds().into_iter().cloned().collect();
    // The nested models: model `j` keeps the `j` families ranked last (withholds the first
    // `n − j`); model `n` is the full one (harmful, judged above).
    let n = families.len();
    let kept = largest_harmless(n, |j| -> Result<bool, CellFitError> {
        let out = n - j;
        if out == 0 {
            return Ok(true);
        }
        let i = order[out - 1];
        why[i] = std::mem::take(&mut harming);
        let trial = if out == 1 {
            ranking[i].clone()
        } else {
            let withheld: Vec<ErrorFamily> = order[..out].iter().map(|&k| families[k]).collect();
            let t = judge_without(&withheld)?;
            trials.push(t.clone());
            t
        };
        if trial.harmful {
            harming = trial
                .folds
                .iter()
                .filter(|f| f.harm.harmful)
                .cloned()
                .collect();
            return Ok(true);
        }
        exported_trial = Some(trial);
        Ok(false)
    })?;
    if kept == 0 {
        // Every family withheld: the last one's reason is the model before it.
        let i = order[n - 1];
        if why[i].is_empty() {
            why[i] = harming;
        }
    }
    let withheld: Vec<ErrorFamily> = order[..n - kept].iter().map(|&k| families[k]).collect();
    let families = families
        .iter()
        .enumerate()
        .map(|(i, &family)| FamilyVerdict {
            family,
            kept: !withheld.contains(&family),
            rank: order.iter().position(|&o| o == i).map(|r| r + 1),
            margin_without: Some(ranking[i].margin),
            harmful_without: Some(ranking[i].harmful),
            harmful_in: std::mem::take(&mut why[i]),
        })
        .collect();
    Ok(Some(FamilyDecision {
        check,
        families,
        withheld,
        trials,
        exported_trial,
    }))
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{sim_cell, Cell};
    use super::super::{calibrate_cell, ParamLayout, ScreenOptions};
    use super::*;

    /// A family is the unknowns its tolerance field gives a prior: withholding it from the
    /// problem leaves a layout without exactly those unknowns, every other one kept.
    #[test]
    fn withholding_a_family_removes_exactly_its_unknowns() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        p.observations = sc.coincident(30, 3e-4, 0.8, 4);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let families = error_families(&p, &cal);
        let names: Vec<String> = families.iter().map(ErrorFamily::name).collect();
        assert!(
            names.contains(&"robot 1 origin positions".to_string())
                && names.contains(&"robot 2 tool tips".to_string()),
            "{names:?}"
        );
        let full = ParamLayout::new(&p, &[]);
        for f in &families {
            let mut without = p.clone();
            f.withhold_from(&mut without);
            let reduced = ParamLayout::new(&without, &[]);
            let expected: Vec<&CellParam> =
                full.params.iter().filter(|q| !f.contains(&p, q)).collect();
            assert_eq!(
                reduced.params.iter().collect::<Vec<_>>(),
                expected,
                "{}",
                f.name()
            );
            assert!(reduced.len() < full.len(), "{}", f.name());
        }
    }

    /// A healthy session: the full model harms no region, every family is kept and no reduced
    /// model is judged.
    #[test]
    fn a_healthy_session_keeps_every_family() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let mut p = sc.problem();
        p.observations = sc.coincident(40, 3e-4, 0.8, 4);
        let solve = SolveOptions::default();
        let cal = calibrate_cell(&p, &solve, &ScreenOptions::default()).unwrap();
        let d = decide_families(&p, &cal, &solve).unwrap().unwrap();
        assert!(!d.check.harmful(), "{:?}", d.check);
        assert!(!d.withholds() && !d.placement_only());
        assert_eq!(d.kept().len(), d.families.len());
        assert!(!d.families.is_empty());
        assert!(d.trials.is_empty() && d.exported_trial.is_none());
    }
}
