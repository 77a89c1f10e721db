//! `frfbayes simulate`: writes a campaign with known truth from a simulation model file.

use frfbayes::io::{RunInfo, StagedDir};
use frfbayes::simulate::{resolve_seed, SimModel, Simulator};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `frfbayes simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Simulation model (TOML; format in the `frfbayes::simulate` docs).
    #[arg(long)]
    pub model: PathBuf,
    /// Campaign folder to write (replaced only once complete).
    #[arg(long)]
    pub out: PathBuf,
    /// Noise seed; overrides the model's `seed`.
    #[arg(long)]
    pub seed: Option<u64>,
}

/// Simulates the campaign and writes it with its `truth.json` and `run.json`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = SimModel::from_path(&args.model)?;
    // Claim the output folder first: a refusal comes before minutes of simulation.
    let staged = StagedDir::new(&args.out)?;
    let seed = resolve_seed(&model, args.seed, &args.model)?;
    let mut info = RunInfo::start(
        seed,
        serde_json::to_value(&model)?,
        args.model.display().to_string(),
    );
    let sim = Simulator::new(model)?;
    if let Some(basis) = sim.modal_basis_info() {
        info.config["modal_basis"] = basis;
    }
    let bar = ProgressBar::new(sim.total_work());
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent:>3}% {elapsed}/{eta}")?
            .progress_chars("=> "),
    );
    bar.set_message("simulating");
    let start = Instant::now();
    let campaign = info.time("simulate", || sim.run(seed, &|n| bar.inc(n)))?;
    let simulated_s = start.elapsed().as_secs_f64();
    bar.set_message("writing");
    info.time("write", || {
        frfbayes::io::write_campaign_files(&campaign, staged.path(), &args.out)
    })?;
    sim.write_truth(staged.path(), seed)?;
    info.write(staged.path())?;
    let root = staged.commit()?;
    bar.finish_and_clear();
    let rows: usize = campaign.tests.iter().map(|t| t.n_samples()).sum();
    println!(
        "wrote {} ({} tests, {rows} rows, seed {seed}) in {:.1} s (simulation {:.1} s)",
        root.display(),
        campaign.tests.len(),
        start.elapsed().as_secs_f64(),
        simulated_s
    );
    Ok(())
}
