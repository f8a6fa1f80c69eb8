//! The whole-cell diagnosis's folds and its do-no-harm export rule, as the report gives them
//! (issue 20).
//!
//! **Folds** ([`FoldsReport`]): how the held-out criterion's folds were made (joint-space
//! regions, or the session's groups when the session is too small for regions, or on request),
//! and each fold: its rows, its held-out units and its mean joint vector per robot.
//!
//! **The rule** ([`DoNoHarmReport`]): the model of each accepted step `j` (families `1..=j`) is
//! compared with the nominal model (nuisances and placement fitted, kinematics nominal) in every
//! fold, both held out on the same folds, by [`calib_core::selection::judge_harm`] (the judge
//! `calibrate --cell --export` uses too): harmful in a fold when, for some observation kind, the
//! paired one-sided t of the per-row gains on the fold's rows of that kind is below the Šidák
//! threshold that holds the chance of a false alarm over all the step's folds and kinds at
//! [`HARM_FALSE_ALARM`]. The export keeps the largest `j` whose model harms no fold (`j = 0`:
//! the placement only); the families after it are **withheld**, each with the folds where the
//! model with it does harm. `diagnose --export --force` exports the full model.

use std::fmt::Write as _;

use calib_core::selection::{KindHarm, RegionHarm, HARM_FALSE_ALARM};
use serde::Serialize;

use crate::cell_diagnosis::{CellDiagnosis, FoldDesign};

/// How the folds were made, and each fold.
#[derive(Debug, Clone, Serialize)]
pub struct FoldsReport {
    /// The design used (after any fallback).
    pub design: FoldDesign,
    /// How the folds were made, in words (and why, on a fallback).
    pub how: String,
    /// Each fold, in fold order.
    pub folds: Vec<FoldReport>,
}

/// One fold of the held-out criterion.
#[derive(Debug, Clone, Serialize)]
pub struct FoldReport {
    /// Its name in the report (`region 1`, … or `fold 1`, …).
    pub name: String,
    /// Rows of the fold.
    pub rows: usize,
    /// Its held-out units (its rows split by nuisance group).
    pub units: usize,
    /// Rows of the fold that stay in training (pieces of a group too small to refit its
    /// nuisance on half of them).
    pub kept_in_training: usize,
    /// Mean joint vector of robot 1 over the fold's rows, degrees (empty: no row of robot 1, or
    /// a groups design).
    pub robot1_mean_q_deg: Vec<f64>,
    /// The same for robot 2.
    pub robot2_mean_q_deg: Vec<f64>,
}

/// The do-no-harm test of one accepted model in one fold (calib-core's, shared with
/// `calibrate --cell --export`).
pub use calib_core::selection::FoldHarm;

/// The model of steps `1..=step` against nominal, fold by fold.
#[derive(Debug, Clone, Serialize)]
pub struct StepHarm {
    /// The step (1-based) and the family it added.
    pub step: usize,
    /// The family's name.
    pub family: String,
    /// Per fold.
    pub folds: Vec<FoldHarm>,
}

/// A family the export withholds, and why.
#[derive(Debug, Clone, Serialize)]
pub struct WithheldFamily {
    /// The family's name.
    pub family: String,
    /// Its step.
    pub step: usize,
    /// The folds where the model with it (steps `1..=step`) is worse than nominal with
    /// significance.
    pub harmful_in: Vec<FoldHarm>,
}

/// The do-no-harm export rule's verdict.
#[derive(Debug, Clone, Serialize)]
pub struct DoNoHarmReport {
    /// The chance, per step's model, that a harmless model is called harmful in some fold
    /// ([`HARM_FALSE_ALARM`]; each fold × kind comparison at its Šidák threshold, `kinds[].t_harm`).
    pub false_alarm: f64,
    /// Each accepted step's model against nominal, per fold.
    pub steps: Vec<StepHarm>,
    /// The families the export keeps (steps `1..=safe_steps`), in order.
    pub exported_families: Vec<String>,
    /// The families the export withholds, with why.
    pub withheld: Vec<WithheldFamily>,
}

