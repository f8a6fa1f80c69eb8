//! `handclasp calibrate` (under construction).

/// Arguments of `handclasp calibrate`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `handclasp calibrate`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("handclasp calibrate is under construction")
}
