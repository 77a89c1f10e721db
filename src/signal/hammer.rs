//! Impact (hammer) tests: find the impacts, window, transform: either the whole record
//! from the first impact on (default, [`HammerEstimator::WholeRecord`]) or one block per
//! impact ([`HammerEstimator::ImpactBlocks`]).
//!
//! ## Impact detection
//! The force channel's noise floor is `sigma = 1.4826 MAD` (median absolute deviation
//! about the median, the median being the sensor offset). Samples with
//! `|f - median| > max(threshold_mad sigma, 1e-3 max|f - median|)` are candidates; a new
//! impact starts at a candidate at least `min_separation_s` after the previous impact's
//! trigger (later candidates within that time, e.g. a double hit, belong to the same
//! impact). Impacts whose peak is below `min_peak_fraction` of the largest peak are
//! discarded (their force is then zeroed by the force window, as noise).
//!
//! ## Whole record (default)
//! One transform from `pretrigger_s` before the first impact (`t0`) to the end of the
//! record, one exponential window `w(t) = exp(-(t - t0)/tau)` on force and responses, and
//! the force window around every impact (including those below `min_peak_fraction`: the
//! structure responds to them too). The system is at rest before `t0`, so the windowed
//! response is exactly the windowed impulse response convolved with the windowed force,
//! `Y_w(omega) = H(omega - j/tau) F_w(omega)`, whatever the number of impacts: H1 is the
//! windowed analytic FRF with no leakage between impacts. What is left is the response
//! cut off by the record's end, estimated from the record and put back
//! ([`super::tail`], `tail_correction`). Noise-free simulated campaign
//! (`tests/signal_simulated.rs`, two impacts 60 s apart): worst error 0.11 % at 0.3-10 Hz
//! with the default window (0.002 % with `tau = 20 s`), against 13 % for impact blocks.
//! `n_averages` is 1; the coherence comes from the local models ([`super::noise`]).
//!
//! Trade-off: the window weights the second impact by `exp(-60 s / tau)` (0.21 by default,
//! 0.05 for `tau = 20 s`), so the estimate rests mostly on the first impact: on the noisy
//! simulated campaign (`compare_hammer_estimators`, 2 seeds) the rms error of `|H1|` at the
//! selected points is 1.10 % (0.90 % for `tau = 20 s`) against 0.64 % for impact blocks,
//! but it is unbiased and its predicted error is calibrated (mean `z^2` 1.02 against 1.14).
//! Impacts of equal weight are not possible in one transform (the input spectrum of two
//! equal impacts `Delta` apart has nulls every `1 / Delta` Hz).
//!
//! ## Blocks
//! Block `b` runs from `pretrigger_s` before impact `b` to the start of block `b + 1` (or
//! the end of the record). All blocks are cut to the shortest length `T` (so they share one
//! frequency grid); a last block shorter than half of the longest is dropped instead.
//! With impacts 60 s apart and modes of 1-2 % damping at 0.9 Hz (`1/(xi omega)` ~ 10-18 s),
//! long blocks matter: the untreated truncation error of a mode is `exp(-xi omega T)`
//! relative (4 % for 1 % at 0.9 Hz over 58 s).
//!
//! ## Windows
//! Force: [`super::windows::force_window`] over the pulse (first to last candidate sample)
//! plus `force_margin_s` each side, with `force_taper_s` cosine tapers; the hammer pulses
//! of the four-story campaign ring (anti-alias filter) for about 20 ms on either side.
//! Both force and responses then take the exponential window from the transform start (see
//! [`super::windows`] for its exact effect, `H_w(omega) = H(omega - j/tau)`).
//!
//! ## Filter ringing
//! A linear-phase anti-alias (decimation) filter spreads an impact shorter than a sample
//! over tens of samples on both sides, and the structure responds to all of it. A
//! transform that starts inside the pre-ringing leaves out force whose response it keeps:
//! the response to the missing force is a free decay, an error nearly constant in
//! frequency, so it swamps `|H1|` where the accelerance is small. A pretrigger in seconds
//! hides this at high output rates (at 500 Hz, 0.1 s is 50 samples) and not at low ones,
//! so it has a floor in samples, [`HammerOptions::min_pretrigger_samples`] (32: the
//! half-length of a filter with 100 dB stop band from the Nyquist frequency and pass band
//! to 0.8 of it, the simulator's design; records at 320 Hz and above keep their 0.1 s).
//! With noise-free force the detector's threshold falls to 1e-3 of the peak and the
//! trigger comes early in the pre-ringing, which is why noise-free checks never saw it. Measured on the simulated
//! bridge campaign (60 Hz output, force noise only; `tests/bridge_frf.rs`): with 0.1 s
//! (6 samples) `|H1|` was 3.5-9 times the analytic accelerance at 0.45-0.6 Hz, where the
//! band selection then found resonances. The check of `tests/simulate_general.rs` (50 Hz,
//! force noise only): worst 201 sd of the force noise's own predicted error with 0.1 s,
//! 50 sd with 16 samples, 3.4 sd with 32.
//!
//! The force window cuts the same ringing after (and before) the pulse wherever it falls
//! below the detector's threshold (10 force-noise sd): with 0.03 s + 0.02 s at 60 Hz the
//! window reached 3 samples beyond the pulse, and the filter's response to a 10 ms pulse
//! still holds 1 % of its energy beyond 3 samples of the peak and changes the force
//! spectrum by 3-4 % (0.2 % at 16 samples, 1.6e-4 at 25). One record's worst bin hides
//! this bias; the mean over noise seeds shows it (`tests/simulate_general.rs`, 50 Hz: a
//! standardised mean-error statistic of 5.9 where 1 is unbiased). So margin plus taper
//! has a floor in samples too, [`HammerOptions::min_force_window_samples`] (25, met
//! by the defaults in seconds at 500 Hz and above; statistic 1.2), paid for with more
//! force noise, which the noise model counts.
//!
//! Trade-off of the exponential window, for a block of `T` s with end level `e`
//! (`tau = T / ln(1/e)`): it adds `Delta xi_i = 1/(tau omega_i)` of apparent damping and
//! suppresses truncation leakage to `e exp(-xi omega T)` and late-block noise. For
//! `T = 58 s`, `e = 0.05` (the default): `tau = 19.4 s`, `Delta xi = 0.9 %` at 0.9 Hz and
//! 0.14 % at 5.7 Hz; leakage `<= 0.2 %` even for 1 % damping at 0.9 Hz. The added damping is
//! exactly known, so model updating either corrects damping or windows the model.
//!
//! ## Accuracy (exactly simulated frame, `tests/signal_hammer.rs`)
//! Noise-free, one impact, strong window: H1 equals the exact discrete-time FRF at
//! `omega - j/tau` to 1e-6 of its peak (the cut tail), and the continuous `H(omega - j/tau)`
//! to the sampling term `(omega dt)^2 / 12`. Two impacts 60 s apart with damping 1, 0.5, 0.5,
//! 0.2 %, default options: worst `|H1|` error in the half-power bands 0.39, 0.31, 0.36,
//! 0.93 % for modes 1-4, all explained by the first impact's ring-down left in block 2
//! (`exp(-xi_j omega_j 60 s)` of mode j's pole terms, halved by the average) and the tail
//! cut at `T`. Half-power damping corrected for the window: 1.01, 0.52, 0.50, 0.26 %.
//! Force-channel noise of `L sigma^2 = |F|^2` biases H1 to 0.48 without the force window
//! and to 0.99 with it; H2 stays at 1.00 either way.

