//! Convergence diagnostics of Vehtari, Gelman, Simpson, Carpenter & Bürkner (2021),
//! "Rank-normalization, folding, and localization: an improved R-hat for assessing
//! convergence of MCMC", Bayesian Analysis 16(2), as in Stan and the R `posterior`
//! package:
//! - chains are split in halves (the middle draw of an odd-length chain is dropped);
//! - rank normalisation: `z = Phi^-1((r - 3/8) / (S + 1/4))`, `r` the rank among all
//!   `S` draws (average rank for ties);
//! - `R-hat = max(bulk, tail)`: split R-hat of the rank-normalised draws and of the
//!   rank-normalised folded draws `|x - median|`;
//! - bulk-ESS: ESS of the rank-normalised split chains; tail-ESS: the smaller ESS of the
//!   indicators `x <= q05` and `x <= q95` (split chains);
//! - ESS: multi-chain autocorrelation `rho_t = 1 - (W - mean acov_t) / var+`, Geyer's
//!   initial positive then initial monotone sequence, `tau = -1 + 2 sum rho + rho_next`,
//!   `ESS = M N / max(tau, 1/log10(M N))`.
//!
//! Chains are given as a slice of equal-length series (`&[Vec<f64>]`).

use statrs::distribution::{ContinuousCDF, Normal};

use super::autocorr::AcovPlan;

/// R-hat and ESS of one quantity.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Diagnostics {
    /// `max(rhat_bulk, rhat_tail)`.
    pub rhat: f64,
    /// Split R-hat of rank-normalised draws.
    pub rhat_bulk: f64,
    /// Split R-hat of rank-normalised folded draws.
    pub rhat_tail: f64,
    /// Bulk effective sample size.
    pub ess_bulk: f64,
    /// Tail effective sample size (5% and 95% quantiles).
    pub ess_tail: f64,
}

/// All of [`Diagnostics`] for independent `chains`.
pub fn diagnostics(chains: &[Vec<f64>]) -> Diagnostics {
    let (rhat_bulk, rhat_tail) = rhat_of_split(&split_chains(chains), chains);
    Diagnostics {
        rhat: rhat_bulk.max(rhat_tail),
        rhat_bulk,
        rhat_tail,
        ess_bulk: ess_bulk(chains),
        ess_tail: ess_tail(chains),
    }
}

/// Diagnostics of ensemble-sampler output: `chains` are walker chains, consecutive groups
/// of `walkers` chains forming one ensemble.
///
/// - R-hat treats each *ensemble* as one chain: its draws are all its walkers' draws,
///   split in time (first and second half of the steps), then rank-normalised and folded
///   as usual. With walkers as chains, each walker holds few effective draws and split
///   R-hat is biased upward by about `(tau_c - 1) / (2 N)` (`N` draws per half-chain,
///   `tau_c` their autocorrelation time): in a seeded 10-D test with 128 walkers, 1.02
///   on well-converged output. Pooling the walkers of an ensemble makes each chain long;
///   independent ensembles still compare as independent chains (cf. nested R-hat,
///   Margossian et al. 2024, superchains of subchains).
/// - ESS is Stan's multi-chain ESS over the walker chains (it needs time series); over
///   100 replicate runs the ESS-based standard errors matched the observed spread of the
///   estimates to within 5% (`tests/mcmc_thorough.rs`).
pub fn ensemble_diagnostics(chains: &[Vec<f64>], walkers: usize) -> Diagnostics {
    assert!(
        walkers > 0 && chains.len().is_multiple_of(walkers),
        "chains must come in whole ensembles"
    );
    let n = chains.first().map_or(0, |c| c.len());
    let half = n / 2;
    let mut split = Vec::with_capacity(2 * chains.len() / walkers);
    for group in chains.chunks(walkers) {
        split.push(
            group
                .iter()
                .flat_map(|c| c[..half].iter().copied())
                .collect(),
        );
        split.push(
            group
                .iter()
                .flat_map(|c| c[n - half..].iter().copied())
                .collect(),
        );
    }
    let (rhat_bulk, rhat_tail) = rhat_of_split(&split, chains);
    Diagnostics {
        rhat: rhat_bulk.max(rhat_tail),
        rhat_bulk,
        rhat_tail,
        ess_bulk: ess_bulk(chains),
        ess_tail: ess_tail(chains),
    }
}

/// Bulk and tail R-hat of already split chains; `chains` (unsplit) give the median
/// about which draws are folded.
fn rhat_of_split(split: &[Vec<f64>], chains: &[Vec<f64>]) -> (f64, f64) {
    let rhat_bulk = rhat_basic(&rank_normalize(split));
    let med = quantile(&sorted_all(chains), 0.5);
    let folded: Vec<Vec<f64>> = split
        .iter()
        .map(|c| c.iter().map(|v| (v - med).abs()).collect())
        .collect();
    (rhat_bulk, rhat_basic(&rank_normalize(&folded)))
}

