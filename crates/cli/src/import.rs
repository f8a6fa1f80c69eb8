//! `handclasp import --cell CELL --map MAP.toml --input FILE.csv [--input …] --out SESSION.csv
//! [--json]`: converts a controller's or a dataset's CSV into a session CSV of `CELL`
//! (`handclasp_cell::Session`), as the mapping file says. The mapping format and the conversion
//! are `handclasp_cell::import` (documented there and in docs/formats.md); this module reads the
//! files, names the flags in errors, writes the session and reads it back through
//! `Session::read_csv` before the command succeeds, and prints.

use std::path::PathBuf;

use anyhow::{bail, Context};
use handclasp_cell::{Cell, ImportMap, Session};

/// Arguments of `handclasp import`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell TOML: its robots' joint counts and tools (`tip`, `[robotN.tools]`) check the mapping,
    /// and its nominal models give the coincident kind's tip columns.
    #[arg(long)]
    pub cell: PathBuf,
    /// Mapping file (TOML): which source columns are each robot's joints and in which unit, the
    /// kind, robot, group, tool, σ and tracker columns, the source id column, and `[[rows]]` for
    /// several session rows per input row (docs/formats.md).
    #[arg(long)]
    pub map: PathBuf,
    /// Source CSV file(s); repeat the flag for several (rows are numbered over all of them).
    #[arg(long, required = true)]
    pub input: Vec<PathBuf>,
    /// Session CSV to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Print one JSON summary instead of the text lines.
    #[arg(long)]
    pub json: bool,
}

/// What one input gave (JSON `input`, `rows`, `skipped`).
#[derive(Debug, serde::Serialize)]
struct FileCount {
    /// The input file.
    #[serde(rename = "input")]
    path: PathBuf,
    /// Rows imported from it.
    rows: usize,
    /// Rows skipped (no tracker value: empty or NaN).
    skipped: usize,
}

/// What `handclasp import` prints: each input's counts, the kind, the session written and its
/// rows. `--json` serialises it; [`render_text`] reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this report
/// was before it had types).
#[derive(Debug, serde::Serialize)]
struct ImportReport {
    /// Each input, in order.
    files: Vec<FileCount>,
    /// The observation kind imported (the mapping's `kind`; the kinds of a map with `[[rows]]`
    /// of several kinds, joined by `+`).
    kind: String,
    /// The session CSV written (`--out`).
    out: PathBuf,
    /// Rows in the written session.
    rows: usize,
}

/// The text report.
fn render_text(r: &ImportReport) -> String {
    let mut s = String::new();
    for c in &r.files {
        let skipped = if c.skipped > 0 {
            format!(", {} skipped (no tracker value: empty or NaN)", c.skipped)
        } else {
            String::new()
        };
        s += &format!(
            "{}: {} {} row(s){skipped}\n",
            c.path.display(),
            c.rows,
            r.kind
        );
    }
    s += &format!("wrote {} rows to {}\n", r.rows, r.out.display());
    s
}

/// Runs `handclasp import`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cell = Cell::from_toml_file(&args.cell)?;
    let text = kinematics::input::read_input_text(&args.map, "import map TOML")
        .with_context(|| format!("--map {}", args.map.display()))?;
    let map = ImportMap::from_toml_str(&text, &args.map, &cell)
        .map_err(|e| anyhow::anyhow!("--map {e}"))?;
    let mut session = Session::default();
    let mut counts = Vec::new();
    let progress = crate::progress::Progress::new(crate::progress::shown(args.json), "importing");
    for input in &args.input {
        progress.phase(format!("importing {}", input.display()));
        let text = kinematics::input::read_input_text(input, "import input CSV")
            .with_context(|| format!("--input {}", input.display()))?;
        let count = map
            .read_rows(&text, input, &cell, &mut session)
            .map_err(|e| anyhow::anyhow!("--input {e}"))?;
        counts.push(FileCount {
            path: input.clone(),
            rows: count.rows,
            skipped: count.skipped,
        });
    }
    if session.is_empty() {
        bail!("no row imported from {} file(s)", args.input.len());
    }
    // The input checks every command runs on a session (radians, metres, duplicates), before
    // a session that calibrate --cell and diagnose would refuse is written.
    handclasp_cell::check_session_inputs(&session).map_err(|source| {
        handclasp_cell::FormatError::SessionCheck {
            path: args.out.clone(),
            source,
        }
    })?;
    progress.phase(format!("writing and reading back {}", args.out.display()));
    session.write_csv(&args.out, &cell)?;
    // The written file must read back as a session of this cell (tips, tools, groups).
    Session::read_csv(&args.out, &cell).context("reading back the written session")?;
    progress.finish();
    let report = ImportReport {
        files: counts,
        kind: map
            .kinds()
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join("+"),
        out: args.out.clone(),
        rows: session.len(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_json_of_an_import() {
        let r = ImportReport {
            files: vec![
                FileCount {
                    path: "a.csv".into(),
                    rows: 212,
                    skipped: 4,
                },
                FileCount {
                    path: "b.csv".into(),
                    rows: 10,
                    skipped: 0,
                },
            ],
            kind: "tracker".into(),
            out: "s.csv".into(),
            rows: 222,
        };
        assert_eq!(
            render_text(&r),
            "a.csv: 212 tracker row(s), 4 skipped (no tracker value: empty or NaN)\n\
             b.csv: 10 tracker row(s)\n\
             wrote 222 rows to s.csv\n"
        );
        assert_eq!(
            serde_json::to_string(&r).unwrap(),
            r#"{"files":[{"input":"a.csv","rows":212,"skipped":4},{"input":"b.csv","rows":10,"skipped":0}],"kind":"tracker","out":"s.csv","rows":222}"#
        );
    }
}