use super::spectra::Fft;
use super::tail::{add_truncated_tail, band_mask, PASSES};
use super::windows::{exponential_window, force_window, ExpWindow};
use crate::error::{Error, Result};
use num_complex::Complex64;

/// Options of impact detection and impact blocks.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HammerOptions {
    /// Detection threshold in units of the force noise `1.4826 MAD`.
    pub threshold_mad: f64,
    /// Impacts whose peak is below this fraction of the largest peak are ignored.
    pub min_peak_fraction: f64,
    /// Minimum time between two impacts, s.
    pub min_separation_s: f64,
    /// Block start before the impact trigger, s (must exceed margin + taper); at least
    /// [`Self::min_pretrigger_samples`] samples.
    pub pretrigger_s: f64,
    /// Apply the force window (false: the force channel is used over the whole block,
    /// noise included; for comparison).
    pub force_window: bool,
    /// Flat part of the force window beyond the pulse, each side, s.
    pub force_margin_s: f64,
    /// Cosine taper of the force window, each side, s.
    pub force_taper_s: f64,
    /// Exponential window on force and responses.
    pub exp_window: ExpWindow,
    /// Upper limit on the block length, s (`None`: up to the next impact, or the end of
    /// the record for [`HammerEstimator::WholeRecord`]).
    pub max_block_s: Option<f64>,
    /// Least pretrigger, samples: the anti-alias filter's ringing before an impact (see
    /// the module docs, "Filter ringing").
    #[serde(default = "default_min_pretrigger_samples")]
    pub min_pretrigger_samples: usize,
    /// Least half-width of the force window beyond the pulse (margin plus taper),
    /// samples: the anti-alias filter's ringing after and before an impact (see the
    /// module docs, "Filter ringing"). The margin grows to meet it; the taper keeps its
    /// seconds.
    #[serde(default = "default_min_force_window_samples")]
    pub min_force_window_samples: usize,
    /// Whole-record transient or one block per impact.
    #[serde(default)]
    pub estimator: HammerEstimator,
    /// Whole record: estimate the response cut off at the end of the record and put it
    /// back ([`super::tail`]).
    #[serde(default = "yes")]
    pub tail_correction: bool,
}

