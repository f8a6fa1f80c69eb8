//! What `calibrate --cell` does with the result check
//! ([`cli_support::result_check::ResultCheckReport`]) and the export's re-prediction: a refusal
//! (exit 1) naming the mistake unless `--force`, else one `warning:` line per finding.

use std::path::Path;

use anyhow::bail;
use calib_core::whole_cell::{CellCalibration, CellProblem};
use cli_support::result_check::{
    reprediction_difference, ExportReprediction, Refusal, ResultCheckReport,
    EXPORT_REPREDICTION_TOL_MM,
};
use handclasp_cell::{Cell, Session};

/// Refuses a `refused` check (its messages, joined) unless `force`; otherwise prints each of
/// its messages on stderr after `warning:`. With `json`, a refusal first prints its
/// [`Refusal`] object (key `result_check`) on stdout; `command` names the command in it.
pub fn refuse_or_warn(
    check: &ResultCheckReport,
    force: bool,
    json: bool,
    command: &'static str,
) -> anyhow::Result<()> {
    if check.refused() && !force {
        let reason = check.refusal_reason();
        if json {
            let mut refusal = Refusal::new(command, reason.clone());
            refusal.result_check = Some(check);
            crate::json_out::print_pretty(&refusal)?;
        }
        bail!("{reason}");
    }
    for m in &check.messages {
        if check.refused() {
            eprintln!("warning: kept by --force: {m}");
        } else {
            eprintln!("warning: {m}");
        }
    }
    Ok(())
}

/// Re-predicts the training rows from the cell exported into `dir`: a difference from the fit
/// beyond [`EXPORT_REPREDICTION_TOL_MM`] refuses the export (a `warning:` with `force`; with
/// `json`, the refusal's [`Refusal`] object, key `export_reprediction`, on stdout first).
pub fn check_export(
    dir: &Path,
    session: &Session,
    problem: &CellProblem,
    cal: &CellCalibration,
    force: bool,
    json: bool,
) -> anyhow::Result<()> {
    let path = dir.join(handclasp_cell::CALIBRATE_EXPORT_NAMES.cell);
    let exported = Cell::from_toml_file(&path)?;
    let (worst_mm, row) = reprediction_difference(&exported, session, problem, cal)?;
    if worst_mm > EXPORT_REPREDICTION_TOL_MM {
        let m = format!(
            "{}: the exported cell re-predicts the session's row {row} {worst_mm:.3} mm away from \
             the fit (limit {EXPORT_REPREDICTION_TOL_MM} mm): the export lost a fitted quantity",
            path.display()
        );
        if !force {
            let reason = format!("{m}; the export is not usable as it stands (--force keeps it)");
            if json {
                let mut refusal = Refusal::new("calibrate --cell", reason.clone());
                refusal.export_reprediction = Some(ExportReprediction {
                    limit_mm: EXPORT_REPREDICTION_TOL_MM,
                    row,
                    worst_mm,
                });
                crate::json_out::print_pretty(&refusal)?;
            }
            bail!("{reason}");
        }
        eprintln!("warning: {m}");
    }
    Ok(())
}
