//! The `--export DIR` rule shared by `calibrate --cell` and `diagnose`: a folder that exists and
//! is not empty is refused (before any fit runs) unless `--force`.

use std::path::Path;

use anyhow::Context;

/// Refuses an `--export` folder that exists and is not empty, unless `--force`: an export writes
/// files of fixed names, and a folder with another export's files would mix two models. Checked
/// before the fit or diagnosis runs (it can take minutes).
pub fn check_export_folder(dir: &Path, force: bool) -> anyhow::Result<()> {
    let mut entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => {
            return Err(e).with_context(|| {
                format!(
                    "--export {}: cannot read the folder (is it a file?)",
                    dir.display()
                )
            })
        }
    };
    if force {
        return Ok(());
    }
    if let Some(first) = entries.next() {
        let first = first.with_context(|| format!("--export {}", dir.display()))?;
        anyhow::bail!(
            "--export {}: the folder is not empty (it holds `{}`{}): choose a new or empty folder, \
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
