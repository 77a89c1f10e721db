//! Observation kinds: how a block of predictions meets its data.
//!
//! A [`Block`] turns a range of the prediction vector into residuals `r` (already
//! divided by any per-entry standard deviation or multiplied by any weight) and has a
//! noise scale `sigma`, fixed or sampled. Its log-likelihood is Gaussian,
//!
//! `ln L_b = c_b - nu_b ln sigma - ||r||^2 / (2 sigma^2)`,
//!
//! with `nu_b` its degrees of freedom and `c_b` the normalising constant
//! (`-nu_b/2 ln 2 pi` plus the per-entry `-ln sd_i` or `+ln w_i`), so that the terms of
//! different blocks and models are comparable (evidence, LOO).
//!
//! Kinds:
//! - [`BlockKind::Values`]: real values with standard deviations, compared after a
//!   transform (identity for FRF magnitudes, `ln` for log magnitudes and log
//!   frequencies, `(2 pi f)^2` for eigenvalues from frequencies in Hz).
//! - [`BlockKind::ShapeMac`]: a measured shape `psi` (scaled to unit length) against the
//!   predicted `phi` with the amplitude integrated out under a flat prior: the residual
//!   is `(I - P_phi) psi`, whose squared norm is `1 - MAC(psi, phi)`, with `n - 1`
//!   degrees of freedom.
//! - [`BlockKind::ShapeDifference`]: the eigenvector difference of SMU (Wang's
//!   Structural Model Updating toolbox): both shapes scaled so that a reference entry is
//!   1, then `r_j = w_j (phi_j / phi_ref - psi_j / psi_ref)` for every other entry.
//! - [`BlockKind::LinearMarginal`]: observations linear in `k` unknown coefficients,
//!   the predictions being their `k` columns, integrated out under a flat prior
//!   ([`linear`]: residual `(I - P_G~) y~` with `m - k` degrees of freedom and the
//!   model-dependent `-ln det(G~^T G~) / 2`, [`Block::ln_marginal`]). Complex values
//!   `y_k` (an FRF of one channel, real and imaginary parts interleaved) with complex
//!   variances `E|e_k|^2 = sigma^2 v_k` are whitened as `y~ = sqrt(2 / v) (Re y, Im y)`.
//!   A real channel gain ([`Block::complex_gain`], one column: the prediction itself,
//!   `-ln ||h~||`) and complex modal residues ([`Block::complex_linear`], two columns
//!   `g`, `j g` per unknown) are its two uses.
//! - [`BlockKind::SharedNoise`]: values as [`BlockKind::Values`] whose noise has, besides
//!   each value's own part scaled by `sigma`, a low-rank part of known size shared by
//!   all of them (one test's force noise in every FRF magnitude of the test):
//!   `cov = sigma^2 diag(sd^2) + L L^T`, evaluated by Woodbury ([`shared`]). Its
//!   least-squares view ([`super::Posterior::least_squares`]) is the per-value part
//!   only, the weighted least squares that starts the plug-in of the loadings.
//!
//! The own noise of [`BlockKind::Values`] and [`BlockKind::SharedNoise`] values may be
//! correlated along the block by a Gauss-Markov [`Chain`] (neighbouring FRF bins of one
//! response, [`Block::correlated_values`]): the standardised residuals are whitened by
//! it (`r <- R^-1 r`), the shared loadings likewise, and `c_b` gains
//! `-ln det C / 2`, so the density is the Gaussian one with covariance
//! `sigma^2 D^(1/2) C D^(1/2) + L L^T`.

use std::ops::Range;

mod build;
pub mod chain;
pub mod linear;
pub mod shared;
pub use chain::Chain;
pub use linear::LinearFit;
pub use shared::SharedFactors;

use crate::error::{Error, Result};
use nalgebra::DMatrix;

const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// What the values of a [`BlockKind::Values`] block are compared as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transform {
    Identity,
    Ln,
    /// Predicted and observed values are frequencies in Hz; compared as eigenvalues
    /// `(2 pi f)^2` in rad^2/s^2 (paper Eq. 22b).
    EigenvalueOfHz,
}

