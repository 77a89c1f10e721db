//! The conclusions of the `bridge-fe` study, computed from the run: how close the SMU
//! reproduction is to the published optimum, what the 5 modes identify, the noise scales,
//! the posterior-predictive frequencies and MACs, and the reduced basis's error at the
//! posterior draws. [`super::bridge_report`] only renders them; `findings.json` holds
//! them.

use serde::Serialize;

use super::bridge::{smu_bounds, SMU_PUBLISHED_ALPHA};
use super::bridge_posterior::Identified;
use super::bridge_run::BridgeStudy;
use super::posterior::quantile_sorted;

/// Median and central 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    pub q50: f64,
    pub q2_5: f64,
    pub q97_5: f64,
}

impl Interval {
    /// Of column `i` of `rows`.
    fn of_column(rows: &[Vec<f64>], i: usize) -> Interval {
        let mut v: Vec<f64> = rows.iter().map(|r| r[i]).collect();
        v.sort_by(f64::total_cmp);
        Interval {
            q50: quantile_sorted(&v, 0.5),
            q2_5: quantile_sorted(&v, 0.025),
            q97_5: quantile_sorted(&v, 0.975),
        }
    }
}

/// A positive scale sampled as its logarithm: `exp` of the posterior mean of the
/// logarithm (the geometric mean) and the 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ScaleInterval {
    pub geometric_mean: f64,
    pub q2_5: f64,
    pub q97_5: f64,
}

/// Posterior-predictive frequency and MAC of one measured mode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PredictedMode {
    pub freq_meas_hz: f64,
    pub freq_sd_hz: f64,
    pub freq_hz: Interval,
    /// `(median - measured) / test scatter`.
    pub z: f64,
    pub mac: Interval,
}

/// How many alphas fall in each [`Identified`] class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct IdentifiedCounts {
    pub by_data: usize,
    pub partly: usize,
    pub prior_only: usize,
    /// At the lower or the upper bound.
    pub at_bound: usize,
}

/// See the module docs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Findings {
    /// Largest `|ours - published| / box width` over the 17 alphas (SMU weighting).
    pub max_dev_from_published_box_frac: f64,
    /// Alphas on a bound at the SMU-weighting and the per-entry optima.
    pub n_on_bound_smu: usize,
    pub n_on_bound_per_entry: usize,
    pub identified: IdentifiedCounts,
    /// Noise scales (1 = the test-to-test scatter explains the misfit).
    pub sigma_eigenvalues: ScaleInterval,
    pub sigma_shapes: ScaleInterval,
    pub predictive: Vec<PredictedMode>,
    /// The reduced basis against the exact solve at posterior draws: largest relative
    /// eigenvalue error and largest `1 - MAC`.
    pub basis_max_eigenvalue_rel_at_draws: f64,
    pub basis_max_one_minus_mac_at_draws: f64,
}

fn identified_counts(study: &BridgeStudy) -> IdentifiedCounts {
    // the alphas only (the noise scales follow them in `verdicts`)
    let alphas = &study.posterior.verdicts[..smu_bounds().len()];
    let count = |v: Identified| alphas.iter().filter(|x| **x == v).count();
    IdentifiedCounts {
        by_data: count(Identified::ByData),
        partly: count(Identified::Partly),
        prior_only: count(Identified::PriorOnly),
        at_bound: count(Identified::AtLowerBound) + count(Identified::AtUpperBound),
    }
}

/// A sampled `ln sigma` coordinate's mean and interval, as `sigma`.
fn noise_scale(study: &BridgeStudy, row: usize) -> ScaleInterval {
    let r = &study.posterior.rows[row];
    ScaleInterval {
        geometric_mean: r.mean.exp(),
        q2_5: r.q2_5.exp(),
        q97_5: r.q97_5.exp(),
    }
}

fn predictive(study: &BridgeStudy) -> Vec<PredictedMode> {
    let post = &study.posterior;
    (0..study.freq_exp_hz.len())
        .map(|i| {
            let freq_hz = Interval::of_column(&post.freq_hz, i);
            PredictedMode {
                freq_meas_hz: study.freq_exp_hz[i],
                freq_sd_hz: study.std_freq_hz[i],
                z: (freq_hz.q50 - study.freq_exp_hz[i]) / study.std_freq_hz[i],
                freq_hz,
                mac: Interval::of_column(&post.mac, i),
            }
        })
        .collect()
}

/// Computes the findings of a run.
pub fn assess(study: &BridgeStudy) -> Findings {
    let (s, p) = (&study.smu, &study.per_entry);
    let n_alpha = smu_bounds().len();
    let at_draws = &study.posterior.basis_at_draws;
    Findings {
        max_dev_from_published_box_frac: smu_bounds()
            .iter()
            .enumerate()
            .map(|(j, (lo, hi))| (s.alpha[j] - SMU_PUBLISHED_ALPHA[j]).abs() / (hi - lo))
            .fold(0.0, f64::max),
        n_on_bound_smu: s.on_bound.iter().filter(|b| **b != 0).count(),
        n_on_bound_per_entry: p.on_bound.iter().filter(|b| **b != 0).count(),
        identified: identified_counts(study),
        sigma_eigenvalues: noise_scale(study, n_alpha),
        sigma_shapes: noise_scale(study, n_alpha + 1),
        predictive: predictive(study),
        basis_max_eigenvalue_rel_at_draws: at_draws
            .iter()
            .flat_map(|p| p.eigenvalue_rel.iter())
            .fold(0.0f64, |a, b| a.max(b.abs())),
        basis_max_one_minus_mac_at_draws: at_draws
            .iter()
            .flat_map(|p| p.one_minus_mac.iter())
            .fold(0.0f64, |a, b| a.max(*b)),
    }
}
