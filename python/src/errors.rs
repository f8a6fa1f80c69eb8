//! Rust errors → Python exceptions, with the CLI's messages ([`cli_support::error_chain_text`]).
//!
//! A chain that holds an `std::io::Error` is a file problem: `FileNotFoundError`,
//! `PermissionError`, `IsADirectoryError`, `FileExistsError` or `OSError`. Otherwise the caller chooses: invalid
//! input is `ValueError`, a fit that fails is [`CalibrationError`].

use pyo3::create_exception;
use pyo3::exceptions::{
    PyException, PyFileExistsError, PyFileNotFoundError, PyIsADirectoryError, PyOSError,
    PyPermissionError, PyValueError,
};
use pyo3::{PyErr, PyResult, Python};

create_exception!(
    handclasp,
    CalibrationError,
    PyException,
    "A calibration or diagnosis failed: the data cannot be fitted as given (too few or degenerate \
     points, residuals far beyond the stated noise, a solver that met non-finite values). The \
     message names the cause and the fix, as the CLI's does."
);

/// The I/O error in `err`'s source chain, if any.
fn io_kind(err: &(dyn std::error::Error + 'static)) -> Option<std::io::ErrorKind> {
    let mut cause: Option<&(dyn std::error::Error + 'static)> = Some(err);
    while let Some(c) = cause {
        if let Some(io) = c.downcast_ref::<std::io::Error>() {
            return Some(io.kind());
        }
        cause = c.source();
    }
    None
}

/// The `OSError` subclass of an I/O error kind, with `message`.
pub fn os_error(kind: std::io::ErrorKind, message: String) -> PyErr {
    use std::io::ErrorKind as K;
    match kind {
        K::NotFound => PyFileNotFoundError::new_err(message),
        K::PermissionDenied => PyPermissionError::new_err(message),
        K::IsADirectory => PyIsADirectoryError::new_err(message),
        K::AlreadyExists => PyFileExistsError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// What an error that is not a file problem becomes.
#[derive(Clone, Copy)]
pub enum Otherwise {
    /// `ValueError`: invalid input (a cell, a session, an option).
    Value,
    /// `handclasp.CalibrationError`: the fit failed.
    Calibration,
}

/// `err` as a Python exception: an `OSError` subclass when its chain holds an I/O error, else
/// `otherwise`; the message is the CLI's `error:` line without `error: `, prefixed by `context`
/// when given.
pub fn to_py(
    err: &(dyn std::error::Error + 'static),
    context: &str,
    otherwise: Otherwise,
) -> PyErr {
    let text = cli_support::error_chain_text(err);
    let message = if context.is_empty() {
        text
    } else {
        format!("{context}: {text}")
    };
    if let Some(kind) = io_kind(err) {
        return os_error(kind, message);
    }
    match otherwise {
        Otherwise::Value => PyValueError::new_err(message),
        Otherwise::Calibration => CalibrationError::new_err(message),
    }
}

/// `CalibrationError(reason)` for a result a check refused, as the CLI's `--json` refusal
/// object says it: the exception carries `status` (`"refused"`), `reason` (the message),
/// `refusal` (the CLI's refusal object as a dict, [`cli_support::result_check::Refusal`]) and
/// `result_check` / `misfit` (the check values behind it, or `None`).
pub fn refusal_error(
    py: pyo3::Python<'_>,
    refusal: &cli_support::result_check::Refusal<'_>,
) -> PyErr {
    let err = CalibrationError::new_err(refusal.reason.clone());
    let attach = || -> pyo3::PyResult<()> {
        use pyo3::types::PyAnyMethods;
        let value = err.value(py);
        let json = serde_json::to_string(refusal)
            .map_err(|e| PyValueError::new_err(format!("serialising the refusal: {e}")))?;
        let dict = crate::arrays::json_to_py(py, &json)?;
        value.setattr("status", refusal.status)?;
        value.setattr("reason", &refusal.reason)?;
        value.setattr("result_check", dict.get_item("result_check").ok())?;
        value.setattr("misfit", dict.get_item("misfit").ok())?;
        value.setattr("refusal", dict)?;
        Ok(())
    };
    match attach() {
        Ok(()) => err,
        Err(e) => e,
    }
}

/// `ValueError(message)`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// Issues `message` as a Python `UserWarning` (a NUL in it becomes a space), attributed to
/// the caller's line.
///
/// Errors: the warning filter turned it into an exception (`-W error`).
pub fn user_warning(py: Python<'_>, message: &str) -> PyResult<()> {
    let text = std::ffi::CString::new(message.replace('\0', " "))
        .map_err(|e| value_error(e.to_string()))?;
    PyErr::warn(
        py,
        &py.get_type::<pyo3::exceptions::PyUserWarning>(),
        &text,
        1,
    )
}
