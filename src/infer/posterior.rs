//! [`Posterior`]: a prior, a predictor and observation blocks; at once a log density for
//! the sampler, a least-squares problem for the MAP solver, and a tempered target for
//! evidence.
//!
//! Coordinates `z = [theta, ln sigma_1 .. ln sigma_S]`: the predictor's coordinates,
//! then the log of every sampled noise scale. The prior is uniform on a box
//! ([`BoxPrior`]); the likelihood is the sum of the blocks' Gaussian terms
//! ([`super::likelihood`]). A parameter point where the predictor reports an
//! inadmissible model ([`Error::Model`]) has zero density.

use std::cell::RefCell;

use nalgebra::DMatrix;
use rand_chacha::ChaCha8Rng;
use thread_local::ThreadLocal;

use super::evidence::TemperedTarget;
use super::likelihood::{Block, NoiseScale};
use super::prior::BoxPrior;
use crate::error::{Error, Result};
use crate::mcmc::LogDensity;
use crate::predict::Predict;
use crate::update::lsq::{fd_jacobian_at, Bounds, FdScheme, LeastSquaresProblem};

/// Scratch memory of one thread.
pub struct Scratch<W> {
    ws: W,
    pred: Vec<f64>,
    res: Vec<f64>,
    /// `d pred / d theta`, when the predictor has an analytic Jacobian.
    dpred: DMatrix<f64>,
    /// Per block: [`Block::ln_marginal`] from the residuals' solve.
    marginal: Vec<f64>,
    /// Per sampled noise scale: `sigma` at the current `z` (one exponential each).
    scales: Vec<f64>,
}

/// See the module docs.
pub struct Posterior<P: Predict> {
    predictor: P,
    prior: BoxPrior,
    blocks: Vec<Block>,
    /// [`Block::ln_norm`] of each block.
    ln_norms: Vec<f64>,
    /// Offset of each block's residuals.
    offsets: Vec<usize>,
    n_residuals: usize,
    scratch: ThreadLocal<RefCell<Scratch<P::Workspace>>>,
}

impl<P: Predict + Clone> Clone for Posterior<P> {
    fn clone(&self) -> Self {
        Posterior {
            predictor: self.predictor.clone(),
            prior: self.prior.clone(),
            blocks: self.blocks.clone(),
            ln_norms: self.ln_norms.clone(),
            offsets: self.offsets.clone(),
            n_residuals: self.n_residuals,
            scratch: ThreadLocal::new(),
        }
    }
}

impl<P: Predict> std::fmt::Debug for Posterior<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Posterior")
            .field("names", &self.prior.names())
            .field("blocks", &self.blocks.len())
            .field("n_residuals", &self.n_residuals)
            .finish()
    }
}

impl<P: Predict> Posterior<P> {
    /// `theta_bounds`: prior box of the predictor's coordinates; `scales`: name and
    /// `ln sigma` box of each sampled noise scale (blocks refer to them by index).
    pub fn new(
        predictor: P,
        theta_bounds: &[(f64, f64)],
        scales: &[(String, (f64, f64))],
        blocks: Vec<Block>,
    ) -> Result<Self> {
        if theta_bounds.len() != predictor.n_params() {
            return Err(Error::Usage(format!(
                "{} prior bounds for {} model coordinates",
                theta_bounds.len(),
                predictor.n_params()
            )));
        }
        let n_out = predictor.n_outputs();
        for b in &blocks {
            if b.predictions.end > n_out || b.predictions.is_empty() {
                return Err(Error::Usage(format!(
                    "block `{}` reads predictions {:?} of {n_out}",
                    b.name, b.predictions
                )));
            }
            if let NoiseScale::Sampled(i) = b.scale {
                if i >= scales.len() {
                    return Err(Error::Usage(format!(
                        "block `{}` uses noise scale {i} of {}",
                        b.name,
                        scales.len()
                    )));
                }
            }
        }
        let mut names = predictor.param_names();
        names.extend(scales.iter().map(|(n, _)| n.clone()));
        let mut bounds = theta_bounds.to_vec();
        bounds.extend(scales.iter().map(|(_, b)| *b));
        let prior = BoxPrior::new(names, &bounds)?;
        let mut offsets = Vec::with_capacity(blocks.len());
        let mut n_residuals = 0;
        for b in &blocks {
            offsets.push(n_residuals);
            n_residuals += b.n_residuals();
        }
        Ok(Posterior {
            predictor,
            prior,
            ln_norms: blocks.iter().map(Block::ln_norm).collect(),
            blocks,
            offsets,
            n_residuals,
            scratch: ThreadLocal::new(),
        })
    }

