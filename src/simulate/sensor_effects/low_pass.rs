//! Second-order low-pass sensor dynamics, `H(s) = w^2 / (s^2 + 2 z w s + w^2)` (unit DC
//! gain), such as an accelerometer's mounted resonance or a conditioning filter.
//!
//! The stage filters the internal-rate samples with the exact FOH discretisation of
//! `H`, i.e. as if their pre-emphasised samples were joined by straight lines
//! ([`crate::simulate::pre_emphasised`]). For a sinusoid of frequency f that multiplies
//! `H` by [`crate::simulate::hold_gain`] `~ 1 - (2 pi f h)^4 / 90`, 3e-10 at 10 Hz and
//! 3e-6 at 100 Hz for h = 1/5000 s: a slightly different sensor, not an integration
//! error.

use crate::error::{Error, Result};
use crate::io::Quantity;
use crate::simulate::discrete::{Foh, OutputMap, StateSpace};
use crate::simulate::sensor::{SensorStage, Signal};
use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// A second-order low-pass on the named channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LowPass {
    /// Channels by name; or give `quantity` instead.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub channels: Vec<String>,
    /// Every channel of this quantity; or give `channels` instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quantity: Option<Quantity>,
    /// Tests it applies to (all when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tests: Option<Vec<String>>,
    pub natural_frequency_hz: f64,
    pub damping_ratio: f64,
}

impl LowPass {
    pub(super) fn check(&self) -> std::result::Result<(), String> {
        if !(self.natural_frequency_hz.is_finite() && self.natural_frequency_hz > 0.0) {
            return Err("low_pass natural_frequency_hz must be positive".into());
        }
        if !(self.damping_ratio.is_finite() && self.damping_ratio > 0.0) {
            return Err("low_pass damping_ratio must be positive".into());
        }
        Ok(())
    }

    /// The continuous frequency response at `freq_hz`.
    pub fn response(&self, freq_hz: f64) -> Complex64 {
        let w = 2.0 * std::f64::consts::PI * self.natural_frequency_hz;
        let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * freq_hz);
        w * w / (s * s + 2.0 * self.damping_ratio * w * s + w * w)
    }

    /// What the stage does to a sinusoid at `freq_hz` sampled at `rate_hz` (the module
    /// docs): `P(f) sum_m H(f + m fs) sinc^2(pi (f + m fs) / fs)` over `|m| <= images`,
    /// `P = 1 + sin^2(pi f / fs) / 3` the pre-emphasis' gain (the images fall like
    /// `1 / m^4`).
    pub fn sampled_response(&self, freq_hz: f64, rate_hz: f64, images: i32) -> Complex64 {
        let pi = std::f64::consts::PI;
        let p = 1.0 + (pi * freq_hz / rate_hz).sin().powi(2) / 3.0;
        p * (-images..=images)
            .map(|m| {
                let nu = freq_hz + m as f64 * rate_hz;
                let x = pi * nu / rate_hz;
                let l = if nu == 0.0 {
                    1.0
                } else {
                    (x.sin() / x).powi(2)
                };
                self.response(nu) * l
            })
            .sum::<Complex64>()
    }
}

impl SensorStage for LowPass {
    fn apply(&self, signal: Signal) -> Result<Signal> {
        if self.check().is_err() {
            return Err(Error::Usage(format!("invalid low-pass {self:?}")));
        }
        let w = 2.0 * std::f64::consts::PI * self.natural_frequency_hz;
        let ss = StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * self.damping_ratio * w]),
            b: DMatrix::from_row_slice(2, 1, &[0.0, w * w]),
            drives: Vec::new(),
        };
        let out = OutputMap {
            c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            d: DMatrix::zeros(1, 1),
        };
        let foh = Foh::new(&ss, 1.0 / signal.rate_hz)?;
        let mut y = foh.simulate(&out, &[signal.samples], None, &|_| {})?;
        Ok(Signal {
            samples: y.pop().unwrap_or_default(),
            rate_hz: signal.rate_hz,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn steady_state_gain_and_phase_match_the_transfer_function() {
        let lp = LowPass {
            channels: vec!["acc1".into()],
            quantity: None,
            tests: None,
            natural_frequency_hz: 60.0,
            damping_ratio: 0.6,
        };
        let rate = 5000.0;
        for f in [0.0, 5.0, 40.0, 60.0, 150.0] {
            let n = 20_000;
            let x: Vec<f64> = (0..n)
                .map(|k| (2.0 * PI * f * k as f64 / rate + 0.4).cos())
                .collect();
            let y = lp
                .apply(Signal {
                    samples: x,
                    rate_hz: rate,
                })
                .unwrap()
                .samples;
            // Expected: Re(G e^{j(wt + 0.4)}) with G = P(f) sum_m H(f + m fs) sinc^2((f + m fs) h)
            // for the straight-line input through the pre-emphasised samples, whose gain
            // is P = 1 + sin^2(pi f h) / 3 (the m != 0 terms are ~1e-8 here and fall like
            // 1/m^4). The transient decays like e^{-z w t}: gone (< 1e-30) after 1 s;
            // compare the last 2 s but the last sample (stepped to the raw end sample).
            let h = lp.sampled_response(f, rate, 50);
            for (k, v) in y.iter().enumerate().take(n - 1).skip(10_000) {
                let ph = 2.0 * PI * f * k as f64 / rate + 0.4;
                let expect = (h * Complex64::from_polar(1.0, ph)).re;
                assert!((v - expect).abs() < 1e-11, "{f} Hz, k {k}: {v} vs {expect}");
            }
        }
    }
}
