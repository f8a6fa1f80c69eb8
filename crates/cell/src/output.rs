//! Writing the toolkit's outputs so that no reader ever sees half a file or half an export:
//! [`write_atomically`] writes a file under a temporary name in its folder and renames it (a
//! rename within one folder is atomic), and [`with_export_lock`] holds an export folder's lock
//! file while a multi-file export is written, refuses a second writer, and removes what a failed
//! export wrote.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::FormatError;

/// The lock file an export holds in its folder while it writes.
pub const EXPORT_LOCK_NAME: &str = ".handclasp-export.lock";

/// Distinguishes the temporary names of one process's writes.
static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically: into `.<name>.<pid>.<n>.tmp` beside it (created new,
/// flushed to disk), then renamed over `path`. An interrupted or failed write leaves `path` as it
/// was (absent or the previous file), never truncated; the temporary file is removed on failure.
///
/// # Errors
/// [`FormatError::Io`] naming the file that could not be written or renamed.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), FormatError> {
    write_atomically_with(path, |w| {
        w.write_all(bytes).map_err(|e| FormatError::io(path, e))
    })
}

/// [`write_atomically`] for output produced as it is written: `write` streams into a buffered
/// writer on the temporary file beside `path` (so a large output is never held in memory), then
/// the file is flushed to disk and renamed over `path`. When `write` fails, or the file cannot be
/// written or renamed, the temporary file is removed and `path` is left as it was.
///
/// # Errors
/// `write`'s error, or [`FormatError::Io`] (converted into `E`) naming the file that could not be
/// created, written or renamed.
///
/// # Examples
/// ```
/// use std::io::Write;
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("poses.csv");
/// handclasp_cell::output::write_atomically_with(&path, |w| -> Result<(), Box<dyn std::error::Error>> {
///     writeln!(w, "x_mm")?;
///     Ok(())
/// })
/// .unwrap();
/// assert_eq!(std::fs::read_to_string(&path).unwrap(), "x_mm\n");
/// ```
pub fn write_atomically_with<E: From<FormatError>>(
    path: &Path,
    write: impl FnOnce(&mut dyn std::io::Write) -> Result<(), E>,
) -> Result<(), E> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let tmp = path.with_file_name(format!(
        ".{name}.{}.{}.tmp",
        std::process::id(),
        TMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| E::from(FormatError::io(path, e)))?;
    let mut out = std::io::BufWriter::new(file);
    let written = write(&mut out).and_then(|()| {
        let file = out
            .into_inner()
            .map_err(|e| E::from(FormatError::io(path, e.into_error())))?;
        file.sync_all()
            .map_err(|e| E::from(FormatError::io(path, e)))
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        E::from(FormatError::io(path, e))
    })
}

