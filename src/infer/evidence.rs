//! Marginal likelihood (evidence) `Z = int L(z) pi(z) dz` of a model by tempered
//! ensembles, for comparing hypotheses of missing physics (issue 5, step 3).
//!
//! ## Method
//! Each replicate is a sequential Monte Carlo sampler over the power posteriors
//! `p_beta ∝ L^beta pi` (Del Moral, Doucet & Jasra 2006), run by the ensemble moves of
//! [`crate::mcmc`]:
//! 1. `n_walkers` independent prior draws at `beta_0 = 0`;
//! 2. the next temperature `beta_{k+1}` is found by bisection so that the effective
//!    sample size of the incremental weights `w_j = exp((beta_{k+1} - beta_k) ln L_j)` is
//!    `target_cess` times the walkers (Zhou, Johansen & Aston 2016), or 1 if that step
//!    already keeps it;
//! 3. stepping-stone increment `ln r_k = ln mean_j w_j` (log-sum-exp); then systematic
//!    resampling by `w_j` and ensemble steps (red-blue split, the
//!    [`EvidenceOptions::moves`] mixture) targeting `p_{beta_{k+1}}` until the walkers
//!    have moved far enough (see [`EvidenceOptions::min_steps_per_temperature`]);
//! 4. at `beta = 1`: `ln Z = sum_k ln r_k` (the stepping-stone estimator of Xie et al.
//!    2011 on this ladder, which is also the SMC estimator: unbiased for `Z`).
//!
//! Thermodynamic integration on the same ladder is a cross-check:
//! `ln Z = int_0^1 E_beta[ln L] d beta` by the trapezoid rule with the derivative
//! correction `- h^2 (V_{k+1} - V_k) / 12`, `V = Var_beta[ln L] = dE/d beta` (Friel,
//! Hurn & Wyse 2014). It is biased by the discretisation where the ladder is coarse;
//! agreement with the stepping-stone value within a few standard errors shows the
//! ladder is fine enough.
//!
//! The reported `ln Z` is the mean of the replicates' estimates, its standard error
//! their standard deviation over `sqrt(n_replicates)` (replicates are independent:
//! separate random streams). As `Z`-hat is unbiased, `ln Z`-hat is biased low by about
//! half its variance (`n_replicates x ln_z_se^2 / 2`), negligible when `ln_z_se` is
//! small.
//!
//! After the ladder, every replicate's ensemble takes `final_steps` more steps at
//! `beta = 1`; all are kept as posterior draws (the ensemble is already at the
//! posterior, so no burn-in is needed), with R-hat (replicates as chains) and the
//! integrated autocorrelation time.
//!
//! ## Accuracy and limits (measured in `tests/discrepancy_evidence.rs`)
//! On a 15-D linear-Gaussian model whose `ln L` rises by ~6e6 nats from prior to
//! posterior, the defaults take ~41 temperatures, ~30 steps each and ~1.2e5 likelihood
//! evaluations per call; one replicate's `ln Z` has sd ~0.9 and the mean over replicates
//! is ~0.5 nats high (with 64 walkers; the bias shrinks with more walkers and more steps
//! per temperature, e.g. -0.15 with 92 walkers). `ln_z_se` does not include that bias,
//! and with 2 replicates it is itself uncertain (one degree of freedom): allow ~1 nat
//! beside it when comparing models. Modes of different widths can be lost: a narrow
//! mode whose tempered mass falls below one walker's share at low `beta` gets no
//! walkers and does not come back (a known limit of tempering).
//!
//! ## Reproducibility
//! Replicate `r` uses the [`crate::mcmc`] stream conventions with ensemble index `r`:
//! walker `w` draws its prior sample and all its proposals from stream `r << 32 | w`,
//! and the move choice, split shuffle and resampling uniform come from the ensemble
//! stream. Results are bit-identical for a seed whatever the number of threads.

use std::sync::atomic::{AtomicU64, Ordering};

use rand_chacha::ChaCha8Rng;

use super::tempering::{temper, Tempered, TemperingRun};
use crate::error::{Error, Result};
use crate::mcmc::{
    ensemble_diagnostics, integrated_time, key_from_seed, Diagnostics, Draws, MoveSpec, Moves,
    Ranks, WeightedMove,
};

