//! The posterior of the updating variables and the noise scale given measured FRF
//! magnitudes.

use super::data::FrfData;
use super::layer::{frf_predictor, mode_solver};
use super::prior::{Prior, PriorKind, DEFAULT_NOISE_SCALE_BOUNDS};
use crate::error::{Error, Result};
use crate::frf::FrfBlock;
use crate::infer::likelihood::Transform;
use crate::infer::{Block, Chain, Correlation, NoiseScale, Posterior};
use crate::mcmc::LogDensity;
use crate::model::StructuralModel;
use crate::predict::choice::Anchor;
use crate::predict::{FrfPredictor, ModeSolverChoice, ModelModes};
use crate::update::{DampingModel, ResidualForm, VariableKind, Variables, VariablesConfig};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Settings of an [`FrfPosterior`] beyond the data and the variables.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PosteriorOptions {
    /// Prior family (see [`super::prior`]).
    pub prior: PriorKind,
    /// Bounds of the log-uniform prior on the noise scale.
    pub noise_scale_bounds: [f64; 2],
    /// Modes kept in the modal sums (all when `None`; required by the reduced and exact
    /// solvers).
    pub n_modes: Option<usize>,
    /// The mode solver ([`ModeSolverChoice::Auto`]: dense for small models, a reduced
    /// basis anchored at the maximum-likelihood point for large ones).
    pub mode_solver: ModeSolverChoice,
}

impl Default for PosteriorOptions {
    fn default() -> Self {
        PosteriorOptions {
            prior: PriorKind::Uniform,
            noise_scale_bounds: DEFAULT_NOISE_SCALE_BOUNDS,
            n_modes: None,
            mode_solver: ModeSolverChoice::Auto,
        }
    }
}

/// `p(z | y)` for FRF magnitudes `y` (see the [module docs](super) for the model).
///
/// The sampled vector `z` is the free updating variables in internal coordinates
/// (multipliers as they are, damping as logarithms) followed by `ln s`. The likelihood is
/// the inference layer's ([`Posterior`] of the [`FrfPredictor`] whose coordinates are
/// `z` without `ln s`, [`frf_predictor`]): one observation block per run of points, a
/// [`crate::infer::BlockKind::SharedNoise`] block for each test's shared force noise and
/// a [`crate::infer::BlockKind::Values`] block for the points between, all with the noise
/// scale `s`. The prior is this module's ([`Prior`]). Evaluation is thread-safe; each
/// thread keeps its own scratch memory.
#[derive(Clone)]
pub struct FrfPosterior {
    layer: Posterior<FrfPredictor<ModelModes>>,
    model: Arc<StructuralModel>,
    /// The mode solver (a reduced basis is kept when the data change: [`Self::with_data`]).
    solver: ModelModes,
    variables: Variables,
    n_modes: usize,
    data: FrfData,
    prior: Prior,
    options: PosteriorOptions,
    /// Per point: `-ln y_k` for log residuals (so every pointwise term is a log density
    /// of `y_k` itself, comparable across residual forms), else empty.
    ln_jacobian: Vec<f64>,
    ln_jacobian_sum: f64,
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

/// The modes in the modal sums: `options.n_modes`, or every mode for the dense solver.
fn modes_in_sums(model: &StructuralModel, options: &PosteriorOptions) -> Result<usize> {
    match (options.n_modes, options.mode_solver.resolve(model)) {
        (Some(n), _) => Ok(n),
        (None, ModeSolverChoice::Dense) => Ok(model.n_dof()),
        (None, choice) => Err(Error::Usage(format!(
            "the model has {} DOFs and is solved by the {choice:?} mode solver: give the \
             number of its lowest modes in the modal sums (`--n-modes N`, or \
             `[posterior] n_modes` in the settings), e.g. every mode up to well above the \
             highest frequency analysed",
            model.n_dof()
        ))),
    }
}

/// The observation blocks of `data`: one per block of shared noise (in order, not
/// overlapping; the data validated them) and one per run of points between them, each
/// with its points' correlated bins ([`FrfData::bin_correlation`]) as a [`Chain`].
fn observation_blocks(data: &FrfData) -> Result<Vec<Block>> {
    let transform = match data.residual {
        ResidualForm::LogMagnitude => Transform::Ln,
        _ => Transform::Identity,
    };
    let (y, sd, scale) = (&data.magnitude, &data.sigma, NoiseScale::Sampled(0));
    let rho = &data.bin_correlation;
    let block = |r: std::ops::Range<usize>, shared: Option<(&[f64], usize)>| {
        let kind = if shared.is_some() {
            " (shared noise)"
        } else {
            ""
        };
        let name = format!("points {}..{}{kind}", r.start, r.end);
        let chain = if rho.is_empty() {
            &[][..]
        } else {
            &rho[r.clone()]
        };
        let correlation = Correlation { shared, chain };
        let (y, sd) = (&y[r.clone()], &sd[r.clone()]);
        Block::correlated_values(&name, r, y, sd, transform, correlation, scale)
    };
    let (mut blocks, mut at) = (Vec::new(), 0);
    for c in &data.correlated {
        if c.start > at {
            blocks.push(block(at..c.start, None)?);
        }
        let loadings = (c.loadings.as_slice(), c.rank);
        blocks.push(block(c.start..c.start + c.len, Some(loadings))?);
        at = c.start + c.len;
    }
    if data.len() > at {
        blocks.push(block(at..data.len(), None)?);
    }
    Ok(blocks)
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
        Self::build(Arc::new(model), data, damping, variables, options, None)
    }

