//! The inference layer: one posterior for every study.
//!
//! A study states its model (a [`crate::predict::Predict`] implementation: what the model
//! predicts at the observed channels), its data and its likelihood (observation blocks),
//! and gets from [`Posterior`] at once
//! - a [`crate::mcmc::LogDensity`] for the ensemble sampler ([`sample`]),
//! - a [`crate::update::lsq::LeastSquaresProblem`] for MAP fits by the trust-region
//!   reflective solver ([`fit`]),
//! - a [`TemperedTarget`] for evidence by stepping-stone ([`evidence`]) and Laplace's
//!   approximation ([`laplace`]).
//!
//! Lower layers (model, modal, frf, predict, update, mcmc) never import this one; the
//! studies (bayes, discrepancy, real, experiment) build on it.

pub mod evidence;
pub mod fit;
pub mod importance;
pub mod laplace;
pub mod likelihood;
pub mod nested;
pub mod posterior;
pub mod prior;
pub mod reference;
pub mod sample;
pub mod screened;
mod tempering;
#[cfg(test)]
mod tests;
pub mod unconstrained;
pub mod validation;

pub use evidence::{
    stepping_stone, Evidence, EvidenceOptions, EvidenceProgress, PosteriorDraws, Stage,
    TemperedTarget,
};
pub use fit::{fit_multistart, FitOptions, FitResult};
pub use importance::{importance_evidence, ImportanceEvidence};
pub use laplace::{laplace, laplace_with_step, LaplaceEvidence, LAPLACE_STEP_FRACTION};
pub use likelihood::{Block, BlockKind, Chain, Correlation, LinearFit, NoiseScale};
pub use nested::{
    bridge_evidence, gain_bound, laplace_in_u, BridgeEvidence, BridgeOptions, InUnconstrained,
};
pub use posterior::Posterior;
pub use prior::BoxPrior;
pub use reference::{
    referenced_evidence, referenced_evidence_at_mode, Referenced, ReferencedEvidence,
};
pub use sample::{sample_to_targets, Sampled, Sampling, Targets};
pub use screened::{
    choose_estimator, choose_for_extension, laplace_of, rival_floors, screened_evidence,
    BaseEvidence, Estimator, Extension, LaplaceInU, ScreenOptions, ScreenedEvidence,
    GSS_REPLICATES, IMPORTANCE_DRAWS,
};
pub use tempering::TemperingRun;
pub use unconstrained::{sample_in_unconstrained, LogitMap, Unconstrained};
