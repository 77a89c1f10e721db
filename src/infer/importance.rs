//! `ln Z` by importance sampling from the reference `g` of [`super::reference`] (the t
//! mixture at the mode in logit coordinates): `Z = E_g[q / g]`, the first and only rung
//! of the generalised stepping-stone. Where the posterior is close to Gaussian in logit
//! coordinates (most models of a diagnosis with thousands of FRF points) one rung is
//! enough, and it costs `n` likelihood evaluations instead of the tempered run's tens of
//! thousands.
//!
//! Whether one rung is enough is judged from the weights themselves, by the Pareto
//! shape `k` of their upper tail (Vehtari, Simpson, Gelman, Yao & Gabry 2024, "Pareto
//! smoothed importance sampling", JMLR 25:72; the tail fit of Zhang & Stephens 2009,
//! Technometrics 51:316): below `1/2` the weights have a finite variance and the
//! delta-method standard error of `ln Z` holds; above it the estimate is not trusted
//! and the caller runs the stepping-stone ([`super::screened`]).

use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::evidence::TemperedTarget;
use super::laplace::LaplaceEvidence;
use super::nested::InUnconstrained;
use super::reference::Referenced;
use super::tempering::log_sum_exp;
use crate::error::Result;

/// Largest Pareto tail shape of the weights at which an estimate is reliable: below 1/2
/// the weights have a finite variance (Vehtari et al. 2024).
pub const MAX_PARETO_K: f64 = 0.5;

/// Smallest effective sample size of the weights, as a fraction of the draws, at which
/// an estimate is reliable: `n / ESS - 1` estimates the chi-square divergence of the
/// posterior from the reference, and 1/5 keeps it below 4 (the reference's own mixture
/// costs half the draws when an effect is decisive, ESS <= n/2). The Pareto diagnostic
/// alone is not enough: on the validation problems with effects at a corner of their
/// box it passed 2 of 20 estimates that were 0.4 nats (7 se) low, both with ESS near
/// n/8 (`tests/evidence_validation.rs`).
pub const MIN_ESS_FRACTION: f64 = 0.2;

/// Largest delta-method standard error of a reliable `ln Z`, nats (the
/// stepping-stone's replicates reach about 0.1 on the diagnosis' models).
pub const MAX_SE_NATS: f64 = 0.25;

/// What one importance-sampling estimate found.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImportanceEvidence {
    /// `ln Z`, nats, and its delta-method standard error.
    pub ln_z: f64,
    pub ln_z_se: f64,
    /// Pareto shape of the weights' upper tail (`k-hat`; below 1/2: finite variance).
    pub pareto_k: f64,
    /// Effective sample size of the weights, `(sum w)^2 / sum w^2`.
    pub ess: f64,
    /// Draws from the reference of the estimate.
    pub n_draws: usize,
    /// The reference was adapted to a first pass's weighted draws (that pass was not
    /// reliable).
    #[serde(default)]
    pub adapted: bool,
    /// Likelihood evaluations of both passes.
    #[serde(default)]
    pub n_likelihood_evaluations: u64,
    /// Posterior draws in box coordinates, resampled from the weighted ones.
    pub draws: Vec<Vec<f64>>,
}

impl ImportanceEvidence {
    /// Whether the estimate can be used: Pareto `k` below [`MAX_PARETO_K`], ESS at least
    /// [`MIN_ESS_FRACTION`] of the draws, sd below [`MAX_SE_NATS`].
    pub fn reliable(&self) -> bool {
        self.pareto_k < MAX_PARETO_K
            && self.ess >= MIN_ESS_FRACTION * self.n_draws as f64
            && self.ln_z_se < MAX_SE_NATS
            && self.ln_z.is_finite()
    }
}

/// One pass: draws in logit coordinates and their log weights `ln q/g`.
struct Pass {
    us: Vec<Vec<f64>>,
    ln_w: Vec<f64>,
}

impl Pass {
    fn run<T: TemperedTarget>(
        reference: &Referenced<'_, T>,
        n_draws: usize,
        rng: &mut ChaCha8Rng,
    ) -> Result<Pass> {
        let us: Vec<Vec<f64>> = (0..n_draws)
            .map(|_| reference.sample_prior(rng))
            .collect::<Result<_>>()?;
        let ln_w: Vec<f64> = us
            .par_iter()
            .map(|u| reference.ln_likelihood(u))
            .collect::<Result<_>>()?;
        Ok(Pass { us, ln_w })
    }

    fn summary<T: TemperedTarget>(
        &self,
        reference: &Referenced<'_, T>,
        n_keep: usize,
        rng: &mut ChaCha8Rng,
    ) -> ImportanceEvidence {
        let (ln_z, ln_z_se, ess) = weighted_mean(&self.ln_w);
        let keep = systematic_resample(&self.ln_w, n_keep, rng.random::<f64>());
        ImportanceEvidence {
            ln_z,
            ln_z_se,
            pareto_k: pareto_k_hat(&self.ln_w),
            ess,
            n_draws: self.ln_w.len(),
            adapted: false,
            n_likelihood_evaluations: self.ln_w.len() as u64,
            draws: keep
                .into_iter()
                .map(|i| reference.to_box(&self.us[i]))
                .collect(),
        }
    }

