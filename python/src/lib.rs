//! The native module `handclasp._handclasp` of the Python package (python/handclasp wraps it).
//!
//! One binding per engine entry point, each a thin shell: numpy arrays in file units (mm,
//! degrees) → SI → the library the CLI uses → its typed report, serialised by serde to the CLI's
//! JSON. Long calls run with the GIL released ([`Python::detach`]). Errors become Python
//! exceptions (`errors`): bad arrays and invalid input `ValueError`, files `OSError`
//! subclasses, a fit that fails `handclasp.CalibrationError`.
//!
//! Modules: `errors` (the mapping), `arrays` (numpy in and out), `points`
//! (`calibrate_points`), `robot` (`Robot`, `fk`), `cell` (`Cell`, `Session`),
//! `calibrate` (`calibrate_cell`, `diagnose`), `sim` (`simulate_session`, `plan`, `sweep`),
//! `outputs` (`export_controllers`), `validate` (`validate`), `work_site` (the verdict's inputs and the page's invocation).

use pyo3::prelude::*;

mod arrays;
mod calibrate;
mod cell;
mod errors;
mod outputs;
mod points;
mod robot;
mod sim;
mod validate;
mod work_site;

/// The native module: classes, functions and `CalibrationError`.
#[pymodule]
fn _handclasp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "CalibrationError",
        py.get_type::<errors::CalibrationError>(),
    )?;
    m.add_class::<robot::Robot>()?;
    m.add_class::<cell::Cell>()?;
    m.add_class::<cell::Session>()?;
    m.add_class::<points::PointsResult>()?;
    m.add_class::<points::PointsMethods>()?;
    m.add_class::<calibrate::CellResult>()?;
    m.add_class::<calibrate::DiagnoseResult>()?;
    m.add_class::<sim::PlanResult>()?;
    m.add_class::<validate::ValidateResult>()?;
    m.add_function(wrap_pyfunction!(points::calibrate_points, m)?)?;
    m.add_function(wrap_pyfunction!(robot::fk, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate_cell, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(sim::simulate_session, m)?)?;
    m.add_function(wrap_pyfunction!(sim::plan, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(cell::import_session, m)?)?;
    m.add_function(wrap_pyfunction!(outputs::export_controllers, m)?)?;
    m.add_function(wrap_pyfunction!(validate::validate, m)?)?;
    Ok(())
}
