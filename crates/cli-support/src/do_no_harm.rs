//! The do-no-harm export decision of a whole-cell calibration (issue 20), shared by
//! `calibrate --cell --export` and Python's `CellResult.export`: before exporting, the fitted
//! model is scored against the nominal model (the placement alone, both robots nominal) by
//! region-held-out cross-validation and, when it is worse than nominal with significance in any
//! held-out region, the error families that harm are withheld family by family
//! ([`calib_core::whole_cell::decide_families`]: the rule, and what its 5 % false-alarm rate per
//! session controls and what it does not). The export is then a **refit** of the session without
//! the withheld families ([`calibrate_session_withholding`]: the same screen and prior-scale
//! choice), or the placement-only calibration when every family is withheld. `force` (the CLI's
//! `--force`, Python's `force=True`) exports the full model and says that it harms.

use std::fmt::Write as _;

use calib_core::whole_cell::{
    decide_families, judge_full_model, CellFitError, FamilyDecision, FamilyTrial, FamilyVerdict,
    HarmCheck, HarmDesign, HarmFold,
};
use handclasp_cell::{Cell, Session};
use serde::Serialize;

use crate::cell_report::{
    calibrate_session_withholding, solve_options, CellCalibrationError, CellModel,
    SessionCalibration,
};
use crate::result_check::ScreenMode;

