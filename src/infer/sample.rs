//! The one sampling driver: an ensemble sampler run to convergence targets (R-hat, bulk
//! and tail ESS, emcee's tau rule), continuing the same chains until they hold.
//!
//! Every study samples through [`sample_to_targets`]; the `frfbayes sample` command adds
//! checkpoints and resumption around the same sampler.

use std::ops::ControlFlow;
use std::time::Instant;

use crate::error::Result;
use crate::mcmc::{
    ensemble_diagnostics, Burn, DifferentialEvolution, Draws, LogDensity, Moves, Progress, Sampler,
    SamplerConfig, Start, StopReason, Stretch,
};

/// Progress of a study's sampling: called after every sampler step with the label of the
/// posterior being sampled (the CLI draws a progress bar from it).
pub type OnStep<'a> = dyn FnMut(&str, &Progress) + 'a;

/// How a study samples: the progress callback, and an optional cap on the steps of
/// every run (smoke tests; `None` samples to the study's [`Targets`]).
pub struct Sampling<'a> {
    pub on_step: Box<OnStep<'a>>,
    pub step_cap: Option<u64>,
}

impl<'a> Sampling<'a> {
    /// Sampling to the targets, reporting every step to `on_step`.
    pub fn new(on_step: impl FnMut(&str, &Progress) + 'a) -> Self {
        Sampling {
            on_step: Box::new(on_step),
            step_cap: None,
        }
    }

    /// Silent sampling with every run capped at `steps` steps.
    pub fn capped(steps: u64) -> Self {
        Sampling {
            on_step: Box::new(|_, _| {}),
            step_cap: Some(steps),
        }
    }

    /// Silent sampling to the targets.
    pub fn quiet() -> Self {
        Sampling::new(|_, _| {})
    }
}

/// Convergence targets: keep sampling (continuing the same chains) until every sampled
/// coordinate has R-hat below `max_rhat` and bulk and tail ESS above `min_ess`, or
/// `hard_cap_steps`.
#[derive(Debug, Clone, PartialEq)]
pub struct Targets {
    pub max_rhat: f64,
    pub min_ess: f64,
    /// First step cap; extended by half each time the targets are missed.
    pub first_cap_steps: u64,
    pub hard_cap_steps: u64,
}

impl Default for Targets {
    fn default() -> Self {
        Targets {
            max_rhat: 1.01,
            min_ess: 400.0,
            first_cap_steps: 4000,
            hard_cap_steps: 60_000,
        }
    }
}

/// A finished run: draws after [`Burn::Auto`], its bookkeeping, and whether the targets
/// were met.
#[derive(Debug, Clone)]
pub struct Sampled {
    pub draws: Draws,
    pub n_walkers: usize,
    pub n_steps: u64,
    pub n_evaluations: u64,
    pub acceptance: f64,
    /// Integrated autocorrelation time per coordinate, in steps.
    pub tau_steps: Vec<f64>,
    pub wall_s: f64,
    /// `Converged` when emcee's tau rule and the targets hold, `StepCap` when the hard
    /// cap came first.
    pub stopped_because: StopReason,
    pub worst_rhat: f64,
    pub min_ess: f64,
    /// The whole chain from step 0, thinned to at most ~500 kept steps, for trace plots.
    pub full: Draws,
    /// Acceptance fraction of every walker chain (ensemble-major, the chains of `draws`).
    pub acceptance_per_chain: Vec<f64>,
    /// Every k-th draw of each walker of `draws` with its pointwise log-likelihood (at
    /// most [`MAX_LOG_LIKELIHOOD_DRAWS`] draws in all), when the density has pointwise
    /// terms; for the `log_likelihood` group of `inference_data.nc` (`az.loo`).
    pub log_likelihood: Option<Draws>,
}

/// Most draws (all chains) at which [`Sampled::log_likelihood`] is evaluated: enough for
/// PSIS-LOO (Stan's default run keeps 4000), bounded so that an expensive model (the
/// bridge) pays at most this many extra evaluations.
pub const MAX_LOG_LIKELIHOOD_DRAWS: usize = 4000;

/// [`Sampled::log_likelihood`] of `draws` under `density` (`None` without pointwise terms).
fn log_likelihood_draws<D: LogDensity + ?Sized>(
    density: &D,
    draws: &Draws,
) -> Result<Option<Draws>> {
    if density.n_pointwise() == 0 {
        return Ok(None);
    }
    let rows = draws.n_chains * draws.n_draws;
    let mut thinned = draws.thinned(rows.div_ceil(MAX_LOG_LIKELIHOOD_DRAWS).max(1));
    thinned.compute_pointwise(density)?;
    Ok(Some(thinned))
}

