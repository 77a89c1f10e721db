//! Sampling to a convergence target and the `posterior.json` summary shared by the
//! real-data studies.
//!
//! `posterior.json` is the [`PosteriorSummary`] of `frfbayes sample`
//! ([`crate::bayes::summary`]): one [`ParameterSummary`] per reported quantity, then the
//! sampler's bookkeeping. A study that samples several independent posteriors (the
//! wheel's bands) reports them in one file ([`posterior_summary`] states how the
//! bookkeeping fields combine).

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use crate::bayes::summary::{stuck_walkers, AT_BOUND_FRACTION};
pub use crate::bayes::summary::{AtBound, ParameterSummary, PosteriorSummary};
use crate::error::{Error, Result};
use crate::io::write_atomic;
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

/// Writes `posterior.json` atomically (pretty JSON).
pub fn write_summary(summary: &PosteriorSummary, path: &Path) -> Result<()> {
    let json = serde_json::to_vec_pretty(summary).map_err(|e| Error::Numerical(e.to_string()))?;
    write_atomic(path, &json)
}

/// The [`PosteriorSummary`] of one or more independent runs with `parameters` already
/// summarised. Combined over `runs`: `acceptance` is the mean, `n_steps`,
/// `discarded_steps` and `thin_steps` the largest, `n_likelihood_evals`, `wall_s` and
/// `n_stuck_walkers` the sums, `n_draws_per_walker` the smallest, and
/// `stopped_because` is `converged` only when every run converged (else `step_cap`).
/// `converged` applies the criterion of `frfbayes sample` to `parameters`.
pub fn posterior_summary(
    runs: &[&Sampled],
    parameters: Vec<ParameterSummary>,
    n_data_points: usize,
) -> PosteriorSummary {
    let n = runs.len().max(1) as f64;
    let n_stuck_walkers = runs.iter().map(|r| stuck_walkers(&r.draws).len()).sum();
    PosteriorSummary {
        converged: PosteriorSummary::meets_criterion(&parameters) && n_stuck_walkers == 0,
        n_stuck_walkers,
        rhat_max: parameters.iter().map(|p| p.rhat).fold(f64::NAN, f64::max),
        ess_bulk_min: parameters
            .iter()
            .map(|p| p.ess_bulk)
            .fold(f64::NAN, f64::min),
        parameters,
        acceptance: runs.iter().map(|r| r.acceptance).sum::<f64>() / n,
        n_walkers: runs.first().map_or(0, |r| r.n_walkers),
        n_ensembles: runs
            .first()
            .map_or(0, |r| r.draws.n_chains / r.n_walkers.max(1)),
        n_steps: runs.iter().map(|r| r.n_steps).max().unwrap_or(0),
        n_likelihood_evals: runs.iter().map(|r| r.n_evaluations).sum(),
        n_data_points,
        n_points_at_sigma_floor: None,
        wall_s: runs.iter().map(|r| r.wall_s).sum(),
        stopped_because: if runs
            .iter()
            .all(|r| r.stopped_because == StopReason::Converged)
        {
            StopReason::Converged
        } else {
            StopReason::StepCap
        },
        n_draws_per_walker: runs.iter().map(|r| r.draws.n_draws).min().unwrap_or(0),
        discarded_steps: runs
            .iter()
            .map(|r| r.draws.discarded_steps)
            .max()
            .unwrap_or(0),
        thin_steps: runs.iter().map(|r| r.draws.thin_steps).max().unwrap_or(0),
    }
}

/// Quantile `p` of sorted values (linear interpolation, as numpy's default).
pub fn quantile_sorted(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = p * (sorted.len() - 1) as f64;
    let (i, frac) = (h.floor() as usize, h - h.floor());
    if i + 1 < sorted.len() {
        sorted[i] + frac * (sorted[i + 1] - sorted[i])
    } else {
        sorted[i]
    }
}

/// Which prior bound (if any) the central 95% interval of `chains` reaches within
/// [`AT_BOUND_FRACTION`] of the range `(lo, hi)`, as in `frfbayes sample`. Judge it in
/// the sampled coordinate (e.g. `ln sigma`), where the prior is uniform.
pub fn near_bound(chains: &[Vec<f64>], (lo, hi): (f64, f64)) -> Option<AtBound> {
    let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    let tol = AT_BOUND_FRACTION * (hi - lo);
    if quantile_sorted(&all, 0.025) - lo < tol {
        Some(AtBound::Lower)
    } else if hi - quantile_sorted(&all, 0.975) < tol {
        Some(AtBound::Upper)
    } else {
        None
    }
}

