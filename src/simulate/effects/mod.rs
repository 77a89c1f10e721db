//! Changes of the simulated physics, each a [`SystemEffect`] in a file of its own and a
//! variant of [`EffectSpec`] (the `[[effect]]` tables of the model file).

mod base;
mod cubic;
mod dashpot;
mod oscillator;

pub use base::BaseFlexibility;
pub use cubic::StiffnessNonlinearity;
pub use dashpot::Dashpot;
pub use oscillator::Oscillator;

use super::system::{LinearSystem, SystemEffect};
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// One `[[effect]]` of the model file; applied in order after the structure is built.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EffectSpec {
    /// A discrete viscous damper across a story or between two floors (non-proportional
    /// damping).
    Dashpot(Dashpot),
    /// A secondary mass-spring-damper attached to a floor (one extra DOF).
    Oscillator(Oscillator),
    /// A base mass on a spring and dashpot under story 1 (one extra DOF).
    BaseFlexibility(BaseFlexibility),
    /// A cubic spring across a story (amplitude-dependent response).
    StiffnessNonlinearity(StiffnessNonlinearity),
}

impl EffectSpec {
    /// Checks the parameters against a structure of `n_floors` floors; `what` is
    /// returned as the reason.
    pub fn check(&self, n_floors: usize) -> std::result::Result<(), String> {
        match self {
            EffectSpec::Dashpot(d) => d.check(n_floors),
            EffectSpec::Oscillator(o) => o.check(n_floors),
            EffectSpec::BaseFlexibility(b) => b.check(),
            EffectSpec::StiffnessNonlinearity(s) => s.check(n_floors),
        }
    }
}

impl SystemEffect for EffectSpec {
    fn apply(&self, system: &mut LinearSystem) -> Result<()> {
        match self {
            EffectSpec::Dashpot(d) => d.apply(system),
            EffectSpec::Oscillator(o) => o.apply(system),
            EffectSpec::BaseFlexibility(b) => b.apply(system),
            EffectSpec::StiffnessNonlinearity(s) => s.apply(system),
        }
    }
}
