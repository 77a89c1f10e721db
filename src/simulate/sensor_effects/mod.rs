//! Instrument effects: [`SensorStage`]s applied at the internal rate, before
//! anti-aliasing, to the channels they name or to every channel of a quantity, in all
//! tests or the named ones (the `[[sensor_effect]]` tables of the model file). Each
//! lives in a file of its own.

mod low_pass;
mod time_offset;

pub use low_pass::LowPass;
pub use time_offset::TimeOffset;

use super::sensor::{SensorStage, Signal};
use crate::error::Result;
use crate::io::Quantity;
use serde::{Deserialize, Serialize};

/// One `[[sensor_effect]]`: which channels (by name, in which tests) and what it does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SensorEffect {
    /// Second-order low-pass sensor dynamics (e.g. an accelerometer's resonance).
    LowPass(LowPass),
    /// The channel's clock is late by `offset_s` (early when negative).
    TimeOffset(TimeOffset),
}

impl SensorEffect {
    /// Channel names it applies to.
    pub fn channels(&self) -> &[String] {
        match self {
            SensorEffect::LowPass(e) => &e.channels,
            SensorEffect::TimeOffset(e) => &e.channels,
        }
    }

    /// The quantity whose channels it applies to, if placed by quantity.
    pub fn quantity(&self) -> Option<Quantity> {
        match self {
            SensorEffect::LowPass(e) => e.quantity,
            SensorEffect::TimeOffset(e) => e.quantity,
        }
    }

    /// Test names it applies to (`None`: all tests).
    pub fn tests(&self) -> Option<&[String]> {
        match self {
            SensorEffect::LowPass(e) => e.tests.as_deref(),
            SensorEffect::TimeOffset(e) => e.tests.as_deref(),
        }
    }

    /// Whether it applies to channel `channel` (measuring `quantity`) of `test`.
    pub fn applies_to(&self, test: &str, channel: &str, quantity: Quantity) -> bool {
        (self.channels().iter().any(|c| c == channel) || self.quantity() == Some(quantity))
            && self.tests().is_none_or(|t| t.iter().any(|t| t == test))
    }

    /// Checks its own parameters; returns the reason on failure.
    pub fn check(&self) -> std::result::Result<(), String> {
        if self.channels().is_empty() == self.quantity().is_none() {
            return Err(
                "sensor_effect: give either `channels` (names) or `quantity`, not both".into(),
            );
        }
        match self {
            SensorEffect::LowPass(e) => e.check(),
            SensorEffect::TimeOffset(e) => e.check(),
        }
    }
}

impl SensorStage for SensorEffect {
    fn apply(&self, signal: Signal) -> Result<Signal> {
        match self {
            SensorEffect::LowPass(e) => e.apply(signal),
            SensorEffect::TimeOffset(e) => e.apply(signal),
        }
    }

    fn lookahead_samples(&self, rate_hz: f64) -> usize {
        match self {
            SensorEffect::LowPass(e) => e.lookahead_samples(rate_hz),
            SensorEffect::TimeOffset(e) => e.lookahead_samples(rate_hz),
        }
    }
}