/// A [`ParameterSummary`] from walker chains of one quantity (`n_walkers` chains per ensemble).
pub fn row_from_chains(
    name: &str,
    unit: &str,
    chains: &[Vec<f64>],
    n_walkers: usize,
    tau_steps: f64,
    at_bound: Option<AtBound>,
) -> ParameterSummary {
    let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
    let n = all.len() as f64;
    let mean = all.iter().sum::<f64>() / n;
    let sd = (all.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    all.sort_by(f64::total_cmp);
    let (q2_5, q50, q97_5) = (
        quantile_sorted(&all, 0.025),
        quantile_sorted(&all, 0.5),
        quantile_sorted(&all, 0.975),
    );
    let d = ensemble_diagnostics(chains, n_walkers);
    ParameterSummary {
        name: name.to_string(),
        unit: unit.to_string(),
        mean,
        sd,
        cv: sd / mean.abs(),
        q2_5,
        q50,
        q97_5,
        rhat: d.rhat,
        ess_bulk: d.ess_bulk,
        ess_tail: d.ess_tail,
        tau: tau_steps,
        at_bound,
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
            return Ok(Sampled {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcmc::{Ball, DensityFn};

    #[test]
    fn quantiles_interpolate_like_numpy() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile_sorted(&v, 0.0), 1.0);
        assert_eq!(quantile_sorted(&v, 1.0), 4.0);
        assert!((quantile_sorted(&v, 0.5) - 2.5).abs() < 1e-15);
        assert!((quantile_sorted(&v, 0.025) - 1.075).abs() < 1e-12);
    }

    /// A 2-D Gaussian (sd 1 and 3, correlation 0.5) sampled to the targets: the summary
    /// must meet them and the moments must match within a few Monte Carlo standard
    /// errors (sd / sqrt(ESS) for the mean; with ESS > 400, 5 MCSE is < 0.25 sd).
    #[test]
    fn samples_a_gaussian_to_the_targets_and_writes_the_schema() {
        let (s1, s2, r) = (1.0, 3.0, 0.5);
        let d = DensityFn::new(2, move |x: &[f64]| {
            let (a, b) = (x[0] / s1, x[1] / s2);
            Ok(-0.5 * (a * a - 2.0 * r * a * b + b * b) / (1.0 - r * r))
        });
        let start = Start::Ball(Ball {
            center: vec![0.5, -0.5],
            scale: vec![0.1, 0.1],
        });
        let mut steps = 0u64;
        let s = sample_to_targets(
            &d,
            start,
            16,
            3,
            &Targets::default(),
            "gaussian",
            &mut Sampling::new(|label: &str, p: &Progress| {
                assert_eq!(label, "gaussian");
                steps = p.step;
            }),
        )
        .unwrap();
        assert_eq!(steps, s.n_steps, "the callback sees every step");
        assert_eq!(s.stopped_because, StopReason::Converged);
        assert!(s.worst_rhat < 1.01 && s.min_ess > 400.0);
        for (p, sd) in [(0, s1), (1, s2)] {
            let row = row_from_chains("x", "", &s.chains(p, |v| v), 16, s.tau_steps[p], None);
            let mcse = row.sd / row.ess_bulk.sqrt();
            assert!(row.mean.abs() < 5.0 * mcse, "{row:?}");
            assert!((row.sd / sd - 1.0).abs() < 0.15, "{row:?}");
            assert!((row.q97_5 - row.q2_5) / (2.0 * 1.96 * sd) > 0.85);
        }
        let file = posterior_summary(
            &[&s],
            vec![row_from_chains(
                "x",
                "m",
                &s.chains(0, |v| v),
                16,
                1.0,
                near_bound(&s.chains(0, |v| v), (-1.0, 1.0)),
            )],
            0,
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("posterior.json");
        write_summary(&file, &path).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let p = &v["parameters"][0];
        for key in [
            "name", "unit", "mean", "sd", "cv", "q2.5", "q50", "q97.5", "rhat", "ess_bulk",
            "ess_tail", "tau", "at_bound",
        ] {
            assert!(p.get(key).is_some(), "missing {key}");
        }
        // A unit-sd variable with bounds (-1, 1) has its 95% interval beyond them.
        assert_eq!(p["at_bound"], serde_json::json!("lower"));
        assert_eq!(v["stopped_because"], serde_json::json!("converged"));
        assert_eq!(v["n_ensembles"], serde_json::json!(4));
        for key in [
            "acceptance",
            "n_walkers",
            "n_steps",
            "n_likelihood_evals",
            "n_data_points",
            "wall_s",
            "stopped_because",
            "converged",
            "n_stuck_walkers",
            "rhat_max",
            "ess_bulk_min",
            "n_draws_per_walker",
            "discarded_steps",
            "thin_steps",
        ] {
            assert!(v.get(key).is_some(), "missing {key}");
        }
    }
}