/// Runs `write` (a multi-file export into `dir`) while holding `dir`'s lock file
/// [`EXPORT_LOCK_NAME`], created with `create_new` (the folder is created first when missing).
///
/// - A second export into the same folder meanwhile is refused ([`FormatError::OutputFolder`]
///   naming the lock file and how to clear a stale one).
/// - Under the lock the folder must hold nothing but the lock unless `overwrite` (the callers
///   check this before their work too; checked again here, two exports that both found the folder
///   new cannot both write into it). `flag` names the caller's folder option in messages.
/// - When `write` fails, every entry it added to the folder is removed: the export is complete or
///   absent.
///
/// # Errors
/// The lock or the folder's refusal ([`FormatError`], converted into `E`), or `write`'s error.
pub fn with_export_lock<T, E: From<FormatError>>(
    dir: &Path,
    overwrite: bool,
    flag: &str,
    write: impl FnOnce() -> Result<T, E>,
) -> Result<T, E> {
    std::fs::create_dir_all(dir).map_err(|e| FormatError::io(dir, e))?;
    let lock = dir.join(EXPORT_LOCK_NAME);
    let mut file = match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&lock)
    {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            let owner = std::fs::read_to_string(&lock).unwrap_or_default();
            return Err(FormatError::OutputFolder {
                path: dir.to_path_buf(),
                message: format!(
                    "another export is writing into this folder (its lock file {} exists{}): wait \
                     for it and choose another folder; if no export is running (one that was \
                     killed leaves the lock behind), delete {} and run again",
                    lock.display(),
                    owner
                        .trim()
                        .parse::<u32>()
                        .map(|pid| format!(", held by process {pid}"))
                        .unwrap_or_default(),
                    lock.display()
                ),
            }
            .into());
        }
        Err(e) => return Err(FormatError::io(&lock, e).into()),
    };
    let _ = write!(file, "{}", std::process::id());
    drop(file);
    let _unlock = RemoveOnDrop(lock.clone());
    let before = entries(dir).map_err(|e| FormatError::io(dir, e))?;
    if !overwrite {
        if let Some(first) = before.iter().find(|p| **p != lock) {
            return Err(FormatError::OutputFolder {
                path: dir.to_path_buf(),
                message: format!(
                    "{flag}: the folder is not empty (it holds `{}`; another export may have just \
                     written it): choose a new or empty folder",
                    first.file_name().unwrap_or_default().to_string_lossy()
                ),
            }
            .into());
        }
    }
    let result = write();
    if result.is_err() {
        if let Ok(after) = entries(dir) {
            for path in after.iter().filter(|p| !before.contains(p) && **p != lock) {
                let _ = std::fs::remove_file(path).or_else(|_| std::fs::remove_dir_all(path));
            }
        }
    }
    result
}

/// The folder's entries, sorted.
fn entries(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut v = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<Vec<_>, _>>()?;
    v.sort();
    Ok(v)
}

/// Removes a file when dropped (the export lock, on success, failure or panic).
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv");
        write_atomically(&path, b"one").unwrap();
        write_atomically(&path, b"two").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        assert_eq!(entries(dir.path()).unwrap(), vec![path]);
        // A write that fails (the folder is missing) leaves nothing under the final name.
        let missing = dir.path().join("no/such/b.csv");
        assert!(write_atomically(&missing, b"x").is_err());
        assert!(!missing.exists());
    }

    /// A streamed write that fails halfway leaves the previous file and no temporary behind; one
    /// that succeeds replaces it.
    #[test]
    fn a_failed_streamed_write_leaves_the_previous_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.csv");
        write_atomically(&path, b"old").unwrap();
        let failed = write_atomically_with(&path, |w| -> Result<(), FormatError> {
            w.write_all(b"half of a new file").unwrap();
            Err(FormatError::io(
                &path,
                std::io::Error::other("row 3 is bad"),
            ))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(entries(dir.path()).unwrap(), vec![path.clone()]);
        write_atomically_with(&path, |w| -> Result<(), FormatError> {
            w.write_all(b"new").map_err(|e| FormatError::io(&path, e))
        })
        .unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(entries(dir.path()).unwrap(), vec![path]);
    }

    /// A held lock refuses a second export naming the lock; a failed export leaves the folder as
    /// it was; the lock is gone afterwards.
    #[test]
    fn lock_refuses_a_second_writer_and_failed_exports_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("export");
        let inner: Result<(), FormatError> = with_export_lock(&out, false, "--export", || {
            std::fs::write(out.join("cell.toml"), "x").unwrap();
            let second: Result<(), FormatError> =
                with_export_lock(&out, true, "--export", || Ok(()));
            let msg = second.unwrap_err().to_string();
            assert!(
                msg.contains(EXPORT_LOCK_NAME) && msg.contains("delete"),
                "{msg}"
            );
            Err(FormatError::io(&out, std::io::Error::other("disk full")))
        });
        assert!(inner.is_err());
        assert_eq!(entries(&out).unwrap(), Vec::<PathBuf>::new());
        with_export_lock::<_, FormatError>(&out, false, "--export", || {
            write_atomically(&out.join("cell.toml"), b"y")
        })
        .unwrap();
        assert_eq!(entries(&out).unwrap(), vec![out.join("cell.toml")]);
        let again: Result<(), FormatError> = with_export_lock(&out, false, "--export", || Ok(()));
        assert!(again.unwrap_err().to_string().contains("not empty"));
    }
}
