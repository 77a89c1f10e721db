//! The error floor's profile: for a fixed prediction, the `eta` in its prior box
//! ([`super::posterior::ETA_BOUNDS`]) that maximises the likelihood. The MAP fits
//! ([`super::fit`]) alternate it with least-squares solves at fixed `eta`.

use super::posterior::{ModelPosterior, ETA_BOUNDS};
use argmin::core::{CostFunction, Executor};
use argmin::solver::brent::BrentOpt;
use num_complex::Complex64;

impl ModelPosterior {
    /// The `eta` in the prior box that maximises the likelihood of a prediction (Brent's
    /// method on `ln eta`, to 1e-7 in it; the profile is unimodal in practice). Every
    /// start of every MAP fit profiles it once per round, each likelihood over every
    /// point.
    pub fn profile_eta(&self, pred: &[Complex64]) -> f64 {
        let (lo, hi) = (ETA_BOUNDS.0.ln(), ETA_BOUNDS.1.ln());
        let problem = EtaProfile { post: self, pred };
        let solver = BrentOpt::new(lo, hi).set_tolerance(f64::EPSILON.sqrt(), 1e-7);
        Executor::new(problem, solver)
            .configure(|s| s.max_iters(200))
            .run()
            .ok()
            .and_then(|r| r.state().best_param)
            // The cost never fails; an empty result would leave the widest floor.
            .unwrap_or(hi)
            .exp()
    }
}

/// The negative log-likelihood of a fixed prediction as a function of `ln eta`
/// ([`ModelPosterior::profile_eta`]); a NaN likelihood counts as the worst.
struct EtaProfile<'a> {
    post: &'a ModelPosterior,
    pred: &'a [Complex64],
}

impl CostFunction for EtaProfile<'_> {
    type Param = f64;
    type Output = f64;

    fn cost(&self, ln_eta: &f64) -> std::result::Result<f64, argmin::core::Error> {
        let ll = self.post.ln_likelihood_of(self.pred, ln_eta.exp());
        Ok(if ll.is_nan() { f64::INFINITY } else { -ll })
    }
}
