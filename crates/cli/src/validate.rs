//! `handclasp validate --cell CALIBRATED.toml --session NEW.csv [--nominal NOMINAL.toml]
//! [--nuisance split|fixed [--calibration-session OLD.csv]] [--json]`: a calibrated cell scored
//! on a session it was not fitted to, beside the nominal cell.
//!
//! Reads both cells and the session (with the nominal cell when given, else or if its models
//! disagree with the tip columns with the calibrated cell), scores each cell on the session with
//! the nuisances `--nuisance` says (`split`: refitted on alternate rows of each group; `fixed`:
//! fitted on `--calibration-session` and carried over by group name), and prints per kind, per
//! group and over all rows each cell's rms, largest and whitened residual and their ratio. How
//! each step is done: [`cli_support::validate`].
//!
//! A calibrated cell whose whitened rms over all rows is above the nominal cell's prints a
//! `warning:` on stderr, as does one whose whitened rms over all rows is above
//! [`cli_support::validate::NOISE_WARNING_WHITENED_RMS`] (the data contradict the stated noise).
//!
//! The scores, the text and the warnings are [`cli_support::validate`]'s, which the Python
//! package's `handclasp.validate` calls too; this module reads the files and prints.

use std::path::PathBuf;

use anyhow::bail;
use cli_support::validate::{
    read_session, render_text, validate, warnings, NamedCell, NuisanceSource,
};
use handclasp_cell::Cell;

/// How a session read with the wrong cell is told to name the nominal cell.
const NOMINAL_HINT: &str = "--nominal NOMINAL.toml";

/// Arguments of `handclasp validate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The calibrated cell TOML (e.g. written by `calibrate --cell --export`).
    #[arg(long)]
    pub cell: PathBuf,
    /// The new session CSV, not used in the calibration (any observation kinds).
    #[arg(long)]
    pub session: PathBuf,
    /// The nominal cell TOML to compare with (its [robotN.errors], if any, are ignored); the
    /// session is read with it (its tip columns are the nominal models').
    #[arg(long)]
    pub nominal: Option<PathBuf>,
    /// Where the session's tracker frames, planes and fitted contact distances come from:
    /// `split` fits each group's on alternate rows and scores the other rows, and back;
    /// `fixed` fits them on --calibration-session with each cell held and carries them over
    /// by group name.
    #[arg(long, value_enum, default_value = "split")]
    pub nuisance: NuisanceArg,
    /// With --nuisance fixed: the session the cell was calibrated on (its groups named as the
    /// new session's).
    #[arg(long)]
    pub calibration_session: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `--nuisance`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum NuisanceArg {
    /// Refitted on alternate rows of each group, scored on the others.
    Split,
    /// Fitted on the calibration session, carried over by group name.
    Fixed,
}

/// Runs `handclasp validate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match (args.nuisance, &args.calibration_session) {
        (NuisanceArg::Split, Some(_)) => bail!(
            "--calibration-session is used with --nuisance fixed only: add --nuisance fixed, or drop it"
        ),
        (NuisanceArg::Fixed, None) => bail!(
            "--nuisance fixed needs --calibration-session OLD.csv (the session the cell was calibrated on)"
        ),
        _ => {}
    }
    let cal_cell = Cell::from_toml_file(&args.cell)?;
    let nom_cell = args
        .nominal
        .as_ref()
        .map(|p| Cell::from_toml_file(p))
        .transpose()?;
    let mut readers: Vec<(String, &Cell)> = Vec::new();
    if let (Some(c), Some(p)) = (&nom_cell, &args.nominal) {
        readers.push((format!("--nominal {}", p.display()), c));
    }
    readers.push((format!("--cell {}", args.cell.display()), &cal_cell));
    let read = |p: &std::path::Path| read_session(p, &readers, NOMINAL_HINT);
    let session = read(&args.session)?;
    let old = args.calibration_session.as_deref().map(read).transpose()?;
    let nuisance = match &old {
        Some(calibration) => NuisanceSource::Fixed { calibration },
        None => NuisanceSource::Split,
    };
    let cal_name = args.cell.display().to_string();
    let nom_name = args.nominal.as_ref().map(|p| p.display().to_string());
    let nominal = nom_cell
        .as_ref()
        .zip(nom_name.as_deref())
        .map(|(cell, name)| NamedCell { cell, name });
    let r = validate(
        NamedCell {
            cell: &cal_cell,
            name: &cal_name,
        },
        nominal,
        &session,
        &args.session.display().to_string(),
        nuisance,
    )?;
    for w in warnings(&r) {
        eprintln!("warning: {w}");
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", render_text(&r));
    }
    Ok(())
}
