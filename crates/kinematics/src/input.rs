//! Reading the toolkit's text inputs within bounds: a size limit checked before the file is read
//! (an input over it is refused, never read whole), a refusal of binary data, and a cap on how
//! much of an input's text an error message may echo.
//!
//! Every reader of a user's file (points CSV, session CSV, URDF, cell TOML, import map and
//! inputs) goes through [`read_input_text`], so they share one limit, one binary rule and one
//! wording.

use std::io::Read as _;
use std::path::{Path, PathBuf};

/// The default size limit of one input file, MB (10^6 bytes): a session of 100 000 rows is ~20 MB.
pub const DEFAULT_MAX_INPUT_MB: u64 = 64;

/// The environment variable that overrides [`DEFAULT_MAX_INPUT_MB`] (a whole number of MB ≥ 1).
pub const MAX_INPUT_ENV: &str = "HANDCLASP_MAX_INPUT_MB";

/// How many leading bytes are searched for a NUL byte (no text input of the toolkit has one).
pub const BINARY_PROBE_BYTES: usize = 8192;

/// The most characters of an input's text an error message echoes ([`cap_echo`]).
pub const ECHO_MAX_CHARS: usize = 200;

/// Why an input file was not read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InputError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read the file: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is larger than the limit; it was not read.
    #[error(
        "{path}: the file is {size_mb:.1} MB, over the input limit of {limit_mb} MB; it was not read. \
         Fix: check that this is the file you meant, or lift the limit with the environment \
         variable {MAX_INPUT_ENV}=<MB> (e.g. {MAX_INPUT_ENV}={suggest})"
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size, MB (10^6 bytes).
        size_mb: f64,
        /// The limit in force, MB.
        limit_mb: u64,
        /// A limit that would admit it, MB.
        suggest: u64,
    },
    /// The file holds a NUL byte in its first [`BINARY_PROBE_BYTES`] bytes: it is binary data,
    /// not the text file expected.
    #[error(
        "{path}: the file is binary (a NUL byte at byte {offset}), not a text file; give the {what} \
         as text (CSV, TOML or URDF XML as documented in docs/formats.md)"
    )]
    Binary {
        /// The file.
        path: PathBuf,
        /// What the file should have been (`points CSV`, `session CSV`, …).
        what: String,
        /// The 0-based offset of the first NUL byte.
        offset: usize,
    },
    /// The file is not UTF-8 text.
    #[error(
        "{path}: the file is not UTF-8 text (invalid byte at {offset}); save the {what} as UTF-8"
    )]
    NotUtf8 {
        /// The file.
        path: PathBuf,
        /// What the file should have been.
        what: String,
        /// The offset of the first invalid byte.
        offset: usize,
    },
    /// [`MAX_INPUT_ENV`] is set but is not a whole number of MB ≥ 1.
    #[error("{MAX_INPUT_ENV}=`{value}` is not a whole number of MB ≥ 1; unset it (default {DEFAULT_MAX_INPUT_MB} MB) or give e.g. {MAX_INPUT_ENV}=256")]
    BadLimit {
        /// The variable's text (capped).
        value: String,
    },
}

/// The input limit in force, MB: [`MAX_INPUT_ENV`] when set, else [`DEFAULT_MAX_INPUT_MB`].
///
/// # Errors
/// [`InputError::BadLimit`] when the variable is set but not a whole number ≥ 1.
pub fn max_input_mb() -> Result<u64, InputError> {
    match std::env::var(MAX_INPUT_ENV) {
        Err(_) => Ok(DEFAULT_MAX_INPUT_MB),
        Ok(v) => match v.trim().parse::<u64>() {
            Ok(mb) if mb >= 1 => Ok(mb),
            _ => Err(InputError::BadLimit {
                value: cap_echo(&v),
            }),
        },
    }
}

/// Reads the text file `path` within the limit of [`max_input_mb`]: its size is checked before
/// it is read (an oversized file is never read), its first [`BINARY_PROBE_BYTES`] bytes must hold
/// no NUL byte, and it must be UTF-8. `what` names the file's role in messages (`points CSV`).
///
/// # Errors
/// [`InputError`]: unreadable, over the limit, binary, not UTF-8, or a bad limit variable.
pub fn read_input_text(path: &Path, what: &str) -> Result<String, InputError> {
    read_input_text_within(path, what, max_input_mb()?)
}

