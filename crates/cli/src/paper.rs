//! `handclasp paper`: the paper's published results (under construction).

use crate::paper_diagnose;

/// Subcommands of `handclasp paper`.
#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Recompute the paper's Table 1 errors from its published transforms, beside the published values.
    Table1(Table1Args),
    /// Fit the simulation to Table 1's measured errors, say what it gets wrong, name the cause, measure the gain.
    Diagnose(paper_diagnose::Args),
}

/// Arguments of `handclasp paper table1`.
#[derive(clap::Args, Debug)]
pub struct Table1Args {}

/// Runs `handclasp paper …`.
pub fn run(cmd: Command) -> anyhow::Result<()> {
    match cmd {
        Command::Table1(_args) => anyhow::bail!("handclasp paper table1 is under construction"),
        Command::Diagnose(args) => paper_diagnose::run(args),
    }
}
