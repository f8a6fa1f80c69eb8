//! The crate's error type.

use std::path::PathBuf;

/// Errors of the file formats: each names the file, key, row or column at fault and says what
/// would work.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    /// A cell file (TOML) is invalid; `message` names the key and the fix.
    #[error("cell {path}: {message}")]
    Cell {
        /// The cell file (or `<string>` for text without a file).
        path: PathBuf,
        /// What is wrong, naming the key, and what would work.
        message: String,
    },
    /// A session CSV is invalid; `message` names the row/column and the fix.
    #[error("session {path}: {message}")]
    Session {
        /// The session file.
        path: PathBuf,
        /// What is wrong, naming the row or column, and what would work.
        message: String,
    },
    /// A session that reads but fails the input checks every command shares
    /// ([`crate::session::check_session_inputs`]).
    #[error("session {path}: {source}")]
    SessionCheck {
        /// The session file (`<session>` for one in memory).
        path: PathBuf,
        /// What is wrong and the fix.
        #[source]
        source: crate::session::SessionCheckError,
    },
    /// An import mapping file is invalid; `message` names the key and the fix.
    #[error("{path}: {message}")]
    Map {
        /// The mapping file.
        path: PathBuf,
        /// What is wrong, naming the key, and what would work.
        message: String,
    },
    /// An input file of an import cannot be converted; `message` names the line and column.
    #[error("{path}: {message}")]
    Input {
        /// The input file.
        path: PathBuf,
        /// What is wrong, naming the line and column, and what would work.
        message: String,
    },
    /// An exported file that does not read back to what was meant to be written (a defect of the
    /// writer or the parser, never expected); the file is not left in place.
    #[error("export {path}: {message}")]
    Export {
        /// The file that was to be written.
        path: PathBuf,
        /// What reading it back found.
        message: String,
    },
    /// An input file is over the input limit, binary or not UTF-8 (`kinematics::input`).
    #[error(transparent)]
    InputFile(#[from] kinematics::input::InputError),
    /// An export folder is locked by another export, or not empty under the lock
    /// ([`crate::output::with_export_lock`]).
    #[error("{path}: {message}")]
    OutputFolder {
        /// The folder.
        path: PathBuf,
        /// What is wrong and the fix.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
}

impl FormatError {
    /// An input file read within the toolkit's bounds ([`kinematics::input::read_input_text`]):
    /// an I/O failure is [`FormatError::Io`], the others [`FormatError::Input`].
    pub(crate) fn input(e: kinematics::input::InputError) -> Self {
        match e {
            kinematics::input::InputError::Io { path, source } => FormatError::Io { path, source },
            other => FormatError::InputFile(other),
        }
    }

    /// Shorthand for [`FormatError::Io`].
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        FormatError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
