//! Laplace approximation of the evidence at the posterior mode, the cheap screen for
//! candidate hypotheses and locations before [`super::stepping_stone`]:
//! `ln Z ≈ f(z*) + (d/2) ln 2 pi - (1/2) ln det(-H)`, `f = ln L + ln pi`, `H` the Hessian
//! of `f` at the mode `z*`. Exact when `f` is quadratic (Gaussian posterior far from the
//! prior's edges); it misses skewness, curvature changes and other modes.
//!
//! `H` is by central differences with steps scaled per dimension: a pilot diagonal
//! curvature `c_i` (steps `1e-4 max(|z_i|, 1)`, then refined once) sets
//! `h_i = step_fraction / sqrt(c_i)`, a fixed fraction of the conditional posterior
//! standard deviation, so that every difference changes `f` by about
//! `step_fraction^2 / 2` whatever the parameter's scale. Rounding error on `H_ij` is
//! then about `eps |f| / (h_i h_j)`, relative `eps |f| / step_fraction^2`.

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::evidence::TemperedTarget;
use crate::error::{Error, Result};

/// Default step as a fraction of the conditional posterior standard deviation.
pub const LAPLACE_STEP_FRACTION: f64 = 0.1;

/// Result of [`laplace`].
#[derive(Debug, Clone)]
pub struct LaplaceEvidence {
    /// Laplace `ln Z`.
    pub ln_z: f64,
    /// `ln L` at the mode.
    pub ln_likelihood: f64,
    /// `ln pi` at the mode.
    pub ln_prior: f64,
    /// `ln det(-H)`.
    pub ln_det_neg_hessian: f64,
    /// `-H` (positive definite), the precision of the Gaussian approximation.
    pub precision: DMatrix<f64>,
    /// `(-H)^-1`, its covariance.
    pub covariance: DMatrix<f64>,
    /// Finite-difference steps used, per parameter.
    pub steps: Vec<f64>,
    /// Likelihood evaluations.
    pub n_likelihood_evaluations: u64,
}

/// [`laplace_with_step`] with [`LAPLACE_STEP_FRACTION`].
pub fn laplace<T: TemperedTarget>(target: &T, map_z: &[f64]) -> Result<LaplaceEvidence> {
    laplace_with_step(target, map_z, LAPLACE_STEP_FRACTION)
}

/// Laplace evidence of `target` at its posterior mode `map_z` (module docs). Errors if
/// `map_z` is within a step of the prior's edge, or if `-H` is not positive definite
/// (not a maximum, or a flat direction: the Laplace approximation does not apply).
pub fn laplace_with_step<T: TemperedTarget>(
    target: &T,
    map_z: &[f64],
    step_fraction: f64,
) -> Result<LaplaceEvidence> {
    let d = target.dim();
    if map_z.len() != d {
        return Err(Error::Usage(format!(
            "laplace: map_z has {} values, the target has {d} parameters",
            map_z.len()
        )));
    }
    if !(step_fraction > 0.0 && step_fraction.is_finite()) {
        return Err(Error::Usage(format!(
            "laplace: step fraction {step_fraction} must be positive"
        )));
    }
    let mut n_eval = 0u64;
    let ln_prior = target.ln_prior(map_z);
    if !ln_prior.is_finite() {
        return Err(Error::Usage(format!(
            "laplace: the mode {map_z:?} is outside the prior support"
        )));
    }
    let ln_likelihood = target.ln_likelihood(map_z)?;
    n_eval += 1;
    let f0 = ln_likelihood + ln_prior;
    if !f0.is_finite() {
        return Err(Error::Numerical(format!(
            "laplace: ln L + ln pi = {f0} at the mode"
        )));
    }
    let f = |z: &[f64]| -> Result<f64> {
        let lp = target.ln_prior(z);
        if !lp.is_finite() {
            return Err(Error::Numerical(format!(
                "laplace: the finite-difference point {z:?} is outside the prior support; \
                 the mode is too close to the prior's edge for a Laplace approximation"
            )));
        }
        let v = lp + target.ln_likelihood(z)?;
        if !v.is_finite() {
            return Err(Error::Numerical(format!(
                "laplace: ln L + ln pi = {v} at {z:?}"
            )));
        }
        Ok(v)
    };
    let shifted = |moves: &[(usize, f64)]| {
        let mut z = map_z.to_vec();
        for &(i, h) in moves {
            z[i] += h;
        }
        z
    };
    // Diagonal curvature by central differences with steps h (parallel, ordered).
    let diagonal = |h: &[f64]| -> Result<Vec<f64>> {
        (0..d)
            .into_par_iter()
            .map(|i| {
                let fp = f(&shifted(&[(i, h[i])]))?;
                let fm = f(&shifted(&[(i, -h[i])]))?;
                Ok(-(fp - 2.0 * f0 + fm) / (h[i] * h[i]))
            })
            .collect()
    };
    let mut h: Vec<f64> = map_z.iter().map(|z| 1e-4 * z.abs().max(1.0)).collect();
    for _ in 0..2 {
        let curv = diagonal(&h)?;
        n_eval += 2 * d as u64;
        if let Some(i) = curv.iter().position(|c| c.is_nan() || *c <= 0.0) {
            return Err(Error::Numerical(format!(
                "laplace: -d2f/dz{i}^2 = {:e} at the mode (must be > 0): not a maximum or \
                 a flat direction; the Laplace approximation does not apply",
                curv[i]
            )));
        }
        h = curv.iter().map(|c| step_fraction / c.sqrt()).collect();
    }
    let curv_final = diagonal(&h)?;
    n_eval += 2 * d as u64;
    let pairs: Vec<(usize, usize)> = (0..d)
        .flat_map(|i| (i + 1..d).map(move |j| (i, j)))
        .collect();
    let off: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let (hi, hj) = (h[i], h[j]);
            let fpp = f(&shifted(&[(i, hi), (j, hj)]))?;
            let fpm = f(&shifted(&[(i, hi), (j, -hj)]))?;
            let fmp = f(&shifted(&[(i, -hi), (j, hj)]))?;
            let fmm = f(&shifted(&[(i, -hi), (j, -hj)]))?;
            Ok(-(fpp - fpm - fmp + fmm) / (4.0 * hi * hj))
        })
        .collect::<Result<_>>()?;
    n_eval += 4 * pairs.len() as u64;
    let mut precision = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(curv_final));
    for (&(i, j), v) in pairs.iter().zip(&off) {
        precision[(i, j)] = *v;
        precision[(j, i)] = *v;
    }
    let chol = nalgebra::Cholesky::new(precision.clone()).ok_or_else(|| {
        Error::Numerical(
            "laplace: the negative Hessian at the mode is not positive definite (a saddle \
             or a ridge): the Laplace approximation does not apply"
                .into(),
        )
    })?;
    let ln_det_neg_hessian = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
    let covariance = chol.inverse();
    let ln_z = f0 + 0.5 * d as f64 * (2.0 * std::f64::consts::PI).ln() - 0.5 * ln_det_neg_hessian;
    Ok(LaplaceEvidence {
        ln_z,
        ln_likelihood,
        ln_prior,
        ln_det_neg_hessian,
        precision,
        covariance,
        steps: h,
        n_likelihood_evaluations: n_eval,
    })
}