fn yes() -> bool {
    true
}

fn default_min_pretrigger_samples() -> usize {
    MIN_PRETRIGGER_SAMPLES
}

fn default_min_force_window_samples() -> usize {
    MIN_FORCE_WINDOW_SAMPLES
}

/// Default of [`HammerOptions::min_pretrigger_samples`]: the half-length of a linear-phase
/// anti-alias filter with 100 dB stop band from the Nyquist frequency and pass band to 0.8
/// of it (the simulator's Kaiser design, `(A - 7.95) / (4.57 pi (1 - p))` output samples).
pub const MIN_PRETRIGGER_SAMPLES: usize = 32;

/// Default of [`HammerOptions::min_force_window_samples`]: where the same filter's
/// response to a pulse shorter than a sample has fallen to 2e-4 of its peak (the force
/// spectrum it leaves out is 1.6e-4 of the peak spectrum; see the module docs). The
/// defaults in seconds give exactly this at 500 Hz (15 + 10 samples).
pub const MIN_FORCE_WINDOW_SAMPLES: usize = 25;

impl HammerOptions {
    /// Samples from a transform's start to the impact trigger:
    /// `max(pretrigger_s fs, min_pretrigger_samples)`.
    pub fn pretrigger_samples(&self, sample_rate_hz: f64) -> usize {
        ((self.pretrigger_s * sample_rate_hz).round() as usize).max(self.min_pretrigger_samples)
    }

    /// Flat part and cosine taper of the force window beyond the pulse, samples:
    /// `taper = round(force_taper_s fs)`, `margin = max(round(force_margin_s fs),
    /// min_force_window_samples - taper)`.
    pub fn force_window_samples(&self, sample_rate_hz: f64) -> (usize, usize) {
        let taper = (self.force_taper_s * sample_rate_hz).round() as usize;
        let margin = ((self.force_margin_s * sample_rate_hz).round() as usize)
            .max(self.min_force_window_samples.saturating_sub(taper));
        (margin, taper)
    }

