//! The runner: `K` independent ensembles stepped together until the chain is long and
//! the autocorrelation time has settled (emcee's recipe), or a step cap.
//!
//! Stopping (checked every `check_every` steps, on the whole stored chain, walkers of
//! all ensembles pooled): stop when, for every parameter, `step > tau_multiple * tau`
//! (50) and `|tau - tau_prev| / tau < tau_rel_change` (1%), `tau_prev` being the
//! previous check's estimate, and Sokal's window was found.
//!
//! Burn-in and thinning ([`Burn::Auto`]): discard the first half of the steps, and at
//! least `ceil(2 max tau)` (Stan's and Gelman et al.'s convention; under the stopping rule
//! the kept half is still longer than 25 tau), and keep every `max(1, floor(min tau / 2))`-th
//! step, but keep at least [`MIN_DRAWS_PER_WALKER`] draws per walker (a judgement call:
//! under the stopping rule, thinning by tau/2 would leave ~50 draws per walker, 25 per
//! split half-chain, few lags for Geyer's ESS estimator to work with). emcee's documentation discards only `2 max tau` ([`Burn::Tau`]); that assumes
//! the walkers started in the typical set: a seeded test on a 10-D Gaussian started
//! from a tiny ball 16 sd away showed variances biased by 4-5 Monte Carlo standard
//! errors after a `2 tau` burn-in, and none after discarding half.

use std::ops::ControlFlow;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::autocorr::{integrated_times_by_walker, TauEstimate};
use super::config::validate;
pub use super::config::{CheckpointConfig, SamplerConfig, MIN_DRAWS_PER_WALKER, MIN_ENSEMBLES};
use super::density::LogDensity;
use super::draws::Draws;
use super::ensemble::Ensemble;
#[allow(unused_imports)] // for the docs
use super::evaluate::Threads;
use super::evaluate::{Evaluator, Ranks};
use super::moves::Moves;
use super::rng::{key_from_seed, walker_rng};
use crate::error::{Error, Result};

/// An initial ball `center + scale ⊙ N(0, I)` (scale per parameter).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ball {
    /// Center.
    pub center: Vec<f64>,
    /// Standard deviation per parameter (> 0).
    pub scale: Vec<f64>,
}

/// How the walkers start.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    /// Every ensemble from the same ball.
    Ball(Ball),
    /// One ball per ensemble (e.g. different optima, for R-hat's sake).
    Balls(Vec<Ball>),
    /// Explicit positions, `n_ensembles * n_walkers` of them, ensemble-major.
    Positions(Vec<Vec<f64>>),
}

/// Why a run stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The tau criteria were met.
    Converged,
    /// `max_steps` was reached first.
    StepCap,
    /// The progress callback asked to stop.
    Interrupted,
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StopReason::Converged => "converged",
            StopReason::StepCap => "step_cap",
            StopReason::Interrupted => "interrupted",
        })
    }
}

/// One convergence check.
#[derive(Debug, Clone, PartialEq)]
pub struct TauCheck {
    /// Step of the check.
    pub step: u64,
    /// Integrated autocorrelation time per parameter, in steps.
    pub tau_steps: Vec<f64>,
    /// Sokal's window found for every parameter.
    pub window_found: bool,
}

/// What the progress callback sees after each step.
#[derive(Debug, Clone, Copy)]
pub struct Progress<'a> {
    /// Steps done.
    pub step: u64,
    /// Step cap.
    pub max_steps: u64,
    /// Acceptance fraction so far, all walkers.
    pub acceptance: f64,
    /// Latest tau estimate (steps), per parameter.
    pub tau_steps: Option<&'a [f64]>,
    /// Density evaluations so far (initial ones included).
    pub n_evaluations: u64,
}

/// Steps between progress reports: the ensembles run this many steps in parallel
/// between meetings (see [`Sampler::run`]).
pub const REPORT_EVERY_STEPS: u64 = 10;

/// The progress callback of [`Sampler::run`]: called every [`REPORT_EVERY_STEPS`] steps
/// and after every convergence check, checkpoint and the last step; returning
/// `ControlFlow::Break(())` stops the run there (a checkpoint is written when
/// configured).
pub type ProgressFn<'a> = dyn FnMut(&Progress) -> ControlFlow<()> + 'a;

/// Outcome of [`Sampler::run`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// Why the run stopped.
    pub stopped_because: StopReason,
    /// Steps done.
    pub steps: u64,
    /// Latest tau estimate (steps) per parameter; empty before the first check.
    pub tau_steps: Vec<f64>,
    /// Acceptance fraction, all walkers.
    pub acceptance: f64,
    /// Density evaluations (initial ones included).
    pub n_evaluations: u64,
}

