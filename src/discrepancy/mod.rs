//! Diagnosis of missing physics (issue 5): data, hypotheses, forward models, posteriors.

mod amplitude;
pub mod data;
pub mod fit;
pub mod forward;
pub mod hypotheses;
pub mod hypothesis;
mod input_noise;
pub mod location;
pub mod posterior;
#[cfg(test)]
mod tests;

pub use data::{ChannelData, DataOptions, DiagnosisData, SegmentData};
pub use fit::{effect_starts, fit_map, frame_starts, nominal_start, MapFit, MapOptions};
pub use forward::{frame_system, BaseParams, ExtendedModel};
pub use hypotheses::{all_hypotheses, hypothesis_by_name};
pub use hypothesis::{Coordinate, EffectParam, Hypothesis};
pub use location::Location;
pub use posterior::{ModelPosterior, PhysicalValue};
