//! FRF estimates of *segments* (a whole test, or one impact of a hammer test) with the
//! per-bin noise the consistency checks need.
//!
//! Noise convention (shared with the rest of `discrepancy`): the estimate's error is
//! complex circular Gaussian with `std(Re H) = std(Im H) = eps |H|`, where
//! `eps = sqrt((1 - gamma^2) / (2 gamma^2 n))` is the Bendat & Piersol normalised random
//! error ([`crate::signal::bendat_piersol_rel_std`]) from the coherence `gamma^2` and the
//! number `n` of averaged blocks. To first order `eps` is then also the standard deviation
//! of `ln |H|` and of `arg H` (rad), and the two are independent.

use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::{Channel, Quantity, Test, TestKind};
use crate::signal::hammer::hammer_spectra;
use crate::signal::noise::local_rational_noise;
use crate::signal::spectra::bin_freq_hz;
use crate::signal::windows::kind_factor_complex;
use crate::signal::{
    bendat_piersol_rel_std, Band, CoherenceMethod, EstimateOptions, InputKind, TestFrf,
};
use num_complex::Complex64;
use rayon::prelude::*;

/// One response channel of a segment.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelEstimate {
    pub channel: Channel,
    /// Receptance (displacement) or accelerance (acceleration; relative to the ground in
    /// shake-table tests, as [`crate::signal`] gives it).
    pub kind: FrfKind,
    /// H1 at every bin of the segment's grid.
    pub h: Vec<Complex64>,
    /// `eps` at every bin (see the module docs); infinite where the coherence is 0.
    pub rel_std: Vec<f64>,
}

/// FRF estimates of one segment on one frequency grid.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentFrf {
    /// Test (folder) name.
    pub test: String,
    /// `test` for a whole test, `test#impactN` (1-based) for one impact.
    pub label: String,
    pub input: InputKind,
    /// Bin frequencies, Hz.
    pub freq_hz: Vec<f64>,
    /// Exponential window time constant (hammer tests): the estimate is `H(omega - j/tau)`.
    pub exp_window_tau_s: Option<f64>,
    /// Peak force of the impact, N (one-impact segments only).
    pub peak_force_n: Option<f64>,
    /// Resonance bands (of the whole test).
    pub bands: Vec<Band>,
    pub channels: Vec<ChannelEstimate>,
}

impl SegmentFrf {
    /// The whole-test estimate, noise from its coherence and number of averages.
    pub fn from_test(est: &TestFrf) -> Self {
        let channels = est
            .responses
            .iter()
            .map(|r| ChannelEstimate {
                channel: r.channel.clone(),
                kind: r.kind,
                h: r.h1.clone(),
                rel_std: r
                    .coherence
                    .iter()
                    .map(|&g| bendat_piersol_rel_std(g, est.n_averages))
                    .collect(),
            })
            .collect();
        SegmentFrf {
            test: est.test.clone(),
            label: est.test.clone(),
            input: est.input.clone(),
            freq_hz: est.freq_hz.clone(),
            exp_window_tau_s: est.exp_window_tau_s,
            peak_force_n: None,
            bands: est.bands.clone(),
            channels,
        }
    }

    /// Whether the segment comes from a shake-table test.
    pub fn is_shake_table(&self) -> bool {
        matches!(self.input, InputKind::Ground { .. })
    }

    /// The channel measuring `quantity` on `floor`, if any.
    pub fn on_floor(&self, quantity: Quantity, floor: usize) -> Option<&ChannelEstimate> {
        self.channels
            .iter()
            .find(|c| c.channel.quantity == quantity && c.channel.floor == floor)
    }

    /// The complex frequency at which the estimate samples the transfer function:
    /// `omega - j / tau` (windowed) or `omega`, rad/s.
    pub fn complex_omega(&self, k: usize) -> Complex64 {
        let omega = 2.0 * std::f64::consts::PI * self.freq_hz[k];
        Complex64::new(omega, -self.exp_window_tau_s.map_or(0.0, |t| 1.0 / t))
    }

    /// `H` of channel `c` at bin `k` divided by its kind factor `(j w)^p` at the sampled
    /// complex frequency `w`: a receptance-like value whose poles are those of the
    /// receptance (exact for the windowed estimate, [`crate::signal::windows`]).
    pub fn receptance_like(&self, c: usize, k: usize) -> Complex64 {
        let ch = &self.channels[c];
        ch.h[k] / kind_factor_complex(ch.kind, self.complex_omega(k))
    }
}

