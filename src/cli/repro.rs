//! `frfbayes repro` and `frfbayes run`: experiments from configuration files.

use frfbayes::experiment::driver::{run_experiment, Outcome};
use frfbayes::experiment::ExperimentConfig;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

/// Arguments of `frfbayes repro`.
#[derive(Debug, clap::Args)]
pub struct ReproArgs {
    /// Campaign folder (default: the bundled four-story campaign).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Output folder (default: results/paper_repro).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Multistart local solves per variant (default from experiments/paper_repro.toml: 64).
    #[arg(long)]
    pub starts: Option<usize>,
    /// Master seed (default from experiments/paper_repro.toml).
    #[arg(long)]
    pub seed: Option<u64>,
}

/// Arguments of `frfbayes run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// Experiment file (experiments/<name>.toml).
    pub config: PathBuf,
    /// Override the output folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn progress_bar() -> ProgressBar {
    let pb = ProgressBar::new(1);
    pb.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb
}

fn execute(cfg: &ExperimentConfig) -> anyhow::Result<Outcome> {
    let pb = progress_bar();
    let progress = |stage: &str, done: usize, total: usize| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
        pb.set_message(stage.to_string());
    };
    let outcome = run_experiment(cfg, &progress);
    pb.finish_and_clear();
    let outcome = outcome?;
    if !frfbayes::dist::is_root() {
        return Ok(outcome);
    }
    println!("wrote {}", outcome.out.display());
    for (stage, s) in &outcome.info.timings_s {
        println!("  {stage:<22} {s:8.2} s");
    }
    for r in &outcome.runs {
        println!(
            "  {:<8} {:<22} cost {:.4e}  {}/{} starts at best  {:>5} points  {:.2} s",
            r.variant.table.key(),
            r.variant.column(),
            r.result.best.cost,
            r.result.n_at_best,
            r.result.starts.len(),
            r.n_points,
            r.wall_s
        );
    }
    Ok(outcome)
}

/// Runs the paper's reproduction.
pub fn repro(args: ReproArgs) -> anyhow::Result<()> {
    let mut cfg = ExperimentConfig::paper_repro()?;
    if let Some(d) = args.data {
        cfg.data = d.to_string_lossy().into_owned();
    }
    if let Some(o) = args.out {
        cfg.out = o;
    }
    if let Some(s) = args.starts {
        anyhow::ensure!(s > 0, "--starts must be at least 1");
        cfg.update.starts = s;
    }
    if let Some(s) = args.seed {
        cfg.seed = s;
    }
    execute(&cfg).map(|_| ())
}

/// Runs an experiment file.
pub fn run(args: RunArgs) -> anyhow::Result<()> {
    let mut cfg = ExperimentConfig::load(&args.config)?;
    if let Some(o) = args.out {
        cfg.out = o;
    }
    execute(&cfg).map(|_| ())
}
