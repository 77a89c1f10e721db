//! `frfbayes real <dataset>`: the studies on real measurements (`frfbayes::real`).

use std::path::PathBuf;

use frfbayes::mcmc::Progress;
use frfbayes::real::posterior::Sampling;
use frfbayes::real::{data_dir, run, shared_dir, Dataset, StudyOptions};
use indicatif::{ProgressBar, ProgressStyle};

/// Which dataset.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Which {
    /// Four-story frame, identified modes, against a shear-frame modal likelihood.
    FourStoryModal,
    /// Light-rail wheel, measured FRFs: Bayesian modal-parameter estimation.
    WheelFrf,
    /// Unison Tower with a hybrid mass damper: FRFs and a 5-story shear model.
    TowerHmd,
    /// Steel pedestrian bridge, a 946-DOF FE model and 5 identified modes: SMU's updating
    /// reproduced, and the posterior of its 17 stiffness groups.
    BridgeFe,
}

/// Arguments of `frfbayes real`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Dataset to study.
    #[arg(value_enum)]
    pub dataset: Which,
    /// Shared folder holding data/real/<dataset> (default: $FRFBAYES_SHARED_DIR, else
    /// ../shared).
    #[arg(long)]
    pub shared: Option<PathBuf>,
    /// Output folder (default: results/real/<dataset>); replaced atomically.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// A short run of every stage, for tests of the command (e.g. `mpirun -n 2` against
    /// one process): 200 sampler steps; the bridge also 4 starts of 200 evaluations, one
    /// exact polish of 40, 100 sampler steps. Its numbers are not the study's.
    #[arg(long)]
    pub quick: bool,
    /// Step cap of every sampler of the study (with --quick, replaces its step count).
    #[arg(long)]
    pub max_steps: Option<u64>,
}

/// Runs the study with a progress bar per sampled posterior and prints where the
/// results went.
pub fn run_cmd(args: Args) -> anyhow::Result<()> {
    let dataset = match args.dataset {
        Which::FourStoryModal => Dataset::FourStoryModal,
        Which::WheelFrf => Dataset::WheelFrf,
        Which::TowerHmd => Dataset::TowerHmd,
        Which::BridgeFe => Dataset::BridgeFe,
    };
    let data = data_dir(&shared_dir(args.shared.as_deref()), dataset);
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("results/real").join(dataset.name()));
    let style = ProgressStyle::with_template(
        "{prefix:32} {elapsed_precise} [{bar:30}] {pos}/{len} steps {msg}",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar())
    .progress_chars("=> ");
    let mut bar: Option<(String, ProgressBar)> = None;
    let on_step = |label: &str, p: &Progress| {
        if bar.as_ref().is_none_or(|(l, _)| l != label) {
            if let Some((_, b)) = bar.take() {
                b.finish();
            }
            let b = ProgressBar::new(p.max_steps).with_style(style.clone());
            b.set_prefix(label.to_string());
            bar = Some((label.to_string(), b));
        }
        if let Some((_, b)) = &bar {
            b.set_length(p.max_steps);
            b.set_position(p.step);
            b.set_message(format!("acceptance {:.3}", p.acceptance));
        }
    };
    let options = StudyOptions {
        seed: args.seed,
        quick: args.quick,
        max_steps: args.max_steps,
    };
    let timings = run(dataset, &data, &out, options, &mut Sampling::new(on_step));
    let timings = timings?;
    if !frfbayes::dist::is_root() {
        return Ok(());
    }
    for (stage, t) in &timings {
        println!("{stage}: {t:.2} s");
    }
    println!("wrote {}/report.md", out.display());
    Ok(())
}