    /// Samples the force window reaches beyond the pulse on either side (margin plus
    /// taper, [`Self::force_window_samples`]).
    pub fn force_guard_samples(&self, sample_rate_hz: f64) -> usize {
        let (margin, taper) = self.force_window_samples(sample_rate_hz);
        margin + taper
    }
}

/// How the impacts of a hammer test are turned into spectra (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HammerEstimator {
    /// One transform from the first impact to the end of the record, one exponential
    /// window for force and responses, a force window around every impact.
    #[default]
    WholeRecord,
    /// One block per impact, H1 / H2 averaged over the blocks.
    ImpactBlocks,
}

impl Default for HammerOptions {
    fn default() -> Self {
        HammerOptions {
            threshold_mad: 10.0,
            min_peak_fraction: 0.1,
            min_separation_s: 1.0,
            pretrigger_s: 0.1,
            force_window: true,
            force_margin_s: 0.03,
            force_taper_s: 0.02,
            exp_window: ExpWindow::EndLevel(0.05),
            max_block_s: None,
            min_pretrigger_samples: MIN_PRETRIGGER_SAMPLES,
            min_force_window_samples: MIN_FORCE_WINDOW_SAMPLES,
            estimator: HammerEstimator::default(),
            tail_correction: true,
        }
    }
}

/// One detected impact (sample indices into the record).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Impact {
    /// First sample above the threshold.
    pub trigger: usize,
    /// Last sample above the threshold within the impact.
    pub pulse_end: usize,
    /// Sample of the largest `|f - median|`.
    pub peak: usize,
    /// Force at the peak, offset removed, N.
    pub peak_force_n: f64,
}

/// Median of a slice (NaN-free input); 0 for an empty slice.
pub(crate) fn median(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v = x.to_vec();
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    let m = *m;
    if v.len() % 2 == 1 {
        m
    } else {
        let lower = v[..mid].iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + m)
    }
}

/// Finds the impacts in a force record (see the module docs). Returns them in time order;
/// empty when nothing exceeds the threshold.
pub fn detect_impacts(force: &[f64], sample_rate_hz: f64, opts: &HammerOptions) -> Vec<Impact> {
    let mut impacts = detect_all_impacts(force, sample_rate_hz, opts);
    let largest = impacts
        .iter()
        .map(|p| p.peak_force_n.abs())
        .fold(0.0, f64::max);
    impacts.retain(|p| p.peak_force_n.abs() >= opts.min_peak_fraction * largest);
    impacts
}

/// Like [`detect_impacts`] but keeps the impacts below `min_peak_fraction` of the largest.
pub fn detect_all_impacts(force: &[f64], sample_rate_hz: f64, opts: &HammerOptions) -> Vec<Impact> {
    let base = median(force);
    let dev: Vec<f64> = force.iter().map(|&f| (f - base).abs()).collect();
    let sigma = force_noise_std(force);
    let max_dev = dev.iter().cloned().fold(0.0, f64::max);
    if max_dev <= 0.0 {
        return Vec::new();
    }
    let threshold = (opts.threshold_mad * sigma).max(1e-3 * max_dev);
    let min_sep = (opts.min_separation_s * sample_rate_hz).round().max(1.0) as usize;
    let mut impacts: Vec<Impact> = Vec::new();
    for (i, &d) in dev.iter().enumerate() {
        if d <= threshold {
            continue;
        }
        match impacts.last_mut() {
            Some(last) if i < last.trigger + min_sep => {
                last.pulse_end = i;
                if d > last.peak_force_n.abs() {
                    last.peak = i;
                    last.peak_force_n = force[i] - base;
                }
            }
            _ => impacts.push(Impact {
                trigger: i,
                pulse_end: i,
                peak: i,
                peak_force_n: force[i] - base,
            }),
        }
    }
    impacts
}