    /// Weighted mean and covariance of the draws.
    fn moments(&self) -> (Vec<f64>, DMatrix<f64>) {
        let top = self.ln_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let w: Vec<f64> = self.ln_w.iter().map(|l| (l - top).exp()).collect();
        let total: f64 = w.iter().sum();
        let d = self.us[0].len();
        let mut mean = DVector::zeros(d);
        for (u, &wi) in self.us.iter().zip(&w) {
            mean += DVector::from_column_slice(u) * (wi / total);
        }
        let mut cov = DMatrix::zeros(d, d);
        for (u, &wi) in self.us.iter().zip(&w) {
            let r = DVector::from_column_slice(u) - &mean;
            cov += &r * r.transpose() * (wi / total);
        }
        (mean.iter().copied().collect(), cov)
    }
}

/// `ln Z` of `target` (box prior on `bounds`) by importance sampling from the reference
/// at the mode `u_mode` (logit coordinates) with Laplace's covariance `lap` there,
/// `effect` the coordinates the base model fixes (as for
/// [`super::reference::referenced_evidence_at_mode`]); `n_draws` draws, then `n_keep`
/// posterior draws resampled (systematic resampling). When that pass is not
/// [`ImportanceEvidence::reliable`], one more from a reference adapted to it (population
/// Monte Carlo, Cappe et al. 2004: centred on the weighted mean, with the average of
/// the weighted covariance and Laplace's), which is returned if it could be made. The
/// same seed gives the same result at any thread count (draws are made in order; only
/// the likelihoods are evaluated in parallel).
#[allow(clippy::too_many_arguments)]
pub fn importance_evidence<T: TemperedTarget>(
    target: &T,
    bounds: &[(f64, f64)],
    u_mode: &[f64],
    lap: &LaplaceEvidence,
    effect: &[usize],
    n_draws: usize,
    n_keep: usize,
    seed: u64,
) -> Result<ImportanceEvidence> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let reference = Referenced::new(
        InUnconstrained::new(target, bounds)?,
        u_mode,
        &lap.covariance,
        effect,
    )?;
    let first = Pass::run(&reference, n_draws, &mut rng)?;
    let found = first.summary(&reference, n_keep, &mut rng);
    if found.reliable() {
        return Ok(found);
    }
    let (mean, cov) = first.moments();
    let cov = (cov + &lap.covariance) * 0.5;
    let second = Referenced::new(InUnconstrained::new(target, bounds)?, &mean, &cov, effect)
        .and_then(|r| {
            let pass = Pass::run(&r, n_draws, &mut rng)?;
            Ok(pass.summary(&r, n_keep, &mut rng))
        });
    Ok(match second {
        Ok(mut s) => {
            s.adapted = true;
            s.n_likelihood_evaluations += found.n_likelihood_evaluations;
            s
        }
        Err(_) => found,
    })
}

/// `ln mean(w)`, its delta-method standard error `sqrt(Var(w) / n) / mean(w)`, and the
/// effective sample size, from log weights `ln_w`.
fn weighted_mean(ln_w: &[f64]) -> (f64, f64, f64) {
    let n = ln_w.len() as f64;
    let top = ln_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = ln_w.iter().map(|l| (l - top).exp()).collect();
    let s1: f64 = w.iter().sum();
    let s2: f64 = w.iter().map(|x| x * x).sum();
    let mean = s1 / n;
    let var = (s2 / n - mean * mean).max(0.0) * n / (n - 1.0);
    let ln_z = log_sum_exp(ln_w) - n.ln();
    (ln_z, (var / n).sqrt() / mean, s1 * s1 / s2)
}

/// `m` indices drawn from the weights `exp(ln_w)` by systematic resampling with offset
/// `u0` in `[0, 1)`.
fn systematic_resample(ln_w: &[f64], m: usize, u0: f64) -> Vec<usize> {
    let total = log_sum_exp(ln_w);
    let mut out = Vec::with_capacity(m);
    let mut cum = 0.0;
    let mut i = 0;
    for j in 0..m {
        let target = (j as f64 + u0) / m as f64;
        while i + 1 < ln_w.len() && cum + (ln_w[i] - total).exp() < target {
            cum += (ln_w[i] - total).exp();
            i += 1;
        }
        out.push(i);
    }
    out
}

