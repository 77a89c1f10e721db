//! The force channel's noise inside the force windows of a hammer estimate, and the error
//! it gives `|H1|`: smooth in frequency and common to every response of the test.
//!
//! With the measured force `X_b = F_b + N_b` of block `b` (one block for the whole-record
//! estimator), `H1 = sum_b Y_b conj(X_b) / sum_b |X_b|^2` and, to first order in `N`,
//!
//! `H1_k = H_k (1 + eps_k)`, `eps_k = -sum_b conj(F_bk) N_bk / G_k`, `G_k = sum_b |F_bk|^2`,
//!
//! the same `eps_k` for every response (they share the force). The force noise is white
//! (`sigma_f`, [`super::hammer::force_noise_std`]) and windowed by `w_bn` (force window
//! times exponential window), `N_bk = sum_n sigma_f w_bn e_bn exp(-2 pi j k n / n_fft)`
//! with `e_bn` independent standard normal, so the relative magnitude error is
//!
//! `ln |H1_k| - ln |H_k| = Re(eps_k) = sum_(b,n) a_(k,bn) e_bn`,
//! `a_(k,bn) = -sigma_f w_bn Re(conj(F_bk) exp(-2 pi j k n / n_fft)) / G_k`.
//!
//! A force window of about 0.1 s makes `eps` smooth over about 10 Hz: at the four
//! modes of the four-story frame (0.9-5.7 Hz) it is nearly one common gain error per test
//! (0.1-0.2 % on the simulated campaign), which no local model of the FRF can see and
//! which, counted as independent between the points of a test, is counted about as many
//! times as the test has points. [`InputNoise::relative_loadings`] gives the `a` at any
//! bins; their covariance `A A^T` has a few significant eigenvalues
//! ([`InputNoise::low_rank`]).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, SymmetricEigen};
use num_complex::Complex64;

/// The force noise of a hammer estimate (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct InputNoise {
    /// Transform length (the `n_fft` of the bins).
    pub n_fft: usize,
    /// Per block, `(n, sigma_f w_bn)` for every sample inside the force window.
    pub weights: Vec<Vec<(usize, f64)>>,
    /// Per block, the force spectrum `F_bk` at the kept bins.
    pub force: Vec<Vec<Complex64>>,
}

/// A low-rank factor of the relative-error covariance at some bins.
#[derive(Debug, Clone, PartialEq)]
pub struct LowRank {
    /// `bins x rank`, row-major: `cov ~ L L^T`.
    pub loadings: Vec<f64>,
    pub rank: usize,
    /// Per bin, the variance of the dropped components (`cov_kk - (L L^T)_kk`, >= 0).
    pub dropped_var: Vec<f64>,
}

impl InputNoise {
    /// Checks the shapes: one weight list and one force spectrum per block.
    pub fn new(
        n_fft: usize,
        weights: Vec<Vec<(usize, f64)>>,
        force: Vec<Vec<Complex64>>,
    ) -> Result<Self> {
        if weights.len() != force.len() || weights.is_empty() || n_fft == 0 {
            return Err(Error::Usage(format!(
                "input noise: {} weight lists for {} force spectra (n_fft {n_fft})",
                weights.len(),
                force.len()
            )));
        }
        Ok(InputNoise {
            n_fft,
            weights,
            force,
        })
    }

    /// Number of independent noise samples (columns of [`Self::relative_loadings`]).
    pub fn n_samples(&self) -> usize {
        self.weights.iter().map(Vec::len).sum()
    }

    /// `a_(k, bn)` at `bins` (rows, row-major, [`Self::n_samples`] columns): the relative
    /// magnitude error at bin `k` is `sum_j a_kj e_j` with `e_j` independent standard
    /// normal. Zero rows where the force spectrum vanishes.
    pub fn relative_loadings(&self, bins: &[usize]) -> Result<Vec<f64>> {
        let n_cols = self.n_samples();
        let n_kept = self.force.iter().map(Vec::len).min().unwrap_or(0);
        let mut a = vec![0.0; bins.len() * n_cols];
        for (row, &k) in bins.iter().enumerate() {
            if k >= n_kept {
                return Err(Error::Usage(format!(
                    "input noise: bin {k} beyond the {n_kept} kept bins"
                )));
            }
            let g: f64 = self.force.iter().map(|f| f[k].norm_sqr()).sum();
            if g <= 0.0 {
                continue;
            }
            let mut col = 0;
            for (w, f) in self.weights.iter().zip(&self.force) {
                let fk = f[k].conj() / g;
                for &(n, sw) in w {
                    let ang = -2.0 * std::f64::consts::PI * ((k * n) % self.n_fft) as f64
                        / self.n_fft as f64;
                    a[row * n_cols + col] = -sw * (fk * Complex64::from_polar(1.0, ang)).re;
                    col += 1;
                }
            }
        }
        Ok(a)
    }

    /// Covariance of the relative magnitude errors at `bins`, `A A^T`.
    pub fn relative_covariance(&self, bins: &[usize]) -> Result<DMatrix<f64>> {
        let a =
            DMatrix::from_row_slice(bins.len(), self.n_samples(), &self.relative_loadings(bins)?);
        Ok(&a * a.transpose())
    }

