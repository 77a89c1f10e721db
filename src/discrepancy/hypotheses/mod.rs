//! The hypotheses of missing physics, one file each, and their registry.

mod base_flexibility;
mod nonproportional_damping;
mod secondary_oscillator;
mod sensor_dynamics;
mod sensor_timing;
mod stiffness_nonlinearity;

pub use base_flexibility::BaseFlexibilityHypothesis;
pub use nonproportional_damping::NonproportionalDamping;
pub use secondary_oscillator::SecondaryOscillator;
pub use sensor_dynamics::{low_pass, SensorDynamics};
pub use sensor_timing::SensorTiming;
pub use stiffness_nonlinearity::StiffnessNonlinearityHypothesis;

use super::hypothesis::Hypothesis;

/// Every hypothesis, in the order of issue 5.
pub fn all_hypotheses() -> Vec<Box<dyn Hypothesis>> {
    vec![
        Box::new(BaseFlexibilityHypothesis),
        Box::new(NonproportionalDamping),
        Box::new(SecondaryOscillator),
        Box::new(StiffnessNonlinearityHypothesis),
        Box::new(SensorTiming),
        Box::new(SensorDynamics),
    ]
}

/// The hypothesis called `name`, if any.
pub fn hypothesis_by_name(name: &str) -> Option<Box<dyn Hypothesis>> {
    all_hypotheses().into_iter().find(|h| h.name() == name)
}
