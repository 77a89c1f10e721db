//! Missing physics: locate where simulation and recordings differ, fit model extensions
//! (hypotheses) that add what the nominal model left out, compare them by marginal
//! likelihood and held-out prediction, and decide (issue 5).

pub mod adequacy;
mod amplitude;
pub mod benchmark;
pub mod bin_correlation;
mod bins;
pub mod consistency;
pub mod data;
mod data_options;
pub mod diagnose;
pub mod effect_coverage;
pub mod effect_summary;
pub mod estimator_bias;
mod eta_profile;
pub mod extension;
pub mod figures;
pub mod fit;
pub mod forward;
mod forward_modal;
#[cfg(test)]
mod forward_modal_tests;
mod frame_layout;
mod gain_solve;
pub mod heldout;
pub mod hypotheses;
pub mod hypothesis;
mod input_noise;
pub mod judge;
pub mod locate;
pub mod location;
pub mod model_evidence;
mod nominal_system;
pub mod output;
mod per_thread;
pub mod posterior;
pub mod reduction;
pub mod refine;
pub mod report;
pub mod residual_map;
pub mod round;
pub mod round_state;
pub mod search;
pub mod stepwise;
#[cfg(test)]
mod tests;
pub mod time_domain;
pub mod verdict;

/// Evidence and Laplace live in the inference layer; re-exported for existing paths.
pub use crate::infer::evidence;
pub use crate::infer::laplace::{
    laplace, laplace_with_step, LaplaceEvidence, LAPLACE_STEP_FRACTION,
};
pub use crate::infer::TemperingRun;
pub use data::{ChannelData, DataOptions, DiagnosisData, SegmentData};
pub use evidence::{
    stepping_stone, Evidence, EvidenceOptions, EvidenceProgress, PosteriorDraws, Stage,
    TemperedTarget,
};
pub use fit::{effect_starts, fit_map, frame_starts, nominal_start, MapFit, MapOptions};
pub use forward::{frame_system, BaseParams, ExtendedModel};
pub use hypotheses::{all_hypotheses, hypothesis_by_name};
pub use hypothesis::{Coordinate, EffectParam, Hypothesis};
pub use location::Location;
pub use posterior::{FrameLayout, ModelPosterior, PhysicalValue};
pub use verdict::{decide, Candidate, Decision, DiagnosisRecord, EffectSummary, FitQuality};
