//! How far a posterior sits from a known truth, jointly: the standardised errors of each
//! parameter, their chi-square with the posterior covariance, and the error along one
//! direction (the mass-stiffness scale).
//!
//! With a calibrated posterior (Bernstein-von Mises: `mu - theta_true ~ N(0, S)` over
//! noise draws, `mu` and `S` the posterior mean and covariance), for `p` parameters
//!
//! - `z_j = (mu_j - t_j) / sqrt(S_jj) ~ N(0, 1)` each, but correlated like `S`;
//! - `chi2 = (mu - t)^T S^(-1) (mu - t) ~ chi2(p)`;
//! - along a direction `v` the generalised-least-squares projection
//!   `c(x) = v^T S^(-1) x / (v^T S^(-1) v)` has posterior sd `(v^T S^(-1) v)^(-1/2)` and
//!   `z_v = v^T S^(-1) (mu - t) / sqrt(v^T S^(-1) v) ~ N(0, 1)`.
//!
//! The scale direction of `K(alpha) = sum_s (1 + alpha_s) K_s`, `M(beta) = sum_r (1 +
//! beta_r) M_r` (paper Eqs. 20-21 with `K0 = sum K_s`): `K -> (1 + c) K`, `M -> (1 + c)
//! M` leaves every natural frequency and mode shape unchanged and scales every FRF by
//! `1 / (1 + c)`; to first order `d alpha_s = c (1 + alpha_s)`, `d beta_r = c (1 +
//! beta_r)`, so `v = 1 + t` and `c` is the relative scale error. Where the FRF
//! amplitudes carry a common gain error (the force channel's noise, [`super::data`]), the
//! alphas and betas move together along `v`, and their individual `z_j` share that offset:
//! `max |z_j|` over correlated parameters is then not the maximum of independent normals.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// Joint standardised errors of a posterior against a truth (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointError {
    /// `(mu_j - t_j) / sd_j` per parameter.
    pub z: Vec<f64>,
    /// `(mu - t)^T S^(-1) (mu - t)`; `chi2(p)` for a calibrated posterior.
    pub chi2: f64,
    /// Standardised error along the direction, `N(0, 1)` for a calibrated posterior.
    pub z_dir: f64,
    /// The GLS estimate of the error along the direction, `c(mu - t)` (relative scale
    /// error for `v = 1 + t`).
    pub offset_dir: f64,
    /// Posterior sd of that estimate, `(v^T S^(-1) v)^(-1/2)`.
    pub sd_dir: f64,
}

/// Posterior mean and covariance of `draws` (`n` rows of `p` values, row-major).
pub fn mean_covariance(draws: &[f64], p: usize) -> Result<(DVector<f64>, DMatrix<f64>)> {
    let n = draws.len().checked_div(p).unwrap_or(0);
    if p == 0 || n <= p || draws.len() != n * p {
        return Err(Error::Usage(format!(
            "joint error: {} values for {p} parameters; need more draws than parameters",
            draws.len()
        )));
    }
    let x = DMatrix::from_row_slice(n, p, draws);
    let mu = x.row_mean().transpose();
    let mut c = x;
    for mut row in c.row_iter_mut() {
        row -= mu.transpose();
    }
    let cov = c.transpose() * &c / (n - 1) as f64;
    Ok((mu, cov))
}

/// [`JointError`] of the draws (`p` parameters per row) against `truth`, along `dir`.
pub fn joint_error(draws: &[f64], truth: &[f64], dir: &[f64]) -> Result<JointError> {
    let p = truth.len();
    if dir.len() != p {
        return Err(Error::Usage(format!(
            "joint error: {p} truths but a direction of {}",
            dir.len()
        )));
    }
    let (mu, cov) = mean_covariance(draws, p)?;
    let chol = cov.clone().cholesky().ok_or_else(|| {
        Error::Numerical("joint error: posterior covariance not positive definite".into())
    })?;
    let e = &mu - DVector::from_column_slice(truth);
    let v = DVector::from_column_slice(dir);
    let s_inv_e = chol.solve(&e);
    let s_inv_v = chol.solve(&v);
    let vsv = v.dot(&s_inv_v);
    if !(vsv.is_finite() && vsv > 0.0) {
        return Err(Error::Numerical(format!("joint error: v^T S^-1 v = {vsv}")));
    }
    let vse = v.dot(&s_inv_e);
    Ok(JointError {
        z: (0..p).map(|j| e[j] / cov[(j, j)].sqrt()).collect(),
        chi2: e.dot(&s_inv_e),
        z_dir: vse / vsv.sqrt(),
        offset_dir: vse / vsv,
        sd_dir: vsv.sqrt().recip(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// Draws of a correlated Gaussian `mu + A e`: the joint error against the exact
    /// formulas with the exact `S = A A^T` (within sampling error of 40,000 draws).
    #[test]
    fn joint_error_of_a_known_gaussian() {
        let a = DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 0.0, 0.9, 0.3, 0.0, 0.8, 0.1, 0.5]);
        let mu = [0.3, -0.2, 0.5];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = 40_000;
        let mut draws = Vec::with_capacity(3 * n);
        for _ in 0..n {
            let e = DVector::from_fn(3, |_, _| StandardNormal.sample(&mut rng));
            let x = &a * e;
            draws.extend((0..3).map(|j| mu[j] + x[j]));
        }
        let truth = [0.0; 3];
        let dir = [1.0, 1.0, 1.0];
        let got = joint_error(&draws, &truth, &dir).unwrap();
        let s = &a * a.transpose();
        let si = s.clone().try_inverse().unwrap();
        let m = DVector::from_column_slice(&mu);
        let v = DVector::from_column_slice(&dir);
        let chi2 = m.dot(&(&si * &m));
        let vsv = v.dot(&(&si * &v));
        let z_dir = v.dot(&(&si * &m)) / vsv.sqrt();
        // sampling errors of the mean (1/200 sd) and covariance (~1 %)
        assert!((got.chi2 - chi2).abs() < 0.05 * chi2, "{} {chi2}", got.chi2);
        assert!(
            (got.z_dir - z_dir).abs() < 0.02, // the mean along v: sampling sd 1/sqrt(n) = 0.005
            "{} {z_dir}",
            got.z_dir
        );
        assert!((got.sd_dir - vsv.sqrt().recip()).abs() < 0.02 * got.sd_dir);
        assert!((got.z[0] - 0.3).abs() < 0.02);
        assert!(joint_error(&draws[..6], &truth, &dir).is_err());
    }
}