    /// The eigen-components of [`Self::relative_covariance`] with eigenvalues at least
    /// `rel_tol` of the largest, as loadings `sqrt(lambda) v`; the rest's variance per bin
    /// is returned apart (to be added to the independent noise).
    pub fn low_rank(&self, bins: &[usize], rel_tol: f64) -> Result<LowRank> {
        let c = self.relative_covariance(bins)?;
        let n = bins.len();
        let eig = SymmetricEigen::new(c.clone());
        let max = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
        let kept: Vec<usize> = order
            .into_iter()
            .filter(|&i| max > 0.0 && eig.eigenvalues[i] >= rel_tol * max)
            .collect();
        let rank = kept.len();
        let mut loadings = vec![0.0; n * rank];
        for (r, &i) in kept.iter().enumerate() {
            let s = eig.eigenvalues[i].sqrt();
            for k in 0..n {
                loadings[k * rank + r] = s * eig.eigenvectors[(k, i)];
            }
        }
        let dropped_var = (0..n)
            .map(|k| {
                let kept_var: f64 = loadings[k * rank..(k + 1) * rank]
                    .iter()
                    .map(|v| v * v)
                    .sum();
                (c[(k, k)] - kept_var).max(0.0)
            })
            .collect();
        Ok(LowRank {
            loadings,
            rank,
            dropped_var,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// A hammer-like force: a 3-sample pulse at sample 50 of 4000, window of 60 samples.
    fn example() -> (Vec<f64>, Vec<f64>, usize) {
        let n = 4000;
        let mut f = vec![0.0; n];
        f[49] = 10.0;
        f[50] = 30.0;
        f[51] = 10.0;
        let w: Vec<f64> = (0..n)
            .map(|i| {
                if (20..80).contains(&i) {
                    (-(i as f64) / 900.0).exp()
                } else {
                    0.0
                }
            })
            .collect();
        (f, w, n)
    }

    fn dft(x: &[f64], k: usize) -> Complex64 {
        let n = x.len();
        x.iter()
            .enumerate()
            .map(|(i, &v)| {
                v * Complex64::from_polar(
                    1.0,
                    -2.0 * std::f64::consts::PI * ((k * i) % n) as f64 / n as f64,
                )
            })
            .sum()
    }

    /// The linearised loadings against the exact `ln |F / (F + N)|` of simulated noise:
    /// covariance over 4000 draws within sampling error, and the low-rank factor equal
    /// to the full covariance within its tolerance.
    #[test]
    fn loadings_match_simulated_force_noise() {
        let (f, w, n) = example();
        let sigma_f = 0.05;
        let bins = [10, 11, 40, 120];
        let force: Vec<Complex64> = (0..=130).map(|k| dft(&f, k)).collect();
        let weights: Vec<(usize, f64)> = w
            .iter()
            .enumerate()
            .filter(|(_, &v)| v != 0.0)
            .map(|(i, &v)| (i, sigma_f * v))
            .collect();
        let noise = InputNoise::new(n, vec![weights], vec![force.clone()]).unwrap();
        let cov = noise.relative_covariance(&bins).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let draws = 4000;
        let mut emp = DMatrix::<f64>::zeros(bins.len(), bins.len());
        for _ in 0..draws {
            let noisy: Vec<f64> = f
                .iter()
                .zip(&w)
                .map(|(&x, &wi)| {
                    let e: f64 = StandardNormal.sample(&mut rng);
                    x + sigma_f * wi * e
                })
                .collect();
            // H1 = Y conj(X) / |X|^2 with Y = H F: ln|H1 / H| = ln|F| - ln|X|
            let err: Vec<f64> = bins
                .iter()
                .map(|&k| force[k].norm().ln() - dft(&noisy, k).norm().ln())
                .collect();
            for i in 0..bins.len() {
                for j in 0..bins.len() {
                    emp[(i, j)] += err[i] * err[j] / draws as f64;
                }
            }
        }
        for i in 0..bins.len() {
            for j in 0..bins.len() {
                let sd = (cov[(i, i)] * cov[(j, j)]).sqrt();
                // sampling sd of a covariance estimate <= sd sqrt(2 / draws) = 0.022 sd
                assert!(
                    (emp[(i, j)] - cov[(i, j)]).abs() < 0.1 * sd,
                    "({i},{j}): empirical {} predicted {}",
                    emp[(i, j)],
                    cov[(i, j)]
                );
            }
        }
        let lr = noise.low_rank(&bins, 1e-12).unwrap();
        for i in 0..bins.len() {
            for j in 0..bins.len() {
                let v: f64 = (0..lr.rank)
                    .map(|r| lr.loadings[i * lr.rank + r] * lr.loadings[j * lr.rank + r])
                    .sum();
                assert!((v - cov[(i, j)]).abs() < 1e-9 * cov[(i, i)].max(cov[(j, j)]));
            }
        }
        // neighbouring bins share their force error almost entirely
        let r = cov[(0, 1)] / (cov[(0, 0)] * cov[(1, 1)]).sqrt();
        assert!(r > 0.99, "correlation of bins 10 and 11: {r}");
    }
}
