//! `export_controllers`: a cell's placement for the robot controllers and ROS 2, as
//! `handclasp export` writes it (the same files, the same report).

use std::path::PathBuf;

use cli_support::controllers::{export_controllers as export, ControllersError};
use cli_support::export_dir::OutputFolderError;
use handclasp_cell::export_formats::ControllerFormat;
use handclasp_cell::FormatError;
use pyo3::prelude::*;

use crate::arrays::json_to_py;
use crate::cell::Cell;
use crate::errors::{os_error, to_py, value_error, Otherwise};

/// Writes the cell's `b1_from_b2` (robot 2's base in robot 1's base) for the controllers and
/// ROS 2 into the folder `to`, as `handclasp export --cell CELL --to TO --format …` does: ABB
/// (m, quaternion), KUKA (mm, A B C deg), Fanuc (mm, W P R deg), Yaskawa (mm, Rx Ry Rz deg) and
/// ROS 2 (cell URDF, xacro properties, launch file), each file parsed back and checked before
/// it is kept. `formats`: names among `abb`, `kuka`, `fanuc`, `yaskawa`, `ros2` (default: all).
/// For a calibrated cell, load the `cell.toml` that `CellResult.export` wrote.
///
/// Returns the report as a dict, equal to `json.loads` of `handclasp export … --json`.
/// Errors: `ValueError` for an unknown format; `FileExistsError` for a folder that is not empty
/// (unless `force=True`) or that another export is writing into; other `OSError` subclasses when
/// a file cannot be written.
#[pyfunction]
#[pyo3(signature = (cell, to, formats=None, force=false))]
pub fn export_controllers<'py>(
    py: Python<'py>,
    cell: &Cell,
    to: PathBuf,
    formats: Option<Vec<String>>,
    force: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let formats = match formats {
        None => ControllerFormat::ALL.to_vec(),
        Some(names) => names
            .iter()
            .map(|n| {
                ControllerFormat::from_name(n).ok_or_else(|| {
                    let known: Vec<&str> = ControllerFormat::ALL.iter().map(|f| f.name()).collect();
                    value_error(format!(
                        "formats: unknown target {n:?}; choose among {}",
                        known.join(", ")
                    ))
                })
            })
            .collect::<PyResult<Vec<_>>>()?,
    };
    let source = cell
        .path
        .as_ref()
        .map_or_else(|| "the cell".to_string(), |p| p.display().to_string());
    let report = py
        .detach(|| {
            export(
                &cell.cell,
                &source,
                &to,
                &formats,
                force,
                ("to", "force=True"),
            )
        })
        .map_err(|e| match &e {
            ControllersError::Folder(OutputFolderError::NotEmpty { .. })
            | ControllersError::Format(FormatError::OutputFolder { .. }) => {
                os_error(std::io::ErrorKind::AlreadyExists, e.to_string())
            }
            _ => to_py(
                &e,
                &format!("exporting {source} to {}", to.display()),
                Otherwise::Value,
            ),
        })?;
    let json = serde_json::to_string(&report).map_err(|e| value_error(e.to_string()))?;
    json_to_py(py, &json)
}
