//! Missing physics: locate where simulation and recordings differ, fit model extensions
//! (hypotheses) that add what the nominal model left out, compare them by marginal
//! likelihood and held-out prediction, and decide (issue 5).

pub mod benchmark;
pub mod verdict;

pub use verdict::{decide, Candidate, Decision, DiagnosisRecord, EffectSummary, FitQuality};
