//! Export of the extended model: the calibrated cell through the one calibrated-cell exporter,
//! [`handclasp_cell::export_calibrated_cell`] (corrected URDFs patched and verified, a cell TOML
//! with the calibrated `b1_from_b2`), and beside it the effects and reports as JSON and text,
//! each written to a temporary file in the target folder, read back and checked, and only then
//! renamed into place.
//!
//! Two diagnoses export: the coincident one ([`export_corrected`]) and the whole-cell one
//! ([`export_cell_diagnosis`]), with the same file names (`robot1_corrected.urdf`,
//! `robot2_corrected.urdf`, `cell_corrected.toml`, `effects.json`; the whole-cell export adds
//! the report as `report.json` and `report.txt`).

use std::path::{Path, PathBuf};

use calib_core::whole_cell::{CellEstimate, RobotCorrection};
use handclasp_cell::{export_calibrated_cell, Cell, ExportNames};
use kinematics::{split_for_urdf, KinematicErrors};
use nalgebra::Isometry3;

use crate::catalogue::effects_to_errors;
use crate::cell_report::{render_cell_text, CellDiagnoseReport};
use crate::report::DiagnoseReport;
use crate::DiagnoseError;

/// The files of the whole-cell export ([`export_cell_diagnosis`]): the coincident export's
/// names, and the header of the cell file.
pub const CELL_DIAGNOSIS_EXPORT_NAMES: ExportNames<'static> = ExportNames {
    cell: "cell_corrected.toml",
    robot1_urdf: "robot1_corrected.urdf",
    robot2_urdf: "robot2_corrected.urdf",
    header: "# Written by `handclasp diagnose --export` (whole-cell diagnosis): the named families' fitted\n\
             # values. robot1_corrected.urdf / robot2_corrected.urdf: joint offsets, origin positions and\n\
             # angles; tip_mm and [robotN.tools]: fitted tool tips; [robotN.errors]: compliance and\n\
             # joint-periodic terms, which a URDF cannot hold; [b1_from_b2]: fitted when the session\n\
             # determines it, else the input cell's. Tracker frames, scales and drifts, planes and contact\n\
             # distances are properties of the session, not of the cell: they are in report.json only.\n",
};

/// Writes the whole-cell diagnosis `report` of a session on `cell` to `dir` (created if
/// missing; files of the same names are overwritten):
/// - `robot1_corrected.urdf`, `robot2_corrected.urdf` and `cell_corrected.toml`: the cell with
///   the named families' fitted values ([`handclasp_cell::export_calibrated_cell`]: joint offsets and
///   origin errors patched into the URDFs and verified; the fitted tip of tool 0 as `tip_mm`
///   and of every other tool in `[robotN.tools]`; compliance and joint-periodic terms as
///   `[robotN.errors]`); `b1_from_b2` is the fitted placement when the session determines it
///   ([`CellDiagnoseReport::placement_fitted`]), else `cell`'s; the cell's placement σ, noise,
///   tolerances and mounts are kept. The unnamed families are zero, so the file is loaded by
///   `handclasp fk --cell`, `calibrate --cell` and `diagnose` like any cell;
/// - `effects.json` (the named effects), `report.json` (the whole report) and `report.txt`
///   ([`render_cell_text`]).
///
/// The session's nuisances (tracker frames, scales and drifts, planes, contact distances) are
/// not written into the cell: they belong to the recording, not to the robots. The input cell's
/// `[robotN.errors]` are not carried over either: the diagnosis fits from the URDFs and tips and
/// ignores them (as `calibrate --cell` does), so the written `[robotN.errors]` hold the named
/// compliance and joint-periodic terms only.
///
/// Returns the files written, in that order. Errors: an estimate of the wrong shape for `cell`
/// (a report of another cell), a URDF that cannot be read or corrected, a file that cannot be
/// written or does not read back.
///
/// **Do no harm.** The cell written holds the families the report's do-no-harm rule keeps
/// ([`CellDiagnoseReport::export_estimate`]: the placement, and the named families up to the
/// first whose model is worse than nominal in a held-out fold); the withheld ones are in
/// `report.json` (`do_no_harm.withheld`) and `report.txt`. [`export_cell_diagnosis_with`]
/// with `keep_withheld` writes the full model (`diagnose --export --force`).
pub fn export_cell_diagnosis(
    cell: &Cell,
    report: &CellDiagnoseReport,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    export_cell_diagnosis_with(cell, report, dir, false)
}