impl Transform {
    fn apply(self, v: f64) -> f64 {
        match self {
            Transform::Identity => v,
            Transform::Ln => v.ln(),
            Transform::EigenvalueOfHz => (2.0 * std::f64::consts::PI * v).powi(2),
        }
    }
}

/// The noise scale `sigma` of a block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseScale {
    /// Known.
    Fixed(f64),
    /// Sampled: `ln sigma` is the posterior's scale coordinate of this index.
    Sampled(usize),
}

/// See the module docs.
#[derive(Debug, Clone, PartialEq)]
pub enum BlockKind {
    Values {
        /// Observed values, already transformed.
        observed: Vec<f64>,
        inv_sd: Vec<f64>,
        transform: Transform,
    },
    ShapeMac {
        /// The measured shape scaled to unit length.
        observed_unit: Vec<f64>,
    },
    ShapeDifference {
        /// The measured shape divided by its reference entry.
        observed: Vec<f64>,
        reference: usize,
        weight: Vec<f64>,
    },
    LinearMarginal {
        /// Whitened observations `y~` (`m` entries).
        observed: Vec<f64>,
        /// Whitening weights `w_i` (`sqrt(2 / v_k)`, repeated for both parts, for complex
        /// values).
        inv_sd: Vec<f64>,
        /// Columns `k`; the block's predictions are `k x m`, column-major.
        n_columns: usize,
    },
    SharedNoise {
        /// Observed values, already transformed.
        observed: Vec<f64>,
        inv_sd: Vec<f64>,
        transform: Transform,
        factors: SharedFactors,
    },
}

/// One block of observations (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    pub name: String,
    /// Where its predictions are in the prediction vector.
    pub predictions: Range<usize>,
    pub kind: BlockKind,
    pub scale: NoiseScale,
    /// Correlation of the values' own noise along the block ([`BlockKind::Values`] and
    /// [`BlockKind::SharedNoise`] only).
    pub chain: Option<Chain>,
}

/// The correlation of a values block's noise beyond each value's own standard deviation
/// ([`Block::correlated_values`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Correlation<'a> {
    /// Noise shared at a known size: the loadings `L` (`n x rank`, row-major, in the
    /// transformed unit) and the rank.
    pub shared: Option<(&'a [f64], usize)>,
    /// The Gauss-Markov correlation of each value with the one before ([`Chain`]); empty
    /// or all zero when the values' own noise is independent.
    pub chain: &'a [f64],
}

impl Block {
    /// The model-dependent part of the likelihood that the residuals do not carry:
    /// `-ln det(G~^T G~) / 2` of a [`BlockKind::LinearMarginal`] block (the coefficient
    /// integral; `-inf` when `G~` is rank-deficient), 0 for the other kinds.
    pub fn ln_marginal(&self, pred: &[f64]) -> f64 {
        let mut r = vec![0.0; self.n_residuals()];
        self.residuals_and_marginal(pred, &mut r)
    }

    /// The weighted least-squares solution of a [`BlockKind::LinearMarginal`] block at
    /// the predictions `pred`; `None` for the other kinds or a rank-deficient design.
    pub fn linear_fit(&self, pred: &[f64]) -> Option<LinearFit> {
        let BlockKind::LinearMarginal {
            observed,
            inv_sd,
            n_columns,
        } = &self.kind
        else {
            return None;
        };
        linear::fit(
            &pred[self.predictions.clone()],
            inv_sd,
            observed,
            *n_columns,
        )
    }

    /// Mean and standard deviation of the gain of a one-column
    /// [`BlockKind::LinearMarginal`] block given the predictions and `sigma`; `None`
    /// otherwise.
    pub fn conditional_gain(&self, pred: &[f64], sigma: f64) -> Option<(f64, f64)> {
        let f = self.linear_fit(pred)?;
        (f.coefficients.len() == 1).then(|| (f.coefficients[0], sigma / f.normal.l_dirty()[(0, 0)]))
    }

    /// Number of residuals.
    pub fn n_residuals(&self) -> usize {
        match &self.kind {
            BlockKind::ShapeDifference { .. } => self.predictions.len() - 1,
            BlockKind::LinearMarginal { observed, .. } => observed.len(),
            _ => self.predictions.len(),
        }
    }

