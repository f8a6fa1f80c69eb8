//! The output-folder rule shared by `calibrate --cell --export`, `diagnose --export`,
//! `export --to` and the Python package's `.export(dir)`: a folder that exists and is not empty
//! is refused (before any work runs) unless forced.

use std::path::{Path, PathBuf};

/// Why an output folder is refused ([`check_output_folder`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputFolderError {
    /// The folder cannot be read (it may be a file).
    #[error("{flag} {}: cannot read the folder (is it a file?)", path.display())]
    Unreadable {
        /// How the caller names the folder's option (`--export`).
        flag: String,
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The folder holds files and the caller did not force.
    #[error(
        "{flag} {}: the folder is not empty (it holds `{first}`{}): choose a new or empty folder, \
         or add {force} to overwrite the files of the same names",
        path.display(),
        if *more { " and more" } else { "" }
    )]
    NotEmpty {
        /// How the caller names the folder's option.
        flag: String,
        /// The folder.
        path: PathBuf,
        /// The first entry found.
        first: String,
        /// More entries than the first.
        more: bool,
        /// How the caller names the option that forces (`--force`).
        force: String,
    },
}

/// Refuses an output folder `dir` that exists and is not empty, unless `force`: an export writes
/// files of fixed names, and a folder with another export's files would mix two models. Checked
/// before the fit or diagnosis runs (it can take minutes). `flag` and `force_name` name the
/// caller's options in the message (`--export`, `--force`).
pub fn check_output_folder(
    dir: &Path,
    force: bool,
    flag: &str,
    force_name: &str,
) -> Result<(), OutputFolderError> {
    let unreadable = |source| OutputFolderError::Unreadable {
        flag: flag.to_string(),
        path: dir.to_path_buf(),
        source,
    };
    let mut entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(unreadable(e)),
    };
    if force {
        return Ok(());
    }
    if let Some(first) = entries.next() {
        let first = first.map_err(unreadable)?;
        return Err(OutputFolderError::NotEmpty {
            flag: flag.to_string(),
            path: dir.to_path_buf(),
            first: first.file_name().to_string_lossy().into_owned(),
            more: entries.next().is_some(),
            force: force_name.to_string(),
        });
    }
    Ok(())
}