    /// The same prior and blocks over another predictor with the same coordinates and
    /// outputs (a different solver, or a constraint lifted for a fit).
    pub fn with_predictor<Q: Predict>(&self, predictor: Q) -> Result<Posterior<Q>> {
        let p = &self.predictor;
        if predictor.n_params() != p.n_params() || predictor.n_outputs() != p.n_outputs() {
            return Err(Error::Usage(format!(
                "a predictor of {} coordinates and {} outputs cannot replace one of {} and {}",
                predictor.n_params(),
                predictor.n_outputs(),
                p.n_params(),
                p.n_outputs()
            )));
        }
        Ok(Posterior {
            predictor,
            prior: self.prior.clone(),
            blocks: self.blocks.clone(),
            ln_norms: self.ln_norms.clone(),
            offsets: self.offsets.clone(),
            n_residuals: self.n_residuals,
            scratch: ThreadLocal::new(),
        })
    }

    pub fn predictor(&self) -> &P {
        &self.predictor
    }
    pub fn prior(&self) -> &BoxPrior {
        &self.prior
    }
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }
    /// Number of coordinates (`theta` and the sampled `ln sigma`).
    pub fn dim(&self) -> usize {
        self.prior.dim()
    }
    /// Number of model coordinates (`theta`).
    pub fn n_model(&self) -> usize {
        self.predictor.n_params()
    }
    pub fn names(&self) -> &[String] {
        self.prior.names()
    }
    /// Residuals of every block, concatenated (before division by the noise scales).
    pub fn n_residuals(&self) -> usize {
        self.n_residuals
    }
    /// Where block `b`'s residuals are.
    pub fn residual_range(&self, b: usize) -> std::ops::Range<usize> {
        self.offsets[b]..self.offsets[b] + self.blocks[b].n_residuals()
    }

    fn new_scratch(&self) -> Scratch<P::Workspace> {
        Scratch {
            ws: self.predictor.workspace(),
            pred: vec![0.0; self.predictor.n_outputs()],
            res: vec![0.0; self.n_residuals],
            dpred: DMatrix::zeros(0, 0),
            marginal: vec![0.0; self.blocks.len()],
            scales: Vec::new(),
        }
    }

    fn with_scratch<R>(&self, f: impl FnOnce(&mut Scratch<P::Workspace>) -> R) -> R {
        let cell = self.scratch.get_or(|| RefCell::new(self.new_scratch()));
        f(&mut cell.borrow_mut())
    }

    /// Predictions at the model coordinates `theta`.
    pub fn predict(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.with_scratch(|s| {
            self.predictor.predict(theta, &mut s.ws, &mut s.pred)?;
            Ok(s.pred.clone())
        })
    }

    /// Block residuals (before the noise scales) at `theta`, concatenated.
    pub fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.with_scratch(|s| {
            self.fill_residuals(theta, s)?;
            Ok(s.res.clone())
        })
    }

    fn fill_residuals(&self, theta: &[f64], s: &mut Scratch<P::Workspace>) -> Result<()> {
        self.predictor.predict(theta, &mut s.ws, &mut s.pred)?;
        for (i, (b, &o)) in self.blocks.iter().zip(&self.offsets).enumerate() {
            s.marginal[i] = b.residuals_and_marginal(&s.pred, &mut s.res[o..o + b.n_residuals()]);
        }
        Ok(())
    }

    /// `sigma` of every block at `z`.
    fn sigma(&self, b: &Block, z: &[f64]) -> f64 {
        match b.scale {
            NoiseScale::Fixed(s) => s,
            NoiseScale::Sampled(i) => z[self.n_model() + i].exp(),
        }
    }

    /// `(sigma, ln sigma)` of a block at `z`, the sampled scales' `sigma` from `scales`
    /// ([`Self::fill_scales`]): one exponential per scale, not per block, and no
    /// logarithm for a sampled scale.
    fn noise_level(&self, b: &Block, z: &[f64], scales: &[f64]) -> (f64, f64) {
        match b.scale {
            NoiseScale::Fixed(s) => (s, s.ln()),
            NoiseScale::Sampled(i) => (scales[i], z[self.n_model() + i]),
        }
    }

    /// `sigma` of every sampled scale at `z` into `scales`.
    fn fill_scales(&self, z: &[f64], scales: &mut Vec<f64>) {
        scales.clear();
        scales.extend(z[self.n_model()..].iter().map(|l| l.exp()));
    }

    /// Log-likelihood at `z` (inside the prior box), one term per block into `terms`
    /// when it is not empty; `-inf` for an inadmissible model.
    pub fn ln_likelihood_terms(&self, z: &[f64], terms: &mut [f64]) -> Result<f64> {
        self.with_scratch(|s| {
            match self
                .predictor
                .predict(&z[..self.n_model()], &mut s.ws, &mut s.pred)
            {
                Ok(()) => {}
                Err(Error::Model(_)) => return Ok(f64::NEG_INFINITY),
                Err(e) => return Err(e),
            }
            let mut total = 0.0;
            // the fused blocks' determinant ratios, multiplied: one logarithm for all
            // (taken early should the product leave a safe range)
            let mut det = 1.0;
            self.fill_scales(z, &mut s.scales);
            for (i, (b, &o)) in self.blocks.iter().zip(&self.offsets).enumerate() {
                let (level, norm) = (self.noise_level(b, z, &s.scales), self.ln_norms[i]);
                let l = match fused_into(b, &s.pred, level, norm, (&mut total, &mut det)) {
                    Some(_) if terms.is_empty() => continue,
                    Some(own) => own(),
                    None => {
                        let res = &mut s.res[o..o + b.n_residuals()];
                        let marginal = b.residuals_and_marginal(&s.pred, res);
                        let l = b.ln_likelihood_with_norm(res, level, norm) + marginal;
                        total += l;
                        l
                    }
                };
                if !terms.is_empty() {
                    terms[i] = l;
                }
            }
            total -= 0.5 * det.ln();
            Ok(if total.is_nan() {
                f64::NEG_INFINITY
            } else {
                total
            })
        })
    }

    /// Log-likelihood at `z` (inside the prior box, the same value as
    /// [`Self::ln_likelihood_terms`]), one term per residual into `out` (length
    /// [`Self::n_residuals`], [`Block::ln_likelihood_pointwise`], summing to it up to
    /// rounding); an inadmissible model gives `-inf` everywhere.
    pub fn ln_likelihood_pointwise(&self, z: &[f64], out: &mut [f64]) -> Result<f64> {
        if out.len() != self.n_residuals {
            return Err(Error::Usage(format!(
                "{} pointwise slots for {} residuals",
                out.len(),
                self.n_residuals
            )));
        }
        self.with_scratch(|s| {
            match self.fill_residuals(&z[..self.n_model()], s) {
                Ok(()) => {}
                Err(Error::Model(_)) => {
                    out.fill(f64::NEG_INFINITY);
                    return Ok(f64::NEG_INFINITY);
                }
                Err(e) => return Err(e),
            }
            let (mut total, mut det) = (0.0, 1.0);
            self.fill_scales(z, &mut s.scales);
            for (i, (b, &o)) in self.blocks.iter().zip(&self.offsets).enumerate() {
                let (range, level) = (o..o + b.n_residuals(), self.noise_level(b, z, &s.scales));
                let out = &mut out[range.clone()];
                b.ln_likelihood_pointwise(&s.res[range.clone()], level.0, out);
                let each = s.marginal[i] / out.len() as f64;
                out.iter_mut().for_each(|v| *v += each);
                // the same total as without the pointwise terms
                let norm = self.ln_norms[i];
                if fused_into(b, &s.pred, level, norm, (&mut total, &mut det)).is_none() {
                    total += b.ln_likelihood_with_norm(&s.res[range], level, norm) + s.marginal[i];
                }
            }
            total -= 0.5 * det.ln();
            Ok(if total.is_nan() {
                f64::NEG_INFINITY
            } else {
                total
            })
        })
    }

    /// The least-squares view at fixed noise scales `sigma` (one per sampled scale):
    /// residuals `r / sigma_b` over the model coordinates, a shared-noise block's
    /// whitened by its Woodbury factors ([`Block::whiten_shared`]), so that its cost is
    /// `-ln L + const` and its minimiser in the prior box is the MAP estimate.
    pub fn least_squares(&self, sigma: &[f64]) -> Result<LeastSquares<'_, P>> {
        let n_scales = self.prior.dim() - self.n_model();
        if sigma.len() != n_scales || sigma.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::Usage(format!(
                "least squares needs {n_scales} positive noise scales, got {sigma:?}"
            )));
        }
        let mut z = vec![0.0; self.n_model()];
        z.extend(sigma.iter().map(|s| s.ln()));
        let inv_sigma = self
            .blocks
            .iter()
            .map(|b| 1.0 / self.sigma(b, &z))
            .collect();
        Ok(LeastSquares {
            post: self,
            inv_sigma,
            bounds: self.prior.bounds_of_first(self.n_model())?,
        })
    }
}

