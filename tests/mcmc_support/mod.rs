//! Shared targets and checks for the `mcmc_*` integration tests.
#![allow(dead_code)]

use frfbayes::mcmc::{ess_mean, Draws, LogDensity};
use nalgebra::{DMatrix, DVector};

/// Multivariate normal `N(mean, cov)` (unnormalised log density).
pub struct Gaussian {
    pub mean: Vec<f64>,
    pub cov: DMatrix<f64>,
    precision: DMatrix<f64>,
}

impl Gaussian {
    pub fn new(mean: Vec<f64>, cov: DMatrix<f64>) -> Self {
        let precision = cov.clone().cholesky().expect("SPD covariance").inverse();
        Gaussian {
            mean,
            cov,
            precision,
        }
    }

    /// A 10-D (or `d`-D) test target with scales from 0.03 to 30 (affine invariance makes
    /// them irrelevant to the stretch move, not to a broken one), correlations
    /// `0.7^|i-j|` with alternating signs, and mean `i - d/2`.
    pub fn correlated(d: usize) -> Self {
        let scale: Vec<f64> = (0..d)
            .map(|i| 10f64.powf(-1.5 + 3.0 * i as f64 / (d as f64 - 1.0).max(1.0)))
            .collect();
        let cov = DMatrix::from_fn(d, d, |i, j| {
            let k = i.abs_diff(j) as i32;
            let sign = if k % 2 == 1 { -1.0 } else { 1.0 };
            sign * 0.7f64.powi(k) * scale[i] * scale[j]
        });
        let mean = (0..d).map(|i| i as f64 - d as f64 / 2.0).collect();
        Gaussian::new(mean, cov)
    }

    pub fn dim_(&self) -> usize {
        self.mean.len()
    }
}

impl LogDensity for Gaussian {
    fn dim(&self) -> usize {
        self.mean.len()
    }
    fn ln_density(&self, x: &[f64]) -> frfbayes::Result<f64> {
        let r = DVector::from_iterator(x.len(), x.iter().zip(&self.mean).map(|(a, b)| a - b));
        Ok(-0.5 * r.dot(&(&self.precision * &r)))
    }
}

/// `(estimate - truth) / MCSE` for the posterior expectation of `f`, where
/// `MCSE = sd(f) / sqrt(ESS_mean(f))` (Vehtari et al. 2021). Under a correct sampler the
/// estimate is asymptotically normal around the truth with that standard error, so
/// `|z| < 4` fails with probability ~6e-5 per check. Returns `(z, estimate, ess)`.
pub fn z_score(draws: &Draws, f: impl Fn(&[f64]) -> f64 + Sync, truth: f64) -> (f64, f64, f64) {
    let chains = draws.map_chains(f);
    let all: Vec<f64> = chains.iter().flatten().copied().collect();
    let n = all.len() as f64;
    let mean = all.iter().sum::<f64>() / n;
    let var = all.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let ess = ess_mean(&chains);
    ((mean - truth) / (var / ess).sqrt(), mean, ess)
}

/// Checks mean, variances and covariances of `draws` against `target` with `|z| < 4`
/// each (65 checks in 10-D: even with exact 4-sigma tails the chance of a false alarm
/// is < 0.5%, and the seed is fixed). Returns the largest `|z|` and the smallest ESS.
pub fn check_gaussian_moments(draws: &Draws, target: &Gaussian, label: &str) -> (f64, f64) {
    let d = target.dim_();
    let mut worst: f64 = 0.0;
    let mut min_ess = f64::INFINITY;
    let mut check = |name: String, z: f64, est: f64, truth: f64, ess: f64| {
        assert!(
            z.abs() < 4.0,
            "{label}: {name} = {est} vs {truth}: z = {z:.2} (ESS {ess:.0})"
        );
        worst = worst.max(z.abs());
        min_ess = min_ess.min(ess);
    };
    for i in 0..d {
        let mu = target.mean[i];
        let (z, est, ess) = z_score(draws, |x| x[i], mu);
        check(format!("mean[{i}]"), z, est, mu, ess);
        for j in i..d {
            let muj = target.mean[j];
            let truth = target.cov[(i, j)];
            // Second moment about the known mean: E[(x_i - mu_i)(x_j - mu_j)] = Sigma_ij;
            // its MCSE uses the ESS of the product series itself.
            let (z, est, ess) = z_score(draws, |x| (x[i] - mu) * (x[j] - muj), truth);
            check(format!("cov[{i},{j}]"), z, est, truth, ess);
        }
    }
    (worst, min_ess)
}