    /// Degrees of freedom `nu_b`.
    pub fn dof(&self) -> f64 {
        match &self.kind {
            BlockKind::Values { .. } | BlockKind::SharedNoise { .. } => {
                self.predictions.len() as f64
            }
            BlockKind::LinearMarginal {
                observed,
                n_columns,
                ..
            } => (observed.len() - n_columns) as f64,
            _ => (self.predictions.len() - 1) as f64,
        }
    }

    /// The normalising constant `c_b`.
    pub fn ln_norm(&self) -> f64 {
        let base = -self.dof() * HALF_LN_2PI;
        match &self.kind {
            BlockKind::Values { inv_sd, .. } | BlockKind::SharedNoise { inv_sd, .. } => {
                let chain = self.chain.iter().flat_map(|c| c.ln_inv_sd_factor());
                base + inv_sd.iter().map(|w| w.ln()).sum::<f64>() + chain.sum::<f64>()
            }
            BlockKind::ShapeMac { .. } => base,
            BlockKind::LinearMarginal { inv_sd, .. } => {
                base + inv_sd.iter().map(|w| w.ln()).sum::<f64>()
            }
            BlockKind::ShapeDifference {
                weight, reference, ..
            } => {
                let all: f64 = weight.iter().map(|w| w.ln()).sum();
                base + all - weight[*reference].ln()
            }
        }
    }

    /// Residuals (before division by `sigma`) of the whole prediction vector `pred`
    /// into `out` (length [`Self::n_residuals`]).
    pub fn residuals(&self, pred: &[f64], out: &mut [f64]) {
        self.residuals_and_marginal(pred, out);
    }

    /// [`Self::residuals`], returning [`Self::ln_marginal`] from the same solve.
    pub fn residuals_and_marginal(&self, pred: &[f64], out: &mut [f64]) -> f64 {
        let p = &pred[self.predictions.clone()];
        if let BlockKind::LinearMarginal {
            observed,
            inv_sd,
            n_columns,
        } = &self.kind
        {
            return match linear::residuals(p, inv_sd, observed, *n_columns, out) {
                Some(ln_det) => -0.5 * ln_det,
                None => f64::NEG_INFINITY,
            };
        }
        match &self.kind {
            BlockKind::Values {
                observed,
                inv_sd,
                transform,
            }
            | BlockKind::SharedNoise {
                observed,
                inv_sd,
                transform,
                ..
            } => {
                for i in 0..p.len() {
                    out[i] = (transform.apply(p[i]) - observed[i]) * inv_sd[i];
                }
                if let Some(chain) = &self.chain {
                    chain.whiten(&mut out[..p.len()]);
                }
            }
            BlockKind::ShapeMac { observed_unit } => {
                let pp: f64 = p.iter().map(|v| v * v).sum();
                let po: f64 = p.iter().zip(observed_unit).map(|(a, b)| a * b).sum();
                let c = if pp > 0.0 { po / pp } else { 0.0 };
                for i in 0..p.len() {
                    out[i] = observed_unit[i] - c * p[i];
                }
            }
            BlockKind::ShapeDifference {
                observed,
                reference,
                weight,
            } => {
                let pref = p[*reference];
                for (k, j) in (0..p.len()).filter(|j| j != reference).enumerate() {
                    out[k] = weight[j] * (p[j] / pref - observed[j]);
                }
            }
            BlockKind::LinearMarginal { .. } => unreachable!("handled above"),
        }
        0.0
    }