impl<P: Predict> LogDensity for Posterior<P> {
    fn dim(&self) -> usize {
        self.prior.dim()
    }
    fn ln_density(&self, z: &[f64]) -> Result<f64> {
        self.ln_density_with_pointwise(z, &mut [])
    }
    fn n_pointwise(&self) -> usize {
        self.blocks.len()
    }
    fn ln_density_with_pointwise(&self, z: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        let lp = self.prior.ln_density(z);
        if lp == f64::NEG_INFINITY {
            return Ok(lp);
        }
        Ok(lp + self.ln_likelihood_terms(z, pointwise)?)
    }
}

impl<P: Predict> TemperedTarget for Posterior<P> {
    fn dim(&self) -> usize {
        self.prior.dim()
    }
    fn ln_prior(&self, z: &[f64]) -> f64 {
        self.prior.ln_density(z)
    }
    fn ln_likelihood(&self, z: &[f64]) -> Result<f64> {
        self.ln_likelihood_terms(z, &mut [])
    }
    fn sample_prior(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        Ok(self.prior.sample(rng))
    }
}

/// [`Posterior::least_squares`]: the whitened residuals as a bounded least-squares
/// problem in the model coordinates.
pub struct LeastSquares<'a, P: Predict> {
    post: &'a Posterior<P>,
    inv_sigma: Vec<f64>,
    bounds: Bounds,
}

