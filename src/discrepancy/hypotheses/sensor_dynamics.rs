//! `sensor_dynamics`: the transducers' own frequency response, a second-order low-pass
//! `w^2 / (s^2 + 2 zeta w s + w^2)` (an accelerometer's mounted resonance or its signal
//! conditioning) on some channels; exact under the exponential window.
//!
//! Priors (log-uniform), scaled by the nominal model: natural frequency 1.5 .. 1000 x
//! the highest nominal natural frequency (a sensor resonance inside the structure's band
//! would not be a sensor; at the upper end the phase lag at the analysed frequencies is
//! below 1 degree, the nominal model being the limit `w -> inf`); damping ratio
//! 0.05..2. Locations: every response quantity, and every channel on its own.

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{
    check_sensor_location, sensor_locations, EffectParam, Hypothesis,
};
use crate::discrepancy::location::Location;
use crate::error::Result;
use crate::io::Channel;
use num_complex::Complex64;

#[derive(Debug, Clone, Copy, Default)]
pub struct SensorDynamics;

/// The low-pass `w^2 / (s^2 + 2 zeta w s + w^2)` at natural frequency `freq_hz`.
pub fn low_pass(freq_hz: f64, zeta: f64, s: Complex64) -> Complex64 {
    let w = 2.0 * std::f64::consts::PI * freq_hz;
    let w2 = w * w;
    w2 / (s * s + s * (2.0 * zeta * w) + w2)
}

impl Hypothesis for SensorDynamics {
    fn name(&self) -> &'static str {
        "sensor_dynamics"
    }

    fn physics(&self) -> &'static str {
        "the transducers filter what they measure (a second-order low-pass)"
    }

    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        sensor_locations(data)
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        check_sensor_location(self.name(), data, loc)?;
        let f_max = data.nominal_freq_hz[data.nominal_freq_hz.len() - 1];
        Ok(vec![
            EffectParam::log_uniform(
                "sensor_frequency",
                "Hz",
                1.5 * f_max,
                1000.0 * f_max,
                Some(f64::INFINITY),
            ),
            EffectParam::log_uniform("sensor_damping_ratio", "1", 0.05, 2.0, None),
        ])
    }

    fn affects_channel(&self, loc: &Location, channel: &Channel) -> bool {
        loc.covers_channel(&channel.name, channel.quantity)
    }

    fn sensor_factor(
        &self,
        loc: &Location,
        effect: &[f64],
        channel: &Channel,
        s: Complex64,
    ) -> Complex64 {
        let _ = (loc, channel);
        low_pass(effect[0], effect[1], s)
    }
}