/// Burn-in and thinning for [`Sampler::draws`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Burn {
    /// Discard half the steps (at least `ceil(2 max tau)`), thin by
    /// `max(1, floor(min tau / 2))` while keeping at least [`MIN_DRAWS_PER_WALKER`] draws.
    Auto,
    /// emcee's advice: discard `ceil(multiple * max tau)` steps (`multiple` = 2 in its
    /// docs), thin as [`Burn::Auto`].
    Tau { multiple: f64 },
    /// Discard the first `discard` steps; keep every `thin`-th step (rounded down to a
    /// multiple of `thin_by`, at least one stored state).
    Steps { discard: u64, thin: u64 },
}

/// The ensemble sampler with its state. See the module docs of [`crate::mcmc`].
pub struct Sampler<'d, D: LogDensity + ?Sized> {
    pub(super) density: &'d D,
    pub(super) moves: Moves,
    pub(super) config: SamplerConfig,
    pub(super) ensembles: Vec<Ensemble>,
    pub(super) step: u64,
    pub(super) history: Vec<TauCheck>,
    pub(super) failed: Option<String>,
    pub(super) evaluator: Box<dyn Evaluator>,
}

impl<'d, D: LogDensity + ?Sized> Sampler<'d, D> {
    /// Validates the settings, builds the ensembles from `start` and evaluates them.
    pub fn new(density: &'d D, moves: Moves, config: SamplerConfig, start: Start) -> Result<Self> {
        validate(density, &moves, &config)?;
        let key = key_from_seed(config.seed);
        let (k, w, dim) = (config.n_ensembles, config.n_walkers, density.dim());
        let sp = config.store_pointwise;
        let ensembles = match start {
            Start::Ball(ball) => (0..k)
                .map(|e| {
                    Ensemble::from_ball(density, key, e, w, &ball.center, &ball.scale, sp, &Ranks)
                })
                .collect::<Result<Vec<_>>>()?,
            Start::Balls(balls) => {
                if balls.len() != k {
                    return Err(Error::Usage(format!(
                        "{} initial balls for {k} ensembles",
                        balls.len()
                    )));
                }
                balls
                    .iter()
                    .enumerate()
                    .map(|(e, b)| {
                        Ensemble::from_ball(density, key, e, w, &b.center, &b.scale, sp, &Ranks)
                    })
                    .collect::<Result<Vec<_>>>()?
            }
            Start::Positions(p) => {
                if p.len() != k * w || p.iter().any(|x| x.len() != dim) {
                    return Err(Error::Usage(format!(
                        "initial positions: need {} vectors of length {dim} \
                         (ensembles x walkers), got {}",
                        k * w,
                        p.len()
                    )));
                }
                p.chunks(w)
                    .enumerate()
                    .map(|(e, ps)| {
                        let rngs = (0..w).map(|i| walker_rng(key, e, i)).collect();
                        Ensemble::from_positions(density, key, e, ps.concat(), rngs, sp, &Ranks)
                    })
                    .collect::<Result<Vec<_>>>()?
            }
        };
        Ok(Sampler {
            density,
            moves,
            config,
            ensembles,
            step: 0,
            history: Vec::new(),
            failed: None,
            evaluator: Box::new(Ranks),
        })
    }

    /// Steps until converged, the step cap, or the callback returns `Break`; writes
    /// checkpoints on the way and at the end when configured. Calling `run` again (or
    /// after [`Sampler::set_max_steps`]) continues the same chain.
    pub fn run(&mut self, mut progress: Option<&mut ProgressFn<'_>>) -> Result<RunSummary> {
        if let Some(why) = &self.failed {
            return Err(Error::Usage(format!(
                "the sampler failed earlier ({why}); resume from a checkpoint"
            )));
        }
        let reason = loop {
            if self.step >= self.config.max_steps {
                break StopReason::StepCap;
            }
            if let Err(e) = self.advance(self.block_len()) {
                self.failed = Some(e.to_string());
                return Err(e);
            }
            let converged =
                self.step.is_multiple_of(self.config.check_every) && self.check_convergence();
            if let Some(cp) = &self.config.checkpoint {
                if self.step.is_multiple_of(cp.every_steps) {
                    self.save_checkpoint(&cp.path)?;
                }
            }
            let interrupted = match progress.as_deref_mut() {
                Some(cb) => cb(&self.progress()).is_break(),
                None => false,
            };
            if converged {
                break StopReason::Converged;
            }
            if interrupted {
                break StopReason::Interrupted;
            }
        };
        if let Some(cp) = &self.config.checkpoint {
            self.save_checkpoint(&cp.path)?;
        }
        Ok(RunSummary {
            stopped_because: reason,
            steps: self.step,
            tau_steps: self
                .history
                .last()
                .map(|h| h.tau_steps.clone())
                .unwrap_or_default(),
            acceptance: self.acceptance(),
            n_evaluations: self.n_evaluations(),
        })
    }