    /// Rows `row0..row0 + n_residuals` of the residual Jacobian, `scale * d r / d theta`,
    /// from the predictions `pred` and their Jacobian `dpred` (`d pred / d theta`, one
    /// row per prediction), by the chain rule through [`Self::residuals`].
    pub fn residual_jacobian(
        &self,
        pred: &[f64],
        dpred: &DMatrix<f64>,
        scale: f64,
        row0: usize,
        jac: &mut DMatrix<f64>,
    ) {
        let (p, off) = (&pred[self.predictions.clone()], self.predictions.start);
        let n_par = dpred.ncols();
        match &self.kind {
            BlockKind::Values {
                inv_sd, transform, ..
            }
            | BlockKind::SharedNoise {
                inv_sd, transform, ..
            } => {
                for i in 0..p.len() {
                    let dt = match transform {
                        Transform::Identity => 1.0,
                        Transform::Ln => 1.0 / p[i],
                        Transform::EigenvalueOfHz => 8.0 * std::f64::consts::PI.powi(2) * p[i],
                    };
                    for t in 0..n_par {
                        jac[(row0 + i, t)] = scale * inv_sd[i] * dt * dpred[(off + i, t)];
                    }
                }
                if let Some(chain) = &self.chain {
                    // each column's rows of this block are contiguous (column-major)
                    let n_rows = jac.nrows();
                    for t in 0..n_par {
                        let start = t * n_rows + row0;
                        chain.whiten(&mut jac.as_mut_slice()[start..start + p.len()]);
                    }
                }
            }
            BlockKind::ShapeMac { observed_unit: u } => {
                // r = u - c p with c = (p.u) / (p.p).
                let pp: f64 = p.iter().map(|v| v * v).sum();
                let pu: f64 = p.iter().zip(u).map(|(a, b)| a * b).sum();
                let c = if pp > 0.0 { pu / pp } else { 0.0 };
                for t in 0..n_par {
                    let dp = |i: usize| dpred[(off + i, t)];
                    let (mut u_dp, mut p_dp) = (0.0, 0.0);
                    for i in 0..p.len() {
                        u_dp += u[i] * dp(i);
                        p_dp += p[i] * dp(i);
                    }
                    let dc = if pp > 0.0 {
                        u_dp / pp - 2.0 * pu * p_dp / (pp * pp)
                    } else {
                        0.0
                    };
                    for i in 0..p.len() {
                        jac[(row0 + i, t)] = -scale * (dc * p[i] + c * dp(i));
                    }
                }
            }
            BlockKind::LinearMarginal {
                observed,
                inv_sd,
                n_columns,
            } => linear::residual_jacobian(
                p,
                inv_sd,
                observed,
                *n_columns,
                (dpred, off),
                scale,
                (row0, jac),
            ),
            BlockKind::ShapeDifference {
                reference, weight, ..
            } => {
                let pref = p[*reference];
                for t in 0..n_par {
                    let dref = dpred[(off + reference, t)];
                    for (k, j) in (0..p.len()).filter(|j| j != reference).enumerate() {
                        let d = dpred[(off + j, t)] / pref - p[j] * dref / (pref * pref);
                        jac[(row0 + k, t)] = scale * weight[j] * d;
                    }
                }
            }
        }
    }

    /// Whitens this block's residuals `r` (already divided by `sigma`, its own chain
    /// applied: [`Self::residuals`]) against its shared noise at `sigma`
    /// ([`SharedFactors::whiten`]), so that `|r|^2 / 2` is the block's `-ln L` up to a
    /// constant; a no-op for blocks without shared noise. Linear, so it applies to the
    /// columns of a residual Jacobian as well.
    pub fn whiten_shared(&self, r: &mut [f64], sigma: f64) {
        if let BlockKind::SharedNoise { factors, .. } = &self.kind {
            factors.whiten(r, sigma * sigma);
        }
    }

    /// [`Self::ln_likelihood`] spread over the residuals into `out` (one term each,
    /// summing to `ln L_b`): for [`BlockKind::Values`] and [`BlockKind::SharedNoise`]
    /// each value's own Gaussian term `ln w_i - ln(2 pi)/2 - ln sigma - r_i^2 / (2
    /// sigma^2)`, with a shared block's Woodbury correction and log determinant spread
    /// evenly over its values (so those terms are not each a conditional density); for
    /// the other kinds the block's term spread evenly.
    pub fn ln_likelihood_pointwise(&self, residuals: &[f64], sigma: f64, out: &mut [f64]) {
        let (BlockKind::Values { inv_sd, .. } | BlockKind::SharedNoise { inv_sd, .. }) = &self.kind
        else {
            let each = self.ln_likelihood(residuals, sigma) / residuals.len() as f64;
            out.iter_mut().for_each(|v| *v = each);
            return;
        };
        let (ln_s, s2) = (sigma.ln(), sigma * sigma);
        for ((o, r), w) in out.iter_mut().zip(residuals).zip(inv_sd) {
            *o = w.ln() - HALF_LN_2PI - ln_s - 0.5 * r * r / s2;
        }
        if let Some(chain) = &self.chain {
            out.iter_mut()
                .zip(chain.ln_inv_sd_factor())
                .for_each(|(o, f)| *o += f);
        }
        if let BlockKind::SharedNoise { factors, .. } = &self.kind {
            let (_, correction, ln_det) = factors.terms(residuals, s2);
            let each = 0.5 * (correction / s2 - ln_det) / residuals.len() as f64;
            out.iter_mut().for_each(|v| *v += each);
        }
    }