    /// [`Self::new`] on a given mode solver (`None`: the one `options` choose, a reduced
    /// basis without anchor).
    fn build(
        model: Arc<StructuralModel>,
        data: FrfData,
        damping: DampingModel,
        variables: &VariablesConfig,
        options: PosteriorOptions,
        solver: Option<ModelModes>,
    ) -> Result<Self> {
        data.validate()?;
        let n_modes = modes_in_sums(&model, &options)?;
        let config = VariablesConfig {
            log_damping: true,
            ..variables.clone()
        };
        let vars = Variables::new(&model, damping, n_modes.min(model.n_dof()), &config)?;
        let prior = Prior::new(options.prior, &vars, options.noise_scale_bounds)?;
        let solver = match solver {
            Some(s) => s,
            None => mode_solver(&model, &vars, n_modes, options.mode_solver, None)?,
        };
        let (blocks, tau) = (&data.blocks, &data.window_tau_s);
        let predictor = frf_predictor(&model, &vars, n_modes, blocks, tau, solver.clone())?;
        let bounds = vars.internal_bounds();
        let theta_bounds: Vec<(f64, f64)> = bounds
            .lower()
            .iter()
            .zip(bounds.upper())
            .map(|(&lo, &hi)| (lo, hi))
            .collect();
        let [s_lo, s_hi] = options.noise_scale_bounds;
        let scale = ("ln_noise_scale".to_string(), (s_lo.ln(), s_hi.ln()));
        let blocks = observation_blocks(&data)?;
        let layer = Posterior::new(predictor, &theta_bounds, &[scale], blocks)?;
        let ln_jacobian: Vec<f64> = match data.residual {
            ResidualForm::LogMagnitude => data.magnitude.iter().map(|y| -y.ln()).collect(),
            _ => Vec::new(),
        };
        Ok(FrfPosterior {
            layer,
            model,
            solver,
            variables: vars,
            n_modes,
            ln_jacobian_sum: ln_jacobian.iter().sum(),
            ln_jacobian,
            data,
            prior,
            options,
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
        FrfPosterior::build(
            self.model.clone(),
            data,
            self.variables.damping_model(),
            &self.variables_config(),
            self.options,
            Some(self.solver.clone()),
        )
    }

    /// Whether the modes come from a reduced basis ([`Self::with_basis_anchored_at`]).
    pub fn has_reduced_basis(&self) -> bool {
        matches!(self.solver, ModelModes::Reduced(_))
    }

    /// The same posterior with its reduced basis rebuilt to be exact at the sampled
    /// vector `z` (its structural coordinates) and accurate around it: without `spread`,
    /// the box's snapshots and `z`'s near ones; with `spread` (per structural coordinate,
    /// e.g. a few Gauss-Newton sd), snapshots of `z +- spread` only
    /// ([`crate::predict::choice::reduced_basis`]); `z`'s exact modes kept whole. The
    /// posterior itself for other solvers.
    pub fn with_basis_anchored_at(&self, z: &[f64], spread: Option<&[f64]>) -> Result<Self> {
        if !self.has_reduced_basis() {
            return Ok(self.clone());
        }
        let params = self.predictor().parametrisation();
        let n = params.len();
        if z.len() < n || spread.is_some_and(|s| s.len() < n) {
            return Err(Error::Usage(format!(
                "an anchor of {} coordinates for {n} structural ones",
                z.len()
            )));
        }
        let v = |z: &[f64]| {
            let (mut alpha, mut beta) = (Vec::new(), Vec::new());
            params.apply(z, &mut alpha, &mut beta);
            alpha.extend(beta);
            alpha
        };
        let point = v(&z[..n]);
        // the spread in the model's variables (multipliers are linear coordinates)
        let steps: Option<Vec<f64>> = spread.map(|s| {
            let shifted: Vec<f64> = z[..n].iter().zip(s).map(|(a, b)| a + b).collect();
            v(&shifted)
                .iter()
                .zip(&point)
                .map(|(a, b)| (a - b).abs())
                .collect()
        });
        let anchor = Anchor {
            point: &point,
            spread: steps.as_deref(),
        };
        let (vars, n_modes) = (&self.variables, self.n_modes);
        let choice = ModeSolverChoice::Reduced;
        let solver = mode_solver(&self.model, vars, n_modes, choice, Some(anchor))?;
        FrfPosterior::build(
            self.model.clone(),
            self.data.clone(),
            self.variables.damping_model(),
            &self.variables_config(),
            self.options,
            Some(solver),
        )
    }

    /// The same posterior on another mode solver (a reduced basis without anchor), e.g.
    /// [`ModeSolverChoice::Exact`] to measure a reduced basis's error against.
    pub fn with_mode_solver(&self, choice: ModeSolverChoice) -> Result<Self> {
        let (vars, n) = (&self.variables, self.n_modes);
        let solver = mode_solver(&self.model, vars, n, choice, None)?;
        FrfPosterior::build(
            self.model.clone(),
            self.data.clone(),
            self.variables.damping_model(),
            &self.variables_config(),
            PosteriorOptions {
                mode_solver: choice,
                ..self.options
            },
            Some(solver),
        )
    }

    /// The mode solver.
    pub fn mode_solver(&self) -> &ModelModes {
        &self.solver
    }

    fn variables_config(&self) -> VariablesConfig {
        let vars = &self.variables;
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

    /// The structural model.
    pub fn model(&self) -> &StructuralModel {
        &self.model
    }
    /// Modes kept in the modal sums.
    pub fn n_modes(&self) -> usize {
        self.n_modes
    }
    /// The likelihood on the inference layer (its coordinates are this posterior's; its
    /// box prior is uniform, this posterior's is [`Self::prior`]).
    pub fn layer(&self) -> &Posterior<FrfPredictor<ModelModes>> {
        &self.layer
    }
    /// The magnitudes `|H^A|` over the data's blocks as a function of the sampled
    /// coordinates without `ln s`.
    pub fn predictor(&self) -> &FrfPredictor<ModelModes> {
        self.layer.predictor()
    }
    /// The same magnitudes over other blocks (e.g. a dense grid for plots), block `b`
    /// through an exponential window of `window_tau_s[b]` s.
    pub fn predictor_over(
        &self,
        blocks: &[FrfBlock],
        window_tau_s: &[Option<f64>],
    ) -> Result<FrfPredictor<ModelModes>> {
        frf_predictor(
            &self.model,
            &self.variables,
            self.n_modes,
            blocks,
            window_tau_s,
            self.solver.clone(),
        )
    }
    /// The updating variables (layout of `theta`).
    pub fn variables(&self) -> &Variables {
        &self.variables
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
        self.layer.predict(&z[..self.n_free()])
    }

    /// Log prior at `z` (`-inf` outside the box).
    pub fn ln_prior(&self, z: &[f64]) -> f64 {
        self.prior.ln_density(z)
    }

    /// Log-likelihood at `z`; fills `pointwise` (empty or one entry per point) with
    /// the per-point terms: each point's own Gaussian term, and each shared run's
    /// Woodbury correction and log determinant spread evenly over its points (they sum
    /// to the log-likelihood; [`Block::ln_likelihood_pointwise`]).
    pub fn ln_likelihood(&self, z: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        self.check_dim(z)?;
        self.check_pointwise(pointwise)?;
        if pointwise.is_empty() {
            return Ok(self.layer.ln_likelihood_terms(z, &mut [])? + self.ln_jacobian_sum);
        }
        let ll = self.layer.ln_likelihood_pointwise(z, pointwise)?;
        for (p, j) in pointwise.iter_mut().zip(&self.ln_jacobian) {
            *p += j;
        }
        Ok(ll + self.ln_jacobian_sum)
    }

    /// One draw of the sampled vector from the prior.
    pub fn sample_prior(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        self.prior.sample(rng)
    }

    /// Magnitudes simulated from the likelihood at `z`: `|H^A_k| + s sigma_k e_k + c_k`
    /// (magnitude residuals) or `|H^A_k| exp(s sigma_k e_k + c_k)` (log residuals), `e_k`
    /// standard normal (a [`Chain`] along correlated bins, [`FrfData::bin_correlation`]),
    /// `c = L eta` the shared noise of [`FrfData::correlated`] at its
    /// known size, not scaled by `s` (`eta` standard normal, drawn after the `e`).
    /// Magnitude-residual draws below zero are kept (the Gaussian model allows them).
    pub fn simulate(&self, z: &[f64], rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        let h = self.magnitudes(z)?;
        let s = self.noise_scale(z);
        let log = self.data.residual == ResidualForm::LogMagnitude;
        let mut e: Vec<f64> = (0..h.len()).map(|_| rng.sample(StandardNormal)).collect();
        if let Some(chain) = Chain::new(&self.data.bin_correlation)? {
            chain.colour(&mut e);
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
        Ok(lp + self.ln_likelihood(z, pointwise)?)
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
