//! Gauss-Markov correlation along a block's values (neighbouring FRF bins correlated by
//! the estimator's window): in units of each value's standard deviation,
//! `e_k = rho_k e_(k-1) + sqrt(1 - rho_k^2) u_k` with `u` independent standard normal
//! (`rho_k = 0` starts a run). Its correlation matrix is `C = R R^T` with `R` lower
//! bidiagonal, so `R^-1 e = u` (whitening) costs one pass, and
//! `ln det C = sum_k ln(1 - rho_k^2)`.

use crate::error::{Error, Result};

/// `rho_k` and `1 / sqrt(1 - rho_k^2)` of every value.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    rho: Vec<f64>,
    scale: Vec<f64>,
}

impl Chain {
    /// `None` when every value is independent (`rho` empty or all zero); an error when
    /// some `rho_k` is outside `(-1, 1)`.
    pub fn new(rho: &[f64]) -> Result<Option<Self>> {
        if rho.iter().all(|&r| r == 0.0) {
            return Ok(None);
        }
        if let Some(r) = rho.iter().find(|r| !(r.is_finite() && r.abs() < 1.0)) {
            return Err(Error::Usage(format!(
                "bin correlation {r}: it must lie in (-1, 1)"
            )));
        }
        let scale = rho.iter().map(|r| 1.0 / (1.0 - r * r).sqrt()).collect();
        Ok(Some(Chain {
            rho: rho.to_vec(),
            scale,
        }))
    }

    /// Whether the first value starts a run (`rho_0 = 0`): a block's chain may not
    /// continue one from before it.
    pub fn starts_a_run(&self) -> bool {
        self.rho.first().is_none_or(|&r| r == 0.0)
    }

    /// `x <- R^-1 x` in place: `x_k <- (x_k - rho_k x_(k-1)) / sqrt(1 - rho_k^2)`, from
    /// the last value down so that `x_(k-1)` is still the original.
    pub fn whiten(&self, x: &mut [f64]) {
        debug_assert_eq!(x.len(), self.rho.len());
        for k in (1..x.len()).rev() {
            x[k] = (x[k] - self.rho[k] * x[k - 1]) * self.scale[k];
        }
        if let Some(x0) = x.first_mut() {
            *x0 *= self.scale[0];
        }
    }

    /// `x <- R x` in place (the inverse of [`Self::whiten`]): independent `u` to the
    /// chain's `e`.
    pub fn colour(&self, x: &mut [f64]) {
        debug_assert_eq!(x.len(), self.rho.len());
        let mut prev = 0.0;
        for ((v, r), sc) in x.iter_mut().zip(&self.rho).zip(&self.scale) {
            prev = r * prev + *v / sc;
            *v = prev;
        }
    }

    /// `-ln` of each value's conditional standard deviation factor,
    /// `-ln(1 - rho_k^2) / 2` (`>= 0`); their sum is `-ln det C / 2`.
    pub fn ln_inv_sd_factor(&self) -> impl Iterator<Item = f64> + '_ {
        self.scale.iter().map(|s| s.ln())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// Oracle: the dense correlation `C_ij = prod rho` along the chain (1 on the
    /// diagonal, 0 across a run start): `u = R^-1 e` gives `u^T u = e^T C^-1 e`,
    /// `colour` inverts `whiten`, and `sum ln(1 - rho^2) = ln det C`.
    #[test]
    fn whitening_matches_the_dense_covariance() {
        let rho = [0.0, 0.69, 0.43, 0.69, 0.0, 0.5, 0.9];
        let n = rho.len();
        let c = DMatrix::from_fn(n, n, |i, j| {
            let (a, b) = (i.min(j), i.max(j));
            (a + 1..=b).map(|k| rho[k]).product::<f64>()
        });
        let e: Vec<f64> = (0..n).map(|k| (k as f64 * 1.7).sin() + 0.3).collect();
        let w = Chain::new(&rho).unwrap().unwrap();
        let mut u = e.clone();
        w.whiten(&mut u);
        let ev = DVector::from_vec(e.clone());
        let quad = (ev.transpose() * c.clone().try_inverse().unwrap() * &ev)[(0, 0)];
        let uu: f64 = u.iter().map(|v| v * v).sum();
        assert!((uu - quad).abs() < 1e-10 * quad, "{uu} {quad}");
        let ln_det: f64 = -2.0 * w.ln_inv_sd_factor().sum::<f64>();
        assert!((ln_det - c.determinant().ln()).abs() < 1e-10);
        w.colour(&mut u);
        for (a, b) in u.iter().zip(&e) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!(w.starts_a_run());
        assert!(!Chain::new(&rho[1..]).unwrap().unwrap().starts_a_run());
        assert!(Chain::new(&[0.0, 0.0]).unwrap().is_none());
        assert!(Chain::new(&[0.0, 1.0]).is_err());
    }
}
