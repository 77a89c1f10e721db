//! Independence Metropolis-Hastings with a proposal fitted to the complementary walkers,
//! in the spirit of emcee's `KDEMove` (which also fits its proposal to the complement).
//!
//! While one split is updated, its complement is fixed, so any proposal density built
//! from the complement alone is a fixed independence proposal `g` for that half-step,
//! and accepting with `min(1, p(q) g(x) / (p(x) g(q)))` leaves the target invariant.
//! Here `g` is a multivariate t with `nu` degrees of freedom (Gaussian when `nu` is
//! `None`), location the complement's mean `m` and scale matrix `scale^2 S`, `S` the
//! complement's sample covariance. With `S = L L^T` and
//! `delta(v) = |L^-1 (v - m)|^2 / scale^2`,
//! `ln g(v) = -(nu + d)/2 ln(1 + delta/nu) + const` (`-delta/2 + const` for the
//! Gaussian), so the move's log factor is `ln g(x) - ln g(q)`. A draw is
//! `q = m + scale L n / sqrt(w / nu)` with `n ~ N(0, I)` and `w ~ chi2(nu)`.
//!
//! On a near-Gaussian target an independence proposal jumps across the whole posterior
//! in one step, where the local moves need many; its acceptance falls with the noise
//! of `S` (complements much larger than `d` help), so it is meant to be mixed with the
//! local DE or stretch moves, which also carry the ensemble through the burn-in.

use nalgebra::{DMatrix, DVector};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{ChiSquared, StandardNormal};
use serde::{Deserialize, Serialize};

use super::moves::{Complement, Move};
use crate::error::{Error, Result};

/// The independence move (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Independence {
    /// Degrees of freedom of the multivariate t proposal; `None`: Gaussian.
    pub nu: Option<f64>,
    /// Factor on the complement's standard deviations (1: its covariance as it is).
    pub scale: f64,
}

impl Default for Independence {
    /// `nu = 10`, `scale = 1`.
    fn default() -> Self {
        Independence {
            nu: Some(10.0),
            scale: 1.0,
        }
    }
}

impl Independence {
    /// Checks the parameters: `nu > 0` when given, `scale > 0`.
    pub fn new(nu: Option<f64>, scale: f64) -> Result<Self> {
        if nu.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
            return Err(Error::Usage(format!(
                "independence: nu must be positive, got {nu:?}"
            )));
        }
        if !(scale.is_finite() && scale > 0.0) {
            return Err(Error::Usage(format!(
                "independence: scale must be positive, got {scale}"
            )));
        }
        Ok(Independence { nu, scale })
    }

    /// The proposal fitted to `complement`; `None` when its covariance is singular
    /// (fewer than `d + 1` walkers, or walkers in a subspace).
    pub fn fit(&self, complement: &Complement<'_>) -> Option<FittedIndependence> {
        let n = complement.len();
        if n < 2 {
            return None;
        }
        let d = complement.get(0).len();
        let points = DMatrix::from_fn(d, n, |r, j| complement.get(j)[r]);
        let mean = points.column_mean();
        let mut dev = points;
        for mut col in dev.column_iter_mut() {
            col -= &mean;
        }
        let cov = (&dev * dev.transpose()) * (self.scale * self.scale / (n as f64 - 1.0));
        let chol = cov.cholesky()?.l();
        if !chol.iter().all(|x| x.is_finite()) {
            return None;
        }
        Some(FittedIndependence {
            nu: self.nu,
            mean,
            chol,
        })
    }
}

impl Move for Independence {
    fn name(&self) -> String {
        match self.nu {
            Some(nu) => format!("independence(t,nu={nu},scale={})", self.scale),
            None => format!("independence(gaussian,scale={})", self.scale),
        }
    }

    fn min_complement(&self) -> usize {
        2
    }

    fn for_complement(&self, complement: &Complement<'_>) -> Option<Box<dyn Move + '_>> {
        Some(match self.fit(complement) {
            Some(f) => Box::new(f),
            None => Box::new(Stay),
        })
    }

    /// Fits the proposal and draws from it (the sampler fits once per split through
    /// [`Move::for_complement`] instead).
    fn propose(
        &self,
        walker: &[f64],
        complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        match self.fit(complement) {
            Some(f) => f.propose(walker, complement, rng, proposal),
            None => Stay.propose(walker, complement, rng, proposal),
        }
    }
}

/// A proposal fitted by [`Independence::fit`]: location, Cholesky factor of the scale
/// matrix (lower-triangular), degrees of freedom.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedIndependence {
    nu: Option<f64>,
    mean: DVector<f64>,
    chol: DMatrix<f64>,
}

impl FittedIndependence {
    /// `ln g(v)` up to a constant.
    pub fn ln_density(&self, v: &[f64]) -> f64 {
        let centred = DVector::from_column_slice(v) - &self.mean;
        let Some(y) = self.chol.solve_lower_triangular(&centred) else {
            return f64::NEG_INFINITY;
        };
        let delta = y.norm_squared();
        match self.nu {
            Some(nu) => -0.5 * (nu + v.len() as f64) * (delta / nu).ln_1p(),
            None => -0.5 * delta,
        }
    }
}