impl Sampled {
    /// Chains of coordinate `p` mapped through `f`.
    pub fn chains(&self, p: usize, f: impl Fn(f64) -> f64 + Sync) -> Vec<Vec<f64>> {
        self.draws.map_chains(|x| f(x[p]))
    }
}

/// The moves used throughout: stretch (a = 2) mixed with differential evolution, which
/// helps on the narrow, curved ridges of modal posteriors.
pub fn default_moves() -> Result<Moves> {
    Moves::mixture(vec![
        (Box::new(Stretch::default()), 0.7),
        (Box::new(DifferentialEvolution::default()), 0.3),
    ])
}

/// Runs the ensemble sampler on `density` from `start` until emcee's stopping rule and
/// `targets` hold (or the hard cap), and returns the draws after [`Burn::Auto`].
/// `sampling.on_step` is called with `label` after every step; `sampling.step_cap`
/// lowers both step caps of `targets`.
pub fn sample_to_targets<D: LogDensity + ?Sized>(
    density: &D,
    start: Start,
    n_walkers: usize,
    seed: u64,
    targets: &Targets,
    label: &str,
    sampling: &mut Sampling<'_>,
) -> Result<Sampled> {
    let t0 = Instant::now();
    let mut targets = targets.clone();
    if let Some(n) = sampling.step_cap {
        targets.first_cap_steps = targets.first_cap_steps.min(n);
        targets.hard_cap_steps = targets.hard_cap_steps.min(n);
    }
    let on_step = &mut sampling.on_step;
    let mut config = SamplerConfig::new(n_walkers, seed);
    config.max_steps = targets.first_cap_steps;
    let mut sampler = Sampler::new(density, default_moves()?, config, start)?;
    let mut cap = targets.first_cap_steps;
    loop {
        let mut cb = |p: &Progress| {
            on_step(label, p);
            ControlFlow::Continue(())
        };
        let summary = sampler.run(Some(&mut cb))?;
        let done_tau = summary.stopped_because == StopReason::Converged;
        let (worst_rhat, min_ess) = match sampler.draws(Burn::Auto) {
            Ok(d) => worst_diagnostics(&d),
            Err(_) => (f64::INFINITY, 0.0),
        };
        let met = worst_rhat < targets.max_rhat && min_ess > targets.min_ess;
        let at_cap = sampler.step_count() >= cap;
        if (done_tau && met) || (at_cap && cap >= targets.hard_cap_steps) {
            // Burn::Auto needs a tau estimate; a capped smoke run may stop before one
            // exists, and then keeps the second half as `frfbayes sample` does.
            let draws = sampler.draws(Burn::Auto).or_else(|_| {
                let s = sampler.step_count();
                sampler.draws(Burn::Steps {
                    discard: s / 2,
                    thin: 1,
                })
            })?;
            let thin = (sampler.step_count() / 500).max(1);
            let full = sampler.draws(Burn::Steps { discard: 0, thin })?;
            let stopped_because = if done_tau && met {
                StopReason::Converged
            } else {
                StopReason::StepCap
            };
            let log_likelihood = log_likelihood_draws(density, &draws)?;
            return Ok(Sampled {
                acceptance_per_chain: sampler.acceptance_fractions().concat(),
                log_likelihood,
                draws,
                n_walkers,
                n_steps: sampler.step_count(),
                n_evaluations: sampler.n_evaluations(),
                acceptance: sampler.acceptance(),
                tau_steps: sampler.tau_estimates().iter().map(|t| t.tau).collect(),
                wall_s: t0.elapsed().as_secs_f64(),
                stopped_because,
                worst_rhat,
                min_ess,
                full,
            });
        }
        if at_cap {
            cap = (cap + cap / 2).min(targets.hard_cap_steps);
            sampler.set_max_steps(cap);
        }
    }
}

/// Largest R-hat and smallest bulk/tail ESS over the coordinates of `draws`.
pub fn worst_diagnostics(draws: &Draws) -> (f64, f64) {
    let mut worst = (1.0f64, f64::INFINITY);
    for p in 0..draws.dim {
        let d = ensemble_diagnostics(&draws.param_chains(p), draws.n_walkers);
        worst.0 = worst.0.max(d.rhat);
        worst.1 = worst.1.min(d.ess_bulk.min(d.ess_tail));
    }
    worst
}
