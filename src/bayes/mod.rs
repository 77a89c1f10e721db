//! Bayesian model updating from FRF magnitudes: the posterior of the masses,
//! stiffnesses and damping of a model given measured FRFs, sampled with the ensemble
//! sampler of [`crate::mcmc`].
//!
//! # The model
//! Data: measured magnitudes `y_k = |H^E_k|` at the selected points of every test
//! (Eqs. 17-19), [`FrfData`]. Forward model: `h_k(theta) = |H^A_k(theta)|`, the modal
//! sums of Eqs. (7), (10), (15), (16) with each test's exponential window applied to the
//! model exactly ([`crate::predict::FrfPredictor`], built by [`layer::frf_predictor`]),
//! so the damping sampled is the structure's. The likelihood is the inference layer's
//! ([`crate::infer::Posterior`]); [`FrfPosterior`] adds this module's priors.
//!
//! Likelihood (independent points, unknown noise scale `s`):
//! - magnitude residuals (default): `y_k ~ N(h_k, (s sigma_k)^2)`,
//!   `sigma_k = y_k max(r_k, r_floor)`;
//! - log-magnitude residuals: `ln y_k ~ N(ln h_k, (s sigma_k)^2)`,
//!   `sigma_k = max(r_k, r_floor)`,
//!
//! where `r_k = sqrt((1 - g_k^2) / (2 g_k^2 n))` is the Bendat & Piersol relative random
//! error of `|H1|` from the coherence `g_k^2` and the number of averages `n`
//! ([`TestFrf::selected_rel_std`](crate::signal::TestFrf::selected_rel_std)) and
//! `r_floor` a floor ([`DEFAULT_REL_SIGMA_FLOOR`], 0.1 %) that keeps points with
//! coherence near 1 from getting unbounded weight. `sigma_k` is computed once from the
//! data (plug-in) and is a constant of the model.
//!
//! Hammer tests (`InputNoiseModel::Shared`, the default of `sample`): the force
//! channel's noise inside the force windows gives `|H1|` an error smooth in frequency
//! and common to every response of the test ([`crate::signal::InputNoise`]); it is
//! taken out of `r_k` (the output noise's coherence) and enters as
//! `cov = s^2 diag(sigma_k^2) + L L^T` per test, `L` its low-rank loadings
//! ([`CorrelatedNoise`]), evaluated in Woodbury form. The sampled scale `s` acts on
//! the per-point part only: the shared part's size is known from the force channel
//! (scaling it too made the mass-stiffness scale's intervals `1/s` ~ 1.4x too narrow,
//! `results/coverage/`). Counted per point instead
//! (`PerPoint`, the former model), the posterior's 90 % intervals covered the true masses
//! and stiffnesses of simulated campaigns in 6-9 of 20 ([`coverage`],
//! `results/coverage/`). `s` carries what the coherence does
//! not see (model error, bias); it is sampled, log-uniform on [`DEFAULT_NOISE_SCALE_BOUNDS`].
//! The loadings are relative errors times the FRF magnitude; `sample` takes the model's
//! magnitude at the maximum-likelihood start, not the measured one, whose own noise
//! would correlate the covariance with the residual and bias the mass-stiffness scale
//! ([`LoadingMagnitude`], [`plug_in_start`]).
//!
//! Pointwise log-likelihood (for PSIS-LOO / WAIC): the log density of each `y_k`
//! (lognormal density for log residuals), so both residual forms compare on one scale;
//! with shared noise, each test's Woodbury correction and log determinant are spread
//! evenly over its points (the terms sum to the log-likelihood but are not each a
//! conditional density).
//!
//! Priors: [`prior`]. Sampled coordinates: the free multipliers `alpha`, `beta` as they
//! are, damping as logarithms, then `ln s` ([`FrfPosterior::names`]). Reported: masses in
//! kg, stiffnesses in N/m, damping in its units, `noise_scale` ([`summary`]).
//!
//! # Running
//! [`run::run_sample`] does a whole `frfbayes sample` run: estimate the FRFs of a
//! campaign, build the posterior, find the maximum-likelihood start ([`find_start`];
//! with the shared noise's loadings at the start's model magnitudes, [`plug_in_start`]),
//! sample with periodic checkpoints (resumable bit for bit), and write
//! `posterior.json`, draws (CSV, `.npy`), the pointwise log-likelihood, figures and
//! the ArviZ InferenceData `inference_data.nc` ([`inference_data`]).
//!
//! # Calibration
//! [`sbc`]: simulation-based calibration (Talts et al. 2018) of the whole chain
//! (prior, simulator, likelihood, start, sampler) on a small problem.

pub mod coverage;
mod data;
pub mod figures;
pub mod fit;
pub mod inference_data;
pub mod layer;
mod moves;
mod posterior;
pub mod predictive;
pub mod prior;
pub mod recovery;
pub mod report;
mod reselect;
pub mod run;
pub mod sbc;
mod settings;
mod start;
pub mod summary;
#[cfg(test)]
mod tests;

pub use data::{
    BinCorrelation, CorrelatedNoise, FrfData, InputNoiseModel, LoadingMagnitude,
    DEFAULT_NOISE_POOL_BINS, DEFAULT_REL_SIGMA_FLOOR, SHARED_NOISE_REL_TOL,
    SHARED_NOISE_REL_TOL_CHAINED,
};
pub use posterior::{FrfPosterior, PosteriorOptions};
pub use prior::{Prior, PriorKind, DEFAULT_NOISE_SCALE_BOUNDS};
pub use reselect::{reselect_on_model, BandSelection};
pub use start::{ball_positions, find_start, plug_in_start, StartPoint};
