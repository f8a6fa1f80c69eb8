//! `handclasp paper diagnose` (under construction).

/// Arguments of `handclasp paper diagnose`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `handclasp paper diagnose`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("handclasp paper diagnose is under construction")
}
