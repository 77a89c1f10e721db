//! `frfbayes check` (under construction).

/// Arguments of `frfbayes check`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the command.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`frfbayes check` is not built yet")
}
