//! Changes of the simulated physics, each a [`SystemEffect`] in a file of its own and a
//! variant of [`EffectSpec`] (the `[[effect]]` tables of the model file).

mod dashpot;
mod oscillator;

pub use dashpot::Dashpot;
pub use oscillator::Oscillator;

use super::system::{LinearSystem, SystemEffect};
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// One `[[effect]]` of the model file; applied in order after the structure is built.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EffectSpec {
    /// A discrete viscous damper between two floors (non-proportional damping).
    Dashpot(Dashpot),
    /// A secondary mass-spring-damper attached to a floor (one extra DOF).
    Oscillator(Oscillator),
}

impl EffectSpec {
    /// Checks the parameters against a structure of `n_floors` floors; `what` is
    /// returned as the reason.
    pub fn check(&self, n_floors: usize) -> std::result::Result<(), String> {
        match self {
            EffectSpec::Dashpot(d) => d.check(n_floors),
            EffectSpec::Oscillator(o) => o.check(n_floors),
        }
    }
}

impl SystemEffect for EffectSpec {
    fn apply(&self, system: &mut LinearSystem) -> Result<()> {
        match self {
            EffectSpec::Dashpot(d) => d.apply(system),
            EffectSpec::Oscillator(o) => o.apply(system),
        }
    }
}
