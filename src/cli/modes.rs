//! `frfbayes modes`: nominal natural frequencies and mode shapes of a campaign's model.

use frfbayes::modal::Modes;
use std::path::PathBuf;

/// Arguments of `frfbayes modes`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Campaign folder (with campaign.toml); only the nominal model is read.
    #[arg(long)]
    pub campaign: PathBuf,
}

/// Prints the nominal modes.
pub fn run(args: Args) -> anyhow::Result<()> {
    let nominal = frfbayes::io::read_nominal(&args.campaign)?;
    let model = nominal.structural_model()?;
    let modes = Modes::solve(
        &model.stiffness(&model.alpha_zero()),
        &model.mass(&model.beta_zero()),
        model.ground_influence(),
        None,
    )?;
    println!("nominal model of {}", args.campaign.display());
    println!(
        "{:>6} {:>10}   mode shape (mass-normalised, floor 1..{})",
        "mode",
        "freq_hz",
        model.n_dof()
    );
    for (i, f) in modes.freq_hz().iter().enumerate() {
        let shape: Vec<String> = modes
            .phi
            .column(i)
            .iter()
            .map(|v| format!("{v:+.4}"))
            .collect();
        println!("{:>6} {:>10.4}   {}", i + 1, f, shape.join(" "));
    }
    Ok(())
}