/// Rank-normalised split R-hat, `max(bulk, tail)`, of independent chains.
pub fn rhat(chains: &[Vec<f64>]) -> f64 {
    diagnostics(chains).rhat
}

/// Bulk-ESS: ESS of rank-normalised split chains.
pub fn ess_bulk(chains: &[Vec<f64>]) -> f64 {
    ess_basic(&rank_normalize(&split_chains(chains)))
}

/// Tail-ESS: `min(ESS(x <= q05), ESS(x <= q95))` on split chains.
pub fn ess_tail(chains: &[Vec<f64>]) -> f64 {
    let all = sorted_all(chains);
    let split = split_chains(chains);
    [0.05, 0.95]
        .iter()
        .map(|&p| {
            let q = quantile(&all, p);
            let ind: Vec<Vec<f64>> = split
                .iter()
                .map(|c| c.iter().map(|&v| if v <= q { 1.0 } else { 0.0 }).collect())
                .collect();
            ess_basic(&ind)
        })
        .fold(f64::INFINITY, f64::min)
}

/// ESS for the mean of the draws themselves (split chains, no rank normalisation;
/// `posterior::ess_mean`). Use it for Monte Carlo standard errors of expectations.
pub fn ess_mean(chains: &[Vec<f64>]) -> f64 {
    ess_basic(&split_chains(chains))
}

/// Monte Carlo standard error of the mean, `sd / sqrt(ess_mean)`.
pub fn mcse_mean(chains: &[Vec<f64>]) -> f64 {
    let all: Vec<f64> = chains.iter().flatten().copied().collect();
    let n = all.len() as f64;
    let mean = all.iter().sum::<f64>() / n;
    let var = all.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (var / ess_mean(chains)).sqrt()
}

/// Each chain cut into two halves (first `floor(N/2)`, last `floor(N/2)` draws).
pub fn split_chains(chains: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(2 * chains.len());
    for c in chains {
        let n = c.len();
        if n < 2 {
            out.push(c.clone());
            continue;
        }
        let half = n / 2;
        out.push(c[..half].to_vec());
        out.push(c[n - half..].to_vec());
    }
    out
}

/// Rank normalisation over all draws of all chains (Blom offset 3/8).
pub fn rank_normalize(chains: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let flat: Vec<f64> = chains.iter().flatten().copied().collect();
    let s = flat.len();
    let mut order: Vec<usize> = (0..s).collect();
    order.sort_by(|&i, &j| flat[i].total_cmp(&flat[j]));
    let mut rank = vec![0.0; s];
    let mut i = 0;
    while i < s {
        let mut j = i;
        while j + 1 < s && flat[order[j + 1]] == flat[order[i]] {
            j += 1;
        }
        // Ranks i+1..=j+1 tie: average rank.
        let r = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            rank[k] = r;
        }
        i = j + 1;
    }
    let normal = Normal::standard();
    let mut out = Vec::with_capacity(chains.len());
    let mut k = 0;
    for c in chains {
        out.push(
            (0..c.len())
                .map(|_| {
                    let z = normal.inverse_cdf((rank[k] - 0.375) / (s as f64 + 0.25));
                    k += 1;
                    z
                })
                .collect(),
        );
    }
    out
}

fn sorted_all(chains: &[Vec<f64>]) -> Vec<f64> {
    let mut all: Vec<f64> = chains.iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    all
}

