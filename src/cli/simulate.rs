//! `frfbayes simulate` (under construction).

/// Arguments of `frfbayes simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the command.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`frfbayes simulate` is not built yet")
}