/// A model for evidence computation: a normalised prior and a likelihood.
pub trait TemperedTarget: Sync {
    /// Number of parameters.
    fn dim(&self) -> usize;
    /// Normalised log prior density (`int exp(ln_prior) dz = 1`); `-inf` outside the
    /// support.
    fn ln_prior(&self, z: &[f64]) -> f64;
    /// Log likelihood; finite everywhere inside the prior support (`Err` on a failed
    /// model evaluation).
    fn ln_likelihood(&self, z: &[f64]) -> Result<f64>;
    /// One draw from the prior.
    fn sample_prior(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>>;
}

/// Settings of [`stepping_stone`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvidenceOptions {
    /// Master seed.
    pub seed: u64,
    /// Walkers per replicate ensemble (at least `2 dim + 2`).
    pub n_walkers: usize,
    /// Independent replicate runs (at least 2, for the standard error).
    pub n_replicates: usize,
    /// ESS fraction of the incremental weights kept at each temperature step, in (0, 1).
    pub target_cess: f64,
    /// Ensemble steps at every temperature after resampling: at least
    /// `min_steps_per_temperature`, then until the walkers' mean squared jump since the
    /// resampling, in the metric of the previous cloud's covariance and per dimension,
    /// reaches `jump_target` (2 = as far apart as independent draws), at most
    /// `max_steps_per_temperature`.
    pub min_steps_per_temperature: usize,
    /// See `min_steps_per_temperature`.
    pub max_steps_per_temperature: usize,
    /// See `min_steps_per_temperature`.
    pub jump_target: f64,
    /// Ensemble steps at `beta = 1` kept as posterior draws (0: no draws).
    pub final_steps: usize,
    /// Error out beyond this many temperatures.
    pub max_temperatures: usize,
    /// Move mixture.
    pub moves: Vec<WeightedMove>,
}

impl EvidenceOptions {
    /// Defaults for `dim` parameters, designed for ~1e5 likelihood evaluations per call
    /// when `dim` is ~15 and the likelihood gains ~1e3-1e5 nats from prior to posterior
    /// (measured on a 15-D linear-Gaussian model: ~1.2e5 evaluations, `ln_z_se` ~0.7;
    /// see `tests/discrepancy_evidence.rs`): `n_walkers = max(4 (dim + 1), 64)` (after resampling
    /// about `target_cess` of the walkers are distinct, and half of those, one split,
    /// must still span the `dim` directions; with `2 dim + 2` walkers the ensemble
    /// collapses onto a subspace and `ln Z` is off by tens of nats), 2 replicates,
    /// `target_cess = 0.6`,
    /// 2..=100 steps per temperature with `jump_target = 1`, 100 final steps, moves:
    /// differential evolution with
    /// `gamma0 = 2.38 / sqrt(2 dim)` (weight 0.7) and `gamma0 = 1` (0.1, mode jumping,
    /// ter Braak 2006), stretch (0.2).
    pub fn new(dim: usize, seed: u64) -> Self {
        let n_walkers = (4 * (dim + 1)).max(64);
        EvidenceOptions {
            seed,
            n_walkers,
            n_replicates: 2,
            target_cess: 0.6,
            min_steps_per_temperature: 2,
            max_steps_per_temperature: 100,
            jump_target: 1.0,
            final_steps: 100,
            max_temperatures: 2000,
            moves: vec![
                WeightedMove {
                    spec: MoveSpec::De {
                        gamma0: None,
                        sigma: 0.1,
                    },
                    weight: 0.7,
                },
                WeightedMove {
                    spec: MoveSpec::De {
                        gamma0: Some(1.0),
                        sigma: 1e-5,
                    },
                    weight: 0.1,
                },
                WeightedMove {
                    spec: MoveSpec::Stretch { a: 2.0 },
                    weight: 0.2,
                },
            ],
        }
    }

    fn validate(&self, dim: usize) -> Result<()> {
        let bad = |what: String| Err(Error::Usage(format!("evidence options: {what}")));
        if dim == 0 {
            return bad("the target has no parameters".into());
        }
        if self.n_walkers < 2 * dim + 2 {
            return bad(format!(
                "{} walkers for {dim} parameters: use at least 2 x {dim} + 2 = {}",
                self.n_walkers,
                2 * dim + 2
            ));
        }
        if self.n_replicates < 2 {
            return bad("use at least 2 replicates (the standard error needs them)".into());
        }
        if !(self.target_cess > 0.0 && self.target_cess < 1.0) {
            return bad(format!(
                "target_cess = {} must be in (0, 1)",
                self.target_cess
            ));
        }
        if self.min_steps_per_temperature == 0
            || self.max_steps_per_temperature < self.min_steps_per_temperature
        {
            return bad(format!(
                "steps per temperature: need 1 <= min ({}) <= max ({})",
                self.min_steps_per_temperature, self.max_steps_per_temperature
            ));
        }
        if !(self.jump_target > 0.0 && self.jump_target.is_finite()) {
            return bad(format!(
                "jump_target = {} must be positive",
                self.jump_target
            ));
        }
        if self.final_steps > 0 && self.final_steps < 4 {
            return bad("final_steps must be 0 or at least 4 (for R-hat)".into());
        }
        Ok(())
    }
}