    /// Steps to the next event: a progress report (every [`REPORT_EVERY_STEPS`]), a
    /// convergence check, a checkpoint or the step cap.
    fn block_len(&self) -> u64 {
        let to_next = |every: u64| every - self.step % every;
        let mut n = to_next(REPORT_EVERY_STEPS).min(to_next(self.config.check_every));
        if let Some(cp) = &self.config.checkpoint {
            n = n.min(to_next(cp.every_steps));
        }
        n.min(self.config.max_steps - self.step)
    }

    /// `n_steps` steps of every ensemble, storing every `thin_by`-th state. The ensembles
    /// run their blocks in parallel and meet only at the end, so each thread works
    /// undisturbed for `n_steps` steps. With fewer ensembles than threads, each one
    /// also spreads its walkers over the pool. With a collective evaluator (several
    /// ranks), the ensembles step in turn on this thread, each half spread over the
    /// ranks and their threads. Every walker draws from its own stream, so the chains
    /// are the same whatever the thread and rank count.
    fn advance(&mut self, n_steps: u64) -> Result<()> {
        let (density, moves, rs) = (self.density, &self.moves, self.config.randomize_split);
        let (start, thin_by) = (self.step, self.config.thin_by);
        let evaluator = self.evaluator.as_ref();
        let block = |e: &mut Ensemble, walkers_parallel: bool| -> Result<()> {
            for step in start + 1..=start + n_steps {
                e.step(density, moves, rs, walkers_parallel, evaluator)?;
                if step.is_multiple_of(thin_by) {
                    e.store();
                }
            }
            Ok(())
        };
        if evaluator.collective() {
            for e in &mut self.ensembles {
                block(e, true)?;
            }
        } else {
            let walkers_parallel = self.ensembles.len() < rayon::current_num_threads();
            let results: Vec<Result<()>> = self
                .ensembles
                .par_iter_mut()
                .with_max_len(1)
                .map(|e| block(e, walkers_parallel))
                .collect();
            results.into_iter().collect::<Result<Vec<()>>>()?;
        }
        self.step += n_steps;
        Ok(())
    }

    /// Replaces how proposals are evaluated (default: [`Ranks`], which is [`Threads`]
    /// in one process). The chain does not depend on it.
    pub fn set_evaluator(&mut self, evaluator: Box<dyn Evaluator>) {
        self.evaluator = evaluator;
    }

    /// Records a tau check; true when emcee's criteria hold.
    fn check_convergence(&mut self) -> bool {
        let est = self.tau_estimates();
        let tau_steps: Vec<f64> = est
            .iter()
            .map(|t| t.tau * self.config.thin_by as f64)
            .collect();
        let window_found = est.iter().all(|t| t.window_found);
        let long = tau_steps
            .iter()
            .all(|t| t.is_finite() && self.config.tau_multiple * t < self.step as f64);
        let stable = self.history.last().is_some_and(|prev| {
            prev.tau_steps
                .iter()
                .zip(&tau_steps)
                .all(|(p, t)| (p - t).abs() / t < self.config.tau_rel_change)
        });
        self.history.push(TauCheck {
            step: self.step,
            tau_steps,
            window_found,
        });
        window_found && long && stable
    }

    /// emcee's integrated autocorrelation time of every parameter on the stored chain
    /// (in stored samples; multiply by `thin_by` for steps), walkers of all ensembles
    /// pooled, `c = 5`.
    pub fn tau_estimates(&self) -> Vec<TauEstimate> {
        let dim = self.density.dim();
        let w = self.config.n_walkers;
        let n = self.ensembles[0].n_stored();
        let k = self.ensembles.len();
        // Walker i = walker i % w of ensemble i / w; its block is (stored step, parameter).
        let fill = |i: usize, block: &mut [f64]| {
            let (e, wi) = (&self.ensembles[i / w], i % w);
            for (t, row) in block.chunks_mut(dim).enumerate() {
                let s = (t * w + wi) * dim;
                row.copy_from_slice(&e.chain[s..s + dim]);
            }
        };
        integrated_times_by_walker(n, dim, k * w, &fill, 5.0)
    }

