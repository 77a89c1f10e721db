//! How the data of a diagnosis are extracted from a campaign ([`DataOptions`]), and the
//! noise-model choices that go with them ([`GainCarrier`], [`weight_bias`]).

use crate::error::{Error, Result};
use crate::signal::EstimateOptions;
use serde::{Deserialize, Serialize};

/// How the data of a diagnosis are extracted from a campaign.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DataOptions {
    /// FRF estimation (windows, coherence, band search).
    pub estimate: EstimateOptions,
    /// One segment per hammer impact (default true); false averages the impacts of a test.
    pub per_impact: bool,
    /// Dense points within this many half-power half-widths of each peak (default 3).
    pub band_factor: f64,
    /// At most this many points per resonance band (default 30).
    pub max_band_points: usize,
    /// Log-spaced points over the analysed range (default 80).
    pub off_band_points: usize,
    /// Analysed range as multiples of the nominal model's lowest and highest natural
    /// frequencies (default 0.25 and 4).
    pub freq_range_rel: (f64, f64),
    /// A channel keeps a point only where its coherence is at least this (default 0.5).
    pub min_coherence: f64,
    /// Peaks searched beyond the nominal number of modes (extra modes; default 2).
    pub extra_peaks: usize,
    /// Compare the models with `h (1 + v)`, `v = min(2 eps^2, MAX_WEIGHT_BIAS)`, instead
    /// of the measured `h` ([`weight_bias`]; default false).
    pub weight_bias_correction: bool,
    /// What the input-gain error multiplies ([`GainCarrier`]; default each model's own
    /// `H` at its MAP).
    pub gain_carrier: GainCarrier,
    /// Shake-table records: the input channel's noise as one relative error per bin
    /// shared by every channel ([`super::data::InputGainBasis::PerBin`]; default true;
    /// false takes the channels' errors as independent).
    pub common_input_error: bool,
    /// Top of the analysed band, Hz (default none: `freq_range_rel` alone; a model
    /// reduced for the diagnosis then uses 0.4 of the slowest sample rate, the
    /// anti-aliasing pass band, and its modes up to this top).
    pub freq_max_hz: Option<f64>,
}

/// What the correlated input-gain error of a hammer segment multiplies in the
/// likelihood's covariance `D + V V^*`, `V = diag(carrier) U`: the data say
/// `h = H (1 + delta) + noise`, so the exact carrier is the true `H`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GainCarrier {
    /// The measured `h` (a plug-in whose noise is correlated with the residual it
    /// weighs: `h = H (1 + delta)` carries the very gain error `delta` whose variance it
    /// scales, which biases effect sizes and, where `delta` is a few percent, as at a low
    /// sample rate for the pulse, adds a false sensor filter; see the README).
    Measured,
    /// The model's `H(theta)` at every evaluation (exact for that noise model, but
    /// `ln det` then depends on `theta` and rewards a smaller `|H|`).
    Model,
    /// Each model's own `H` at its MAP, fixed while it is sampled, its evidence computed
    /// and its held-out segments scored (the two-stage plug-in of `sample`): free of the
    /// measured noise, and `ln det` does not depend on `theta`. The MAP is refitted once
    /// with it ([`super::fit::refit_at_map`]). The default.
    #[default]
    ModelAtMap,
}

/// Largest relative correction of [`weight_bias`] (its expansion holds for small `eps`).
pub const MAX_WEIGHT_BIAS: f64 = 0.1;

/// The relative bias `v` of a fit whose errors are scaled by the measured `|h|`, for one
/// point of relative error `eps` (`std(Re) = std(Im) = eps |H|`, so `h = H (1 + x)` with
/// `E|x|^2 = 2 eps^2`). The weight `1 / |h|^2` follows the point's own noise: with
/// `E[x] = E[x^2] = 0`, `E[(h - H) / |h|^2] = E[x / |1 + x|^2] / conj(H) = -E|x|^2 /
/// conj(H)` to second order, while `E[h / |h|^2] = E[1 / conj(1 + x)] / conj(H) = 1 /
/// conj(H)`. So comparing a model with `h (1 + v)`, `v = E|x|^2 = 2 eps^2`, removes the
/// bias to that order (what is left is about `2 v^2`); `v` is capped at
/// [`MAX_WEIGHT_BIAS`], where the expansion stops holding (and such points weigh little).
pub fn weight_bias(eps: f64) -> f64 {
    (2.0 * eps * eps).min(MAX_WEIGHT_BIAS)
}

impl Default for DataOptions {
    fn default() -> Self {
        DataOptions {
            estimate: EstimateOptions::default(),
            per_impact: true,
            band_factor: 3.0,
            max_band_points: 30,
            off_band_points: 80,
            freq_range_rel: (0.25, 4.0),
            min_coherence: 0.5,
            extra_peaks: 2,
            weight_bias_correction: false,
            gain_carrier: GainCarrier::ModelAtMap,
            common_input_error: true,
            freq_max_hz: None,
        }
    }
}

impl DataOptions {
    /// Errors unless the range, the band factor and the coherence threshold are usable.
    pub fn check(&self) -> Result<()> {
        let o = self;
        let (lo, hi) = o.freq_range_rel;
        if !(lo > 0.0 && hi > lo && hi.is_finite()) {
            return Err(Error::Usage(format!(
                "freq_range_rel must satisfy 0 < lo < hi, got ({lo}, {hi})"
            )));
        }
        if !(o.band_factor.is_finite() && o.band_factor > 0.0) {
            return Err(Error::Usage(format!(
                "band_factor must be positive, got {}",
                o.band_factor
            )));
        }
        if !(0.0..1.0).contains(&o.min_coherence) {
            return Err(Error::Usage(format!(
                "min_coherence must be in [0, 1), got {}",
                o.min_coherence
            )));
        }
        if let Some(f) = o.freq_max_hz {
            if !(f.is_finite() && f > 0.0) {
                return Err(Error::Usage(format!(
                    "freq_max_hz must be positive, got {f}"
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_checked() {
        let bad = DataOptions {
            freq_range_rel: (2.0, 1.0),
            ..Default::default()
        };
        assert!(bad.check().is_err());
        assert!(DataOptions::default().check().is_ok());
    }
}
