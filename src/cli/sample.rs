//! `frfbayes sample`: posterior sampling of the model given a campaign's FRFs.

use frfbayes::bayes::run::{
    checkpoint_path, resume_sample, run_sample, SampleOutcome, SampleSettings, StageFn,
    TestSelection,
};
use frfbayes::bayes::{BandSelection, BinCorrelation, PriorKind};
use frfbayes::frf::FrfKind;
use frfbayes::io::{OutputClaim, StagedDir};
use frfbayes::mcmc::{Progress, ProgressFn};
use frfbayes::predict::ModeSolverChoice;
use frfbayes::update::{DampingModel, ResidualForm};
use indicatif::{ProgressBar, ProgressStyle};
use std::ops::ControlFlow;
use std::path::PathBuf;

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DampingArg {
    Rayleigh,
    Caughey,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum FrfArg {
    Receptance,
    Accelerance,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum TestsArg {
    Hammer,
    #[value(name = "shake_table", alias = "shake-table")]
    ShakeTable,
    All,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum BinCorrelationArg {
    Independent,
    Window,
    Phase,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum BandSelectionArg {
    Measured,
    Model,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ResidualArg {
    Magnitude,
    LogMagnitude,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ModeSolverArg {
    /// Dense for models of up to 200 DOFs with mass on every DOF, else reduced.
    Auto,
    /// Every mode by the dense solver.
    Dense,
    /// The exact lowest modes by static condensation (slow; for checks).
    Exact,
    /// A Ritz reduced basis over the prior box, exact at the maximum-likelihood point.
    Reduced,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum PriorArg {
    /// Uniform masses and stiffnesses, log-uniform damping.
    Uniform,
    /// Uniform in physical units, damping included.
    UniformPhysical,
    /// Truncated lognormal (see --prior-cv, --prior-damping-ln-sd).
    Lognormal,
}

/// Arguments of `frfbayes sample`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (posterior.json, draws, figures; checkpoint while running).
    #[arg(long)]
    pub out: PathBuf,
    /// Continue the killed run of --out (its state is kept beside it, in
    /// `.<out>.frfbayes-partial`) or extend a finished run that stopped unconverged, from
    /// its checkpoint, with its settings.
    #[arg(long)]
    pub resume: bool,
    /// Step cap (default 20000; with --resume it may be raised).
    #[arg(long)]
    pub max_steps: Option<u64>,
    /// Campaign folder, or bundled:four-story (the default).
    #[arg(long)]
    pub campaign: Option<String>,
    /// Measured FRFs instead of a campaign: a manifest (TOML) mapping UFF 58/58b, .mat or
    /// CSV FRFs to model DOFs and naming the model (see the README, "Measured FRFs in").
    #[arg(long, value_name = "MANIFEST", conflicts_with = "campaign")]
    pub frfs: Option<PathBuf>,
    /// Damping model [default: caughey].
    #[arg(long, value_enum)]
    pub damping: Option<DampingArg>,
    /// FRF type [default: receptance].
    #[arg(long, value_enum)]
    pub frf: Option<FrfArg>,
    /// Tests to use [default: hammer].
    #[arg(long, value_enum)]
    pub tests: Option<TestsArg>,
    /// Master seed [default: 1].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Settings file to start from (a run's settings.toml); flags override it.
    #[arg(long)]
    pub settings: Option<PathBuf>,
    /// Residuals on magnitudes (default) or log-magnitudes.
    #[arg(long, value_enum)]
    pub residual: Option<ResidualArg>,
    /// Output noise of neighbouring bins: correlated as the estimator's exponential
    /// window makes a magnitude's error, `phase` (default: the window's complex bin
    /// correlation turned by the estimate's and the input's phase, the shared force
    /// noise at full rank), `window` (its modulus, an upper bound), or `independent`
    /// (the default before 2026-12-02; too narrow on general models). See
    /// docs/calibration.md.
    #[arg(long, value_enum)]
    pub bin_correlation: Option<BinCorrelationArg>,
    /// Where each test's bins are selected: after a first fit, again on the fitted
    /// model's FRFs (`model`, default: the peak bins and -3 dB points then do not lean on
    /// the noise of the bins they select; README), or on its estimate alone (`measured`,
    /// the default before 2026-12-02).
    #[arg(long, value_enum)]
    pub band_selection: Option<BandSelectionArg>,
    /// Pool the output noise's auto-spectrum behind each point's sd over this many bins
    /// either side [default: 8; 0: each bin's own coherence]; see the README.
    #[arg(long)]
    pub noise_pool_bins: Option<usize>,
    /// Prior family [default: uniform].
    #[arg(long, value_enum)]
    pub prior: Option<PriorArg>,
    /// Lowest modes in the modal sums [default: all for the dense solver; required for
    /// large models, e.g. every mode up to well above the highest frequency analysed].
    #[arg(long)]
    pub n_modes: Option<usize>,
    /// Mode solver [default: auto: dense for small models, a reduced basis for large ones
    /// or ones with massless DOFs].
    #[arg(long, value_enum)]
    pub mode_solver: Option<ModeSolverArg>,
    /// Upper frequency of the FRF estimates, Hz [default: the campaign's Nyquist
    /// frequency].
    #[arg(long)]
    pub freq_max_hz: Option<f64>,
    /// Lognormal prior: coefficient of variation of masses and stiffnesses [default: 0.1].
    #[arg(long)]
    pub prior_cv: Option<f64>,
    /// Lognormal prior: log standard deviation of damping [default: 1].
    #[arg(long)]
    pub prior_damping_ln_sd: Option<f64>,
    /// Floor on the relative standard deviation of a magnitude [default: 0.001].
    #[arg(long)]
    pub rel_sigma_floor: Option<f64>,
    /// Walkers per ensemble = this x number of parameters [default: 12].
    #[arg(long)]
    pub walkers_per_dim: Option<usize>,
    /// Independent ensembles [default: 4].
    #[arg(long)]
    pub ensembles: Option<usize>,
    /// Steps between checkpoints [default: 500].
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Multistart solves for the start point [default: 32].
    #[arg(long)]
    pub starts: Option<usize>,
    /// Prior box of every stiffness variable alpha, `LO,HI`: multipliers of the model's
    /// influence matrices, `K = K0 + sum_r alpha_r K_r` (for a shear frame and for a
    /// manifest whose `K_r` are the parts at their nominal values, story r has
    /// `k_r0 (1 + alpha_r)`) [default: -0.3,0.3].
    #[arg(long, value_name = "LO,HI", value_parser = parse_box, allow_hyphen_values = true)]
    pub alpha_bounds: Option<Box2>,
    /// Prior box of every mass variable beta, `LO,HI`, `M = M0 + sum_r beta_r M_r`
    /// [default: -0.1,0.111, the paper's bounds].
    #[arg(long, value_name = "LO,HI", value_parser = parse_box, allow_hyphen_values = true)]
    pub beta_bounds: Option<Box2>,
    /// Prior box of one variable by name, `NAME=LO,HI` (repeatable), overriding the
    /// above: `--bound k3=-0.5,0.5`, `--bound a1=1e-6,1e-2` (damping in physical units:
    /// a0 1/s [default 1e-4,1], a1 s [1e-10,1e-3], xiN [1e-4,0.1]).
    #[arg(long = "bound", value_name = "NAME=LO,HI", value_parser = parse_named_box, allow_hyphen_values = true)]
    pub bounds: Vec<(String, Box2)>,
}

/// A `[lower, upper]` pair given on the command line.
pub type Box2 = [f64; 2];

/// Parses `LO,HI` (finite, `LO < HI`).
fn parse_box(s: &str) -> Result<Box2, String> {
    let (lo, hi) = s
        .split_once(',')
        .ok_or_else(|| format!("'{s}': give the box as LO,HI, e.g. -0.3,0.3"))?;
    let num = |v: &str| {
        v.trim()
            .parse::<f64>()
            .map_err(|e| format!("'{s}': '{v}' is not a number ({e})"))
    };
    let (lo, hi) = (num(lo)?, num(hi)?);
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(format!("'{s}': the box needs finite LO < HI"));
    }
    Ok([lo, hi])
}

/// Parses `NAME=LO,HI`.
fn parse_named_box(s: &str) -> Result<(String, Box2), String> {
    let (name, b) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}': give NAME=LO,HI, e.g. k3=-0.5,0.5"))?;
    Ok((name.trim().to_string(), parse_box(b)?))
}

impl Args {
    fn problem_flags_given(&self) -> Vec<&'static str> {
        let flags = [
            ("--campaign", self.campaign.is_some()),
            ("--frfs", self.frfs.is_some()),
            ("--damping", self.damping.is_some()),
            ("--frf", self.frf.is_some()),
            ("--tests", self.tests.is_some()),
            ("--seed", self.seed.is_some()),
            ("--settings", self.settings.is_some()),
            ("--residual", self.residual.is_some()),
            ("--bin-correlation", self.bin_correlation.is_some()),
            ("--band-selection", self.band_selection.is_some()),
            ("--noise-pool-bins", self.noise_pool_bins.is_some()),
            ("--prior", self.prior.is_some()),
            ("--n-modes", self.n_modes.is_some()),
            ("--mode-solver", self.mode_solver.is_some()),
            ("--freq-max-hz", self.freq_max_hz.is_some()),
            ("--prior-cv", self.prior_cv.is_some()),
            ("--prior-damping-ln-sd", self.prior_damping_ln_sd.is_some()),
            ("--rel-sigma-floor", self.rel_sigma_floor.is_some()),
            ("--walkers-per-dim", self.walkers_per_dim.is_some()),
            ("--ensembles", self.ensembles.is_some()),
            ("--checkpoint-every", self.checkpoint_every.is_some()),
            ("--starts", self.starts.is_some()),
            ("--alpha-bounds", self.alpha_bounds.is_some()),
            ("--beta-bounds", self.beta_bounds.is_some()),
            ("--bound", !self.bounds.is_empty()),
        ];
        flags.iter().filter(|f| f.1).map(|f| f.0).collect()
    }

    fn settings(&self) -> anyhow::Result<SampleSettings> {
        let mut s = match &self.settings {
            Some(p) => SampleSettings::load(p)?,
            None => SampleSettings::new(
                "bundled:four-story".into(),
                DampingModel::Caughey,
                FrfKind::Receptance,
                TestSelection::Hammer,
                1,
            )?,
        };
        if let Some(c) = &self.campaign {
            s.campaign = c.clone();
            s.frfs = None;
        }
        if let Some(m) = &self.frfs {
            // absolute, so that --resume finds it from anywhere
            let m = std::path::absolute(m).unwrap_or_else(|_| m.clone());
            s.frfs = Some(m.to_string_lossy().into_owned());
        }
        if let Some(d) = self.damping {
            s.damping = match d {
                DampingArg::Rayleigh => DampingModel::Rayleigh,
                DampingArg::Caughey => DampingModel::Caughey,
            };
        }
        if let Some(f) = self.frf {
            s.frf = match f {
                FrfArg::Receptance => FrfKind::Receptance,
                FrfArg::Accelerance => FrfKind::Accelerance,
            };
        }
        if let Some(t) = self.tests {
            s.tests = match t {
                TestsArg::Hammer => TestSelection::Hammer,
                TestsArg::ShakeTable => TestSelection::ShakeTable,
                TestsArg::All => TestSelection::All,
            };
        }
        if let Some(v) = self.seed {
            s.seed = v;
        }
        if let Some(b) = self.bin_correlation {
            s.bin_correlation = match b {
                BinCorrelationArg::Independent => BinCorrelation::Independent,
                BinCorrelationArg::Window => BinCorrelation::Window,
                BinCorrelationArg::Phase => BinCorrelation::Phase,
            };
        }
        if let Some(w) = self.noise_pool_bins {
            s.noise_pool_bins = w;
        }
        if let Some(b) = self.band_selection {
            s.band_selection = match b {
                BandSelectionArg::Measured => BandSelection::Measured,
                BandSelectionArg::Model => BandSelection::Model,
            };
        }
        if let Some(r) = self.residual {
            s.residual = match r {
                ResidualArg::Magnitude => ResidualForm::Magnitude,
                ResidualArg::LogMagnitude => ResidualForm::LogMagnitude,
            };
        }
        let (cv0, sd0) = match s.posterior.prior {
            PriorKind::LogNormal { cv, damping_ln_sd } => (cv, damping_ln_sd),
            _ => (0.1, 1.0),
        };
        let (cv, sd) = (
            self.prior_cv.unwrap_or(cv0),
            self.prior_damping_ln_sd.unwrap_or(sd0),
        );
        match self.prior {
            Some(PriorArg::Uniform) => s.posterior.prior = PriorKind::Uniform,
            Some(PriorArg::UniformPhysical) => s.posterior.prior = PriorKind::UniformPhysical,
            Some(PriorArg::Lognormal) => {
                s.posterior.prior = PriorKind::LogNormal {
                    cv,
                    damping_ln_sd: sd,
                }
            }
            None => {
                if let PriorKind::LogNormal { .. } = s.posterior.prior {
                    s.posterior.prior = PriorKind::LogNormal {
                        cv,
                        damping_ln_sd: sd,
                    };
                } else {
                    anyhow::ensure!(
                        self.prior_cv.is_none() && self.prior_damping_ln_sd.is_none(),
                        "--prior-cv and --prior-damping-ln-sd need --prior lognormal"
                    );
                }
            }
        }
        if let Some(v) = self.rel_sigma_floor {
            s.rel_sigma_floor = v;
        }
        if let Some(f) = self.freq_max_hz {
            anyhow::ensure!(f.is_finite() && f > 0.0, "--freq-max-hz must be positive");
            s.estimate.freq_max_hz = Some(f);
        }
        if let Some(n) = self.n_modes {
            s.posterior.n_modes = Some(n);
        }
        if let Some(m) = self.mode_solver {
            s.posterior.mode_solver = match m {
                ModeSolverArg::Auto => ModeSolverChoice::Auto,
                ModeSolverArg::Dense => ModeSolverChoice::Dense,
                ModeSolverArg::Exact => ModeSolverChoice::Exact,
                ModeSolverArg::Reduced => ModeSolverChoice::Reduced,
            };
        }
        if let Some(v) = self.walkers_per_dim {
            s.walkers_per_dim = v;
        }
        if let Some(v) = self.ensembles {
            s.n_ensembles = v;
        }
        if let Some(v) = self.checkpoint_every {
            s.checkpoint_every = v;
        }
        if let Some(v) = self.starts {
            s.n_starts = v;
        }
        if let Some(v) = self.max_steps {
            s.max_steps = v;
        }
        if let Some(b) = self.alpha_bounds {
            s.variables.alpha = b;
        }
        if let Some(b) = self.beta_bounds {
            s.variables.beta = b;
        }
        for (name, b) in &self.bounds {
            s.variables.bounds.insert(name.clone(), *b);
        }
        Ok(s)
    }
}

fn progress_bar() -> ProgressBar {
    let pb = ProgressBar::new(1);
    pb.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} steps {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb
}

fn print(outcome: &SampleOutcome) {
    let s = &outcome.summary;
    println!("wrote {}", outcome.out.display());
    println!(
        "{} steps x {} walkers x {} ensembles, acceptance {:.3}, {} evaluations in {:.1} s ({:.0}/s), stopped: {}",
        s.n_steps,
        s.n_walkers,
        s.n_ensembles,
        s.acceptance,
        s.n_likelihood_evals,
        s.wall_s,
        s.n_likelihood_evals as f64 / s.wall_s.max(1e-9),
        s.stopped_because
    );
    println!(
        "{:<12} {:>12} {:>11} {:>7} {:>12} {:>12} {:>7} {:>8} {:>7}  at bound",
        "parameter", "mean", "sd", "cv %", "q2.5", "q97.5", "rhat", "ess_bulk", "tau"
    );
    for p in &s.parameters {
        println!(
            "{:<12} {:>12.5e} {:>11.3e} {:>7.3} {:>12.5e} {:>12.5e} {:>7.4} {:>8.0} {:>7.1}  {}",
            format!("{} ({})", p.name, p.unit),
            p.mean,
            p.sd,
            100.0 * p.cv,
            p.q2_5,
            p.q97_5,
            p.rhat,
            p.ess_bulk,
            p.tau,
            p.at_bound
                .map_or(String::new(), |b| format!("{b:?}").to_lowercase())
        );
    }
    if s.converged {
        println!(
            "converged: every R-hat < 1.01 (max {:.4}) and bulk ESS > 400 (min {:.0})",
            s.rhat_max, s.ess_bulk_min
        );
    } else {
        println!(
            "NOT converged (R-hat < 1.01, bulk ESS > 400, no stuck walkers: max R-hat {:.4}, \
             min ESS {:.0}, {} stuck); extend it with --resume --max-steps <more>",
            s.rhat_max, s.ess_bulk_min, s.n_stuck_walkers
        );
    }
}

/// `frfbayes fit`: the maximum-likelihood point of the posterior `sample` would sample,
/// with Gauss-Newton standard deviations (`fit.json`).
pub fn fit(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        !args.resume,
        "fit has no --resume: it starts again in seconds"
    );
    let settings = args.settings()?;
    let staged = StagedDir::new(&args.out)?;
    let report = frfbayes::bayes::fit::run_fit(&settings, staged.path())?;
    let out = staged.commit()?;
    println!("wrote {}", out.join("fit.json").display());
    println!(
        "{} points ({} bins dropped for zero coherence), {} starts, {} at the best cost {:.6e}",
        report.n_points,
        report.n_dropped_bins,
        report.start.n_starts,
        report.start.n_at_best,
        report.start.cost
    );
    println!("{:<20} {:>14} {:>12}", "parameter", "value", "sd (GN)");
    for p in &report.parameters {
        println!(
            "{:<20} {:>14.6e} {:>12.3e}",
            format!("{} ({})", p.name, p.unit),
            p.value,
            p.sd
        );
    }
    Ok(())
}

/// `sample --resume` into the claimed `--out`: a killed run continues aside and is
/// swapped in when done; a finished run that stopped unconverged is extended in place
/// (its outputs are rewritten only at the end; until then they stay as they were).
fn resume_claimed(
    args: &Args,
    claim: OutputClaim,
    stage: StageFn,
    on_step: &mut ProgressFn<'_>,
) -> anyhow::Result<SampleOutcome> {
    let interrupted = checkpoint_path(&claim.partial_path()).exists();
    let given = args.problem_flags_given();
    anyhow::ensure!(
        given.is_empty(),
        "--resume continues with the run's own settings ({}); drop {}",
        args.out.join("settings.toml").display(),
        given.join(", ")
    );
    anyhow::ensure!(
        interrupted || checkpoint_path(&args.out).exists(),
        "{}: nothing to resume (no interrupted run beside it, no checkpoint in it: the \
         run converged, or was stopped before its first checkpoint); start it again \
         without --resume",
        args.out.display()
    );
    if interrupted {
        let (staged, _) = StagedDir::resumable(claim, true)?;
        let mut o = resume_sample(staged.path(), args.max_steps, stage, Some(on_step))?;
        o.out = staged.commit()?;
        Ok(o)
    } else {
        let o = resume_sample(&args.out, args.max_steps, stage, Some(on_step))?;
        claim.refresh_manifest()?;
        Ok(o)
    }
}

/// A fresh `sample` into the claimed `--out`, run aside in its partial folder (kept for
/// `--resume` if the run is killed) and swapped in when done.
fn fresh_claimed(
    args: &Args,
    claim: OutputClaim,
    stage: StageFn,
    on_step: &mut ProgressFn<'_>,
) -> anyhow::Result<SampleOutcome> {
    let partial = claim.partial_path();
    anyhow::ensure!(
        !checkpoint_path(&partial).exists(),
        "{} holds the state of an interrupted run of {}: continue it with --resume, or \
         delete that folder to start over",
        partial.display(),
        args.out.display()
    );
    anyhow::ensure!(
        !checkpoint_path(&args.out).exists(),
        "{} holds an unfinished run (checkpoint.mcmc); extend it with --resume or delete it",
        args.out.display()
    );
    let settings = args.settings()?;
    let (staged, _) = StagedDir::resumable(claim, false)?;
    let mut o = run_sample(&settings, staged.path(), stage, Some(on_step))?;
    o.out = staged.commit()?;
    Ok(o)
}

/// The same run on a rank other than 0 of an MPI run: every rank samples the same
/// chain (its walkers' densities are spread over the ranks), but only rank 0 writes
/// `--out`; this rank writes into a scratch folder it deletes. To resume, it copies
/// the run's state before rank 0 goes on.
fn on_other_rank(args: &Args, stage: StageFn, on_step: &mut ProgressFn<'_>) -> anyhow::Result<()> {
    let scratch = frfbayes::io::ScratchDir::new("sample")?;
    let copied = if args.resume {
        let partial = frfbayes::io::partial_path_of(&args.out);
        let from = if checkpoint_path(&partial).exists() {
            partial
        } else {
            args.out.clone()
        };
        frfbayes::io::read_tree(&from)
            .and_then(|files| frfbayes::io::write_tree(scratch.path(), &files))
            .map_err(|e| e.to_string())
    } else {
        Ok(())
    };
    frfbayes::dist::barrier(copied)?;
    if args.resume {
        resume_sample(scratch.path(), args.max_steps, stage, Some(on_step))?;
    } else {
        run_sample(&args.settings()?, scratch.path(), stage, Some(on_step))?;
    }
    Ok(())
}

/// Runs or resumes a sampling run.
pub fn run(args: Args) -> anyhow::Result<()> {
    let pb = progress_bar();
    let stage = |msg: &str| pb.set_message(msg.to_string());
    let mut on_step = |p: &Progress| {
        pb.set_length(p.max_steps);
        pb.set_position(p.step);
        let tau = p
            .tau_steps
            .map(|t| format!(", tau max {:.1}", t.iter().copied().fold(0.0, f64::max)))
            .unwrap_or_default();
        pb.set_message(format!("acceptance {:.3}{tau}", p.acceptance));
        ControlFlow::Continue(())
    };
    if !frfbayes::dist::is_root() {
        let outcome = on_other_rank(&args, &stage, &mut on_step);
        pb.finish_and_clear();
        return outcome;
    }
    let claim = OutputClaim::claim(&args.out);
    // Under MPI, the other ranks copy a run to resume before this rank goes on.
    frfbayes::dist::barrier(claim.as_ref().map(|_| ()).map_err(|e| e.to_string()))?;
    let claim = claim?;
    let outcome = if args.resume {
        resume_claimed(&args, claim, &stage, &mut on_step)
    } else {
        fresh_claimed(&args, claim, &stage, &mut on_step)
    };
    pb.finish_and_clear();
    print(&outcome?);
    Ok(())
}