impl DoNoHarmReport {
    /// Whether the rule withholds anything.
    pub fn withholds(&self) -> bool {
        !self.withheld.is_empty()
    }

    /// One line per withheld family and why: `FAMILY (step N): the model with it is worse
    /// than nominal in FOLD ratio R (t T), …` (the text report's lines, without indent).
    pub fn withheld_lines(&self) -> Vec<String> {
        self.withheld
            .iter()
            .map(|w| {
                let why: Vec<String> = w
                    .harmful_in
                    .iter()
                    .map(|f| format!("{} ratio {:.3} (t {:.1})", f.fold, f.ratio, f.t))
                    .collect();
                format!(
                    "{} (step {}): the model with it is worse than nominal in {}",
                    w.family,
                    w.step,
                    why.join(", ")
                )
            })
            .collect()
    }

    /// The warning when the rule withholds anything (`None` otherwise): which families the
    /// export withholds and keeps, the folds being `fold_word`s (`region` or `fold`), and
    /// `keep` the way to export the full model (`--force` in the CLI).
    pub fn warning(&self, fold_word: &str, keep: &str) -> Option<String> {
        if !self.withholds() {
            return None;
        }
        Some(format!(
            "do no harm: --export withholds {} (the model with them is worse than nominal on \
             held-out {fold_word}s; see \"Do no harm\" in the report) and exports {}; {keep} \
             exports the full model",
            self.withheld
                .iter()
                .map(|w| w.family.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            if self.exported_families.is_empty() {
                "the placement only".to_string()
            } else {
                format!("the placement and {}", self.exported_families.join(", "))
            }
        ))
    }
}

fn deg(q: &[f64]) -> Vec<f64> {
    q.iter().map(|v| v.to_degrees()).collect()
}

/// The folds' report of a diagnosis.
pub(crate) fn folds_report(d: &CellDiagnosis) -> FoldsReport {
    let (design, how) = &d.fold_design;
    let prefix = match design {
        FoldDesign::JointRegions => "region",
        _ => "fold",
    };
    FoldsReport {
        design: *design,
        how: how.clone(),
        folds: d
            .fold_info
            .iter()
            .enumerate()
            .map(|(i, f)| FoldReport {
                name: format!("{prefix} {}", i + 1),
                rows: f.rows,
                units: f.units,
                kept_in_training: f.kept_in_training,
                robot1_mean_q_deg: deg(&f.mean_q[0]),
                robot2_mean_q_deg: deg(&f.mean_q[1]),
            })
            .collect(),
    }
}

fn fold_harm(name: &str, (h, kinds): &(RegionHarm, Vec<KindHarm>)) -> FoldHarm {
    FoldHarm::new(name, h, kinds.clone())
}

/// The rule's report of a diagnosis, fold names from `folds`.
pub(crate) fn do_no_harm_report(d: &CellDiagnosis, folds: &FoldsReport) -> DoNoHarmReport {
    let accepted: Vec<&str> = d
        .steps
        .iter()
        .filter(|s| s.accepted)
        .map(|s| s.family.name.as_str())
        .collect();
    let steps: Vec<StepHarm> = d
        .harm
        .iter()
        .zip(&accepted)
        .enumerate()
        .map(|(j, (row, family))| StepHarm {
            step: j + 1,
            family: (*family).to_string(),
            folds: row
                .iter()
                .zip(&folds.folds)
                .map(|(h, f)| fold_harm(&f.name, h))
                .collect(),
        })
        .collect();
    let withheld = steps
        .iter()
        .skip(d.safe_steps)
        .map(|s| WithheldFamily {
            family: s.family.clone(),
            step: s.step,
            harmful_in: s.folds.iter().filter(|f| f.harmful).cloned().collect(),
        })
        .collect();
    DoNoHarmReport {
        false_alarm: HARM_FALSE_ALARM,
        exported_families: accepted
            .iter()
            .take(d.safe_steps)
            .map(|f| (*f).to_string())
            .collect(),
        steps,
        withheld,
    }
}

/// The text of the folds and the rule (the whole-cell report's section).
pub(crate) fn write_text(s: &mut String, folds: &FoldsReport, harm: &DoNoHarmReport) {
    let _ = writeln!(s, "Folds: {}", folds.how);
    for f in &folds.folds {
        let mean = |q: &[f64]| {
            q.iter()
                .map(|v| format!("{v:.0}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let mut line = format!("  {}: {} rows, {} units", f.name, f.rows, f.units);
        if f.kept_in_training > 0 {
            let _ = write!(line, " ({} rows kept in training)", f.kept_in_training);
        }
        if !f.robot1_mean_q_deg.is_empty() {
            let _ = write!(
                line,
                "; robot 1 mean q [{}] deg",
                mean(&f.robot1_mean_q_deg)
            );
        }
        if !f.robot2_mean_q_deg.is_empty() {
            let _ = write!(
                line,
                "; robot 2 mean q [{}] deg",
                mean(&f.robot2_mean_q_deg)
            );
        }
        let _ = writeln!(s, "{line}");
    }
    if harm.steps.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "Do no harm (each step's model against nominal, held out fold by fold; harmful = worse with significance, {:.0} % false alarms per model over its folds and kinds):",
        100.0 * harm.false_alarm
    );
    for st in &harm.steps {
        let cells: Vec<String> = st
            .folds
            .iter()
            .map(|f| {
                format!(
                    "{} {:.3}{}",
                    f.fold,
                    f.ratio,
                    if f.harmful {
                        format!(" (t {:.1}) HARMFUL", f.t)
                    } else {
                        String::new()
                    }
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "  step {} (+ {}): {}",
            st.step,
            st.family,
            cells.join(", ")
        );
    }
    if harm.withholds() {
        let _ = writeln!(
            s,
            "Export (--export): the placement{} — WITHHELD (--force exports them):",
            if harm.exported_families.is_empty() {
                String::new()
            } else {
                format!(" and {}", harm.exported_families.join(", "))
            }
        );
        for line in harm.withheld_lines() {
            let _ = writeln!(s, "  {line}");
        }
    } else {
        let _ = writeln!(
            s,
            "Export (--export): every named family (none is worse than nominal in any fold)"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rule's report that keeps `kept` and withholds one family harmful in one fold.
    fn withholding(kept: &[&str]) -> DoNoHarmReport {
        let harmful = FoldHarm {
            fold: "region 2".into(),
            ratio: 1.234,
            t: -3.21,
            harmful: true,
            kinds: Vec::new(),
        };
        DoNoHarmReport {
            false_alarm: HARM_FALSE_ALARM,
            steps: Vec::new(),
            exported_families: kept.iter().map(|f| f.to_string()).collect(),
            withheld: vec![WithheldFamily {
                family: "robot 1 joint offsets".into(),
                step: kept.len() + 1,
                harmful_in: vec![harmful],
            }],
        }
    }

    #[test]
    fn the_warning_names_each_withheld_family_what_is_kept_and_how_to_keep_all() {
        let r = withholding(&["robot 2 joint compliance"]);
        let w = r
            .warning("region", "keep_withheld=True")
            .expect("withholds");
        assert!(
            w.starts_with("do no harm: --export withholds robot 1 joint offsets "),
            "{w}"
        );
        assert!(w.contains("held-out regions"), "{w}");
        assert!(
            w.contains("exports the placement and robot 2 joint compliance; keep_withheld=True exports the full model"),
            "{w}"
        );
        assert_eq!(
            r.withheld_lines(),
            ["robot 1 joint offsets (step 2): the model with it is worse than nominal in region 2 ratio 1.234 (t -3.2)"]
        );
        let placement_only = withholding(&[]);
        assert!(placement_only
            .warning("fold", "--force")
            .unwrap()
            .contains("exports the placement only; --force"));
        let nothing = DoNoHarmReport {
            withheld: Vec::new(),
            ..placement_only
        };
        assert_eq!(nothing.warning("fold", "--force"), None);
        assert!(nothing.withheld_lines().is_empty());
    }
}
