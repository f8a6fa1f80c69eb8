//! `handclasp diagnose` (under construction).

/// Arguments of `handclasp diagnose`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `handclasp diagnose`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("handclasp diagnose is under construction")
}