/// Noise standard deviation of a force record, `1.4826 MAD` about the median (the impacts
/// are a small fraction of the samples and do not move it).
pub fn force_noise_std(force: &[f64]) -> f64 {
    let base = median(force);
    let dev: Vec<f64> = force.iter().map(|&f| (f - base).abs()).collect();
    1.4826 * median(&dev)
}

/// Sensor offset of a response record: the mean of the `quiet` samples before the first
/// block when there are at least 64 of them, else 0. (The record mean would be wrong: an
/// impact response has a genuine mean `H(0) * impulse / T`, and once multiplied by the
/// exponential window a subtracted constant leaks into every bin.)
pub fn response_offset(r: &[f64], quiet: usize) -> f64 {
    if quiet >= 64 {
        r[..quiet].iter().sum::<f64>() / quiet as f64
    } else {
        0.0
    }
}

/// Impact blocks of a record: one start per used impact and a common length.
#[derive(Debug, Clone, PartialEq)]
pub struct ImpactBlocks {
    /// The impacts used, one per block.
    pub impacts: Vec<Impact>,
    /// First sample of each block.
    pub starts: Vec<usize>,
    /// Common block length, samples.
    pub len: usize,
}

/// Cuts one block per impact (see the module docs).
pub fn impact_blocks(
    impacts: &[Impact],
    n_samples: usize,
    sample_rate_hz: f64,
    opts: &HammerOptions,
) -> Result<ImpactBlocks> {
    if impacts.is_empty() {
        return Err(Error::Usage("no impacts to cut blocks from".into()));
    }
    let pre = opts.pretrigger_samples(sample_rate_hz);
    let mut starts: Vec<usize> = impacts
        .iter()
        .map(|p| p.trigger.saturating_sub(pre))
        .collect();
    let mut ends: Vec<usize> = starts[1..].to_vec();
    ends.push(n_samples);
    let mut used: Vec<Impact> = impacts.to_vec();
    let longest = starts
        .iter()
        .zip(&ends)
        .map(|(s, e)| e - s)
        .max()
        .unwrap_or(0);
    if used.len() > 1 && 2 * (n_samples - starts[used.len() - 1]) < longest {
        used.pop();
        starts.pop();
        ends.pop();
    }
    let mut len = starts
        .iter()
        .zip(&ends)
        .map(|(s, e)| e - s)
        .min()
        .unwrap_or(0);
    if let Some(max_s) = opts.max_block_s {
        len = len.min((max_s * sample_rate_hz).round() as usize);
    }
    let margin = opts.force_guard_samples(sample_rate_hz);
    for (p, &s) in used.iter().zip(&starts) {
        if p.pulse_end + margin >= s + len || len < 16 {
            return Err(Error::Usage(format!(
                "impact at sample {} does not fit in a block of {len} samples",
                p.trigger
            )));
        }
    }
    Ok(ImpactBlocks {
        impacts: used,
        starts,
        len,
    })
}

/// Whole-record transient of a hammer test: one transform from `pretrigger_s` before the
/// first impact to the end of the record (see the module docs).
pub fn whole_record(
    impacts: &[Impact],
    n_samples: usize,
    sample_rate_hz: f64,
    opts: &HammerOptions,
) -> Result<(usize, usize)> {
    let first = impacts
        .first()
        .ok_or_else(|| Error::Usage("no impacts to transform".into()))?;
    let pre = opts.pretrigger_samples(sample_rate_hz);
    let start = first.trigger.saturating_sub(pre);
    let mut len = n_samples - start;
    if let Some(max_s) = opts.max_block_s {
        len = len.min((max_s * sample_rate_hz).round() as usize);
    }
    let margin = opts.force_guard_samples(sample_rate_hz);
    if len < 16 || first.pulse_end + margin >= start + len {
        return Err(Error::Usage(format!(
            "impact at sample {} does not fit in a record of {len} samples",
            first.trigger
        )));
    }
    Ok((start, len))
}

