//! The output-folder rule shared by `calibrate --cell --export`, `diagnose --export` and
//! `export --to` ([`cli_support::export_dir`], shared with the Python package).

use std::path::Path;

/// Refuses an output folder given by `flag` (`export --to`) that exists and is not empty,
/// unless `--force` ([`cli_support::export_dir::check_output_folder`]).
pub fn check_output_folder(dir: &Path, force: bool, flag: &str) -> anyhow::Result<()> {
    Ok(cli_support::export_dir::check_output_folder(
        dir, force, flag, "--force",
    )?)
}

/// Runs `write`, a multi-file export into `dir`, under the folder's lock
/// ([`handclasp_cell::output::with_export_lock`]): a concurrent export into the same folder is
/// refused, the folder must still be empty unless `force` (checked again under the lock), and a
/// failed export leaves none of its files. `flag` names the folder's option in messages.
pub fn locked<T>(
    dir: &Path,
    force: bool,
    flag: &str,
    write: impl FnOnce() -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    handclasp_cell::output::with_export_lock(dir, force, flag, write)
}

/// The `--export` folder rule of `calibrate --cell` and `diagnose`, whose overwrite flag is
/// `--overwrite` (their `--force` keeps a refused result): a non-empty folder without
/// `--overwrite` is refused, and with `--force` (the old usage) the message says that `--force`
/// alone no longer overwrites.
pub fn check_export_folder_overwrite(
    dir: &Path,
    overwrite: bool,
    force: bool,
) -> anyhow::Result<()> {
    let checked =
        cli_support::export_dir::check_output_folder(dir, overwrite, "--export", "--overwrite");
    match checked {
        Err(e) if force => Err(anyhow::Error::from(e).context(
            "--force keeps a refused result; it no longer overwrites an export (add --overwrite)",
        )),
        other => Ok(other?),
    }
}
