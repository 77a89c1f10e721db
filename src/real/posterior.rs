//! Sampling to a convergence target and the `posterior.json` summary shared by the
//! real-data studies.
//!
//! `posterior.json` is the [`PosteriorSummary`] of `frfbayes sample`
//! ([`crate::bayes::summary`]): one [`ParameterSummary`] per reported quantity, then the
//! sampler's bookkeeping. A study that samples several independent posteriors (the
//! wheel's bands) reports them in one file ([`posterior_summary`] states how the
//! bookkeeping fields combine).

use std::path::Path;

use crate::bayes::summary::{stuck_walkers, AT_BOUND_FRACTION};
pub use crate::bayes::summary::{AtBound, ParameterSummary, PosteriorSummary};
use crate::error::{Error, Result};
pub use crate::infer::sample::{
    default_moves, sample_to_targets, worst_diagnostics, OnStep, Sampled, Sampling, Targets,
};
use crate::infer::{BlockKind, Posterior};
use crate::io::write_atomic;
pub use crate::mcmc::INFERENCE_DATA_FILE;
use crate::mcmc::{ensemble_diagnostics, Draws, InferenceData, Observed, StopReason};
use rayon::prelude::*;

/// Writes `path` (`inference_data.nc` beside `posterior.json`), ArviZ's InferenceData of
/// `sampled` ([`crate::mcmc::InferenceData`]; chains = ensembles): `posterior` holds the
/// quantities `rows` (their names and units) computed from each draw's sampled
/// coordinates by `reported` (one value per row, in order); `sample_stats` the log
/// posterior and the walkers' acceptance; `log_likelihood` (`terms`, one per data block
/// of the likelihood, so that `az.loo` leaves one block out) when the density has
/// pointwise terms ([`Sampled::log_likelihood`]); `observed_data` the blocks' data
/// ([`observed_blocks`]) when given.
pub fn write_inference_data(
    path: &Path,
    sampled: &Sampled,
    rows: &[ParameterSummary],
    reported: impl Fn(&[f64]) -> Vec<f64> + Sync,
    observed: Option<Observed>,
    study: &str,
) -> Result<()> {
    let d = &sampled.draws;
    let values: Vec<f64> = d
        .values
        .par_chunks(d.dim.max(1))
        .flat_map_iter(&reported)
        .collect();
    if values.len() != rows.len() * d.n_chains * d.n_draws {
        return Err(Error::Usage(format!(
            "{study}: {} reported values per draw for {} rows",
            values.len() / (d.n_chains * d.n_draws).max(1),
            rows.len()
        )));
    }
    let phys = Draws {
        dim: rows.len(),
        values,
        n_pointwise: 0,
        pointwise: Vec::new(),
        ..d.clone()
    };
    let names: Vec<String> = rows.iter().map(|r| r.name.clone()).collect();
    let units: Vec<String> = rows.iter().map(|r| r.unit.clone()).collect();
    let mut idata = InferenceData::new(&phys, &names, &units)?
        .with_acceptance(sampled.acceptance_per_chain.clone())?
        .with_attr("frfbayes_study", study);
    if let Some(ll) = &sampled.log_likelihood {
        idata = idata.with_log_likelihood("terms", "block", ll)?;
    }
    if let Some(obs) = observed {
        idata = idata.with_observed(obs)?;
    }
    idata.write(path)
}

/// The `observed_data` of a posterior on the inference layer: every block's data in
/// block order along `value`, as its likelihood compares them (a `Values` block's
/// transformed values, e.g. `ln f` or eigenvalues; a `ShapeMac` block's unit shape; a
/// `ShapeDifference` block's shape over its reference entry; a `LinearMarginal`
/// block's complex values as real and imaginary parts), with the coordinate `block`
/// (the index along `log_likelihood`'s `block`) and the blocks' names and kinds as
/// attributes.
pub fn observed_blocks<P: crate::predict::Predict>(post: &Posterior<P>) -> Observed {
    let (mut values, mut block) = (Vec::new(), Vec::new());
    let (mut names, mut kinds) = (Vec::new(), Vec::new());
    for (i, b) in post.blocks().iter().enumerate() {
        let (v, kind) = match &b.kind {
            BlockKind::Values { observed, .. } => (observed.clone(), "values"),
            BlockKind::SharedNoise { observed, .. } => (observed.clone(), "shared_noise"),
            BlockKind::ShapeMac { observed_unit } => (observed_unit.clone(), "shape_mac"),
            BlockKind::ShapeDifference { observed, .. } => (observed.clone(), "shape_difference"),
            BlockKind::LinearMarginal {
                observed, inv_sd, ..
            } => (
                observed.iter().zip(inv_sd).map(|(y, w)| y / w).collect(),
                "linear_marginal",
            ),
        };
        block.extend(std::iter::repeat_n(i as f64, v.len()));
        values.extend(v);
        names.push(b.name.clone());
        kinds.push(kind);
    }
    Observed {
        name: "observations".into(),
        dim: "value".into(),
        values,
        unit: "as each block compares them (see block_kinds)".into(),
        coords: vec![("block".into(), block)],
        attrs: vec![
            ("block_names".into(), names.join(", ")),
            ("block_kinds".into(), kinds.join(", ")),
        ],
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

/// Posterior bands of a quantity on a grid: `(q2.5, q25, q50, q75, q97.5)`, each a
/// vector over the grid.
pub type QuantileBands = [Vec<f64>; 5];

/// [`QuantileBands`] of the samples of every grid point (`per_bin[i]`: the draws at
/// point `i`).
pub fn quantile_bands(per_bin: Vec<Vec<f64>>) -> QuantileBands {
    let mut out: QuantileBands = Default::default();
    for mut v in per_bin {
        v.sort_by(f64::total_cmp);
        for (o, q) in out.iter_mut().zip([0.025, 0.25, 0.5, 0.75, 0.975]) {
            o.push(quantile_sorted(&v, q));
        }
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcmc::{Ball, DensityFn, Progress, Start};

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