/// Why the decision could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DoNoHarmError {
    /// A fit of the check failed (a fold's training rows too few for the unknowns, a model
    /// failure).
    #[error("the do-no-harm check: {0}")]
    Check(#[from] CellFitError),
    /// The refit without the withheld families failed.
    #[error("the do-no-harm refit without the withheld families: {0}")]
    Refit(#[from] CellCalibrationError),
}

/// A family the export withholds, and the held-out figures that decided it.
#[derive(Debug, Clone, Serialize)]
pub struct WithheldFamily {
    /// Its name (`robot 1 joint offsets`).
    pub family: String,
    /// Its rank in the withholding order (1 = withheld first).
    pub rank: usize,
    /// The smallest `t + t_harm` of the model without it alone (the ranking's figure; negative:
    /// that model still harms).
    pub margin_without: f64,
    /// The regions where the model still holding it was worse than nominal with significance.
    pub harmful_in: Vec<HarmFold>,
}

/// The rule's verdict, as the JSON's `do_no_harm` object gives it.
#[derive(Debug, Clone, Serialize)]
pub struct DoNoHarmReport {
    /// The full model's check: its folds, each with the model's held-out rms over nominal's
    /// and the t.
    #[serde(flatten)]
    pub check: HarmCheck,
    /// The model exported: the model's name (`kinematic`, `kinematic+compliance`) when nothing
    /// is withheld, `partial` when some families are, `placement` when all are.
    pub exported: String,
    /// The families the export keeps, by name.
    pub kept: Vec<String>,
    /// The families the export withholds, in the order withheld, with why (empty when the
    /// full model is exported).
    pub withheld: Vec<WithheldFamily>,
    /// Every family of the model: kept or withheld, with the ranking's figures.
    pub families: Vec<FamilyVerdict>,
    /// The models judged after the full one (each withholding some families), in order.
    pub trials: Vec<FamilyTrial>,
    /// The exported partial model's verdict per region (absent when the full model or the
    /// placement only is exported).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exported_folds: Option<Vec<HarmFold>>,
    /// `force` kept the full model although it harms a region.
    pub forced: bool,
    /// Whether the families were ranked and withheld family by family: `"not checked: --force
    /// exports the full model"` under `force` (`families[]` then lists every family kept,
    /// without ranking figures), `"checked"` otherwise (a harmless model needs no ranking).
    pub ranking: String,
}

impl DoNoHarmReport {
    /// Whether the export withholds anything.
    pub fn withholds(&self) -> bool {
        !self.withheld.is_empty()
    }

    fn new(decision: FamilyDecision, model: CellModel, force: bool) -> Self {
        let harmful = decision.check.harmful();
        let keep_all = force || !decision.withholds();
        let exported = if keep_all {
            model.name().to_string()
        } else if decision.placement_only() {
            CellModel::Placement.name().to_string()
        } else {
            "partial".to_string()
        };
        let (kept, withheld) = if keep_all {
            (
                decision.families.iter().map(|f| f.family.name()).collect(),
                Vec::new(),
            )
        } else {
            let mut withheld: Vec<WithheldFamily> = decision
                .families
                .iter()
                .filter(|f| !f.kept)
                .map(|f| WithheldFamily {
                    family: f.family.name(),
                    rank: f.rank.unwrap_or(0),
                    margin_without: f.margin_without.unwrap_or(f64::NAN),
                    harmful_in: f.harmful_in.clone(),
                })
                .collect();
            withheld.sort_by_key(|w| w.rank);
            (decision.kept().iter().map(|f| f.name()).collect(), withheld)
        };
        DoNoHarmReport {
            check: decision.check,
            exported,
            kept,
            withheld,
            families: decision.families,
            trials: decision.trials,
            exported_folds: if keep_all {
                None
            } else {
                decision.exported_trial.map(|t| t.folds)
            },
            forced: harmful && force,
            ranking: if force {
                "not checked: --force exports the full model".to_string()
            } else {
                "checked".to_string()
            },
        }
    }
}

/// The decision for `calibrated` (a calibration of `session` of `cell` with `model`, at
/// `tolerance_scale` and `screen`, as [`crate::cell_report::calibrate_session_with`] made it)
/// and, when the rule withholds anything and `force` is off, the calibration to export: the
/// refit without the withheld families (placement only when all are). `None` for `--model
/// placement`, or a calibration with no kinematic unknown (the nominal model: nothing to check).
///
/// # Errors
/// A fit of the check or the refit fails.
pub fn check(
    cell: &Cell,
    session: &Session,
    calibrated: &SessionCalibration,
    model: CellModel,
    screen: ScreenMode,
    tolerance_scale: Option<f64>,
    force: bool,
) -> Result<Option<(DoNoHarmReport, Option<SessionCalibration>)>, DoNoHarmError> {
    if model == CellModel::Placement {
        return Ok(None);
    }
    // The check's fits start where the calibration's did (on a shared trunk: at the trunk).
    let solve = solve_options(cell, session);
    // Under `force` the full model is exported whatever the verdict: judge it (the warning says
    // whether it harms), but rank no family (that could only withhold).
    let decide = if force {
        judge_full_model
    } else {
        decide_families
    };
    let Some(decision) = decide(&calibrated.problem, &calibrated.calibration, &solve)? else {
        return Ok(None);
    };
    let safe = if decision.withholds() && !force {
        Some(if decision.placement_only() {
            calibrate_session_withholding(
                cell,
                session,
                CellModel::Placement,
                screen,
                tolerance_scale,
                &[],
            )?
        } else {
            calibrate_session_withholding(
                cell,
                session,
                model,
                screen,
                tolerance_scale,
                &decision.withheld,
            )?
        })
    } else {
        None
    };
    Ok(Some((DoNoHarmReport::new(decision, model, force), safe)))
}

/// The folds' verdicts in one line: `region 1 0.912, region 2 1.340 (t −3.1) HARMFUL, …`.
fn folds_line(folds: &[HarmFold]) -> String {
    folds
        .iter()
        .map(|f| {
            let mut s = format!(
                "{} {:.3}{}",
                f.harm.fold,
                f.harm.ratio,
                if f.harm.harmful {
                    format!(" (t {:.1}) HARMFUL", f.harm.t)
                } else {
                    String::new()
                }
            );
            if f.harm.kinds.len() > 1 || f.harm.kinds.iter().any(|k| k.kind != "coincident") {
                let kinds: Vec<String> = f
                    .harm
                    .kinds
                    .iter()
                    .map(|k| {
                        format!(
                            "{} {} rows {:.3}{}",
                            k.kind,
                            k.rows,
                            k.ratio,
                            if k.harmful {
                                format!(" (t {:.1}) HARMFUL", k.t)
                            } else {
                                String::new()
                            }
                        )
                    })
                    .collect();
                let _ = write!(s, " [{}]", kinds.join("; "));
            }
            s
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The harmful folds in words: `region 2 (12 rows: held-out rms ×1.340 nominal's, t −3.1)`.
fn harm_words(folds: &[&HarmFold]) -> String {
    folds
        .iter()
        .map(|f| {
            let kinds: Vec<String> = f
                .harm
                .kinds
                .iter()
                .filter(|k| k.harmful && f.harm.kinds.len() > 1)
                .map(|k| {
                    format!(
                        "{} rows ×{:.3}, t {:.1} ≤ −{:.2}",
                        k.kind, k.ratio, k.t, k.t_harm
                    )
                })
                .collect();
            format!(
                "{} ({} rows: held-out rms ×{:.3} nominal's, t {:.1}{})",
                f.harm.fold,
                f.rows,
                f.harm.ratio,
                f.harm.t,
                if kinds.is_empty() {
                    String::new()
                } else {
                    format!("; {}", kinds.join("; "))
                }
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// What the export keeps, in words: `the placement only` or `the placement and robot 1 origin
/// positions, …`.
fn kept_words(r: &DoNoHarmReport) -> String {
    if r.kept.is_empty() {
        "the placement only".to_string()
    } else {
        format!("the placement and {}", r.kept.join(", "))
    }
}

/// The lines to warn with: a `warning: do no harm …` naming what was withheld (or kept by
/// `force`) and why, or a `note:` when the check fell back or could not run. `keep` is how to
/// export the full model (`--force`, `force=True`).
pub fn messages(r: &DoNoHarmReport, model: CellModel, keep: &str) -> Vec<String> {
    let mut out = Vec::new();
    let c = &r.check;
    match c.design {
        HarmDesign::NotChecked => out.push(format!(
            "note: do no harm: {}; the export writes the model as fitted",
            c.how
        )),
        HarmDesign::RowBlocks => out.push(format!("note: do no harm: folds are {}", c.how)),
        HarmDesign::ReferenceNotFitted => out.push(format!(
            "warning: do no harm: {}; the export writes the model as fitted, UNCHECKED against \
             nominal (check the session's tracker groups and planes: each needs rows to register \
             on in every region)",
            c.how
        )),
        _ => {}
    }
    if c.kept_in_training > 0 {
        out.push(format!(
            "note: do no harm: {} rows train every fold and are not scored (pieces of a contact, \
             tracker or plane group too small to refit the group's nuisance on half of them)",
            c.kept_in_training
        ));
    }
    if !c.harmful() {
        return out;
    }
    let why = harm_words(&c.harmful_folds());
    if r.forced {
        out.push(format!(
            "warning: kept by {keep}: do no harm: the {} model is worse than the nominal model \
             (placement only) where it was not fitted: {why}; the full model is exported",
            model.name()
        ));
        return out;
    }
    let withheld: Vec<String> = r
        .withheld
        .iter()
        .map(|w| {
            let folds: Vec<&HarmFold> = w.harmful_in.iter().collect();
            format!("{} (the model with it: {})", w.family, harm_words(&folds))
        })
        .collect();
    out.push(format!(
        "warning: do no harm: the {} model is worse than the nominal model (placement only) \
         where it was not fitted: {why}; exported {}, WITHHELD {} ({keep} exports the full model)",
        model.name(),
        kept_words(r),
        withheld.join("; ")
    ));
    out
}

/// The text report's section.
pub fn text(r: &DoNoHarmReport) -> String {
    let mut s = String::new();
    let c = &r.check;
    let _ = writeln!(
        s,
        "do no harm (--export): the model against nominal (placement only), each fitted without the fold; held-out rms ratio per fold (harmful = worse with significance, {:.0} % false alarms per session):",
        100.0 * c.false_alarm
    );
    let _ = writeln!(s, "  folds: {}", c.how);
    if c.comparisons > 0 {
        let _ = writeln!(
            s,
            "  judged: {} comparisons (fold × kind of row), each at one-sided level {:.4} (Šidák) and Student's t at its rows − 1",
            c.comparisons, c.alpha_each
        );
    }
    if !c.folds.is_empty() {
        let _ = writeln!(s, "  {}", folds_line(&c.folds));
    }
    if !r.trials.is_empty() {
        let _ = writeln!(
            s,
            "  family by family (each model without some families, against nominal on the same folds; margin = smallest t + threshold, negative = harmful):"
        );
        for f in &r.families {
            if let (Some(rank), Some(m), Some(h)) = (f.rank, f.margin_without, f.harmful_without) {
                let _ = writeln!(
                    s,
                    "    without {}: margin {:.2}{} (rank {rank})",
                    f.family.name(),
                    m,
                    if h { ", still harmful" } else { "" }
                );
            }
        }
    }
    if let Some(folds) = &r.exported_folds {
        let _ = writeln!(s, "  exported model: {}", folds_line(folds));
    }
    let verdict = if r.withheld.is_empty() {
        if r.forced {
            format!("exported: {} (--force; it harms a fold)", r.exported)
        } else {
            format!("exported: {}", r.exported)
        }
    } else {
        let names: Vec<&str> = r.withheld.iter().map(|w| w.family.as_str()).collect();
        let kept = if r.kept.is_empty() {
            String::new()
        } else {
            format!(", {}", kept_words(r))
        };
        format!(
            "exported: {}{kept} — WITHHELD {} (--force exports them)",
            r.exported,
            names.join(", ")
        )
    };
    let _ = writeln!(s, "  {verdict}");
    s
}