/// Sample quantile of sorted data, R's default (type 7): linear interpolation between
/// order statistics at `h = (n - 1) p`.
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    let n = sorted.len();
    if n == 0 {
        return f64::NAN;
    }
    let h = (n - 1) as f64 * p;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(n - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

fn is_constant(chains: &[Vec<f64>]) -> bool {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in chains.iter().flatten() {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    (hi - lo).abs() < f64::EPSILON
}

fn mean_var(c: &[f64]) -> (f64, f64) {
    let n = c.len() as f64;
    let m = c.iter().sum::<f64>() / n;
    let v = c.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, v)
}

/// Classic R-hat of the given chains (call with split chains for split R-hat):
/// `sqrt((B/W + N - 1)/N)`, `B = N var(chain means)`, `W = mean chain variance`.
/// NaN for non-finite draws or chains shorter than 2; 1 for constant draws.
pub fn rhat_basic(chains: &[Vec<f64>]) -> f64 {
    let m = chains.len();
    let n = chains.first().map_or(0, |c| c.len());
    if m < 2 || n < 2 || chains.iter().flatten().any(|v| !v.is_finite()) {
        return f64::NAN;
    }
    if is_constant(chains) {
        return 1.0;
    }
    let stats: Vec<(f64, f64)> = chains.iter().map(|c| mean_var(c)).collect();
    let means: Vec<f64> = stats.iter().map(|s| s.0).collect();
    let (_, var_means) = mean_var(&means);
    let var_between = n as f64 * var_means;
    let var_within = stats.iter().map(|s| s.1).sum::<f64>() / m as f64;
    ((var_between / var_within + n as f64 - 1.0) / n as f64).sqrt()
}

/// Multi-chain ESS with Geyer's initial monotone sequence (call with split chains).
/// NaN for non-finite draws or chains shorter than 3; `M N` for constant draws.
pub fn ess_basic(chains: &[Vec<f64>]) -> f64 {
    let m = chains.len();
    let n = chains.first().map_or(0, |c| c.len());
    if m == 0 || n < 3 || chains.iter().flatten().any(|v| !v.is_finite()) {
        return f64::NAN;
    }
    assert!(
        chains.iter().all(|c| c.len() == n),
        "chains must have equal lengths"
    );
    let total = (m * n) as f64;
    if is_constant(chains) {
        return total;
    }
    let refs: Vec<&[f64]> = chains.iter().map(|c| c.as_slice()).collect();
    let acov = AcovPlan::new(n).mean_autocovariance(&refs);
    let mean_acov = |t: usize| acov[t];
    let nf = n as f64;
    let chain_means: Vec<f64> = chains.iter().map(|c| c.iter().sum::<f64>() / nf).collect();
    // Mean within-chain variance W (denominator N - 1) and var+ = (N-1)/N W + B/N.
    let within = mean_acov(0) * nf / (nf - 1.0);
    let mut var_plus = within * (nf - 1.0) / nf;
    if m > 1 {
        var_plus += mean_var(&chain_means).1;
    }
    let rho = |t: usize| 1.0 - (within - mean_acov(t)) / var_plus;

    // Geyer's initial positive sequence.
    let mut rho_hat = vec![0.0; n];
    let mut t = 0;
    let mut rho_even = 1.0;
    rho_hat[0] = rho_even;
    let mut rho_odd = rho(1);
    rho_hat[1] = rho_odd;
    while t + 5 < n && !(rho_even + rho_odd).is_nan() && rho_even + rho_odd > 0.0 {
        t += 2;
        rho_even = rho(t);
        rho_odd = rho(t + 1);
        if rho_even + rho_odd >= 0.0 {
            rho_hat[t] = rho_even;
            rho_hat[t + 1] = rho_odd;
        }
    }
    let max_t = t;
    // Used in the improved estimate.
    if rho_even > 0.0 {
        rho_hat[max_t] = rho_even;
    }
    // Geyer's initial monotone sequence.
    let mut t = 0;
    while t + 4 <= max_t {
        t += 2;
        if rho_hat[t] + rho_hat[t + 1] > rho_hat[t - 2] + rho_hat[t - 1] {
            rho_hat[t] = (rho_hat[t - 2] + rho_hat[t - 1]) / 2.0;
            rho_hat[t + 1] = rho_hat[t];
        }
    }
    // tau = -1 + 2 sum_{k < max_t} rho_k + rho_{max_t} (improved truncation).
    let tau = -1.0 + 2.0 * rho_hat[..max_t].iter().sum::<f64>() + rho_hat[max_t];
    let tau = tau.max(1.0 / total.log10());
    total / tau
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_type7() {
        let s = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile(&s, 0.5), 2.5);
        assert!((quantile(&s, 0.05) - 1.15).abs() < 1e-12);
        assert_eq!(quantile(&s, 1.0), 4.0);
    }

    #[test]
    fn ranks_average_ties_and_use_blom_offset() {
        let z = rank_normalize(&[vec![3.0, 1.0], vec![1.0, 2.0]]);
        // ranks: 3 -> 4, 1 -> 1.5 (tie), 2 -> 3; S = 4.
        let normal = Normal::standard();
        let expect = |r: f64| normal.inverse_cdf((r - 0.375) / 4.25);
        assert!((z[0][0] - expect(4.0)).abs() < 1e-14);
        assert!((z[0][1] - expect(1.5)).abs() < 1e-14);
        assert_eq!(z[0][1], z[1][0]);
        assert!((z[1][1] - expect(3.0)).abs() < 1e-14);
    }

    #[test]
    fn split_drops_the_middle_of_odd_chains() {
        let s = split_chains(&[vec![1.0, 2.0, 3.0, 4.0, 5.0]]);
        assert_eq!(s, vec![vec![1.0, 2.0], vec![4.0, 5.0]]);
    }

    #[test]
    fn rhat_basic_by_hand() {
        // Two chains, N = 3: means 2 and 5, variances 1 and 1.
        // B = 3 * var([2, 5]) = 3 * 4.5 = 13.5, W = 1; R = sqrt((13.5 + 2) / 3).
        let r = rhat_basic(&[vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]]);
        assert!((r - (15.5f64 / 3.0).sqrt()).abs() < 1e-14);
    }
}
