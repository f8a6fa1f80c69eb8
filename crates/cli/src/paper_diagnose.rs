//! `handclasp paper diagnose`: fits the simulation to the paper's Table 1, says what it gets wrong
//! about the published errors, names the cause among candidate extended simulations, and measures
//! the gain (likelihood ratio, AIC, leave-one-experiment-out prediction). The engine is
//! `sim_cell::paper`; this module only parses flags and prints.

use anyhow::Context;
use sim_cell::paper::{diagnosis_text, run_paper_diagnosis, StudyOptions};

/// Arguments of `handclasp paper diagnose`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// The study's seed, size and bootstrap.
    #[command(flatten)]
    pub study: StudyOptions,
}

/// Runs `handclasp paper diagnose`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let diagnosis = run_paper_diagnosis(&args.study).context("handclasp paper diagnose")?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&diagnosis)?);
    } else {
        print!("{}", diagnosis_text(&diagnosis));
    }
    Ok(())
}