/// Windowed spectra of a hammer test, one entry per transform (one per impact block, or
/// a single one for the whole record).
#[derive(Debug, Clone)]
pub struct HammerSpectra {
    /// Which estimator produced them.
    pub estimator: HammerEstimator,
    /// The impacts whose force is used (inside the force windows).
    pub impacts: Vec<Impact>,
    /// First sample of each transform.
    pub starts: Vec<usize>,
    /// Common transform length, samples (before padding).
    pub len: usize,
    /// Force spectra per transform.
    pub force: Vec<Vec<Complex64>>,
    /// Per transform, the per-bin power of the force noise inside the force window:
    /// `sigma_f^2 sum_n w_n^2` (`sigma_f` = [`force_noise_std`], `w` the force window times
    /// the exponential window); 0 without force window (the noise is then spread over
    /// the block and the local model sees it). See
    /// [`super::noise::add_smooth_input_noise`].
    pub force_noise_power: Vec<f64>,
    /// Per transform, the force noise inside the force window sample by sample:
    /// `(n, sigma_f w_n)` for every sample `n` of the transform with `w_n != 0` (empty
    /// without force window). See [`super::input_noise`].
    pub force_noise_weights: Vec<Vec<(usize, f64)>>,
    /// Response spectra per response (in the order given), then per transform.
    pub responses: Vec<Vec<Vec<Complex64>>>,
    /// Exponential window time constant used, s.
    pub tau_s: Option<f64>,
    pub n_fft: usize,
}

/// The union of the force windows of `pulses` over samples `[s, s + len)`.
fn pulse_windows(pulses: &[Impact], s: usize, len: usize, margin: usize, taper: usize) -> Vec<f64> {
    let mut w = vec![0.0; len];
    for p in pulses {
        let lo = p.trigger.saturating_sub(margin).max(s) - s;
        let hi = (p.pulse_end + margin).saturating_sub(s).min(len - 1);
        for (a, b) in w.iter_mut().zip(force_window(len, lo, hi, taper)) {
            *a = f64::max(*a, b);
        }
    }
    w
}

/// The force as [`hammer_spectra`] sees it, over the whole record: the median removed
/// and, with `opts.force_window`, zero outside the force windows of every impact found
/// ([`detect_all_impacts`]). The estimator attributes the responses to this force, so
/// it is the input of a model replay of the test (the force noise outside the windows
/// is not what drove the structure).
pub fn windowed_force(force: &[f64], sample_rate_hz: f64, opts: &HammerOptions) -> Vec<f64> {
    let base = median(force);
    if !opts.force_window || force.is_empty() {
        return force.iter().map(|f| f - base).collect();
    }
    let pulses = detect_all_impacts(force, sample_rate_hz, opts);
    let (margin, taper) = opts.force_window_samples(sample_rate_hz);
    let w = pulse_windows(&pulses, 0, force.len(), margin, taper);
    force.iter().zip(&w).map(|(f, w)| (f - base) * w).collect()
}

