//! What `calibrate --cell` does with the result check
//! ([`cli_support::result_check::ResultCheckReport`]) and the export's re-prediction: a refusal
//! (exit 1) naming the mistake unless `--force`, else one `warning:` line per finding.

use std::path::Path;

use anyhow::bail;
use calib_core::whole_cell::{CellCalibration, CellProblem};
use cli_support::result_check::{
    reprediction_difference, ResultCheckReport, EXPORT_REPREDICTION_TOL_MM,
};
use handclasp_cell::{Cell, Session};

/// Refuses a `refused` check (its messages, joined) unless `force`; otherwise prints each of
/// its messages on stderr after `warning:`.
pub fn refuse_or_warn(check: &ResultCheckReport, force: bool) -> anyhow::Result<()> {
    if check.refused() && !force {
        bail!(
            "the result contradicts what the cell states: {}",
            check.messages.join("; ")
        );
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
/// beyond [`EXPORT_REPREDICTION_TOL_MM`] refuses the export (a `warning:` with `force`).
pub fn check_export(
    dir: &Path,
    session: &Session,
    problem: &CellProblem,
    cal: &CellCalibration,
    force: bool,
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
            bail!("{m}; the export is not usable as it stands (--force keeps it)");
        }
        eprintln!("warning: {m}");
    }
    Ok(())
}
