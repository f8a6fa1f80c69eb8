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
