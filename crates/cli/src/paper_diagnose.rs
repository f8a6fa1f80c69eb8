//! `handclasp paper diagnose`: fits the simulation to the paper's Table 1, says what it gets wrong
//! about the published errors, names the cause among candidate extended simulations, and measures
//! the gain (likelihood ratio, AIC, leave-one-experiment-out prediction). The engine is
//! `sim_cell::paper`; this module only parses flags and prints.

use anyhow::Context;
use sim_cell::paper::{
    render_diagnosis_text, run_paper_diagnosis, StudyOptions, DEFAULT_BOOTSTRAP, DEFAULT_SEED,
    DEFAULT_TRIALS,
};

/// Arguments of `handclasp paper diagnose`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// Seed of the Monte Carlo simulation (same seed, same report).
    #[arg(long, default_value_t = DEFAULT_SEED)]
    pub seed: u64,
    /// Simulated experiments per cell (at least 200).
    #[arg(long, default_value_t = DEFAULT_TRIALS)]
    pub trials: usize,
    /// Parametric-bootstrap replicates of the "both methods share σ" test (0 skips it).
    #[arg(long, default_value_t = DEFAULT_BOOTSTRAP)]
    pub bootstrap: usize,
}

/// Runs `handclasp paper diagnose`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = StudyOptions {
        seed: args.seed,
        trials: args.trials,
        bootstrap: args.bootstrap,
    };
    let diagnosis = run_paper_diagnosis(&opts).context("handclasp paper diagnose")?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&diagnosis)?);
    } else {
        print!("{}", render_diagnosis_text(&diagnosis));
    }
    Ok(())
}
