//! Each point's noise scale at an error floor, kept per thread: a least-squares fit
//! holds `eta` fixed while it moves the model ([`super::super::fit`]), so every residual
//! and Jacobian evaluation of one round would otherwise take the same square root and
//! quotient per point again. Kept values are computed by the same expressions as
//! before, so results are bit for bit those of computing them anew.

use super::super::per_thread::PerThread;
use std::sync::Arc;

/// Per point at one error floor `eta`: `sigma_i = sqrt((eps_i^2 + eta^2) |h_i|^2)` and
/// `1 / d_i = 1 / (2 sigma_i^2)` (as `1 / (2 (eps_i^2 + eta^2) |h_i|^2)`).
#[derive(Debug)]
pub(super) struct Scales {
    pub(super) sd: Vec<f64>,
    pub(super) inv_d: Vec<f64>,
}

impl Scales {
    fn new(eta: f64, eps2: &[f64], abs2: &[f64]) -> Self {
        let eta2 = eta * eta;
        let sd = eps2
            .iter()
            .zip(abs2)
            .map(|(e2, a2)| ((e2 + eta2) * a2).sqrt())
            .collect();
        let inv_d = eps2
            .iter()
            .zip(abs2)
            .map(|(e2, a2)| 1.0 / (2.0 * (e2 + eta2) * a2))
            .collect();
        Scales { sd, inv_d }
    }
}

/// Each thread's [`Scales`] at the last error floor (its bits) it asked for. A clone
/// starts empty.
#[derive(Default, Clone, Debug)]
pub(super) struct ScaleCache(PerThread<u64, Arc<Scales>>);

impl ScaleCache {
    /// The scales at `eta` of points with `eps2` and `abs2`, which must be the same
    /// for every call on one cache (a posterior's own).
    pub(super) fn at(&self, eta: f64, eps2: &[f64], abs2: &[f64]) -> Arc<Scales> {
        let bits = eta.to_bits();
        self.0.with(
            |&kept| kept == bits,
            || bits,
            || Arc::new(Scales::new(eta, eps2, abs2)),
            Arc::clone,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kept_scales_are_those_computed_anew_and_follow_the_floor() {
        let eps2 = [1e-4, 4e-4, 0.0];
        let abs2 = [2.0, 0.5, 3.0];
        let cache = ScaleCache::default();
        for eta in [0.01, 0.02, 0.01] {
            let kept = cache.at(eta, &eps2, &abs2);
            for i in 0..3 {
                let sigma2 = (eps2[i] + eta * eta) * abs2[i];
                assert_eq!(kept.sd[i].to_bits(), sigma2.sqrt().to_bits());
                assert_eq!(kept.inv_d[i].to_bits(), (1.0 / (2.0 * sigma2)).to_bits());
            }
        }
        let a = cache.at(0.03, &eps2, &abs2);
        assert!(Arc::ptr_eq(&a, &cache.at(0.03, &eps2, &abs2)));
    }
}