    /// `ln L_b` given the residuals and `sigma`.
    pub fn ln_likelihood(&self, residuals: &[f64], sigma: f64) -> f64 {
        self.ln_likelihood_with_norm(residuals, (sigma, sigma.ln()), self.ln_norm())
    }

    /// `ln L_b` straight from the whole prediction vector `pred`, the residuals formed in
    /// the same pass as the sums (the density's inner loop), at the noise level
    /// `(sigma, ln sigma)`, for a [`BlockKind::SharedNoise`] block compared without
    /// transform or chain (`None` for the others, whose callers form the residuals
    /// first), as `(ln L_b + ln det_b / 2, det_b)`: `det_b` is the shared noise's
    /// determinant ratio `prod_i (1 + lambda_i / sigma^2)`, so that a caller summing many
    /// blocks multiplies the ratios and takes one logarithm.
    pub fn ln_likelihood_fused_det(
        &self,
        pred: &[f64],
        (sigma, ln_sigma): (f64, f64),
        ln_norm: f64,
    ) -> Option<(f64, f64)> {
        if self.chain.is_some() {
            return None;
        }
        let BlockKind::SharedNoise {
            observed,
            inv_sd,
            transform: Transform::Identity,
            factors,
        } = &self.kind
        else {
            return None;
        };
        let s2 = sigma * sigma;
        let a = &pred[self.predictions.clone()];
        let (ss, correction, det) = factors.terms_of_det(a, observed, inv_sd, s2);
        let base = ln_norm - self.dof() * ln_sigma;
        Some((base - 0.5 * (ss - correction) / s2, det))
    }

    /// [`Self::ln_likelihood`] with [`Self::ln_norm`] computed by the caller (once, for
    /// many evaluations) at the noise level `(sigma, ln sigma)`.
    pub fn ln_likelihood_with_norm(
        &self,
        residuals: &[f64],
        (sigma, ln_sigma): (f64, f64),
        ln_norm: f64,
    ) -> f64 {
        let s2 = sigma * sigma;
        let base = ln_norm - self.dof() * ln_sigma;
        match &self.kind {
            BlockKind::SharedNoise { factors, .. } => {
                let (ss, correction, ln_det) = factors.terms(residuals, s2);
                base - 0.5 * (ss - correction) / s2 - 0.5 * ln_det
            }
            _ => {
                let ss: f64 = residuals.iter().map(|r| r * r).sum();
                base - 0.5 * ss / s2
            }
        }
    }
}

/// The Woodbury factors of shared loadings `L` on values of weights `inv_sd`, in the
/// whitened coordinates of `chain` when there is one: `V = R^-1 D^(-1/2) L`.
fn shared_factors(
    loadings: &[f64],
    rank: usize,
    inv_sd: &[f64],
    chain: Option<&Chain>,
) -> Result<SharedFactors> {
    let sd: Vec<f64> = inv_sd.iter().map(|w| 1.0 / w).collect();
    let Some(chain) = chain else {
        return SharedFactors::new(loadings, rank, &sd);
    };
    let n = inv_sd.len();
    if loadings.len() != n * rank {
        return Err(Error::Usage(format!(
            "{} shared-noise loadings for {n} values of rank {rank}",
            loadings.len()
        )));
    }
    let mut whitened = vec![0.0; n * rank];
    let mut column = vec![0.0; n];
    for r in 0..rank {
        for (k, v) in column.iter_mut().enumerate() {
            *v = loadings[k * rank + r] * inv_sd[k];
        }
        chain.whiten(&mut column);
        for (k, v) in column.iter().enumerate() {
            whitened[k * rank + r] = *v;
        }
    }
    SharedFactors::new(&whitened, rank, &vec![1.0; n])
}

#[cfg(test)]
mod tests;
