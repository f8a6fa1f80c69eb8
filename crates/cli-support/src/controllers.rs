//! The controller and ROS 2 export of a cell's placement, shared by `handclasp export` and the
//! Python package's `handclasp.export_controllers`: one typed report ([`ExportReport`]), printed
//! as JSON or as the text table ([`render_text`]), so both show the same numbers.
//!
//! Units: the report's placement forms are in each target's own convention (see
//! [`PlacementFormats`]); read-back differences in µm and µrad.

use std::path::Path;

use handclasp_cell::export_formats::{
    export_placement, ControllerFormat, PlacementFormats, READ_BACK_TOL_M, READ_BACK_TOL_RAD,
};
use handclasp_cell::{Cell, FormatError};
use serde::Serialize;

use crate::export_dir::{check_output_folder, OutputFolderError};

/// One written file in the report.
#[derive(Debug, Clone, Serialize)]
pub struct FileReport {
    /// The file.
    pub path: String,
    /// Its target (`abb`, …).
    pub format: &'static str,
    /// Translation difference when read back, µm.
    pub read_back_um: f64,
    /// Rotation difference when read back, µrad.
    pub read_back_urad: f64,
}

/// What an export did: one struct, printed as JSON (`handclasp export --json`, Python's dict)
/// or as a table ([`render_text`]).
#[derive(Debug, Clone, Serialize)]
pub struct ExportReport {
    /// The cell file, as the caller named it.
    pub cell: String,
    /// The output folder.
    pub to: String,
    /// b1_from_b2 in each target's convention.
    pub formats: PlacementFormats,
    /// The files written, each read back within 1 µm and 1 µrad.
    pub files: Vec<FileReport>,
    /// What the files cannot carry (the CLI also prints them on stderr as `warning:` lines).
    pub warnings: Vec<String>,
}

/// Why an export was not written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ControllersError {
    /// The output folder is refused (not empty without `force`, unreadable).
    #[error(transparent)]
    Folder(#[from] OutputFolderError),
    /// A file could not be written or read back, or another export holds the folder's lock.
    #[error(transparent)]
    Format(#[from] FormatError),
}

/// Writes `cell`'s placement `b1_from_b2` for `formats` into `to` (created if missing) under the
/// folder's export lock ([`handclasp_cell::output::with_export_lock`]), each file read back and
/// checked, and returns the report. `source` names the cell in the files and the report;
/// `flag` / `force_name` name the caller's folder option and its overwrite option in messages
/// (`--to`, `--force`; Python passes its argument names).
///
/// Errors: a non-empty `to` without `force`, a concurrent export into `to`, a file that cannot
/// be written or does not read back ([`ControllersError`]); a failed export leaves none of its
/// files.
pub fn export_controllers(
    cell: &Cell,
    source: &str,
    to: &Path,
    formats: &[ControllerFormat],
    force: bool,
    (flag, force_name): (&str, &str),
) -> Result<ExportReport, ControllersError> {
    check_output_folder(to, force, flag, force_name)?;
    let mut formats = formats.to_vec();
    formats.sort();
    formats.dedup();
    let out = handclasp_cell::output::with_export_lock(to, force, flag, || {
        export_placement(cell, source, to, &formats)
    })?;
    Ok(ExportReport {
        cell: source.to_string(),
        to: to.display().to_string(),
        formats: out.formats,
        files: out
            .files
            .iter()
            .map(|f| FileReport {
                path: f.path.display().to_string(),
                format: f.format.name(),
                read_back_um: f.translation_error_m * 1e6,
                read_back_urad: f.rotation_error_rad * 1e6,
            })
            .collect(),
        warnings: out.warnings,
    })
}

/// The readable table of `report` (what `handclasp export` prints without `--json`).
pub fn render_text(report: &ExportReport) -> String {
    let mut s = format!(
        "b1_from_b2 (robot 2's base in robot 1's base) of {}, written to {}:\n",
        report.cell, report.to
    );
    let f = &report.formats;
    let row = |name: &str, a: String, b: String| format!("  {name:<8} {a}   {b}\n");
    if let Some(v) = f.abb {
        s += &row(
            "ABB",
            format!("x y z (m)  {:.9} {:.9} {:.9}", v.x_m, v.y_m, v.z_m),
            format!(
                "q1 q2 q3 q4  {:.12} {:.12} {:.12} {:.12}",
                v.q1, v.q2, v.q3, v.q4
            ),
        );
    }
    if let Some(v) = f.kuka {
        s += &row(
            "KUKA",
            format!("X Y Z (mm)  {:.6} {:.6} {:.6}", v.x_mm, v.y_mm, v.z_mm),
            format!("A B C (deg)  {:.9} {:.9} {:.9}", v.a_deg, v.b_deg, v.c_deg),
        );
    }
    if let Some(v) = f.fanuc {
        s += &row(
            "Fanuc",
            format!("X Y Z (mm)  {:.6} {:.6} {:.6}", v.x_mm, v.y_mm, v.z_mm),
            format!("W P R (deg)  {:.9} {:.9} {:.9}", v.w_deg, v.p_deg, v.r_deg),
        );
    }
    if let Some(v) = f.yaskawa {
        s += &row(
            "Yaskawa",
            format!("X Y Z (mm)  {:.6} {:.6} {:.6}", v.x_mm, v.y_mm, v.z_mm),
            format!(
                "Rx Ry Rz (deg)  {:.9} {:.9} {:.9}",
                v.rx_deg, v.ry_deg, v.rz_deg
            ),
        );
    }
    if let Some(v) = f.ros2 {
        s += &row(
            "ROS 2",
            format!("x y z (m)  {:.9} {:.9} {:.9}", v.x_m, v.y_m, v.z_m),
            format!(
                "qx qy qz qw  {:.12} {:.12} {:.12} {:.12}",
                v.qx, v.qy, v.qz, v.qw
            ),
        );
    }
    s += &format!(
        "files (each parsed back and within {} µm / {} µrad of the placement before it was kept):\n",
        READ_BACK_TOL_M * 1e6,
        READ_BACK_TOL_RAD * 1e6
    );
    for file in &report.files {
        s += &format!(
            "  {:<8} {}   read back {:.2e} µm {:.2e} µrad\n",
            file.format, file.path, file.read_back_um, file.read_back_urad
        );
    }
    s += "what to type where: docs/guide/export.md\n";
    s
}
