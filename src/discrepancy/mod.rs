//! Missing physics: locate where simulation and recordings differ, fit model extensions
//! (hypotheses) that add what the nominal model left out, compare them by marginal
//! likelihood and held-out prediction, and decide (issue 5).

pub mod evidence;
pub mod laplace;
mod tempering;
pub mod verdict;

pub use evidence::{
    stepping_stone, Evidence, EvidenceOptions, EvidenceProgress, PosteriorDraws, Stage,
    TemperedTarget,
};
pub use laplace::{laplace, laplace_with_step, LaplaceEvidence, LAPLACE_STEP_FRACTION};
pub use tempering::TemperingRun;
pub use verdict::{decide, Candidate, Decision, DiagnosisRecord, EffectSummary, FitQuality};
