//! The output-folder rule shared by `calibrate --cell --export`, `diagnose --export` and
//! `export --to`: a folder that exists and is not empty is refused (before any work runs) unless
//! `--force`.

use std::path::Path;

use anyhow::Context;

/// Refuses an `--export` folder that exists and is not empty, unless `--force`: an export writes
/// files of fixed names, and a folder with another export's files would mix two models. Checked
/// before the fit or diagnosis runs (it can take minutes).
pub fn check_export_folder(dir: &Path, force: bool) -> anyhow::Result<()> {
    check_output_folder(dir, force, "--export")
}

/// [`check_export_folder`] for a folder given by `flag` (e.g. `--to`): the messages name it.
pub fn check_output_folder(dir: &Path, force: bool, flag: &str) -> anyhow::Result<()> {
    let mut entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => {
            return Err(e).with_context(|| {
                format!(
                    "{flag} {}: cannot read the folder (is it a file?)",
                    dir.display()
                )
            })
        }
    };
    if force {
        return Ok(());
    }
    if let Some(first) = entries.next() {
        let first = first.with_context(|| format!("{flag} {}", dir.display()))?;
        anyhow::bail!(
            "{flag} {}: the folder is not empty (it holds `{}`{}): choose a new or empty folder, \
             or add --force to overwrite the files of the same names",
            dir.display(),
            first.file_name().to_string_lossy(),
            if entries.next().is_some() {
                " and more"
            } else {
                ""
            }
        );
    }
    Ok(())
}
