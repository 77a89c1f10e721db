//! The problem side of sampling: an unnormalised log density, optionally with pointwise
//! log-likelihood terms ("blobs") for LOO/WAIC.

use crate::error::{Error, Result};

/// Unnormalised log posterior density on `R^dim`.
///
/// Contract:
/// - `ln_density` returns `f64::NEG_INFINITY` outside the support (e.g. prior bounds);
/// - `Err` on a numerical failure (the sampler stops and reports it);
/// - never NaN or `+inf` (the sampler turns either into an [`Error::Numerical`]).
///
/// Pointwise log-likelihood: a density that can split its log-likelihood into
/// `n_pointwise()` terms (one per observation) implements
/// [`LogDensity::ln_density_with_pointwise`]; the sampler then stores the terms of every
/// stored state alongside the chain (for PSIS-LOO / WAIC). The terms must be finite
/// whenever the returned log density is finite.
///
/// ```
/// use frfbayes::mcmc::LogDensity;
/// struct StdNormal;
/// impl LogDensity for StdNormal {
///     fn dim(&self) -> usize { 2 }
///     fn ln_density(&self, x: &[f64]) -> frfbayes::Result<f64> {
///         Ok(-0.5 * x.iter().map(|v| v * v).sum::<f64>())
///     }
/// }
/// assert_eq!(StdNormal.ln_density(&[0.0, 0.0]).unwrap(), 0.0);
/// ```
pub trait LogDensity: Sync {
    /// Number of parameters.
    fn dim(&self) -> usize;

    /// Log density at `theta` (length `dim()`), up to an additive constant.
    fn ln_density(&self, theta: &[f64]) -> Result<f64>;

    /// Number of pointwise log-likelihood terms; 0 (the default) when not supported.
    fn n_pointwise(&self) -> usize {
        0
    }

    /// Log density at `theta`, also filling `pointwise` (length `n_pointwise()`) with the
    /// pointwise log-likelihood terms. The default ignores `pointwise`.
    fn ln_density_with_pointwise(&self, theta: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        let _ = pointwise;
        self.ln_density(theta)
    }
}

impl<T: LogDensity + ?Sized> LogDensity for &T {
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn ln_density(&self, theta: &[f64]) -> Result<f64> {
        (**self).ln_density(theta)
    }
    fn n_pointwise(&self) -> usize {
        (**self).n_pointwise()
    }
    fn ln_density_with_pointwise(&self, theta: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        (**self).ln_density_with_pointwise(theta, pointwise)
    }
}

/// A [`LogDensity`] from a closure, for quick use and tests.
///
/// ```
/// use frfbayes::mcmc::{DensityFn, LogDensity};
/// let d = DensityFn::new(1, |x: &[f64]| Ok(-0.5 * x[0] * x[0]));
/// assert_eq!(d.ln_density(&[2.0]).unwrap(), -2.0);
/// ```
pub struct DensityFn<F> {
    dim: usize,
    f: F,
}

impl<F> DensityFn<F>
where
    F: Fn(&[f64]) -> Result<f64> + Sync,
{
    /// Wraps `f` as a density on `R^dim`.
    pub fn new(dim: usize, f: F) -> Self {
        DensityFn { dim, f }
    }
}

impl<F> LogDensity for DensityFn<F>
where
    F: Fn(&[f64]) -> Result<f64> + Sync,
{
    fn dim(&self) -> usize {
        self.dim
    }
    fn ln_density(&self, theta: &[f64]) -> Result<f64> {
        (self.f)(theta)
    }
}

/// Evaluates `density` at `theta` and enforces the contract: NaN and `+inf` become
/// errors, and so do non-finite pointwise terms when the log density is finite.
/// `pointwise` is empty when pointwise terms are not wanted.
pub(crate) fn checked_ln_density<D: LogDensity + ?Sized>(
    density: &D,
    theta: &[f64],
    pointwise: &mut [f64],
) -> Result<f64> {
    let lp = if pointwise.is_empty() {
        density.ln_density(theta)?
    } else {
        density.ln_density_with_pointwise(theta, pointwise)?
    };
    if lp.is_nan() || lp == f64::INFINITY {
        return Err(Error::Numerical(format!(
            "log density is {lp} at theta = {theta:?} (must be finite or -inf)"
        )));
    }
    if lp.is_finite() {
        if let Some(i) = pointwise.iter().position(|v| !v.is_finite()) {
            return Err(Error::Numerical(format!(
                "pointwise log-likelihood term {i} is {} at theta = {theta:?} \
                 while the log density is finite",
                pointwise[i]
            )));
        }
    }
    Ok(lp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_and_plus_infinity_are_errors_minus_infinity_is_not() {
        let d = DensityFn::new(1, |x: &[f64]| Ok(x[0]));
        assert!(checked_ln_density(&d, &[f64::NAN], &mut []).is_err());
        assert!(checked_ln_density(&d, &[f64::INFINITY], &mut []).is_err());
        assert_eq!(
            checked_ln_density(&d, &[f64::NEG_INFINITY], &mut []).unwrap(),
            f64::NEG_INFINITY
        );
        assert_eq!(checked_ln_density(&d, &[1.5], &mut []).unwrap(), 1.5);
    }
}
