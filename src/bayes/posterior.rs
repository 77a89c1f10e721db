//! The posterior of the updating variables and the noise scale given measured FRF
//! magnitudes.

use super::data::FrfData;
use super::forward::{ForwardModel, ForwardWorkspace};
use super::likelihood::ResidualLayout;
use super::prior::{Prior, PriorKind, DEFAULT_NOISE_SCALE_BOUNDS};
use super::whiten::Whitening;
use crate::error::{Error, Result};
use crate::mcmc::LogDensity;
use crate::model::StructuralModel;
use crate::update::{DampingModel, ResidualForm, VariableKind, Variables, VariablesConfig};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use std::cell::RefCell;
use thread_local::ThreadLocal;

/// Settings of an [`FrfPosterior`] beyond the data and the variables.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PosteriorOptions {
    /// Prior family (see [`super::prior`]).
    pub prior: PriorKind,
    /// Bounds of the log-uniform prior on the noise scale.
    pub noise_scale_bounds: [f64; 2],
    /// Modes kept in the modal sums (all when `None`).
    pub n_modes: Option<usize>,
}

impl Default for PosteriorOptions {
    fn default() -> Self {
        PosteriorOptions {
            prior: PriorKind::Uniform,
            noise_scale_bounds: DEFAULT_NOISE_SCALE_BOUNDS,
            n_modes: None,
        }
    }
}

/// `p(z | y)` for FRF magnitudes `y` (see the [module docs](super) for the model).
///
/// The sampled vector `z` is the free updating variables in internal coordinates
/// (multipliers as they are, damping as logarithms) followed by `ln s`.
/// Evaluation is thread-safe; each thread keeps its own scratch memory (no lock, and
/// the memory stays in that core's cache).
pub struct FrfPosterior {
    forward: ForwardModel,
    data: FrfData,
    prior: Prior,
    options: PosteriorOptions,
    /// `y_k` (magnitude residuals) or `ln y_k` (log residuals).
    target: Vec<f64>,
    /// `1 / sigma_k` (1 when whitened: `target` and the residuals are then in units of
    /// `sigma`, whitened along each chain of correlated bins).
    inv_sigma: Vec<f64>,
    /// Correlated neighbouring bins ([`FrfData::bin_correlation`]) and the raw
    /// `1 / sigma_k`: the model's magnitudes are standardised and whitened like `target`.
    whitening: Option<(Whitening, Vec<f64>)>,
    /// Per point: `-ln sigma_k - ln(2 pi)/2`, and `- ln y_k` for log residuals (so every
    /// pointwise term is a log density of `y_k` itself, comparable across residual forms).
    ln_norm: Vec<f64>,
    ln_norm_sum: f64,
    /// Runs of points, with the Woodbury factors of [`FrfData::correlated`].
    layout: ResidualLayout,
    workspaces: ThreadLocal<RefCell<ForwardWorkspace>>,
}

impl Clone for FrfPosterior {
    fn clone(&self) -> Self {
        FrfPosterior {
            forward: self.forward.clone(),
            data: self.data.clone(),
            prior: self.prior.clone(),
            options: self.options,
            target: self.target.clone(),
            inv_sigma: self.inv_sigma.clone(),
            whitening: self.whitening.clone(),
            ln_norm: self.ln_norm.clone(),
            ln_norm_sum: self.ln_norm_sum,
            layout: self.layout.clone(),
            workspaces: ThreadLocal::new(),
        }
    }
}

impl std::fmt::Debug for FrfPosterior {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrfPosterior")
            .field("names", &self.names())
            .field("n_points", &self.data.len())
            .field("options", &self.options)
            .finish()
    }
}