impl<P: Predict> LeastSquares<'_, P> {
    /// The prior box of the model coordinates.
    pub fn bounds(&self) -> &Bounds {
        &self.bounds
    }
}

impl<P: Predict> LeastSquaresProblem for LeastSquares<'_, P> {
    type Workspace = Scratch<P::Workspace>;

    fn n_params(&self) -> usize {
        self.post.n_model()
    }
    fn n_residuals(&self) -> usize {
        self.post.n_residuals
    }
    fn workspace(&self) -> Self::Workspace {
        self.post.new_scratch()
    }
    fn residuals(&self, x: &[f64], ws: &mut Self::Workspace, r: &mut [f64]) -> Result<()> {
        self.post.fill_residuals(x, ws)?;
        for (b, w) in self.inv_sigma.iter().enumerate() {
            let range = self.post.residual_range(b);
            for i in range.clone() {
                r[i] = ws.res[i] * w;
            }
            self.post.blocks[b].whiten_shared(&mut r[range], 1.0 / w);
        }
        Ok(())
    }
    /// The predictor's analytic Jacobian through each block's
    /// [`Block::residual_jacobian`] when it has one, else the one finite-difference
    /// fallback ([`fd_jacobian_at`]).
    fn jacobian(&self, x: &[f64], ws: &mut Self::Workspace, jac: &mut DMatrix<f64>) -> Result<()> {
        self.jacobian_from(x, None, ws, jac)
    }

    fn jacobian_at(
        &self,
        x: &[f64],
        f: &[f64],
        ws: &mut Self::Workspace,
        jac: &mut DMatrix<f64>,
    ) -> Result<()> {
        self.jacobian_from(x, Some(f), ws, jac)
    }
}

impl<P: Predict> LeastSquares<'_, P> {
    /// [`LeastSquaresProblem::jacobian`], with the residuals at `x` when known (`f0`).
    fn jacobian_from(
        &self,
        x: &[f64],
        f0: Option<&[f64]>,
        ws: &mut Scratch<P::Workspace>,
        jac: &mut DMatrix<f64>,
    ) -> Result<()> {
        let p = &self.post.predictor;
        ws.dpred.resize_mut(p.n_outputs(), p.n_params(), 0.0);
        if p.jacobian(x, &mut ws.ws, &mut ws.pred, &mut ws.dpred)? {
            let n_rows = jac.nrows();
            for (b, block) in self.post.blocks.iter().enumerate() {
                let row0 = self.post.offsets[b];
                block.residual_jacobian(&ws.pred, &ws.dpred, self.inv_sigma[b], row0, jac);
                let rows = self.post.residual_range(b);
                for column in jac.as_mut_slice().chunks_exact_mut(n_rows) {
                    block.whiten_shared(&mut column[rows.clone()], 1.0 / self.inv_sigma[b]);
                }
            }
            return Ok(());
        }
        fd_jacobian_at(
            FdScheme::Forward,
            x,
            f0,
            &self.bounds,
            |xp: &[f64], r: &mut [f64]| self.residuals(xp, ws, r),
            jac,
        )?;
        Ok(())
    }
}

/// Adds a fused block's log-likelihood to `total` less its `-ln det_b / 2`, whose ratio
/// `det_b` multiplies `det` (one logarithm for all blocks, taken early should the product
/// leave a safe range; [`Block::ln_likelihood_fused_det`]); `None` when the block has no
/// fused form. The returned closure gives the block's own term.
fn fused_into(
    b: &Block,
    pred: &[f64],
    level: (f64, f64),
    ln_norm: f64,
    (total, det): (&mut f64, &mut f64),
) -> Option<impl FnOnce() -> f64> {
    let (l, d) = b.ln_likelihood_fused_det(pred, level, ln_norm)?;
    *total += l;
    *det *= d;
    if !(1e-100..1e100).contains(det) {
        *total -= 0.5 * det.ln();
        *det = 1.0;
    }
    Some(move || l - 0.5 * d.ln())
}
