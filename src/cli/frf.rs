//! `frfbayes frf` (under construction).

/// Arguments of `frfbayes frf`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the command.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`frfbayes frf` is not built yet")
}
