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
mod json_out;
mod paper;
mod paper_diagnose;
mod plan;
mod progress;
mod report_page;
mod result_check;
mod validate;

/// Test support shared by the subcommands' unit tests.
#[cfg(test)]
mod test_support {
    /// `report`'s compact JSON, after checking that its keys stand in the order a
    /// `serde_json::Value` gives them (a BTreeMap: this workspace does not turn on
    /// `preserve_order`), the order of the JSON these commands printed before their reports
    /// had types.
    pub(crate) fn json_in_value_order(report: &impl serde::Serialize) -> String {
        let json = serde_json::to_string(report).unwrap();
        let value: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(
            json,
            serde_json::to_string(&value).unwrap(),
            "keys out of alphabetical order"
        );
        json
    }
}

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
    /// Score a calibrated cell on a session it was not fitted to, per kind and group, against the nominal cell.
    Validate(validate::Args),
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
        Command::Validate(args) => validate::run(args),
    }
}

fn main() -> ExitCode {
    cli_support::exit_quietly_on_broken_pipe();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", cli_support::error_chain_text(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("handclasp").chain(args.iter().copied()))
    }

    #[test]
    fn command_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    /// `calibrate`'s two paths have their own `Args` behind one command: the same command lines
    /// are accepted and refused as when they shared one struct.
    #[test]
    fn calibrate_dispatches_on_cell_and_keeps_its_conflicts() {
        let Command::Calibrate(a) = parse(&[
            "calibrate",
            "--cell",
            "c.toml",
            "--session",
            "s.csv",
            "--json",
            "--force",
            "--verbose",
        ])
        .unwrap()
        .command
        else {
            panic!("not calibrate")
        };
        assert!(a.cell.cell.is_some() && a.cell.verbose && a.json && a.force);
        assert!(a.points.points.is_none());
        let Command::Calibrate(a) = parse(&["calibrate", "p.csv", "--mounts", "floor-wall"])
            .unwrap()
            .command
        else {
            panic!("not calibrate")
        };
        assert!(a.cell.cell.is_none() && a.points.points.is_some());
        use clap::error::ErrorKind;
        for (args, kind) in [
            (&["calibrate"][..], ErrorKind::MissingRequiredArgument),
            (
                &["calibrate", "p.csv", "--cell", "c", "--session", "s"],
                ErrorKind::ArgumentConflict,
            ),
            (
                &[
                    "calibrate",
                    "--cell",
                    "c",
                    "--session",
                    "s",
                    "--method",
                    "lsq",
                ],
                ErrorKind::ArgumentConflict,
            ),
            (
                &["calibrate", "--cell", "c"],
                ErrorKind::MissingRequiredArgument,
            ),
            (
                &["calibrate", "p.csv", "--verbose"],
                ErrorKind::MissingRequiredArgument,
            ),
            (
                &["calibrate", "p.csv", "--mount1", "floor"],
                ErrorKind::MissingRequiredArgument,
            ),
        ] {
            assert_eq!(parse(args).unwrap_err().kind(), kind, "{args:?}");
        }
    }

    /// `calibrate --help` lists the options in the order they had in one struct (the
    /// `display_order` of `--json`, `--expected-noise-mm`, `--force` and `--verbose`).
    #[test]
    fn calibrate_help_keeps_its_option_order() {
        let mut cmd = Cli::command();
        let help = cmd
            .find_subcommand_mut("calibrate")
            .unwrap()
            .render_long_help()
            .to_string();
        let order = [
            "--cell",
            "--session",
            "--model",
            "--export",
            "--mounts",
            "--mount1",
            "--mount2",
            "--method",
            "--tilt-sigma-deg",
            "--point-sigma-mm",
            "--json",
            "--expected-noise-mm",
            "--force",
            "--verbose",
            "--help",
        ];
        let at: Vec<usize> = order
            .iter()
            .map(|o| {
                // An option's own line starts with 6 spaces (`-h, ` takes 4 of them).
                help.find(&format!("\n      {o}"))
                    .or_else(|| help.find(&format!("\n  -h, {o}")))
                    .unwrap_or_else(|| panic!("{o} missing in {help}"))
            })
            .collect();
        assert!(at.windows(2).all(|w| w[0] < w[1]), "{help}");
    }
}