impl FrfPosterior {
    /// Assembles the posterior. `variables` gives the box (and fixed variables); damping
    /// is always sampled on a log scale (`log_damping` is forced on).
    pub fn new(
        model: StructuralModel,
        data: FrfData,
        damping: DampingModel,
        variables: &VariablesConfig,
        options: PosteriorOptions,
    ) -> Result<Self> {
        data.validate()?;
        let n_modes = options.n_modes.unwrap_or(model.n_dof());
        let config = VariablesConfig {
            log_damping: true,
            ..variables.clone()
        };
        let vars = Variables::new(&model, damping, n_modes.min(model.n_dof()), &config)?;
        let prior = Prior::new(options.prior, &vars, options.noise_scale_bounds)?;
        let forward = ForwardModel::new(
            model,
            vars,
            n_modes,
            data.blocks.clone(),
            &data.window_tau_s,
        )?;
        let log = data.residual == ResidualForm::LogMagnitude;
        let half_ln_2pi = 0.5 * (2.0 * std::f64::consts::PI).ln();
        let target: Vec<f64> = data
            .magnitude
            .iter()
            .map(|&y| if log { y.ln() } else { y })
            .collect();
        let inv_sigma: Vec<f64> = data.sigma.iter().map(|s| 1.0 / s).collect();
        let ln_norm: Vec<f64> = data
            .sigma
            .iter()
            .zip(&data.magnitude)
            .map(|(s, y)| -s.ln() - half_ln_2pi - if log { y.ln() } else { 0.0 })
            .collect();
        let whitening = Whitening::new(&data.bin_correlation)?;
        let (target, inv_sigma, ln_norm, layout, whitening) = match whitening {
            None => {
                let layout = ResidualLayout::new(data.len(), &data.correlated, &data.sigma)?;
                (target, inv_sigma, ln_norm, layout, None)
            }
            Some(w) => {
                let t = w.transform(&data, &target, &inv_sigma, &ln_norm)?;
                let layout = ResidualLayout::new(data.len(), &t.correlated, &t.unit)?;
                (t.target, t.unit, t.ln_norm, layout, Some((w, inv_sigma)))
            }
        };
        Ok(FrfPosterior {
            layout,
            whitening,
            forward,
            ln_norm_sum: ln_norm.iter().sum(),
            data,
            prior,
            options,
            target,
            inv_sigma,
            ln_norm,
            workspaces: ThreadLocal::new(),
        })
    }

    /// The same posterior with other measured magnitudes (same points, same sigmas), e.g.
    /// data simulated by [`Self::simulate`].
    pub fn with_magnitude(&self, magnitude: Vec<f64>) -> Result<Self> {
        self.with_data(FrfData {
            magnitude,
            ..self.data.clone()
        })
    }

    /// The same model, variables and options with other data on the same blocks.
    pub fn with_data(&self, data: FrfData) -> Result<Self> {
        FrfPosterior::new(
            self.forward.model().clone(),
            data,
            self.forward.variables().damping_model(),
            &self.variables_config(),
            self.options,
        )
    }

    fn variables_config(&self) -> VariablesConfig {
        let vars = self.forward.variables();
        let mut c = VariablesConfig::default();
        for v in vars.variables() {
            if let Some(x) = v.fixed {
                c.fixed.insert(v.name.clone(), x);
            } else {
                c.bounds.insert(v.name.clone(), [v.lower, v.upper]);
                c.initial.insert(v.name.clone(), v.initial);
            }
        }
        c
    }

    /// The forward model.
    pub fn forward(&self) -> &ForwardModel {
        &self.forward
    }
    /// The updating variables (layout of `theta`).
    pub fn variables(&self) -> &Variables {
        self.forward.variables()
    }
    /// The data.
    pub fn data(&self) -> &FrfData {
        &self.data
    }
    /// The prior.
    pub fn prior(&self) -> &Prior {
        &self.prior
    }
    /// The options.
    pub fn options(&self) -> &PosteriorOptions {
        &self.options
    }
    /// Number of free updating variables (`dim() - 1`).
    pub fn n_free(&self) -> usize {
        self.variables().free().len()
    }

