//! The crate's error type.

use std::path::PathBuf;

/// Errors of sim-cell: each names the file, key, row or teach point at fault and says what would work.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A session input of the simulator (a teach-points CSV) is invalid; `message` names the
    /// row/column and the fix. (The cell and session files' own errors are
    /// [`SimError::Format`].)
    #[error("session {path}: {message}")]
    Session {
        /// The session file.
        path: PathBuf,
        /// What is wrong, naming the row or column, and what would work.
        message: String,
    },
    /// A cell or session file is invalid, or could not be read or written
    /// ([`handclasp_cell::FormatError`]).
    #[error(transparent)]
    Format(#[from] handclasp_cell::FormatError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A plot could not be drawn into its file.
    #[error("{path}: cannot draw the plot: {message}")]
    Plot {
        /// The SVG file.
        path: PathBuf,
        /// The plotting library's message.
        message: String,
    },
    /// A teach point that one of the robots cannot reach.
    #[error("teach point {point} at ({:.1}, {:.1}, {:.1}) mm in b1 is outside the common workspace: {message}", p_b1_mm[0], p_b1_mm[1], p_b1_mm[2])]
    Unreachable {
        /// 1-based teach point number.
        point: usize,
        /// The point, mm, robot 1's base frame.
        p_b1_mm: [f64; 3],
        /// Which robot failed and what would work.
        message: String,
    },
    /// An invalid argument (spec, grid axis, option): the message names it and what would work.
    #[error("{0}")]
    InvalidInput(String),
    /// A setting of a configuration struct is out of range: `field` is its name in the struct
    /// (e.g. [`crate::sweep::SweepConfig::trials`]), `message` what is wrong and what would work.
    #[error("{field} {message}")]
    InvalidSetting {
        /// The field's name.
        field: &'static str,
        /// What is wrong and what would work (follows the field name in the message).
        message: String,
    },
}

impl SimError {
    /// Shorthand for [`SimError::Io`].
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        SimError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
