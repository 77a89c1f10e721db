//! What the rounds of a stepwise diagnosis ([`super::round`]) share: the model a round
//! extends, what it found, its context, and the stage timer.

use super::data::DiagnosisData;
use super::diagnose::{DiagnoseOptions, ModelResult};
use super::extension::Effect;
use super::hypothesis::Hypothesis;
use super::location::Location;
use super::model_evidence::{laplace_u, LaplaceOutcome};
use super::search::HypothesisSearch;
use super::verdict::Decision;
use crate::io::stages::Stages;
use crate::io::Campaign;
use std::sync::Arc;
use std::time::Instant;

/// The model a round extends.
#[derive(Debug, Clone)]
pub struct BaseModel {
    /// Its fit, evidence and effects.
    pub result: ModelResult,
    /// Laplace at its mode in logit coordinates (the screen's reference).
    pub laplace: LaplaceOutcome,
    /// Its extension of the nominal model (`None`: the nominal model itself).
    pub extension: Option<(Arc<dyn Hypothesis>, Location)>,
    /// The effects it contains, in the order they were accepted.
    pub effects: Vec<Effect>,
}

impl BaseModel {
    /// `result` of a round, accepted: its hypothesis is the one effect added to `self`.
    pub fn accept(&self, result: &ModelResult, plain: Arc<dyn Hypothesis>) -> BaseModel {
        let mut effects = self.effects.clone();
        effects.push(Effect {
            hypothesis: plain,
            location: result.location.clone(),
        });
        BaseModel {
            laplace: laplace_u(&result.posterior, &result.map.z),
            extension: result.posterior.model().hypothesis().cloned(),
            result: result.clone(),
            effects,
        }
    }
}

/// What a round found.
#[derive(Debug, Clone)]
pub struct Round {
    /// Names of the effects in the model the round extended, in order (empty: the
    /// nominal model).
    pub extends: Vec<String>,
    /// Log evidence of that model and its sd.
    pub base_ln_z: f64,
    pub base_ln_z_sd: f64,
    /// Every hypothesis' location search.
    pub searches: Vec<HypothesisSearch>,
    /// Laplace's log evidence of every hypothesis' best location (`None` where there is
    /// no mode or its curvature is not positive definite).
    pub laplace: Vec<(String, Option<f64>)>,
    /// Hypotheses whose evidence was computed, ranked by log evidence.
    pub finalists: Vec<ModelResult>,
    pub decision: Decision,
}

/// What every round shares.
pub struct RoundContext<'a> {
    pub campaign: &'a Campaign,
    pub data: &'a Arc<DiagnosisData>,
    pub opts: &'a DiagnoseOptions,
    pub stages: Option<&'a Stages>,
    /// The hypotheses, each on its own.
    pub hypotheses: &'a [Arc<dyn Hypothesis>],
}

/// Wall times of the stages, s, in order.
pub type Timings = Vec<(String, f64)>;

/// Records the time since the last mark as `what`.
pub struct Stopwatch {
    lap: Instant,
}

impl Stopwatch {
    pub fn new(from: Instant) -> Self {
        Stopwatch { lap: from }
    }

    pub fn mark(&mut self, what: &str, timings: &mut Timings) {
        timings.push((what.to_string(), self.lap.elapsed().as_secs_f64()));
        self.lap = Instant::now();
    }
}

/// The stage-key prefix of round `step` (none for the first, so that runs of the
/// one-round diagnosis resume).
pub(super) fn tag(step: usize) -> String {
    if step == 0 {
        String::new()
    } else {
        format!("step{step}-")
    }
}