/// Pareto shape `k` of the upper tail of the weights `exp(ln_w)`: the largest
/// `M = min(n / 5, 3 sqrt(n))` weights' excesses over the next one, fitted by
/// [`gpd_shape`] (PSIS, Vehtari et al. 2024, section 3).
pub fn pareto_k_hat(ln_w: &[f64]) -> f64 {
    let n = ln_w.len();
    let m = ((n as f64 / 5.0).min(3.0 * (n as f64).sqrt())).floor() as usize;
    if m < 5 || n < m + 1 {
        return f64::INFINITY;
    }
    let mut sorted = ln_w.to_vec();
    sorted.sort_by(f64::total_cmp);
    let top = sorted[n - 1];
    let cutoff = (sorted[n - m - 1] - top).exp();
    let excess: Vec<f64> = sorted[n - m..]
        .iter()
        .map(|l| (l - top).exp() - cutoff)
        .collect();
    gpd_shape(&excess)
}

/// Shape `k` of a generalised Pareto distribution fitted to the excesses `x` (all >= 0)
/// by the profile-likelihood quadrature of Zhang & Stephens (2009) with the weakly
/// informative adjustment towards 1/2 of PSIS (`k <- (n k + 5) / (n + 10)`); `k > 0` is
/// a heavy tail. Infinite when `x` carries no information (all equal).
pub fn gpd_shape(x: &[f64]) -> f64 {
    let mut x = x.to_vec();
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n < 4 {
        return f64::INFINITY;
    }
    let (x_max, x_q1) = (x[n - 1], x[((n as f64) / 4.0 + 0.5).floor() as usize - 1]);
    if x_max <= 0.0 || x_q1 <= 0.0 {
        return f64::INFINITY;
    }
    let n_grid = 30 + (n as f64).sqrt().floor() as usize;
    // Profile log-likelihood of theta (Zhang & Stephens' b): n (ln(-theta / k) - k - 1)
    // with k = mean ln(1 - theta x).
    let k_of = |theta: f64| x.iter().map(|&v| (-theta * v).ln_1p()).sum::<f64>() / n as f64;
    let thetas: Vec<f64> = (1..=n_grid)
        .map(|j| 1.0 / x_max + (1.0 - (n_grid as f64 / (j as f64 - 0.5)).sqrt()) / 3.0 / x_q1)
        .collect();
    let ln_l: Vec<f64> = thetas
        .iter()
        .map(|&t| {
            let k = k_of(t);
            n as f64 * ((-t / k).ln() - k - 1.0)
        })
        .collect();
    let ln_norm = log_sum_exp(&ln_l);
    let theta: f64 = thetas
        .iter()
        .zip(&ln_l)
        .map(|(t, l)| t * (l - ln_norm).exp())
        .sum();
    let k = k_of(theta);
    if !k.is_finite() {
        return f64::INFINITY;
    }
    (n as f64 * k + 5.0) / (n as f64 + 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    /// Excesses of a generalised Pareto with shape `k`, scale 1 (inverse CDF).
    fn gpd_draws(k: f64, n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let u: f64 = rng.random_range(1e-12..1.0);
                (u.powf(-k) - 1.0) / k
            })
            .collect()
    }

    #[test]
    fn the_tail_fit_recovers_a_known_pareto_shape() {
        // n = 2,000 excesses: the estimate's sd is about (1 + k) / sqrt(n) = 0.03;
        // the adjustment towards 1/2 moves it by (0.5 - k) 10 / 2010 < 0.003.
        for &k in &[0.2, 0.5, 0.8] {
            let est = gpd_shape(&gpd_draws(k, 2000, 7));
            assert!((est - k).abs() < 0.1, "k = {k}: estimated {est}");
        }
    }

    #[test]
    fn weights_of_a_perfect_proposal_are_light_tailed() {
        // Equal weights up to tiny noise: every estimate is exact, k far below 1/2.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let ln_w: Vec<f64> = (0..2000)
            .map(|_| 1e-3 * rng.random::<f64>() - 2.0)
            .collect();
        let (ln_z, se, ess) = weighted_mean(&ln_w);
        assert!((ln_z + 2.0 - 5e-4).abs() < 1e-4, "{ln_z}");
        assert!(se < 1e-4 && ess > 1999.0, "se {se}, ess {ess}");
        assert!(pareto_k_hat(&ln_w) < 0.5);
    }

    #[test]
    fn weights_with_an_infinite_variance_are_flagged() {
        // Weights Pareto with index 1/k = 1.25: infinite variance, k = 0.8.
        let ln_w: Vec<f64> = gpd_draws(0.8, 4000, 11).iter().map(|x| x.ln_1p()).collect();
        assert!(pareto_k_hat(&ln_w) > 0.6);
    }

    #[test]
    fn systematic_resampling_follows_the_weights() {
        // Weights 1 : 3 over two points: 1,000 draws give 250 and 750 exactly (the
        // systematic scheme's error is below one draw).
        let ln_w = [0.0, 3f64.ln()];
        let idx = systematic_resample(&ln_w, 1000, 0.37);
        let ones = idx.iter().filter(|&&i| i == 1).count();
        assert!((ones as i64 - 750).abs() <= 1, "{ones}");
    }
}
