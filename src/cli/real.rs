//! `frfbayes real`: the studies on real measurements (`frfbayes::real`).

use std::path::PathBuf;

use frfbayes::real::{default_data_dir, run, Dataset};

/// Which dataset.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Which {
    /// Four-story frame, identified modes, against a shear-frame modal likelihood.
    FourStoryModal,
    /// Light-rail wheel, measured FRFs: Bayesian modal-parameter estimation.
    WheelFrf,
    /// Unison Tower with a hybrid mass damper: FRFs and a 5-story shear model.
    TowerHmd,
}

/// Arguments of `frfbayes real`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Dataset to study.
    #[arg(value_enum)]
    pub dataset: Which,
    /// Data folder (default: $FRFBAYES_SHARED_DIR/data/real/<dataset>, else
    /// ../shared/data/real/<dataset>).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Output folder (default: results/real/<dataset>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs the study and prints where the results went.
pub fn run_cmd(args: Args) -> anyhow::Result<()> {
    let dataset = match args.dataset {
        Which::FourStoryModal => Dataset::FourStoryModal,
        Which::WheelFrf => Dataset::WheelFrf,
        Which::TowerHmd => Dataset::TowerHmd,
    };
    let data = args.data.unwrap_or_else(|| default_data_dir(dataset));
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("results/real").join(dataset.name()));
    let timings = run(dataset, &data, &out, args.seed)?;
    for (stage, t) in &timings {
        println!("{stage}: {t:.2} s");
    }
    println!("wrote {}/report.md", out.display());
    Ok(())
}
