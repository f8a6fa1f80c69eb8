//! `calibrate --cell --export`'s do-no-harm rule (issue 20): before exporting, the fitted model
//! is scored against the nominal model (the placement alone, both robots nominal) by
//! region-held-out cross-validation ([`calib_core::whole_cell::region_harm_check`], the test
//! `diagnose --export` applies to its folds). When the model is worse than nominal with
//! significance in any held-out region ([`calib_core::selection::judge_harm`], 5 % false alarms
//! per session), the export is the safe model: the placement-only
//! calibration of the same session (`calibrate --cell --model placement`), and every kinematic
//! correction is withheld; `--force` exports the full model. `calibrate --cell` has no
//! family-by-family selection to keep part of the model by, so the safe model is the placement.

use std::fmt::Write as _;

use calib_core::whole_cell::{region_harm_check, HarmCheck, HarmDesign, SolveOptions};
use cli_support::cell_report::{calibrate_session_with, CellModel, SessionCalibration};
use cli_support::result_check::ScreenMode;
use handclasp_cell::{Cell, Session};
use serde::Serialize;

/// The rule's verdict, as the JSON's `do_no_harm` object gives it.
#[derive(Debug, Clone, Serialize)]
pub struct DoNoHarmReport {
    /// The check: its folds, each with the model's held-out rms over nominal's and the t.
    #[serde(flatten)]
    pub check: HarmCheck,
    /// The model exported: `kinematic`, `kinematic+compliance` or `placement` (the safe model).
    pub exported: &'static str,
    /// What the export withholds (empty when it exports the full model).
    pub withheld: Vec<String>,
    /// `--force` kept the full model although it harms a region.
    pub forced: bool,
}

/// The check of `calibrated` (a calibration of `session` of `cell` with `model`) and, when
/// the model harms a region and `force` is off, the safe model's calibration (placement only,
/// the same screen). `None` for `--model placement` (the nominal model: nothing to check).
pub fn check(
    cell: &Cell,
    session: &Session,
    calibrated: &SessionCalibration,
    model: CellModel,
    screen: ScreenMode,
    force: bool,
) -> anyhow::Result<Option<(DoNoHarmReport, Option<SessionCalibration>)>> {
    if model == CellModel::Placement {
        return Ok(None);
    }
    let mut solve = SolveOptions::default();
    if session.points.len() < 3 {
        solve.initial_b1_from_b2 = Some(cell.b1_from_b2);
    }
    let Some(check) = region_harm_check(&calibrated.problem, &calibrated.calibration, &solve)?
    else {
        return Ok(None);
    };
    let harmful = check.harmful();
    let (exported, withheld, safe) = if harmful && !force {
        let safe = calibrate_session_with(cell, session, CellModel::Placement, screen, None)?;
        let n = calibrated.report.parameters.len();
        (
            CellModel::Placement.name(),
            vec![format!(
                "the {n} kinematic corrections of --model {} (both robots stay nominal)",
                model.name()
            )],
            Some(safe),
        )
    } else {
        (model.name(), Vec::new(), None)
    };
    let report = DoNoHarmReport {
        check,
        exported,
        withheld,
        forced: harmful && force,
    };
    Ok(Some((report, safe)))
}

/// The folds' verdicts in one line: `region 1 0.912, region 2 1.340 (t −3.1) HARMFUL, …`.
fn folds_line(check: &HarmCheck) -> String {
    check
        .folds
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

/// The lines for stderr: a `warning: do no harm …` naming what was withheld (or kept by
/// `--force`) and why, or a `note:` when the check fell back or could not run.
pub fn messages(r: &DoNoHarmReport, model: CellModel) -> Vec<String> {
    let mut out = Vec::new();
    let c = &r.check;
    match c.design {
        HarmDesign::NotChecked => out.push(format!(
            "note: do no harm: {}; --export writes the model as fitted",
            c.how
        )),
        HarmDesign::RowBlocks => out.push(format!("note: do no harm: folds are {}", c.how)),
        _ => {}
    }
    if c.kept_in_training > 0 {
        out.push(format!(
            "note: do no harm: {} rows train every fold and are not scored (pieces of a contact, \
             tracker or plane group too small to refit the group's nuisance on half of them)",
            c.kept_in_training
        ));
    }
    if c.harmful() {
        let why: Vec<String> = c
            .harmful_folds()
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
            .collect();
        if r.forced {
            out.push(format!(
                "warning: kept by --force: do no harm: the {} model is worse than the nominal \
                 model (placement only) where it was not fitted: {}; the full model is exported",
                model.name(),
                why.join(", ")
            ));
        } else {
            out.push(format!(
                "warning: do no harm: the {} model is worse than the nominal model (placement \
                 only) where it was not fitted: {}; exported the placement only, WITHHELD {} \
                 (--force exports the full model)",
                model.name(),
                why.join(", "),
                r.withheld.join(", ")
            ));
        }
    }
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
        let _ = writeln!(s, "  {}", folds_line(c));
    }
    let verdict = if r.withheld.is_empty() {
        if r.forced {
            format!("exported: {} (--force; it harms a fold)", r.exported)
        } else {
            format!("exported: {}", r.exported)
        }
    } else {
        format!(
            "exported: {} — WITHHELD {} (--force exports them)",
            r.exported,
            r.withheld.join(", ")
        )
    };
    let _ = writeln!(s, "  {verdict}");
    s
}
