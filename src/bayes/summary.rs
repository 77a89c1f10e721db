//! Posterior draws in physical units and their summary (`posterior.json`).

use super::posterior::FrfPosterior;
use crate::mcmc::{ensemble_diagnostics, quantile, Draws, LogDensity, StopReason};
use crate::update::VariableKind;
use rayon::prelude::*;
use serde::Serialize;

/// A reported parameter: an increasing function of one sampled coordinate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutputParam {
    /// `m1`, `k2`, `a0`, `xi3`, `noise_scale`.
    pub name: String,
    /// `kg`, `N/m`, `1/s`, `s`, `1`.
    pub unit: String,
    /// Index of the sampled coordinate it is a function of.
    pub coord: usize,
}

/// The reported parameters in the order masses, stiffnesses, damping, noise scale
/// (free variables only). Masses and stiffnesses are physical (`m_r0 (1 + beta_r)`,
/// `k_r0 (1 + alpha_r)`) where the model has nominal values, multipliers otherwise.
pub fn output_params(post: &FrfPosterior) -> Vec<OutputParam> {
    let vars = post.variables();
    let units = vars.physical_units(post.model());
    let rank = |k: VariableKind| match k {
        VariableKind::Beta(_) => 0,
        VariableKind::Alpha(_) => 1,
        _ => 2,
    };
    let mut out: Vec<(usize, OutputParam)> = vars
        .free()
        .iter()
        .enumerate()
        .map(|(coord, &i)| {
            let v = &vars.variables()[i];
            let p = OutputParam {
                name: v.name.clone(),
                unit: units[i].clone(),
                coord,
            };
            (rank(v.kind), p)
        })
        .collect();
    out.sort_by_key(|(r, p)| (*r, p.coord));
    let mut params: Vec<OutputParam> = out.into_iter().map(|(_, p)| p).collect();
    params.push(OutputParam {
        name: "noise_scale".into(),
        unit: "1".into(),
        coord: post.n_free(),
    });
    params
}

/// Physical values of the reported parameters at a sampled vector `z`.
pub fn physical_values(post: &FrfPosterior, params: &[OutputParam], z: &[f64]) -> Vec<f64> {
    let vars = post.variables();
    let phys = vars.physical(post.model(), &post.theta(z));
    params
        .iter()
        .map(|p| match vars.free().get(p.coord) {
            Some(&i) => phys[i],
            None => z[p.coord].exp(),
        })
        .collect()
}

/// The draws mapped to the reported parameters (same chains, draws, log densities and
/// pointwise terms).
pub fn physical_draws(post: &FrfPosterior, params: &[OutputParam], draws: &Draws) -> Draws {
    let values: Vec<f64> = draws
        .values
        .par_chunks(draws.dim)
        .flat_map_iter(|z| physical_values(post, params, z))
        .collect();
    Draws {
        dim: params.len(),
        values,
        ..draws.clone()
    }
}

/// Which bound a parameter's posterior presses against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AtBound {
    Lower,
    Upper,
}

/// One row of `posterior.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParameterSummary {
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
    /// `max(bulk, tail)` rank-normalised split R-hat, each ensemble one chain.
    pub rhat: f64,
    pub ess_bulk: f64,
    pub ess_tail: f64,
    /// Integrated autocorrelation time of the sampled coordinate, steps.
    pub tau: f64,
    /// `lower` (`upper`) when the 2.5 % (97.5 %) quantile lies within 1 % of the prior
    /// range of the bound, in the sampled coordinate: the bound, not the data, limits
    /// the posterior there; `null` otherwise.
    pub at_bound: Option<AtBound>,
}

/// Fraction of the prior range (sampled coordinate) within which a tail quantile
/// counts as at the bound.
pub const AT_BOUND_FRACTION: f64 = 0.01;