    fn progress(&self) -> Progress<'_> {
        Progress {
            step: self.step,
            max_steps: self.config.max_steps,
            acceptance: self.acceptance(),
            tau_steps: self.history.last().map(|h| h.tau_steps.as_slice()),
            n_evaluations: self.n_evaluations(),
        }
    }

    /// Changes the step cap (e.g. to extend a resumed run).
    pub fn set_max_steps(&mut self, max_steps: u64) {
        self.config.max_steps = max_steps;
    }

    /// Changes where (and whether) checkpoints are written, e.g. after resuming from a
    /// moved file.
    pub fn set_checkpoint(&mut self, checkpoint: Option<CheckpointConfig>) -> Result<()> {
        if checkpoint.as_ref().is_some_and(|cp| cp.every_steps == 0) {
            return Err(Error::Usage(
                "checkpoint every_steps must be at least 1".into(),
            ));
        }
        self.config.checkpoint = checkpoint;
        Ok(())
    }

    /// Steps done.
    pub fn step_count(&self) -> u64 {
        self.step
    }

    /// The settings.
    pub fn config(&self) -> &SamplerConfig {
        &self.config
    }

    /// All convergence checks so far.
    pub fn tau_history(&self) -> &[TauCheck] {
        &self.history
    }

    /// Density evaluations so far (initial ones included).
    pub fn n_evaluations(&self) -> u64 {
        (self.config.n_ensembles * self.config.n_walkers) as u64 * (self.step + 1)
    }

    /// Acceptance fraction of every walker, per ensemble.
    pub fn acceptance_fractions(&self) -> Vec<Vec<f64>> {
        let s = self.step.max(1) as f64;
        self.ensembles
            .iter()
            .map(|e| e.accepted.iter().map(|&a| a as f64 / s).collect())
            .collect()
    }

    /// Acceptance fraction of all walkers together.
    pub fn acceptance(&self) -> f64 {
        let acc: u64 = self.ensembles.iter().flat_map(|e| &e.accepted).sum();
        acc as f64
            / (self.step.max(1) * (self.config.n_ensembles * self.config.n_walkers) as u64) as f64
    }

    /// Current positions, ensemble-major then walker, `dim` each.
    pub fn positions(&self) -> Vec<Vec<f64>> {
        let dim = self.density.dim();
        self.ensembles
            .iter()
            .flat_map(|e| e.positions.chunks(dim).map(|c| c.to_vec()))
            .collect()
    }

    /// Draws after burn-in and thinning, walkers of all ensembles as chains
    /// (chain = ensemble * n_walkers + walker).
    pub fn draws(&self, burn: Burn) -> Result<Draws> {
        let thin_by = self.config.thin_by;
        let (discard, thin) = match burn {
            Burn::Steps { discard, thin } => (discard, thin),
            Burn::Auto | Burn::Tau { .. } => {
                let tau: Vec<f64> = self
                    .tau_estimates()
                    .iter()
                    .map(|t| t.tau * thin_by as f64)
                    .collect();
                if tau.is_empty() || tau.iter().any(|t| !t.is_finite()) {
                    return Err(Error::Usage(
                        "no autocorrelation time yet: run the sampler longer".into(),
                    ));
                }
                let max = tau.iter().copied().fold(f64::MIN, f64::max);
                let min = tau.iter().copied().fold(f64::MAX, f64::min);
                let by_tau = match burn {
                    Burn::Tau { multiple } => (multiple * max).ceil() as u64,
                    _ => ((2.0 * max).ceil() as u64).max(self.step / 2),
                };
                let kept_steps = self.step.saturating_sub(by_tau);
                let thin = ((0.5 * min).floor() as u64)
                    .min(kept_steps / MIN_DRAWS_PER_WALKER)
                    .max(1);
                (by_tau, thin)
            }
        };
        let first = (discard / thin_by) as usize;
        let stride = (thin / thin_by).max(1) as usize;
        let n_stored = self.ensembles[0].n_stored();
        if first >= n_stored {
            return Err(Error::Usage(format!(
                "burn-in of {discard} steps leaves no draws ({} steps stored)",
                n_stored as u64 * thin_by
            )));
        }
        let kept: Vec<usize> = (first..n_stored).step_by(stride).collect();
        Ok(Draws::from_ensembles(
            &self.ensembles,
            &kept,
            self.density.dim(),
            discard,
            stride as u64 * thin_by,
        ))
    }
}