/// Detects impacts and returns the windowed spectra of the force and of each response
/// record (`responses[i]`; force offset = its median, response offsets by
/// [`response_offset`]) for the estimator of `opts.estimator`. `pad` is the zero-padding
/// factor (`n_fft = pad * transform length`).
pub fn hammer_spectra(
    force: &[f64],
    responses: &[&[f64]],
    sample_rate_hz: f64,
    opts: &HammerOptions,
    pad: usize,
) -> Result<HammerSpectra> {
    let n = force.len();
    if responses.iter().any(|r| r.len() != n) {
        return Err(Error::Usage(
            "force and response records differ in length".into(),
        ));
    }
    let detected = detect_impacts(force, sample_rate_hz, opts);
    if detected.is_empty() {
        return Err(Error::Usage(format!(
            "no impact found in the force channel (threshold {} x MAD noise)",
            opts.threshold_mad
        )));
    }
    // per transform: its start and the impacts inside its force window
    let (starts, len, windowed): (Vec<usize>, usize, Vec<Vec<Impact>>) = match opts.estimator {
        HammerEstimator::ImpactBlocks => {
            let b = impact_blocks(&detected, n, sample_rate_hz, opts)?;
            let windowed = b.impacts.iter().map(|&p| vec![p]).collect();
            (b.starts, b.len, windowed)
        }
        HammerEstimator::WholeRecord => {
            let all = detect_all_impacts(force, sample_rate_hz, opts);
            let (start, len) = whole_record(&all, n, sample_rate_hz, opts)?;
            let inside: Vec<Impact> = all
                .into_iter()
                .filter(|p| p.trigger < start + len)
                .collect();
            (vec![start], len, vec![inside])
        }
    };
    let dt = 1.0 / sample_rate_hz;
    let tau_s = opts.exp_window.tau_s(len as f64 * dt)?;
    let expw = tau_s.map(|tau| exponential_window(len, dt, tau));
    let n_fft = len * pad.max(1);
    let base = median(force);
    let (margin, taper) = opts.force_window_samples(sample_rate_hz);
    let mut fft = Fft::new();
    let mut force_w = Vec::with_capacity(starts.len());
    let mut force_noise_power = Vec::with_capacity(starts.len());
    let mut force_noise_weights = Vec::with_capacity(starts.len());
    let noise_var = force_noise_std(force).powi(2);
    let mut force_spectra = Vec::with_capacity(starts.len());
    for (pulses, &s) in windowed.iter().zip(&starts) {
        let mut w = if opts.force_window {
            pulse_windows(pulses, s, len, margin, taper)
        } else {
            vec![1.0; len]
        };
        if let Some(e) = &expw {
            w.iter_mut().zip(e).for_each(|(a, b)| *a *= b);
        }
        let fw: Vec<f64> = force[s..s + len]
            .iter()
            .zip(&w)
            .map(|(&f, &w)| (f - base) * w)
            .collect();
        force_noise_power.push(if opts.force_window {
            noise_var * w.iter().map(|v| v * v).sum::<f64>()
        } else {
            0.0
        });
        let sigma_f = noise_var.sqrt();
        force_noise_weights.push(if opts.force_window && sigma_f > 0.0 {
            w.iter()
                .enumerate()
                .filter(|(_, &v)| v != 0.0)
                .map(|(n, &v)| (n, sigma_f * v))
                .collect()
        } else {
            Vec::new()
        });
        force_spectra.push(fft.forward(&fw, None, n_fft)?);
        force_w.push(fw);
    }
    // whole record: lags of the impulse response kept by the tail estimate (the end of
    // the first impact's force window onwards is the estimate's own tail error)
    let tail =
        (opts.estimator == HammerEstimator::WholeRecord && opts.tail_correction).then(|| {
            let first_end = windowed[0][0].pulse_end + margin + taper + 1 - starts[0];
            (len.saturating_sub(first_end), band_mask(&force_spectra[0]))
        });
    let quiet = starts[0];
    use rayon::prelude::*;
    let response_spectra = responses
        .par_iter()
        .map(|r| {
            let mean = response_offset(r, quiet);
            let mut fft = Fft::new();
            starts
                .iter()
                .zip(&force_w)
                .zip(&force_spectra)
                .map(|((&s, fw), fs)| {
                    let seg: Vec<f64> = r[s..s + len].iter().map(|&v| v - mean).collect();
                    let y = fft.forward(&seg, expw.as_deref(), n_fft)?;
                    match &tail {
                        Some((max_lag, mask)) => {
                            add_truncated_tail(fw, fs, &y, n_fft, *max_lag, mask, PASSES, &mut fft)
                        }
                        None => Ok(y),
                    }
                })
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(HammerSpectra {
        estimator: opts.estimator,
        impacts: windowed.into_iter().flatten().collect(),
        starts,
        len,
        force: force_spectra,
        force_noise_power,
        force_noise_weights,
        responses: response_spectra,
        tau_s,
        n_fft,
    })
}

#[cfg(test)]
#[path = "hammer_tests.rs"]
mod tests;
