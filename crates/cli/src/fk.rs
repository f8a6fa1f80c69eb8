//! `handclasp fk` (under construction).

/// Arguments of `handclasp fk`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `handclasp fk`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("handclasp fk is under construction")
}
