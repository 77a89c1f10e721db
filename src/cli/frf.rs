//! `frfbayes frf`: FRF estimates of every test of a campaign, as CSV, UFF dataset 58 and
//! plots, with a measured-FRF manifest (`frfs.toml`) that `sample --frfs` reads.

use frfbayes::experiment::figures::estimate_figures;
use frfbayes::io::{read_campaign, StagedDir};
use frfbayes::signal::measured::export::{manifest_for, test_frf_datasets};
use frfbayes::signal::{estimate_test, EstimateOptions, ExpWindow};
use frfbayes::uff::{write_uff, Encoding};
use indicatif::ProgressBar;
use std::path::PathBuf;

/// Arguments of `frfbayes frf`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Campaign folder.
    pub campaign: PathBuf,
    /// Output folder: `<out>/<test>/frf.csv` and plots (replaced only when complete).
    #[arg(long)]
    pub out: PathBuf,
    /// Half-power band factor for the frequency-point selection.
    #[arg(long, default_value_t = 1.0)]
    pub band_factor: f64,
    /// Exponential window time constant on impact blocks, s (0: no window).
    #[arg(long, default_value_t = 20.0)]
    pub exp_window_tau_s: f64,
    /// Highest frequency kept, Hz.
    #[arg(long, default_value_t = 25.0)]
    pub freq_max_hz: f64,
    /// Least hammer pretrigger, samples: at least the half-length of the recorder's
    /// anti-alias filter (its pre-ringing); the pretrigger is `max(0.1 s, this)`.
    #[arg(long, default_value_t = frfbayes::signal::MIN_PRETRIGGER_SAMPLES)]
    pub min_pretrigger_samples: usize,
    /// Least half-width of the hammer force window beyond the pulse, samples: the same
    /// filter's ringing after the impact; the margin is `max(0.03 s, this - taper)`.
    #[arg(long, default_value_t = frfbayes::signal::MIN_FORCE_WINDOW_SAMPLES)]
    pub min_force_window_samples: usize,
    /// Write `frf.uff` as binary dataset 58b (exact doubles) instead of ASCII 58.
    #[arg(long)]
    pub uff_binary: bool,
}

/// Estimates, writes and plots.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.band_factor > 0.0, "--band-factor must be positive");
    anyhow::ensure!(
        args.exp_window_tau_s >= 0.0,
        "--exp-window-tau-s must not be negative"
    );
    let campaign = read_campaign(&args.campaign)?;
    for w in &campaign.warnings {
        eprintln!("warning: {w}");
    }
    let mut opts = EstimateOptions::default();
    opts.bands.band_factor = args.band_factor;
    opts.freq_max_hz = Some(args.freq_max_hz);
    opts.hammer.min_pretrigger_samples = args.min_pretrigger_samples;
    opts.hammer.min_force_window_samples = args.min_force_window_samples;
    opts.hammer.exp_window = if args.exp_window_tau_s > 0.0 {
        ExpWindow::TauS(args.exp_window_tau_s)
    } else {
        ExpWindow::None
    };
    let staged = StagedDir::new(&args.out)?;
    let pb = ProgressBar::new(campaign.tests.len() as u64);
    let mut frfs = Vec::new();
    for test in &campaign.tests {
        pb.set_message(test.name.clone());
        let frf = estimate_test(test, &opts)?;
        let dir = staged.path().join(&test.name);
        frfbayes::signal::frf_csv::write_frf_csv(&dir.join("frf.csv"), &frf)?;
        let encoding = if args.uff_binary {
            Encoding::Binary {
                little_endian: true,
            }
        } else {
            Encoding::Ascii
        };
        write_uff(&dir.join("frf.uff"), &test_frf_datasets(&frf), encoding)?;
        estimate_figures(&frf, &dir)?;
        let peaks: Vec<String> = frf
            .bands
            .iter()
            .map(|b| format!("{:.3}", b.peak_hz))
            .collect();
        pb.suspend(|| {
            println!(
                "{}: {} responses, {} averages, peaks at [{}] Hz, {} selected points",
                test.name,
                frf.responses.len(),
                frf.n_averages,
                peaks.join(", "),
                frf.selected.len()
            )
        });
        pb.inc(1);
        frfs.push(frf);
    }
    pb.finish_and_clear();
    let model = std::path::absolute(&args.campaign)?;
    let manifest = manifest_for(&frfs, &model, "frf.uff")?;
    frfbayes::io::write_atomic(&staged.path().join("frfs.toml"), manifest.as_bytes())?;
    let out = staged.commit()?;
    println!("wrote {}", out.display());
    Ok(())
}
