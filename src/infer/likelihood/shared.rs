//! Noise shared by a block's values at a known size, on top of their own noise scaled by
//! the block's `sigma`: `cov = sigma^2 D + L L^T` (`D = diag(sd_k^2)`, `L` the loadings,
//! `n x rank`), as one test's force noise is shared by every FRF value of the test.
//!
//! With the standardised residuals `d_k = r_k / sd_k`, `V = D^(-1/2) L` and the
//! eigen-decomposition `V^T V = Q diag(lambda) Q^T` (computed once), the rows of
//! `P = Q^T V^T` give `u = P d` and
//!
//! - `r^T cov^(-1) r = (d^T d - sum_i u_i^2 / (sigma^2 + lambda_i)) / sigma^2`,
//! - `ln det cov = ln det D + 2 n ln sigma + sum_i ln(1 + lambda_i / sigma^2)`
//!
//! (Woodbury and the matrix determinant lemma on `sigma^2 I + V V^T`), so an evaluation
//! costs `O(n rank)`.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, SymmetricEigen};

/// The Woodbury factors of a block's shared noise (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SharedFactors {
    rank: usize,
    /// `P`, `rank x n`, row-major.
    p: Vec<f64>,
    /// Eigenvalues `lambda_i` of `V^T V` (>= 0).
    lambda: Vec<f64>,
}

impl SharedFactors {
    /// The factors of loadings `loadings` (`n x rank`, row-major) on values with standard
    /// deviations `sd` (`n`).
    pub fn new(loadings: &[f64], rank: usize, sd: &[f64]) -> Result<Self> {
        let n = sd.len();
        if loadings.len() != n * rank {
            return Err(Error::Usage(format!(
                "{} shared-noise loadings for {n} values of rank {rank}",
                loadings.len()
            )));
        }
        if loadings.iter().any(|x| !x.is_finite()) {
            return Err(Error::Usage("shared-noise loadings must be finite".into()));
        }
        if rank == 0 {
            return Ok(SharedFactors {
                rank,
                p: Vec::new(),
                lambda: Vec::new(),
            });
        }
        let v = DMatrix::from_fn(n, rank, |k, r| loadings[k * rank + r] / sd[k]);
        let eig = SymmetricEigen::new(v.transpose() * &v);
        if eig.eigenvalues.iter().any(|x| !x.is_finite()) {
            return Err(Error::Numerical(
                "shared noise: non-finite eigenvalues of V^T V".into(),
            ));
        }
        let vq = &v * &eig.eigenvectors;
        let p = (0..rank)
            .flat_map(|i| (0..n).map(move |k| (i, k)))
            .map(|(i, k)| vq[(k, i)])
            .collect();
        Ok(SharedFactors {
            rank,
            p,
            lambda: eig.eigenvalues.iter().map(|x| x.max(0.0)).collect(),
        })
    }

    /// Columns of `L`.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Eigenvalues `lambda_i` of `V^T V`.
    pub fn lambda(&self) -> &[f64] {
        &self.lambda
    }

    /// `(sum_i u_i^2 / (s2 + lambda_i), sum_i ln(1 + lambda_i / s2))` for the standardised
    /// residuals `d` at `sigma^2 = s2`.
    pub fn terms(&self, d: &[f64], s2: f64) -> (f64, f64) {
        let n = d.len();
        let mut correction = 0.0;
        let mut prod = 1.0;
        for (row, &lambda) in self.p.chunks_exact(n.max(1)).zip(&self.lambda) {
            let u: f64 = row.iter().zip(d).map(|(p, d)| p * d).sum();
            let q = s2 + lambda;
            correction += u * u / q;
            prod *= q / s2;
        }
        (correction, prod.ln())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::infer::likelihood::{Block, NoiseScale, Transform};

    /// Oracle: the block's log-likelihood equals the dense Gaussian log density
    /// `-n/2 ln 2 pi - ln det(cov)/2 - r^T cov^-1 r / 2` with
    /// `cov = sigma^2 diag(sd^2) + L L^T`, for ranks 0 to 3, both transforms and several
    /// noise scales.
    #[test]
    fn shared_noise_block_is_the_dense_gaussian_density() {
        let n = 11;
        let obs: Vec<f64> = (0..n).map(|k| 1.0 + 0.3 * (k as f64).sin().abs()).collect();
        let pred: Vec<f64> = (0..n)
            .map(|k| obs[k] * (1.0 + 0.02 * (k as f64 * 1.7).cos()))
            .collect();
        let sd: Vec<f64> = (0..n).map(|k| 0.01 + 0.002 * k as f64).collect();
        for rank in 0..4 {
            let loadings: Vec<f64> = (0..n * rank)
                .map(|i| 0.008 * ((i as f64 * 0.9).sin() + 0.3))
                .collect();
            for transform in [Transform::Identity, Transform::Ln] {
                let b = Block::shared_noise(
                    "s",
                    0..n,
                    &obs,
                    &sd,
                    transform,
                    (&loadings, rank),
                    NoiseScale::Sampled(0),
                )
                .unwrap();
                let mut r = vec![0.0; n];
                b.residuals(&pred, &mut r);
                for sigma in [0.3, 1.0, 2.5] {
                    let got = b.ln_likelihood(&r, sigma);
                    let cov = DMatrix::from_fn(n, n, |i, j| {
                        let own = if i == j { (sigma * sd[i]).powi(2) } else { 0.0 };
                        own + (0..rank)
                            .map(|c| loadings[i * rank + c] * loadings[j * rank + c])
                            .sum::<f64>()
                    });
                    let e = nalgebra::DVector::from_fn(n, |k, _| match transform {
                        Transform::Ln => pred[k].ln() - obs[k].ln(),
                        _ => pred[k] - obs[k],
                    });
                    let chol = cov.cholesky().unwrap();
                    let ln_det: f64 = 2.0 * chol.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
                    let quad = e.dot(&chol.solve(&e));
                    let dense = -0.5 * n as f64 * (2.0 * std::f64::consts::PI).ln()
                        - 0.5 * ln_det
                        - 0.5 * quad;
                    assert!(
                        (got - dense).abs() <= 1e-10 * dense.abs().max(1.0),
                        "rank {rank} {transform:?} sigma {sigma}: {got} vs {dense}"
                    );
                }
            }
        }
    }

    #[test]
    fn rejects_loadings_of_the_wrong_size() {
        let err = SharedFactors::new(&[1.0; 5], 2, &[1.0; 3]).unwrap_err();
        assert!(err.to_string().contains("rank 2"), "{err}");
    }
}