/// [`read_input_text`] with an explicit limit, MB.
///
/// # Errors
/// As [`read_input_text`].
pub fn read_input_text_within(
    path: &Path,
    what: &str,
    limit_mb: u64,
) -> Result<String, InputError> {
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let limit = limit_mb.saturating_mul(1_000_000);
    let too_large = |size: u64| InputError::TooLarge {
        path: path.to_path_buf(),
        size_mb: size as f64 / 1e6,
        limit_mb,
        suggest: size.div_ceil(1_000_000).max(limit_mb + 1),
    };
    let meta = file.metadata().map_err(io)?;
    if meta.is_file() && meta.len() > limit {
        return Err(too_large(meta.len()));
    }
    // Read at most one byte past the limit (a pipe or a file growing meanwhile has no size).
    let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    check_text(bytes, path, what)
}

/// Text from `bytes` read from `path`: no NUL byte in the first [`BINARY_PROBE_BYTES`], UTF-8.
fn check_text(bytes: Vec<u8>, path: &Path, what: &str) -> Result<String, InputError> {
    if let Some(offset) = bytes.iter().take(BINARY_PROBE_BYTES).position(|&b| b == 0) {
        return Err(InputError::Binary {
            path: path.to_path_buf(),
            what: what.into(),
            offset,
        });
    }
    String::from_utf8(bytes).map_err(|e| InputError::NotUtf8 {
        path: path.to_path_buf(),
        what: what.into(),
        offset: e.utf8_error().valid_up_to(),
    })
}

/// `text` as an error message may echo it: unchanged up to [`ECHO_MAX_CHARS`] characters, else
/// its first [`ECHO_MAX_CHARS`] characters, `…` and its length (`… (20000000 bytes)`).
pub fn cap_echo(text: &str) -> String {
    match text.char_indices().nth(ECHO_MAX_CHARS) {
        None => text.to_string(),
        Some((cut, _)) => format!("{}… ({} bytes)", &text[..cut], text.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bytes` written to `name` in a fresh temporary folder, removed when the returned guard
    /// drops (a fixed folder under the system's temp dir was left behind by every run).
    fn temp_file(name: &str, bytes: &[u8]) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        (dir, path)
    }

    #[test]
    fn reads_text_within_the_limit() {
        let (_dir, path) = temp_file("ok.csv", b"a,b\n1,2\n");
        assert_eq!(
            read_input_text_within(&path, "points CSV", 1).unwrap(),
            "a,b\n1,2\n"
        );
    }

    /// A file over the limit is refused from its size, naming the limit, the size and the fix.
    #[test]
    fn oversized_file_is_refused_naming_limit_size_and_variable() {
        let (_dir, path) = temp_file("big.csv", &vec![b'1'; 1_500_000]);
        let msg = read_input_text_within(&path, "points CSV", 1)
            .unwrap_err()
            .to_string();
        for want in ["1.5 MB", "limit of 1 MB", MAX_INPUT_ENV, "big.csv", "=2"] {
            assert!(msg.contains(want), "{want}: {msg}");
        }
    }

    #[test]
    fn binary_and_non_utf8_files_are_refused() {
        let (_dir, path) = temp_file("zeros.csv", &[b'a', 0, 0, 0]);
        let e = read_input_text_within(&path, "session CSV", 1).unwrap_err();
        assert!(matches!(e, InputError::Binary { offset: 1, .. }), "{e}");
        assert!(e.to_string().contains("session CSV"), "{e}");
        let (_dir, path) = temp_file("latin1.csv", &[b'a', 0xe9, b'\n']);
        let e = read_input_text_within(&path, "points CSV", 1).unwrap_err();
        assert!(matches!(e, InputError::NotUtf8 { offset: 1, .. }), "{e}");
    }

    #[test]
    fn echo_is_capped_with_the_length() {
        assert_eq!(cap_echo("short"), "short");
        let long = "é".repeat(ECHO_MAX_CHARS + 10);
        let capped = cap_echo(&long);
        assert_eq!(
            capped.chars().count(),
            ECHO_MAX_CHARS + 1 + " (420 bytes)".len()
        );
        assert!(capped.ends_with("… (420 bytes)"), "{capped}");
    }
}