/// Summaries of the reported parameters. `draws` are in sampled coordinates (as the
/// sampler gives them); `tau_steps` per sampled coordinate.
pub fn summarize(
    post: &FrfPosterior,
    params: &[OutputParam],
    draws: &Draws,
    tau_steps: &[f64],
) -> Vec<ParameterSummary> {
    let phys = physical_draws(post, params, draws);
    let (lo, hi) = (post.prior().lower(), post.prior().upper());
    params
        .par_iter()
        .enumerate()
        .map(|(j, p)| {
            let chains = phys.param_chains(j);
            let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
            let n = all.len() as f64;
            let mean = all.iter().sum::<f64>() / n;
            let sd = (all.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            all.sort_by(f64::total_cmp);
            let d = ensemble_diagnostics(&chains, draws.n_walkers);
            let mut zs: Vec<f64> = draws
                .values
                .iter()
                .skip(p.coord)
                .step_by(draws.dim)
                .copied()
                .collect();
            zs.sort_by(f64::total_cmp);
            let margin = AT_BOUND_FRACTION * (hi[p.coord] - lo[p.coord]);
            let at_bound = if quantile(&zs, 0.025) <= lo[p.coord] + margin {
                Some(AtBound::Lower)
            } else if quantile(&zs, 0.975) >= hi[p.coord] - margin {
                Some(AtBound::Upper)
            } else {
                None
            };
            ParameterSummary {
                name: p.name.clone(),
                unit: p.unit.clone(),
                mean,
                sd,
                cv: sd / mean.abs(),
                q2_5: quantile(&all, 0.025),
                q50: quantile(&all, 0.5),
                q97_5: quantile(&all, 0.975),
                rhat: d.rhat,
                ess_bulk: d.ess_bulk,
                ess_tail: d.ess_tail,
                tau: tau_steps.get(p.coord).copied().unwrap_or(f64::NAN),
                at_bound,
            }
        })
        .collect()
}

/// Walkers (chain indices) whose median log posterior over the kept draws lies more
/// than `dim` below the median of all kept draws: walkers stuck away from the bulk,
/// which R-hat and ESS (rank-based, pooled) miss when they are few.
///
/// Why `dim`: for a posterior close to a `d`-dimensional Gaussian the log density of a
/// draw is `max - chi2_d / 2`, so one draw falls `d` below the median with probability
/// `P(chi2_d > 3d - 2/3)` (2.6e-4 for `d` = 13, 0.014 for `d` = 5); a walker's median of
/// `m` effectively independent draws does so only if half of them do, below 1e-15 for
/// `m >= 25` at `d >= 5`. The pooled median stays put while fewer than half the walkers
/// are stuck.
pub fn stuck_walkers(draws: &Draws) -> Vec<usize> {
    let mut all = draws.ln_density.clone();
    all.sort_by(f64::total_cmp);
    let threshold = quantile(&all, 0.5) - draws.dim as f64;
    (0..draws.n_chains)
        .filter(|&c| {
            let mut v = draws.ln_density[c * draws.n_draws..(c + 1) * draws.n_draws].to_vec();
            v.sort_by(f64::total_cmp);
            quantile(&v, 0.5) < threshold
        })
        .collect()
}

/// Convergence criterion of the issue: R-hat below this for every parameter ...
pub const RHAT_MAX: f64 = 1.01;
/// ... and bulk ESS above this.
pub const ESS_BULK_MIN: f64 = 400.0;

/// `posterior.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PosteriorSummary {
    pub parameters: Vec<ParameterSummary>,
    /// Acceptance fraction over all walkers and steps.
    pub acceptance: f64,
    /// Walkers per ensemble.
    pub n_walkers: usize,
    pub n_ensembles: usize,
    /// Steps run.
    pub n_steps: u64,
    /// Log-density evaluations of the sampler (initial ones included).
    pub n_likelihood_evals: u64,
    pub n_data_points: usize,
    /// Points whose Bendat & Piersol relative error was raised to the floor (`None`
    /// for posteriors without such a floor).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_points_at_sigma_floor: Option<usize>,
    /// Sampling wall time, s (this process; a resumed run counts from its resumption).
    pub wall_s: f64,
    pub stopped_because: StopReason,
    /// Every parameter has `rhat < 1.01` and `ess_bulk > 400`, and no walker is stuck.
    pub converged: bool,
    /// Walkers stuck away from the bulk ([`stuck_walkers`]).
    pub n_stuck_walkers: usize,
    pub rhat_max: f64,
    pub ess_bulk_min: f64,
    /// Draws kept per walker, burn-in discarded, thinning (steps).
    pub n_draws_per_walker: usize,
    pub discarded_steps: u64,
    pub thin_steps: u64,
}

impl PosteriorSummary {
    /// True when every parameter meets the R-hat and bulk-ESS criterion.
    pub fn meets_criterion(parameters: &[ParameterSummary]) -> bool {
        parameters
            .iter()
            .all(|p| p.rhat < RHAT_MAX && p.ess_bulk > ESS_BULK_MIN)
    }
}

/// The dimension check of [`physical_draws`]' callers.
pub(crate) fn check_draws(post: &FrfPosterior, draws: &Draws) -> crate::Result<()> {
    if draws.dim != post.dim() {
        return Err(crate::Error::Usage(format!(
            "draws have {} coordinates, the posterior {}",
            draws.dim,
            post.dim()
        )));
    }
    Ok(())
}
