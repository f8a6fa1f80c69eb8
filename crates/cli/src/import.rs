//! `handclasp import --cell CELL --map MAP.toml --input FILE.csv [--input …] --out SESSION.csv
//! [--json]`: converts a controller's or a dataset's CSV into a session CSV of `CELL`
//! (`handclasp_cell::Session`), as the mapping file says. The mapping format and the conversion
//! are `handclasp_cell::import` (documented there and in the main README); this module reads the
//! files, names the flags in errors, writes the session and reads it back through
//! `Session::read_csv` before the command succeeds, and prints.

use std::path::PathBuf;

use anyhow::{bail, Context};
use handclasp_cell::{Cell, ImportMap, Session};
use serde_json::json;

/// Arguments of `handclasp import`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell TOML: its robots' joint counts and tools (`tip`, `[robotN.tools]`) check the mapping,
    /// and its nominal models give the coincident kind's tip columns.
    #[arg(long)]
    pub cell: PathBuf,
    /// Mapping file (TOML): which source columns are each robot's joints and in which unit, the
    /// kind, robot, group, tool, σ and tracker columns (see the README).
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

/// What one input gave.
struct FileCount {
    path: PathBuf,
    rows: usize,
    skipped: usize,
}

/// Runs `handclasp import`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cell = Cell::from_toml_file(&args.cell)?;
    let text = std::fs::read_to_string(&args.map)
        .with_context(|| format!("--map {}", args.map.display()))?;
    let map = ImportMap::from_toml_str(&text, &args.map, &cell)
        .map_err(|e| anyhow::anyhow!("--map {e}"))?;
    let mut session = Session::default();
    let mut counts = Vec::new();
    for input in &args.input {
        let text = std::fs::read_to_string(input)
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
    session.write_csv(&args.out, &cell)?;
    // The written file must read back as a session of this cell (tips, tools, groups).
    Session::read_csv(&args.out, &cell).context("reading back the written session")?;
    let kind = map.kind().name();
    if args.json {
        let files: Vec<_> = counts
            .iter()
            .map(|c| json!({"input": c.path, "rows": c.rows, "skipped": c.skipped}))
            .collect();
        let out = json!({"out": args.out, "kind": kind, "rows": session.len(), "files": files});
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        for c in &counts {
            let skipped = if c.skipped > 0 {
                format!(", {} skipped (no tracker value: empty or NaN)", c.skipped)
            } else {
                String::new()
            };
            println!("{}: {} {} row(s){skipped}", c.path.display(), c.rows, kind);
        }
        println!("wrote {} rows to {}", session.len(), args.out.display());
    }
    Ok(())
}
