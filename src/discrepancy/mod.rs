//! Missing physics: locate where simulation and recordings differ, fit model extensions
//! (hypotheses) that add what the nominal model left out, compare them by marginal
//! likelihood and held-out prediction, and decide (issue 5).

mod amplitude;
pub mod benchmark;
pub mod data;
pub mod diagnose;
pub mod figures;
pub mod heldout;
pub mod fit;
pub mod forward;
pub mod hypotheses;
pub mod hypothesis;
mod input_noise;
pub mod location;
pub mod output;
pub mod posterior;
pub mod report;
pub mod search;
#[cfg(test)]
mod tests;
pub mod verdict;

pub use data::{ChannelData, DataOptions, DiagnosisData, SegmentData};
pub use fit::{effect_starts, fit_map, frame_starts, nominal_start, MapFit, MapOptions};
pub use forward::{frame_system, BaseParams, ExtendedModel};
pub use hypotheses::{all_hypotheses, hypothesis_by_name};
pub use hypothesis::{Coordinate, EffectParam, Hypothesis};
pub use location::Location;
pub use posterior::{ModelPosterior, PhysicalValue};
pub use verdict::{decide, Candidate, Decision, DiagnosisRecord, EffectSummary, FitQuality};
