//! The output-folder rule shared by `calibrate --cell --export`, `diagnose --export` and
//! `export --to` ([`cli_support::export_dir`], shared with the Python package).

use std::path::Path;

/// Refuses an `--export` folder that exists and is not empty, unless `--force`
/// ([`cli_support::export_dir::check_output_folder`]).
pub fn check_export_folder(dir: &Path, force: bool) -> anyhow::Result<()> {
    check_output_folder(dir, force, "--export")
}

/// [`check_export_folder`] for a folder given by `flag` (e.g. `--to`): the messages name it.
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