/// [`export_cell_diagnosis`], writing the full model (every named family, the do-no-harm rule
/// overridden) when `keep_withheld`.
///
/// Errors: as [`export_cell_diagnosis`].
pub fn export_cell_diagnosis_with(
    cell: &Cell,
    report: &CellDiagnoseReport,
    dir: &Path,
    keep_withheld: bool,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::ExportFolder {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut estimate = if keep_withheld {
        report.final_estimate.clone()
    } else {
        report.export_estimate.clone()
    };
    if !report.placement_fitted {
        estimate.b1_from_b2 = cell.b1_from_b2;
    }
    // Tools after tool 0 (`[robotN.tools]`): their fitted tips go into the cell's tool table;
    // `export_calibrated_cell` writes tool 0's as `tip_mm`.
    let mut with_tools = cell.clone();
    for (setup, correction) in [
        (&mut with_tools.robot1, &estimate.robot1),
        (&mut with_tools.robot2, &estimate.robot2),
    ] {
        if correction.tool_tip_m.len() != setup.tools.len() + 1 {
            return Err(DiagnoseError::Export {
                path: setup.urdf_path.clone(),
                message: format!(
                    "the diagnosis has {} tools for this robot, the cell {} (tip_mm and [robotN.tools]): export with the cell that was diagnosed",
                    correction.tool_tip_m.len(),
                    setup.tools.len() + 1
                ),
            });
        }
        for (tool, tip_error) in setup.tools.iter_mut().zip(&correction.tool_tip_m[1..]) {
            tool.flange_from_tip += tip_error;
        }
    }
    let mut written =
        export_calibrated_cell(&with_tools, &estimate, dir, &CELL_DIAGNOSIS_EXPORT_NAMES)?;
    let effects_path = dir.join("effects.json");
    write_json_checked(&effects_path, &report.effects)?;
    written.push(effects_path);
    let report_path = dir.join("report.json");
    write_json_checked(&report_path, report)?;
    written.push(report_path);
    let text_path = dir.join("report.txt");
    let text = render_cell_text(report);
    write_checked(&text_path, &text, |back, tmp| {
        if back == text {
            Ok(())
        } else {
            Err(DiagnoseError::Export {
                path: tmp.to_path_buf(),
                message: "the written report reads back different".into(),
            })
        }
    })?;
    written.push(text_path);
    Ok(written)
}

/// Writes `text` to a temporary file beside `path` (in the same folder, so that the rename is
/// atomic), reads it back, runs `check` on what was read, and only if that passes renames it to
/// `path`: nothing unchecked is ever written under the final name. On a failed check the
/// temporary file is removed and the check's error returned.
/// Writes `value` as pretty JSON to `path` through [`write_checked`], which reads it back as JSON.
fn write_json_checked<T: serde::Serialize + ?Sized>(
    path: &Path,
    value: &T,
) -> Result<(), DiagnoseError> {
    let text = serde_json::to_string_pretty(value).map_err(|source| DiagnoseError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    write_checked(path, &text, |back, tmp| {
        serde_json::from_str::<serde_json::Value>(back)
            .map(|_| ())
            .map_err(|source| DiagnoseError::Json {
                path: tmp.to_path_buf(),
                source,
            })
    })
}

fn write_checked<T>(
    path: &Path,
    text: &str,
    check: impl FnOnce(&str, &Path) -> Result<T, DiagnoseError>,
) -> Result<T, DiagnoseError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.partial"));
    std::fs::write(&tmp, text).map_err(|e| DiagnoseError::io(&tmp, e))?;
    let checked = std::fs::read_to_string(&tmp)
        .map_err(|e| DiagnoseError::io(&tmp, e))
        .and_then(|back| check(&back, &tmp));
    match checked {
        Ok(value) => {
            std::fs::rename(&tmp, path).map_err(|e| DiagnoseError::io(path, e))?;
            Ok(value)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// The files of the coincident export ([`export_corrected`]) and the header of its cell file.
pub const CORRECTED_EXPORT_NAMES: ExportNames<'static> = ExportNames {
    cell: "cell_corrected.toml",
    robot1_urdf: "robot1_corrected.urdf",
    robot2_urdf: "robot2_corrected.urdf",
    header: "# Written by `handclasp diagnose --export`: the extended model (corrected URDFs, tip offsets,\n\
             # calibrated b1_from_b2; joint scale and compliance as [robotN.errors]).\n",
};

/// Writes the extended model to `dir` through the one calibrated-cell exporter
/// ([`handclasp_cell::export_calibrated_cell`], names [`CORRECTED_EXPORT_NAMES`]):
/// `robot1_corrected.urdf`, `robot2_corrected.urdf` (joint origins and offsets patched into the
/// URDFs and verified), `cell_corrected.toml` (the calibrated `b1_from_b2`, corrected tip offsets,
/// URDF paths to the corrected files, and the joint-scale and compliance errors, which URDF cannot
/// express, as `[robotN.errors]`; the named mount tilts and joint-periodic terms are not written)
/// and `effects.json`. Returns the files written.
pub fn export_corrected(
    cell: &Cell,
    report: &DiagnoseReport,
    b1_from_b2: &Isometry3<f64>,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::ExportFolder {
        path: dir.to_path_buf(),
        source,
    })?;
    let (e1, e2) = effects_to_errors(cell, &report.effects);
    // The exporter writes tool 0's tip error as `tip_mm`, the URDF part into the URDFs and the
    // rest beside them: keep the URDF part, the joint scale and the compliance.
    let correction = |errors: &KinematicErrors| {
        let (mut kept, _) = split_for_urdf(errors);
        kept.joint_scale.clone_from(&errors.joint_scale);
        kept.compliance.clone_from(&errors.compliance);
        RobotCorrection {
            errors: kept,
            tool_tip_m: vec![errors.tip],
        }
    };
    let estimate = CellEstimate {
        b1_from_b2: *b1_from_b2,
        robot1: correction(&e1),
        robot2: correction(&e2),
        tracker_from_anchor: Vec::new(),
        tracker_scale: Vec::new(),
        tracker_drift_m: Vec::new(),
        planes: Vec::new(),
        contact_distance_m: Vec::new(),
    };
    let mut written = export_calibrated_cell(cell, &estimate, dir, &CORRECTED_EXPORT_NAMES)?;
    let eff_path = dir.join("effects.json");
    write_json_checked(&eff_path, &report.effects)?;
    written.push(eff_path);
    Ok(written)
}
