//! `frfbayes modes`: nominal natural frequencies and mode shapes of a campaign's model.

use frfbayes::modal::condensed::lowest_modes_condensed;
use frfbayes::model::condense::massless_dofs;
use std::path::PathBuf;

/// Shapes are printed whole up to this many DOFs; a larger model's at its first DOFs only.
const SHAPE_DOFS_SHOWN: usize = 20;

/// Arguments of `frfbayes modes`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Campaign folder (with campaign.toml); only the nominal model is read.
    #[arg(long)]
    pub campaign: PathBuf,
    /// Modes printed, lowest first (default: every mode of a model of up to 20 DOFs with
    /// mass, else the lowest 20). Massless DOFs (rotations of a beam model) are condensed.
    #[arg(long)]
    pub n_modes: Option<usize>,
}

/// Prints the nominal modes.
pub fn run(args: Args) -> anyhow::Result<()> {
    let nominal = frfbayes::io::read_nominal(&args.campaign)?;
    let model = nominal.structural_model()?;
    let k = model.stiffness(&model.alpha_zero());
    let m = model.mass(&model.beta_zero());
    let n_with_mass = model.n_dof() - massless_dofs(&m).len();
    let n_modes = args.n_modes.unwrap_or(n_with_mass.min(20));
    if n_modes == 0 || n_modes > n_with_mass {
        anyhow::bail!("--n-modes {n_modes}: the model has 1..={n_with_mass} modes");
    }
    let modes = lowest_modes_condensed(&k, &m, n_modes)?;
    let shown = model.n_dof().min(SHAPE_DOFS_SHOWN);
    println!("nominal model of {}", args.campaign.display());
    println!(
        "{:>6} {:>10}   mode shape (mass-normalised, DOF 1..{shown} of {})",
        "mode",
        "freq_hz",
        model.n_dof()
    );
    for (i, lambda) in modes.eigenvalues.iter().enumerate() {
        let f_hz = lambda.max(0.0).sqrt() / (2.0 * std::f64::consts::PI);
        // Sign as `Modes`: the largest-magnitude entry positive.
        let col = modes.shapes.column(i);
        let sign = col
            .iter()
            .fold(0.0f64, |a, &v| if v.abs() > a.abs() { v } else { a })
            .signum();
        let shape: Vec<String> = (0..shown)
            .map(|d| format!("{:+.4}", sign * modes.shapes[(d, i)]))
            .collect();
        println!("{:>6} {:>10.4}   {}", i + 1, f_hz, shape.join(" "));
    }
    Ok(())
}
