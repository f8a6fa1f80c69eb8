//! `handclasp ik` (under construction).

/// Arguments of `handclasp ik`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `handclasp ik`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("handclasp ik is under construction")
}