    /// Names of the sampled coordinates: `k1`, `m2`, `ln_xi1`, `ln_a0`, ..., `ln_noise_scale`.
    pub fn names(&self) -> Vec<String> {
        let vars = self.variables();
        vars.free()
            .iter()
            .map(|&i| {
                let v = &vars.variables()[i];
                match v.kind {
                    VariableKind::Alpha(_) | VariableKind::Beta(_) => v.name.clone(),
                    _ => format!("ln_{}", v.name),
                }
            })
            .chain(std::iter::once("ln_noise_scale".to_string()))
            .collect()
    }

    /// `theta` (full layout of [`Self::variables`]) of a sampled vector.
    pub fn theta(&self, z: &[f64]) -> Vec<f64> {
        self.variables().theta(&z[..self.n_free()])
    }

    /// The noise scale `s` of a sampled vector.
    pub fn noise_scale(&self, z: &[f64]) -> f64 {
        z[self.n_free()].exp()
    }

    /// Model magnitudes `|H^A|` at `z` in long-vector order.
    pub fn magnitudes(&self, z: &[f64]) -> Result<Vec<f64>> {
        self.check_dim(z)?;
        let mut out = vec![0.0; self.data.len()];
        self.with_workspace(|ws| {
            self.variables()
                .from_internal(&z[..self.n_free()], &mut ws.theta);
            let theta = std::mem::take(&mut ws.theta);
            let r = self.forward.magnitudes(&theta, ws, &mut out);
            ws.theta = theta;
            r
        })?;
        Ok(out)
    }

    /// Log prior at `z` (`-inf` outside the box).
    pub fn ln_prior(&self, z: &[f64]) -> f64 {
        self.prior.ln_density(z)
    }

    /// Log-likelihood at `z`; fills `pointwise` (empty or one entry per point) with
    /// the per-point terms.
    pub fn ln_likelihood(&self, z: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        self.check_dim(z)?;
        self.check_pointwise(pointwise)?;
        self.with_workspace(|ws| self.ln_likelihood_with(z, ws, pointwise))
    }

    /// Runs `f` with this thread's scratch memory (a nested call on the same thread,
    /// which nothing does today, gets fresh memory).
    fn with_workspace<T>(&self, f: impl FnOnce(&mut ForwardWorkspace) -> T) -> T {
        let cell = self
            .workspaces
            .get_or(|| RefCell::new(self.forward.workspace()));
        match cell.try_borrow_mut() {
            Ok(mut ws) => f(&mut ws),
            Err(_) => f(&mut self.forward.workspace()),
        }
    }

    fn ln_likelihood_with(
        &self,
        z: &[f64],
        ws: &mut ForwardWorkspace,
        pointwise: &mut [f64],
    ) -> Result<f64> {
        let n_free = self.n_free();
        self.variables().from_internal(&z[..n_free], &mut ws.theta);
        let mut mag = std::mem::take(&mut ws.magnitude);
        let theta = std::mem::take(&mut ws.theta);
        let r = self.forward.magnitudes(&theta, ws, &mut mag);
        ws.theta = theta;
        let result = r.map(|()| {
            let ln_s = z[n_free];
            let s2 = (2.0 * ln_s).exp();
            if self.data.residual == ResidualForm::LogMagnitude {
                for h in mag.iter_mut() {
                    *h = h.ln();
                }
            }
            if let Some((w, inv_sigma)) = &self.whitening {
                mag.iter_mut().zip(inv_sigma).for_each(|(h, s)| *h *= s);
                w.whiten(&mut mag);
            }
            // one pass over the points, the same with or without the pointwise terms
            let sums = self.layout.sums(&mag, &self.target, &self.inv_sigma, s2);
            if !pointwise.is_empty() {
                self.fill_pointwise(&mag, ln_s, s2, pointwise);
            }
            let quad = (sums.ss - sums.correction) / s2;
            -0.5 * quad - self.data.len() as f64 * ln_s - 0.5 * sums.ln_det + self.ln_norm_sum
        });
        ws.magnitude = mag;
        result
    }

