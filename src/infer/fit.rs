//! MAP fits of a [`Posterior`]: bounded multistart least squares (the trust-region
//! reflective solver of [`crate::update::lsq`], Latin hypercube starts in the prior box)
//! on its whitened residuals at fixed noise scales.

use super::posterior::Posterior;
use crate::error::Result;
use crate::predict::Predict;
use crate::update::lsq::{multistart, MultistartOptions, MultistartResult};

/// Settings of [`fit_multistart`] (starts, seed, solver tolerances).
pub type FitOptions = MultistartOptions;
/// Every start's solution and the best.
pub type FitResult = MultistartResult;

/// Minimises `0.5 sum_b ||r_b(theta)||^2 / sigma_b^2` over the model coordinates in
/// their prior box, with the sampled noise scales held at `sigma` (one per scale);
/// `initial`, when given, is the first start.
pub fn fit_multistart<P: Predict>(
    post: &Posterior<P>,
    sigma: &[f64],
    initial: Option<&[f64]>,
    options: &FitOptions,
) -> Result<FitResult> {
    let problem = post.least_squares(sigma)?;
    multistart(&problem, problem.bounds(), initial, options)
}