/// One segment per impact of a hammer test, each impact's block estimated alone (H1 of one
/// block, coherence from the local model of [`crate::signal::noise`] with one block, so
/// `n = 1` in the Bendat & Piersol error). `est` is the whole test's estimate (for the
/// bands and grid length); windows, blocks and options are those of
/// [`crate::signal::estimate_test`].
pub fn impact_segments(
    test: &Test,
    est: &TestFrf,
    opts: &EstimateOptions,
) -> Result<Vec<SegmentFrf>> {
    if !matches!(test.kind, TestKind::Hammer { .. }) {
        return Err(Error::Usage(format!(
            "test {}: impacts exist only in hammer tests",
            test.name
        )));
    }
    let fi = test
        .find(Quantity::Force)
        .ok_or_else(|| Error::Usage(format!("hammer test {} has no force channel", test.name)))?;
    let resp_idx = test.response_channels();
    let records: Vec<&[f64]> = resp_idx.iter().map(|&i| test.data[i].as_slice()).collect();
    let pad = opts.zero_pad_factor.max(1);
    // One transform per impact, whatever the default estimator: the impacts are to be
    // compared with each other.
    let mut hammer = opts.hammer;
    hammer.estimator = crate::signal::HammerEstimator::ImpactBlocks;
    let spectra = hammer_spectra(&test.data[fi], &records, test.sample_rate_hz, &hammer, pad)
        .map_err(|e| Error::Usage(format!("test {}: {e}", test.name)))?;
    let n_keep = est.freq_hz.len();
    let freq_hz: Vec<f64> = bin_freq_hz(spectra.n_fft, test.sample_rate_hz)
        .into_iter()
        .take(n_keep)
        .collect();
    let half_width = match opts.coherence {
        CoherenceMethod::LocalRational { half_width_bins } => half_width_bins,
        CoherenceMethod::Ordinary => 4,
    };
    let mut segments = Vec::with_capacity(spectra.force.len());
    for (b, (f_block, impact)) in spectra.force.iter().zip(&spectra.impacts).enumerate() {
        // The channels' local models are independent: one task each, in channel order
        // (the same numbers as one after the other).
        let channels = resp_idx
            .par_iter()
            .enumerate()
            .map(|(r, &ci)| {
                let y_block = &spectra.responses[r][b];
                let (f_one, y_one) = (std::slice::from_ref(f_block), std::slice::from_ref(y_block));
                channel_estimate(&test.channels[ci], f_one, y_one, half_width, pad, n_keep)
            })
            .collect::<Result<Vec<_>>>()?;
        segments.push(SegmentFrf {
            test: test.name.clone(),
            label: format!("{}#impact{}", test.name, b + 1),
            input: est.input.clone(),
            freq_hz: freq_hz.clone(),
            exp_window_tau_s: spectra.tau_s,
            peak_force_n: Some(impact.peak_force_n.abs()),
            bands: est.bands.clone(),
            channels,
        });
    }
    Ok(segments)
}

/// One channel's estimate from one impact's block (`f_one`, `y_one`: that block's force
/// and response spectra, one block each): H1 of the single block (NaN where the force
/// has no power, kept as 0 in `h`) and its Bendat-Piersol relative error from the local
/// rational model's coherence.
fn channel_estimate(
    channel: &Channel,
    f_one: &[Vec<Complex64>],
    y_one: &[Vec<Complex64>],
    half_width: usize,
    pad: usize,
    n_keep: usize,
) -> Result<ChannelEstimate> {
    let h: Vec<Complex64> = y_one[0]
        .iter()
        .zip(&f_one[0])
        .map(|(y, f)| {
            if f.norm_sqr() > 0.0 {
                y / f
            } else {
                Complex64::new(f64::NAN, f64::NAN)
            }
        })
        .collect();
    let h_finite: Vec<Complex64> = h
        .iter()
        .map(|v| {
            if v.is_finite() {
                *v
            } else {
                Complex64::new(0.0, 0.0)
            }
        })
        .collect();
    let noise = local_rational_noise(f_one, y_one, &h_finite, half_width, pad, None)?;
    let kind = match channel.quantity {
        Quantity::Acceleration => FrfKind::Accelerance,
        _ => FrfKind::Receptance,
    };
    Ok(ChannelEstimate {
        channel: channel.clone(),
        kind,
        rel_std: noise
            .coherence
            .iter()
            .zip(&h)
            .take(n_keep)
            .map(|(&g, v)| {
                if v.is_finite() {
                    bendat_piersol_rel_std(g, 1)
                } else {
                    f64::INFINITY
                }
            })
            .collect(),
        h: h_finite.into_iter().take(n_keep).collect(),
    })
}

/// Bins used around band `i` of `bands` on the grid `freq_hz`: the peak +- `half_widths`
/// half-power bandwidths (at least +- 4 bins), never past half-way to a neighbouring
/// band's peak. Returns the bin index range (may be empty on a degenerate grid).
pub fn band_window(
    freq_hz: &[f64],
    bands: &[Band],
    i: usize,
    half_widths: f64,
) -> std::ops::Range<usize> {
    if freq_hz.len() < 2 || i >= bands.len() {
        return 0..0;
    }
    let df = freq_hz[1] - freq_hz[0];
    let b = &bands[i];
    let half = (half_widths * b.bandwidth_hz()).max(4.0 * df);
    let mut lo = b.peak_hz - half;
    let mut hi = b.peak_hz + half;
    if i > 0 {
        lo = lo.max(0.5 * (bands[i - 1].peak_hz + b.peak_hz));
    }
    if i + 1 < bands.len() {
        hi = hi.min(0.5 * (bands[i + 1].peak_hz + b.peak_hz));
    }
    let start = freq_hz.partition_point(|&f| f < lo);
    let end = freq_hz.partition_point(|&f| f <= hi);
    start..end.max(start)
}