    /// Pointwise terms: `-d_k^2 / (2 s^2) - ln s` plus the point's constant, and each
    /// shared run's Woodbury correction and log determinant spread evenly over its points
    /// (they sum to the log-likelihood).
    fn fill_pointwise(&self, mag: &[f64], ln_s: f64, s2: f64, pointwise: &mut [f64]) {
        for (k, p) in pointwise.iter_mut().enumerate() {
            let d = (mag[k] - self.target[k]) * self.inv_sigma[k];
            *p = -0.5 * d * d / s2 - ln_s + self.ln_norm[k];
        }
        self.layout
            .spread_shared(mag, &self.target, &self.inv_sigma, s2, pointwise);
    }

    /// One draw of the sampled vector from the prior.
    pub fn sample_prior(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        self.prior.sample(rng)
    }

    /// Magnitudes simulated from the likelihood at `z`: `|H^A_k| + s sigma_k e_k + c_k`
    /// (magnitude residuals) or `|H^A_k| exp(s sigma_k e_k + c_k)` (log residuals), `e_k`
    /// standard normal (a chain along correlated bins, [`FrfData::bin_correlation`]), `c = L eta` the shared noise of [`FrfData::correlated`] at its
    /// known size, not scaled by `s` (`eta` standard normal, drawn after the `e`).
    /// Magnitude-residual draws below zero are kept (the Gaussian model allows them).
    pub fn simulate(&self, z: &[f64], rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        let h = self.magnitudes(z)?;
        let s = self.noise_scale(z);
        let log = self.data.residual == ResidualForm::LogMagnitude;
        let mut e: Vec<f64> = (0..h.len()).map(|_| rng.sample(StandardNormal)).collect();
        if let Some((w, _)) = &self.whitening {
            w.colour(&mut e);
        }
        // the shared noise after every point's own (without it, the draws of before)
        let mut shared = vec![0.0; h.len()];
        for c in &self.data.correlated {
            let eta: Vec<f64> = (0..c.rank).map(|_| rng.sample(StandardNormal)).collect();
            for (k, row) in c.loadings.chunks_exact(c.rank.max(1)).enumerate() {
                shared[c.start + k] = row.iter().zip(&eta).map(|(a, b)| a * b).sum::<f64>();
            }
        }
        Ok(h.iter()
            .zip(&self.data.sigma)
            .zip(e.iter().zip(&shared))
            .map(|((&h, &sigma), (&e, &c))| {
                let n = s * sigma * e + c;
                if log {
                    h * n.exp()
                } else {
                    h + n
                }
            })
            .collect())
    }

    fn check_dim(&self, z: &[f64]) -> Result<()> {
        if z.len() != self.dim() {
            return Err(Error::Usage(format!(
                "the sampled vector has {} entries, the posterior {} ({})",
                z.len(),
                self.dim(),
                self.names().join(", ")
            )));
        }
        Ok(())
    }

    /// `pointwise` must be empty or hold one slot per point.
    fn check_pointwise(&self, pointwise: &[f64]) -> Result<()> {
        if !pointwise.is_empty() && pointwise.len() != self.data.len() {
            return Err(Error::Usage(format!(
                "{} pointwise slots for {} points",
                pointwise.len(),
                self.data.len()
            )));
        }
        Ok(())
    }

    fn evaluate(&self, z: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        self.check_dim(z)?;
        let lp = self.prior.ln_density(z);
        if lp == f64::NEG_INFINITY {
            return Ok(lp);
        }
        let ll = self.with_workspace(|ws| self.ln_likelihood_with(z, ws, pointwise))?;
        Ok(lp + ll)
    }
}

impl LogDensity for FrfPosterior {
    fn dim(&self) -> usize {
        self.prior.dim()
    }

    fn ln_density(&self, z: &[f64]) -> Result<f64> {
        self.evaluate(z, &mut [])
    }

    fn n_pointwise(&self) -> usize {
        self.data.len()
    }

    fn ln_density_with_pointwise(&self, z: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        if pointwise.is_empty() && !self.data.is_empty() {
            return Err(Error::Usage(format!(
                "0 pointwise slots for {} points",
                self.data.len()
            )));
        }
        self.check_pointwise(pointwise)?;
        self.evaluate(z, pointwise)
    }
}