/// What [`stepping_stone`] is doing, reported after every temperature and every final
/// step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvidenceProgress {
    /// Replicate being run (0-based).
    pub replicate: usize,
    /// Replicates in all.
    pub n_replicates: usize,
    /// Stage of that replicate.
    pub stage: Stage,
    /// This replicate's `ln Z` so far (complete once `beta = 1`).
    pub ln_z_partial: f64,
    /// Likelihood evaluations so far, all replicates.
    pub n_likelihood_evaluations: u64,
}

/// Stage of a replicate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stage {
    /// Temperature `temperature` (1-based) reached at `beta`.
    Tempering { temperature: usize, beta: f64 },
    /// Final step `step` of `of` at `beta = 1`.
    Sampling { step: usize, of: usize },
}

/// Posterior draws at `beta = 1` from the replicates' final ensembles.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct PosteriorDraws {
    /// The draws: chains = replicate x walker; `ln_density` = `ln L + ln pi`.
    pub draws: Draws,
    /// `ln L` of every draw, `(chain, draw)`.
    pub ln_likelihood: Vec<f64>,
    /// `ln pi` of every draw, `(chain, draw)`.
    pub ln_prior: Vec<f64>,
    /// R-hat (replicates as chains) and ESS (walkers as chains) of every parameter.
    pub diagnostics: Vec<Diagnostics>,
    /// Integrated autocorrelation time of every parameter, in steps (walkers pooled).
    pub tau_steps: Vec<f64>,
    /// Acceptance fraction of the final steps.
    pub acceptance: f64,
}

/// Result of [`stepping_stone`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Evidence {
    /// Stepping-stone `ln Z`, mean over replicates.
    pub ln_z: f64,
    /// Its standard error (replicate sd / sqrt(n_replicates)).
    pub ln_z_se: f64,
    /// Thermodynamic-integration `ln Z`, mean over replicates (cross-check).
    pub ln_z_ti: f64,
    /// Its standard error over replicates.
    pub ln_z_ti_se: f64,
    /// Every replicate's ladder and estimates.
    pub runs: Vec<TemperingRun>,
    /// Posterior draws (`None` when `final_steps = 0`).
    pub posterior: Option<PosteriorDraws>,
    /// Likelihood evaluations in all (tempering and final steps).
    pub n_likelihood_evaluations: u64,
}

impl Evidence {
    /// Information gained from prior to posterior, `E_post[ln L] - ln Z` (the
    /// Kullback-Leibler divergence of the posterior from the prior), in nats, from the
    /// walkers at `beta = 1` of every replicate.
    pub fn information_nats(&self) -> f64 {
        let n = self.runs.len() as f64;
        let mean: f64 = self
            .runs
            .iter()
            .map(|r| r.mean_ln_likelihood.last().copied().unwrap_or(f64::NAN))
            .sum::<f64>()
            / n;
        mean - self.ln_z
    }

    /// Mean number of temperatures per replicate (including `beta = 0` and 1).
    pub fn mean_temperatures(&self) -> f64 {
        self.runs.iter().map(|r| r.betas.len() as f64).sum::<f64>() / self.runs.len() as f64
    }
}

