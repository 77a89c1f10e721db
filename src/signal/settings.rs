//! FRF estimation settings as they are written in configuration files, and the
//! [`EstimateOptions`] they stand for.

use super::{EstimateOptions, ExpWindow, HammerEstimator};
use crate::io::Quantity;
use serde::{Deserialize, Serialize};

/// FRF estimation settings as written in a TOML file: the `[estimate]` section of an
/// experiment file and of a sampling run's `settings.toml`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimateSection {
    /// How hammer tests become spectra: `whole_record` (one transform from the first
    /// impact, a force window around every impact; the default) or `impact_blocks` (one
    /// block per impact, averaged).
    pub hammer_estimator: HammerEstimator,
    /// Time constant of the exponential window on hammer records, s; `None`: no window.
    /// One common value keeps the added damping the same for every hammer test, so it can
    /// be removed from the updated damping exactly (see [`crate::signal::windows`]).
    pub exp_window_tau_s: Option<f64>,
    /// Half-power band factor of the frequency-point selection (paper section 3.1).
    pub band_factor: f64,
    /// Upper frequency of the estimates, Hz.
    pub freq_max_hz: Option<f64>,
    /// Least hammer pretrigger, samples ([`super::HammerOptions::min_pretrigger_samples`]:
    /// at least the half-length of the recorder's anti-alias filter).
    pub min_pretrigger_samples: usize,
    /// Least half-width of the hammer force window beyond the pulse, samples
    /// ([`super::HammerOptions::min_force_window_samples`]: the same filter's ringing).
    pub min_force_window_samples: usize,
    /// Transducer filters to take out of the estimates (e.g. the low-pass `frfbayes
    /// diagnose` identified in a campaign's accelerometers); none by default.
    pub sensor_low_pass: Vec<SensorLowPass>,
}

/// A second-order low-pass `w^2 / (s^2 + 2 zeta w s + w^2)` in every channel of one
/// quantity (the `sensor_dynamics` hypothesis of `diagnose`), divided out of the FRF
/// estimates of those channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorLowPass {
    pub quantity: Quantity,
    pub freq_hz: f64,
    pub damping_ratio: f64,
}

impl Default for EstimateSection {
    fn default() -> Self {
        EstimateSection {
            hammer_estimator: HammerEstimator::default(),
            exp_window_tau_s: Some(20.0),
            band_factor: 1.0,
            freq_max_hz: Some(25.0),
            min_pretrigger_samples: super::MIN_PRETRIGGER_SAMPLES,
            min_force_window_samples: super::MIN_FORCE_WINDOW_SAMPLES,
            sensor_low_pass: Vec::new(),
        }
    }
}

impl EstimateSection {
    /// The estimator options these settings stand for.
    pub fn options(&self) -> EstimateOptions {
        let mut o = EstimateOptions::default();
        o.hammer.estimator = self.hammer_estimator;
        o.hammer.exp_window = match self.exp_window_tau_s {
            Some(t) => ExpWindow::TauS(t),
            None => ExpWindow::None,
        };
        o.bands.band_factor = self.band_factor;
        o.freq_max_hz = self.freq_max_hz;
        o.hammer.min_pretrigger_samples = self.min_pretrigger_samples;
        o.hammer.min_force_window_samples = self.min_force_window_samples;
        o
    }
}
