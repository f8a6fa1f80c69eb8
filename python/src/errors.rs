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
use pyo3::PyErr;

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

/// `ValueError(message)`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}
