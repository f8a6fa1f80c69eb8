//! Writing a calibrated cell: corrected URDFs (the URDF-expressible corrections — joint offsets,
//! origin xyz/rpy) and a cell TOML (the fitted `b1_from_b2`, corrected tips, and in
//! `[robotN.errors]` what a URDF cannot hold: joint scale, compliance). Used by
//! `handclasp calibrate --cell --export` and the `ctu_motoman` study.

use std::path::{Path, PathBuf};

use calib_core::whole_cell::CellEstimate;
use calib_core::Robot;
use kinematics::{patch_urdf_text, split_for_urdf, verify_patched_urdf, RobotModel};

use crate::cell::Cell;
use crate::error::SimError;

/// The files [`export_calibrated_cell`] writes, relative to its output folder, and the comment
/// put at the top of the cell file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExportNames<'a> {
    /// The cell file, e.g. `cell.toml`.
    pub cell: &'a str,
    /// Robot 1's corrected URDF, e.g. `robot1.urdf`.
    pub robot1_urdf: &'a str,
    /// Robot 2's corrected URDF, e.g. `robot2.urdf`.
    pub robot2_urdf: &'a str,
    /// Comment lines (each starting with `#`, ending with a newline) written before the TOML.
    pub header: &'a str,
}

/// The names `handclasp calibrate --cell --export DIR` uses: `robot1.urdf`, `robot2.urdf`,
/// `cell.toml`.
pub const CALIBRATE_EXPORT_NAMES: ExportNames<'static> = ExportNames {
    cell: "cell.toml",
    robot1_urdf: "robot1.urdf",
    robot2_urdf: "robot2.urdf",
    header: "# Written by `handclasp calibrate --cell --export`: the calibrated cell (fitted b1_from_b2,\n\
             # corrected URDFs robot1.urdf / robot2.urdf and tip offsets; [robotN.errors] holds only what a\n\
             # URDF cannot express). A session recorded with the old models has their tip columns, which\n\
             # these models reject (record a new session, or use the old cell for it).\n",
};

/// Writes the calibrated `cell` into `dir` (created if missing): each robot's URDF corrected by
/// the URDF-expressible part of `estimate`'s corrections ([`split_for_urdf`]), and the cell file
/// with `estimate.b1_from_b2`, the tips corrected by tool 0's tip error (tool 0 = the cell's tip,
/// as [`crate::whole_cell::cell_problem`] builds it), the rest of each robot's errors (joint
/// scale, compliance) as `[robotN.errors]`, and robot 2's gravity rotated by the fitted placement.
/// Each URDF is written to a temporary file, re-loaded, verified against the fitted model
/// ([`verify_patched_urdf`], flange within [`kinematics::PATCH_TOLERANCE_M`]) and renamed into
/// place; the cell file is written the same way and re-loaded. Returns the files written (the two
/// URDFs, then the cell).
///
/// Errors: `estimate` of the wrong shape for `cell` (joint counts, no tool 0), a URDF that cannot
/// be read or corrected ([`SimError::Cell`] naming the robot and file), any file that cannot be
/// written ([`SimError::Io`]), a written cell that does not load.
pub fn export_calibrated_cell(
    cell: &Cell,
    estimate: &CellEstimate,
    dir: &Path,
    names: &ExportNames<'_>,
) -> Result<Vec<PathBuf>, SimError> {
    std::fs::create_dir_all(dir).map_err(|e| SimError::io(dir, e))?;
    let mut out = cell.clone();
    out.base_dir = dir.to_path_buf();
    out.b1_from_b2 = estimate.b1_from_b2;
    let mut written = Vec::new();
    for robot in [Robot::One, Robot::Two] {
        let setup = cell.robot(robot);
        let correction = estimate.robot(robot);
        let bad = |message: String| SimError::Cell {
            path: setup.urdf_path.clone(),
            message: format!("{robot}: {message}"),
        };
        let Some(tip_error) = correction.tool_tip_m.first() else {
            return Err(bad(
                "the estimate has no tool 0 (the cell's tip); build it from this cell's problem"
                    .into(),
            ));
        };
        let (urdf_part, rest) = split_for_urdf(&correction.errors);
        let xml = std::fs::read_to_string(&setup.urdf_path)
            .map_err(|e| SimError::io(&setup.urdf_path, e))?;
        let patched = patch_urdf_text(&xml, &setup.model, &urdf_part)
            .map_err(|e| bad(format!("cannot write the corrected URDF: {e}")))?;
        let file = match robot {
            Robot::One => names.robot1_urdf,
            Robot::Two => names.robot2_urdf,
        };
        let path = dir.join(file);
        let tmp = path.with_extension("urdf.tmp");
        std::fs::write(&tmp, &patched).map_err(|e| SimError::io(&tmp, e))?;
        let reread = std::fs::read_to_string(&tmp).map_err(|e| SimError::io(&tmp, e))?;
        verify_patched_urdf(&reread, &setup.model, &urdf_part)
            .map_err(|e| bad(format!("verifying {}: {e}", tmp.display())))?;
        let model = RobotModel::from_urdf_file(&tmp, &setup.tool_link)
            .map_err(|e| bad(format!("re-loading {}: {e}", tmp.display())))?;
        std::fs::rename(&tmp, &path).map_err(|e| SimError::io(&path, e))?;
        written.push(path.clone());
        let r = if robot == Robot::One {
            &mut out.robot1
        } else {
            &mut out.robot2
        };
        r.model = model;
        r.urdf = file.to_string();
        r.urdf_path = path;
        r.flange_from_tip = setup.flange_from_tip + tip_error;
        // What a URDF cannot hold (scale, compliance; tips are in tip_mm, mounts are never fitted).
        r.errors = rest;
    }
    // Robot 2's gravity follows the calibrated placement.
    out.robot2.g_base = out.b1_from_b2.rotation.inverse() * out.robot1.g_base;
    let cell_path = dir.join(names.cell);
    let text = format!("{}{}", names.header, out.to_toml_string());
    let tmp = cell_path.with_extension("tmp");
    std::fs::write(&tmp, text).map_err(|e| SimError::io(&tmp, e))?;
    std::fs::rename(&tmp, &cell_path).map_err(|e| SimError::io(&cell_path, e))?;
    Cell::from_toml_file(&cell_path)?;
    written.push(cell_path);
    Ok(written)
}
