//! `handclasp`: base-frame calibration of two cooperating robots, for engineers.
//!
//! Thin glue: `main → run → ExitCode`. Each subcommand lives in its own module with a clap `Args`
//! struct and a `run` function; the libraries do the work.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod calibrate;
mod calibrate_cell;
mod diagnose;
mod export;
mod export_dir;
mod fk;
mod ik;
mod import;
mod paper;
mod paper_diagnose;
mod plan;

/// Calibrate the base frames of two cooperating robots from handclasp points.
///
/// Files and flags speak millimetres and degrees, like robot controllers. Every command takes
/// `--json` for scripts; the default output is a readable table.
#[derive(Parser, Debug)]
#[command(name = "handclasp", version, about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Forward kinematics: joint angles (deg) to the tip pose (mm, ZYZ deg), as the pendant shows it.
    Fk(fk::Args),
    /// Inverse kinematics: a tip position (mm) to joint angles (deg), or "unreachable".
    Ik(ik::Args),
    /// Fit b1_from_b2 from a CSV of handclasp points.
    Calibrate(calibrate::Args),
    /// The paper's published results: Table 1 recomputed, and its discrepancy diagnosis.
    #[command(subcommand)]
    Paper(paper::Command),
    /// Find what the nominal models get wrong in a measured session, name the cause, and measure the gain.
    Diagnose(diagnose::Args),
    /// Plan a session: the N handclasp poses that calibrate the whole cell best, as a session CSV to teach from.
    Plan(plan::Args),
    /// Convert a controller's or dataset's CSV into a session CSV, as a mapping file says.
    Import(import::Args),
    /// Write the cell's b1_from_b2 for ABB, KUKA, Fanuc, Yaskawa controllers and ROS 2, each file read back and checked.
    Export(export::Args),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Fk(args) => fk::run(args),
        Command::Ik(args) => ik::run(args),
        Command::Calibrate(args) => calibrate::run(args),
        Command::Paper(cmd) => paper::run(cmd),
        Command::Diagnose(args) => diagnose::run(args),
        Command::Plan(args) => plan::run(args),
        Command::Import(args) => import::run(args),
        Command::Export(args) => export::run(args),
    }
}

fn main() -> ExitCode {
    sim_cell::cli_support::exit_quietly_on_broken_pipe();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!(
                "error: {}",
                sim_cell::cli_support::error_chain_text(err.as_ref())
            );
            ExitCode::FAILURE
        }
    }
}
