//! `sensor_timing`: some channels are recorded late (or early) by `T` against the others
//! (separate acquisition systems): the channel records `y(t - T)`, a factor `exp(-s T)`
//! on what it measures (exact under the exponential window, `s = j omega + 1/tau`). On
//! the input channel it divides every FRF of the tests it drives.
//!
//! Prior: `T` uniform on +-0.25 / f_max (f_max the nominal model's highest natural
//! frequency: a quarter period there, 90 degrees of phase); the nominal model is `T = 0`.
//! Locations: every response quantity, and every channel on its own.

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{
    check_sensor_location, sensor_locations, Coordinate, EffectParam, Hypothesis,
};
use crate::discrepancy::location::Location;
use crate::error::Result;
use crate::io::Channel;
use num_complex::Complex64;

#[derive(Debug, Clone, Copy, Default)]
pub struct SensorTiming;

impl Hypothesis for SensorTiming {
    fn name(&self) -> &'static str {
        "sensor_timing"
    }

    fn physics(&self) -> &'static str {
        "some channels are recorded with a time offset against the others"
    }

    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        sensor_locations(data)
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        check_sensor_location(self.name(), data, loc)?;
        let f_max = data.nominal_freq_hz[data.nominal_freq_hz.len() - 1];
        let t_max = 0.25 / f_max;
        Ok(vec![EffectParam {
            name: "time_offset".into(),
            unit: "s",
            coordinate_name: "time_offset_s".into(),
            lower: -t_max,
            upper: t_max,
            coordinate: Coordinate::Linear { factor: 1.0 },
            no_effect: Some(0.0),
        }])
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
        (-s * effect[0]).exp()
    }
}
