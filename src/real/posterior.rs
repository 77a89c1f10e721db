//! Sampling to a convergence target and the `posterior.json` summary shared by the
//! real-data studies.
//!
//! `posterior.json` follows the schema of `frfbayes sample` (to be unified later):
//! `{"parameters": [{"name", "unit", "mean", "sd", "cv", "q2.5", "q50", "q97.5", "rhat",
//! "ess_bulk", "ess_tail", "tau", "at_bound"}], "acceptance", "n_walkers", "n_steps",
//! "n_likelihood_evals", "n_data_points", "wall_s", "stopped_because"}`.

use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::io::write_atomic;
use crate::mcmc::{
    ensemble_diagnostics, Burn, DifferentialEvolution, Draws, LogDensity, Moves, Sampler,
    SamplerConfig, Start, Stretch,
};

/// One parameter (or derived quantity) of `posterior.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamRow {
    pub name: String,
    pub unit: String,
    pub mean: f64,
    pub sd: f64,
    /// `sd / |mean|`.
    pub cv: f64,
    #[serde(rename = "q2.5")]
    pub q2_5: f64,
    pub q50: f64,
    #[serde(rename = "q97.5")]
    pub q97_5: f64,
    pub rhat: f64,
    pub ess_bulk: f64,
    pub ess_tail: f64,
    /// Integrated autocorrelation time in steps (of the sampled coordinate this quantity
    /// is a monotone function of; NaN for quantities derived from several coordinates).
    pub tau: f64,
    /// The central 95% interval reaches within 1% of the prior range of a bound.
    pub at_bound: bool,
}

/// The whole `posterior.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PosteriorFile {
    pub parameters: Vec<ParamRow>,
    pub acceptance: f64,
    pub n_walkers: usize,
    pub n_steps: u64,
    pub n_likelihood_evals: u64,
    pub n_data_points: usize,
    pub wall_s: f64,
    pub stopped_because: String,
}

impl PosteriorFile {
    /// Writes the file atomically (pretty JSON).
    pub fn write(&self, path: &Path) -> Result<()> {
        let json = serde_json::to_vec_pretty(self).map_err(|e| Error::Numerical(e.to_string()))?;
        write_atomic(path, &json)
    }

    /// The row named `name`.
    pub fn row(&self, name: &str) -> Option<&ParamRow> {
        self.parameters.iter().find(|r| r.name == name)
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

/// True when the central 95% interval of `chains` reaches within 1% of the range
/// `(lo, hi)` of a bound. Judge it in the sampled coordinate (e.g. `ln sigma`), where the
/// prior is uniform.
pub fn near_bound(chains: &[Vec<f64>], (lo, hi): (f64, f64)) -> bool {
    let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    let tol = 0.01 * (hi - lo);
    quantile_sorted(&all, 0.025) - lo < tol || hi - quantile_sorted(&all, 0.975) < tol
}

/// A [`ParamRow`] from walker chains of one quantity (`n_walkers` chains per ensemble).
pub fn row_from_chains(
    name: &str,
    unit: &str,
    chains: &[Vec<f64>],
    n_walkers: usize,
    tau_steps: f64,
    at_bound: bool,
) -> ParamRow {
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
    ParamRow {
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
    /// `converged` when emcee's tau rule and the targets hold, else why not.
    pub stopped_because: String,
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
pub fn sample_to_targets<D: LogDensity + ?Sized>(
    density: &D,
    start: Start,
    n_walkers: usize,
    seed: u64,
    targets: &Targets,
) -> Result<Sampled> {
    let t0 = Instant::now();
    let mut config = SamplerConfig::new(n_walkers, seed);
    config.max_steps = targets.first_cap_steps;
    let mut sampler = Sampler::new(density, default_moves()?, config, start)?;
    let mut cap = targets.first_cap_steps;
    loop {
        let summary = sampler.run(None)?;
        let done_tau = summary.stopped_because == crate::mcmc::StopReason::Converged;
        let (worst_rhat, min_ess) = match sampler.draws(Burn::Auto) {
            Ok(d) => worst_diagnostics(&d),
            Err(_) => (f64::INFINITY, 0.0),
        };
        let met = worst_rhat < targets.max_rhat && min_ess > targets.min_ess;
        let at_cap = sampler.step_count() >= cap;
        if (done_tau && met) || (at_cap && cap >= targets.hard_cap_steps) {
            let draws = sampler.draws(Burn::Auto)?;
            let thin = (sampler.step_count() / 500).max(1);
            let full = sampler.draws(Burn::Steps { discard: 0, thin })?;
            let stopped_because = if done_tau && met {
                "converged".to_string()
            } else {
                format!(
                    "step_cap ({} steps; worst R-hat {worst_rhat:.4}, smallest ESS {min_ess:.0})",
                    sampler.step_count()
                )
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
        let s = sample_to_targets(&d, start, 16, 3, &Targets::default()).unwrap();
        assert_eq!(s.stopped_because, "converged");
        assert!(s.worst_rhat < 1.01 && s.min_ess > 400.0);
        for (p, sd) in [(0, s1), (1, s2)] {
            let row = row_from_chains("x", "", &s.chains(p, |v| v), 16, s.tau_steps[p], false);
            let mcse = row.sd / row.ess_bulk.sqrt();
            assert!(row.mean.abs() < 5.0 * mcse, "{row:?}");
            assert!((row.sd / sd - 1.0).abs() < 0.15, "{row:?}");
            assert!((row.q97_5 - row.q2_5) / (2.0 * 1.96 * sd) > 0.85);
        }
        let file = PosteriorFile {
            parameters: vec![row_from_chains(
                "x",
                "m",
                &s.chains(0, |v| v),
                16,
                1.0,
                near_bound(&s.chains(0, |v| v), (-1.0, 1.0)),
            )],
            acceptance: s.acceptance,
            n_walkers: 16,
            n_steps: s.n_steps,
            n_likelihood_evals: s.n_evaluations,
            n_data_points: 0,
            wall_s: s.wall_s,
            stopped_because: s.stopped_because.clone(),
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("posterior.json");
        file.write(&path).unwrap();
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let p = &v["parameters"][0];
        for key in [
            "name", "unit", "mean", "sd", "cv", "q2.5", "q50", "q97.5", "rhat", "ess_bulk",
            "ess_tail", "tau", "at_bound",
        ] {
            assert!(p.get(key).is_some(), "missing {key}");
        }
        // A unit-sd variable with bounds (-1, 1) has its 95% interval beyond them.
        assert_eq!(p["at_bound"], serde_json::Value::Bool(true));
        for key in [
            "acceptance",
            "n_walkers",
            "n_steps",
            "n_likelihood_evals",
            "n_data_points",
            "wall_s",
            "stopped_because",
        ] {
            assert!(v.get(key).is_some(), "missing {key}");
        }
    }
}