impl Move for FittedIndependence {
    fn name(&self) -> String {
        "independence(fitted)".into()
    }

    fn propose(
        &self,
        walker: &[f64],
        _complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        let d = self.mean.len();
        let n = DVector::<f64>::from_fn(d, |_, _| rng.sample(StandardNormal));
        let radius = match self.nu {
            Some(nu) => {
                let w: f64 = match ChiSquared::new(nu) {
                    Ok(chi2) => rng.sample(chi2),
                    Err(_) => nu,
                };
                (nu / w).sqrt()
            }
            None => 1.0,
        };
        let q = &self.mean + (&self.chol * n) * radius;
        proposal.copy_from_slice(q.as_slice());
        self.ln_density(walker) - self.ln_density(proposal)
    }
}

/// The null proposal `q = x` (always accepted; leaves every target invariant), used when
/// the complement's covariance is singular.
struct Stay;

impl Move for Stay {
    fn name(&self) -> String {
        "stay".into()
    }
    fn propose(
        &self,
        walker: &[f64],
        _complement: &Complement<'_>,
        _rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        proposal.copy_from_slice(walker);
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcmc::rng::{key_from_seed, walker_rng};

    /// The fitted mean and `L L^T` equal the complement's mean and scaled sample
    /// covariance, computed naively.
    #[test]
    fn fit_reproduces_mean_and_covariance() {
        let walkers: Vec<Vec<f64>> = (0..9)
            .map(|i| {
                let t = i as f64;
                vec![t.sin(), (1.3 * t).cos() + 0.2 * t, (0.7 * t).sin() * t]
            })
            .collect();
        let refs: Vec<&[f64]> = walkers.iter().map(|w| w.as_slice()).collect();
        let mv = Independence::new(None, 1.5).unwrap();
        let f = mv.fit(&Complement::new(&refs)).unwrap();
        let n = walkers.len() as f64;
        for r in 0..3 {
            let m = walkers.iter().map(|w| w[r]).sum::<f64>() / n;
            assert!((f.mean[r] - m).abs() < 1e-14);
            for c in 0..3 {
                let mc = walkers.iter().map(|w| w[c]).sum::<f64>() / n;
                let cov = walkers
                    .iter()
                    .map(|w| (w[r] - m) * (w[c] - mc))
                    .sum::<f64>()
                    / (n - 1.0)
                    * 2.25;
                let llt: f64 = (0..3).map(|k| f.chol[(r, k)] * f.chol[(c, k)]).sum();
                assert!((llt - cov).abs() < 1e-12, "({r},{c}): {llt} vs {cov}");
            }
        }
        // Too few walkers for a 3-D covariance: no fit, the null move.
        let few = Complement::new(&refs[..3]);
        assert!(mv.fit(&few).is_none());
        let mut rng = walker_rng(key_from_seed(1), 0, 0);
        let mut q = [0.0; 3];
        let stay = mv.for_complement(&few).unwrap();
        assert_eq!(stay.propose(&walkers[5], &few, &mut rng, &mut q), 0.0);
        assert_eq!(q.as_slice(), walkers[5].as_slice());
        assert!(Independence::new(Some(0.0), 1.0).is_err());
        assert!(Independence::new(None, -1.0).is_err());
    }

    /// The log factor is `ln g(x) - ln g(q)` of the multivariate t density, checked
    /// against the closed form in 1-D (`g ∝ (1 + (v - m)^2 / (nu s^2))^-((nu+1)/2)`).
    #[test]
    fn factor_is_the_density_ratio() {
        let walkers: Vec<Vec<f64>> = [0.3, -1.0, 2.0, 0.5, 1.1]
            .iter()
            .map(|&v| vec![v])
            .collect();
        let refs: Vec<&[f64]> = walkers.iter().map(|w| w.as_slice()).collect();
        let comp = Complement::new(&refs);
        let nu = 4.0;
        let f = Independence::new(Some(nu), 1.2)
            .unwrap()
            .fit(&comp)
            .unwrap();
        let m = 2.9 / 5.0;
        let var = walkers.iter().map(|w| (w[0] - m).powi(2)).sum::<f64>() / 4.0 * 1.44;
        let ln_g = |v: f64| -0.5 * (nu + 1.0) * (1.0 + (v - m).powi(2) / (nu * var)).ln();
        let mut rng = walker_rng(key_from_seed(2), 0, 0);
        let mut q = [0.0];
        for _ in 0..50 {
            let x = [rng.random_range(-3.0..3.0)];
            let factor = f.propose(&x, &comp, &mut rng, &mut q);
            let expect = ln_g(x[0]) - ln_g(q[0]);
            assert!((factor - expect).abs() < 1e-12, "{factor} vs {expect}");
        }
    }
}