/// Log evidence of `target` by stepping-stone over tempered ensembles (module docs),
/// with thermodynamic integration as cross-check, a replicate standard error and
/// posterior draws. `progress` is called after every temperature and final step.
///
/// ```
/// use frfbayes::discrepancy::{stepping_stone, EvidenceOptions, TemperedTarget};
/// use rand::RngExt;
/// // ln L = -z^2 / (2 s^2) with s = 0.01, uniform prior on [-1, 1]:
/// // Z = s sqrt(2 pi) / 2.
/// struct Narrow;
/// impl TemperedTarget for Narrow {
///     fn dim(&self) -> usize { 1 }
///     fn ln_prior(&self, z: &[f64]) -> f64 {
///         if z[0].abs() <= 1.0 { -(2f64.ln()) } else { f64::NEG_INFINITY }
///     }
///     fn ln_likelihood(&self, z: &[f64]) -> frfbayes::Result<f64> {
///         Ok(-0.5 * (z[0] / 0.01).powi(2))
///     }
///     fn sample_prior(&self, rng: &mut rand_chacha::ChaCha8Rng) -> frfbayes::Result<Vec<f64>> {
///         Ok(vec![rng.random_range(-1.0..1.0)])
///     }
/// }
/// let ev = stepping_stone(&Narrow, &EvidenceOptions::new(1, 3), None).unwrap();
/// let exact = (0.01 * (2.0 * std::f64::consts::PI).sqrt() / 2.0).ln();
/// assert!((ev.ln_z - exact).abs() < 0.3);
/// ```
pub fn stepping_stone<T: TemperedTarget>(
    target: &T,
    opts: &EvidenceOptions,
    mut progress: Option<&mut dyn FnMut(EvidenceProgress)>,
) -> Result<Evidence> {
    let dim = target.dim();
    opts.validate(dim)?;
    let moves = Moves::from_specs(&opts.moves)?;
    let key = key_from_seed(opts.seed);
    let counter = AtomicU64::new(0);
    let mut runs = Vec::with_capacity(opts.n_replicates);
    let mut ensembles = Vec::with_capacity(opts.n_replicates);
    for r in 0..opts.n_replicates {
        let before = counter.load(Ordering::Relaxed);
        let (mut run, ens) = temper(target, opts, &moves, key, r, &counter, &mut progress)?;
        run.n_likelihood_evaluations = counter.load(Ordering::Relaxed) - before;
        runs.push(run);
        ensembles.push(ens);
    }
    let posterior = if opts.final_steps > 0 {
        let density = Tempered { target, beta: 1.0 };
        for (r, ens) in ensembles.iter_mut().enumerate() {
            for step in 0..opts.final_steps {
                let n = ens.step(&density, &moves, true, true, &Ranks)?;
                counter.fetch_add(n, Ordering::Relaxed);
                ens.store();
                if let Some(cb) = progress.as_deref_mut() {
                    cb(EvidenceProgress {
                        replicate: r,
                        n_replicates: opts.n_replicates,
                        stage: Stage::Sampling {
                            step: step + 1,
                            of: opts.final_steps,
                        },
                        ln_z_partial: runs[r].ln_z,
                        n_likelihood_evaluations: counter.load(Ordering::Relaxed),
                    });
                }
            }
        }
        Some(posterior_draws(&ensembles, dim, opts))
    } else {
        None
    };
    let (ln_z, ln_z_se) = mean_and_se(runs.iter().map(|r| r.ln_z));
    let (ln_z_ti, ln_z_ti_se) = mean_and_se(runs.iter().map(|r| r.ln_z_ti));
    Ok(Evidence {
        ln_z,
        ln_z_se,
        ln_z_ti,
        ln_z_ti_se,
        runs,
        posterior,
        n_likelihood_evaluations: counter.load(Ordering::Relaxed),
    })
}

/// Mean and standard error (sd with divisor n - 1, over sqrt(n)).
fn mean_and_se(x: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = x.clone().count() as f64;
    let mean = x.clone().sum::<f64>() / n;
    let var = x.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

fn posterior_draws(
    ensembles: &[crate::mcmc::Ensemble],
    dim: usize,
    opts: &EvidenceOptions,
) -> PosteriorDraws {
    let kept: Vec<usize> = (0..opts.final_steps).collect();
    let mut draws = Draws::from_ensembles(ensembles, &kept, dim, 0, 1);
    let ln_likelihood = draws.pointwise.chunks(2).map(|t| t[0]).collect();
    let ln_prior = draws.pointwise.chunks(2).map(|t| t[1]).collect();
    draws.pointwise = Vec::new();
    draws.n_pointwise = 0;
    let diagnostics = (0..dim)
        .map(|p| ensemble_diagnostics(&draws.param_chains(p), draws.n_walkers))
        .collect();
    let tau_steps = (0..dim)
        .map(|p| {
            let chains = draws.param_chains(p);
            let refs: Vec<&[f64]> = chains.iter().map(|c| c.as_slice()).collect();
            integrated_time(&refs, 5.0).tau
        })
        .collect();
    let accepted: u64 = ensembles.iter().flat_map(|e| &e.accepted).sum();
    let acceptance = accepted as f64 / (draws.n_chains * opts.final_steps) as f64;
    PosteriorDraws {
        draws,
        ln_likelihood,
        ln_prior,
        diagnostics,
        tau_steps,
        acceptance,
    }
}
