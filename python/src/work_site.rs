//! The verdict's inputs from Python (`work_points`, `accept_mm`, `accept_deg`), read as the
//! CLI reads `--work-points`, `--accept-mm` and `--accept-deg`, and the page's invocation line.
//! The prediction and the page are the `report` crate's, the functions the CLI calls.

use std::path::PathBuf;

use nalgebra::Point3;
use pyo3::prelude::*;
use report::{read_work_points, work_site_points, Acceptance, Invocation};

use crate::arrays::rows;
use crate::errors::{to_py, Otherwise};

/// The verdict's inputs, checked.
pub struct SiteInputs {
    /// The work points (m, base 1) and where they come from (the page's and JSON's `source`).
    pub points: Vec<Point3<f64>>,
    /// Where the points come from.
    pub source: String,
    /// What the job accepts.
    pub acceptance: Acceptance,
}

impl SiteInputs {
    /// Reads `work_points` (None: the cell's `[teach]` centre; a path: the CLI's work-points
    /// CSV, header `x_mm,y_mm,z_mm`; else an (n, 3) array of tool positions in base 1, mm) and
    /// the acceptance. Errors: `ValueError` for a bad array, a bad threshold or a bad CSV row;
    /// `OSError` subclasses for an unreadable file.
    pub fn read(
        cell: &handclasp_cell::Cell,
        work_points: Option<&Bound<'_, PyAny>>,
        accept_mm: Option<f64>,
        accept_deg: Option<f64>,
    ) -> PyResult<SiteInputs> {
        let acceptance = Acceptance::new(accept_mm, accept_deg)
            .map_err(|e| to_py(&e, "accept_mm / accept_deg", Otherwise::Value))?;
        let (points, source) = match work_points {
            None => work_site_points(cell, None),
            Some(obj) => match obj.extract::<PathBuf>() {
                Ok(path) => {
                    let points = read_work_points(&path).map_err(|e| {
                        // The reader names the I/O error in its text only.
                        match std::fs::metadata(&path) {
                            Err(io) => crate::errors::os_error(
                                io.kind(),
                                format!("work_points: {}", cli_support::error_chain_text(&e)),
                            ),
                            Ok(_) => to_py(&e, "work_points", Otherwise::Value),
                        }
                    })?;
                    work_site_points(cell, Some((&path, &points)))
                }
                Err(_) => {
                    let (rows, _) = rows(
                        obj,
                        "work_points",
                        3,
                        "tool positions x, y, z in base 1, mm",
                    )?;
                    if rows.is_empty() {
                        return Err(crate::errors::value_error(
                            "work_points: no work point: give an (n, 3) array of tool positions \
                             in base 1, mm",
                        ));
                    }
                    let points: Vec<Point3<f64>> = rows
                        .iter()
                        .map(|r| Point3::new(r[0], r[1], r[2]) * 1e-3)
                        .collect();
                    let source = format!("{} points of the work_points array", points.len());
                    (points, source)
                }
            },
        };
        Ok(SiteInputs {
            points,
            source,
            acceptance,
        })
    }
}

/// The page's command line (`what`: the Python call) and version (`handclasp X.Y.Z (Python)`).
pub fn invocation(what: &str) -> Invocation {
    Invocation {
        command_line: format!("python: handclasp.{what}"),
        version: format!("handclasp {} (Python)", env!("CARGO_PKG_VERSION")),
    }
}

/// A file's path as the page names it (`given` when the object was not read from a file).
pub fn shown(path: Option<&std::path::Path>, given: &str) -> String {
    path.map(|p| p.display().to_string())
        .unwrap_or_else(|| given.to_string())
}
