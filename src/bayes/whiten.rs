//! The Gauss-Markov chain of correlated neighbouring bins ([`super::FrfData::bin_correlation`]):
//! in units of `sigma`, `e_k = rho_k e_(k-1) + sqrt(1 - rho_k^2) u_k` with `u` independent
//! standard normal (`rho_k = 0` starts a run). Its covariance is `C = R R^T` with `R`
//! lower bidiagonal, so `R^-1 e = u` (whitening) costs one pass, and
//! `ln det C = sum_k ln(1 - rho_k^2)`.

use super::data::{CorrelatedNoise, FrfData};
use crate::error::{Error, Result};

/// `rho_k` and `1 / sqrt(1 - rho_k^2)` of every point.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Whitening {
    rho: Vec<f64>,
    scale: Vec<f64>,
}

impl Whitening {
    /// `None` when every point is independent (`rho` empty or all zero).
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
        Ok(Some(Whitening {
            rho: rho.to_vec(),
            scale,
        }))
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.rho.len()
    }

    /// `x <- R^-1 x` in place: `x_k <- (x_k - rho_k x_(k-1)) / sqrt(1 - rho_k^2)`, from
    /// the last point down so that `x_(k-1)` is still the original.
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

    /// `ln` of the conditional standard deviation factor of each point,
    /// `0.5 ln(1 - rho_k^2)` (`<= 0`); their sum is `0.5 ln det C`.
    pub fn ln_sd_factor(&self) -> impl Iterator<Item = f64> + '_ {
        self.scale.iter().map(|s| -s.ln())
    }
}

/// The likelihood's per-point inputs in whitened coordinates: `target' = R^-1 D^-1/2
/// target`, unit weights, each shared-noise column `R^-1 D^-1/2 L` with unit sigmas for
/// [`super::likelihood::ResidualLayout`], and the conditional log-normalisers.
pub(super) struct Whitened {
    pub target: Vec<f64>,
    pub unit: Vec<f64>,
    pub correlated: Vec<CorrelatedNoise>,
    pub ln_norm: Vec<f64>,
}

impl Whitening {
    /// [`Whitened`] inputs from the raw `target`, `inv_sigma` and `ln_norm` of `data`.
    /// A run of shared noise must start and end where chains start (`rho = 0`), so its
    /// whitened columns stay inside it.
    pub fn transform(
        &self,
        data: &FrfData,
        target: &[f64],
        inv_sigma: &[f64],
        ln_norm: &[f64],
    ) -> Result<Whitened> {
        let n = self.len();
        if target.len() != n || inv_sigma.len() != n || ln_norm.len() != n {
            return Err(Error::Usage(format!(
                "whitening of {n} points given {} targets",
                target.len()
            )));
        }
        let mut t: Vec<f64> = target.iter().zip(inv_sigma).map(|(a, b)| a * b).collect();
        self.whiten(&mut t);
        let mut correlated = data.correlated.clone();
        for c in correlated.iter_mut() {
            let end = c.start + c.len;
            if self.rho[c.start] != 0.0 || (end < n && self.rho[end] != 0.0) {
                return Err(Error::Usage(format!(
                    "shared noise over points {}..{end} crosses a chain of correlated bins",
                    c.start
                )));
            }
            let mut col = vec![0.0; c.len];
            for r in 0..c.rank {
                for (k, v) in col.iter_mut().enumerate() {
                    *v = c.loadings[k * c.rank + r] * inv_sigma[c.start + k];
                }
                Whitening {
                    rho: self.rho[c.start..end].to_vec(),
                    scale: self.scale[c.start..end].to_vec(),
                }
                .whiten(&mut col);
                for (k, v) in col.iter().enumerate() {
                    c.loadings[k * c.rank + r] = *v;
                }
            }
        }
        let ln_norm = ln_norm
            .iter()
            .zip(self.ln_sd_factor())
            .map(|(a, f)| a - f)
            .collect();
        Ok(Whitened {
            target: t,
            unit: vec![1.0; n],
            correlated,
            ln_norm,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// Oracle: the dense covariance `C_ij = prod rho` along the chain (1 on the
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
        let w = Whitening::new(&rho).unwrap().unwrap();
        let mut u = e.clone();
        w.whiten(&mut u);
        let ev = nalgebra::DVector::from_vec(e.clone());
        let quad = (ev.transpose() * c.clone().try_inverse().unwrap() * &ev)[(0, 0)];
        let uu: f64 = u.iter().map(|v| v * v).sum();
        assert!((uu - quad).abs() < 1e-10 * quad, "{uu} {quad}");
        let ln_det: f64 = 2.0 * w.ln_sd_factor().sum::<f64>();
        assert!((ln_det - c.determinant().ln()).abs() < 1e-10);
        w.colour(&mut u);
        for (a, b) in u.iter().zip(&e) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!(Whitening::new(&[0.0, 0.0]).unwrap().is_none());
        assert!(Whitening::new(&[0.0, 1.0]).is_err());
    }
}
