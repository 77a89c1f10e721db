//! Frequency-point selection by half-power bandwidth around each resonance peak (paper
//! section 3.1: "Half-power bandwidth is recommended ... to choose the frequency points
//! around every peak in the FRF plot").
//!
//! ## Which curve
//! One set of bands per test (one frequency grid = one `FrfBlock`), found on the mean over
//! the test's response channels of `20 log10 |H1|` (the geometric mean magnitude):
//! - it does not depend on channel units or scale, and the `omega^2` between receptance and
//!   accelerance only tilts it, so no channel dominates and none needs normalising;
//! - near an isolated mode every channel is `~ |phi_r phi_e| / |omega_i^2 - omega^2 + j c_i omega|`,
//!   so the mean keeps that shape and its -3 dB points are those of each channel;
//! - a channel near a node of one mode only lowers that peak in the mean, it does not hide it.
//!
//! Only bins inside `range_hz` where the input power is within `min_input_db` (-40 dB) of its
//! maximum and the mean coherence is at least `min_coherence` (0.5) are searched: the
//! shake-table chirp excites 0-10 Hz only, and above it `H` is noise over noise; the hammer
//! records have incoherent high-frequency bumps (76 Hz, 150 Hz, ...) that are as prominent
//! as a weakly excited mode in the mean curve.
//!
//! ## Peaks and bands
//! The `n_peaks` local maxima of largest topographic prominence (height above the higher of
//! the two lowest points separating it from a higher peak or the searched band's end) that
//! are at least `min_prominence_db` (3 dB) prominent and have a mean coherence of at least
//! `min_peak_coherence` (0.9) at the peak are the resonances (fewer if fewer qualify). In
//! the shake-table test of the shared campaign mode 4 (5.72 Hz, little ground participation)
//! is only 4.5 dB prominent in the mean curve, as prominent as a 0.12 Hz drift bump of
//! coherence 0.75: the peak-coherence rule is what separates them. From each, the curve is followed outwards to the first crossing of
//! `peak - 10 log10(2)` dB (linear interpolation in dB between bins): `lo_hz`, `hi_hz`. If
//! the curve rises above the peak again or leaves the searched bins first, the band stops
//! at the lowest point passed and is marked `clipped`. Selected points are the bins in
//! `[f_p - b (f_p - lo), f_p + b (hi - f_p)]` with `b = band_factor` (1 = the half-power
//! band), always including the peak bin.

use crate::error::{Error, Result};
use num_complex::Complex64;

/// Half-power level below the peak, dB.
pub const HALF_POWER_DB: f64 = 3.010_299_956_639_812;

/// One resonance and its half-power band.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Band {
    /// Frequency of the peak bin, Hz.
    pub peak_hz: f64,
    /// Index of the peak bin in the estimate's `freq_hz`.
    pub peak_index: usize,
    /// Lower half-power frequency, Hz.
    pub lo_hz: f64,
    /// Upper half-power frequency, Hz.
    pub hi_hz: f64,
    /// True when a side stopped before reaching -3 dB (neighbouring peak or band edge).
    pub clipped: bool,
}

impl Band {
    /// Half-power bandwidth `hi - lo`, Hz.
    pub fn bandwidth_hz(&self) -> f64 {
        self.hi_hz - self.lo_hz
    }

    /// Half-power damping estimate `xi = (hi - lo) / (2 f_peak)`. From an exponentially
    /// windowed FRF, correct it with [`super::windows::correct_exp_window_damping`].
    pub fn damping_ratio(&self) -> f64 {
        self.bandwidth_hz() / (2.0 * self.peak_hz)
    }
}

/// Options of band selection.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BandOptions {
    /// Number of resonances to find; `None`: as many as the model has modes (the caller
    /// decides; [`super::estimate_campaign`] uses the nominal model's floors).
    pub n_peaks: Option<usize>,
    /// Selected band = `band_factor` times the half-power band around each peak.
    pub band_factor: f64,
    /// Search range, Hz (`None`: the whole grid).
    pub range_hz: Option<(f64, f64)>,
    /// Bins whose input power is more than this many dB below its maximum are not searched.
    pub min_input_db: f64,
    /// Bins where the coherence averaged over the responses is below this are not searched.
    pub min_coherence: f64,
    /// Peaks less prominent than this (dB, on the search curve) are not resonances.
    pub min_prominence_db: f64,
    /// A resonance must be well measured: mean coherence at the peak bin at least this.
    pub min_peak_coherence: f64,
}

impl Default for BandOptions {
    fn default() -> Self {
        BandOptions {
            n_peaks: None,
            band_factor: 1.0,
            range_hz: None,
            min_input_db: -40.0,
            min_coherence: 0.5,
            min_prominence_db: 3.0,
            min_peak_coherence: 0.9,
        }
    }
}

/// Mean over responses of `20 log10 |H|` (see the module docs). Bins where any response is
/// zero (undefined input) get `-inf`.
pub fn peak_curve_db(responses: &[&[Complex64]]) -> Vec<f64> {
    let n = responses.first().map_or(0, |r| r.len());
    (0..n)
        .map(|k| {
            let s: f64 = responses.iter().map(|r| 20.0 * r[k].norm().log10()).sum();
            let v = s / responses.len() as f64;
            if v.is_nan() {
                f64::NEG_INFINITY
            } else {
                v
            }
        })
        .collect()
}

/// Every local maximum among the bins with `valid[k]` whose two grid neighbours are also
/// valid, with its topographic prominence in dB (on the sequence of valid bins), most
/// prominent first.
pub fn peak_prominences(curve_db: &[f64], valid: &[bool]) -> Vec<(usize, f64)> {
    let idx: Vec<usize> = (0..curve_db.len())
        .filter(|&k| valid[k] && curve_db[k].is_finite())
        .collect();
    let v: Vec<f64> = idx.iter().map(|&k| curve_db[k]).collect();
    let n = v.len();
    let mut peaks: Vec<usize> = Vec::new();
    let mut i = 1;
    while i + 1 < n {
        if v[i] > v[i - 1] {
            // plateau: first index with v > v[i] or v < v[i]
            let mut j = i;
            while j + 1 < n && v[j + 1] == v[i] {
                j += 1;
            }
            // a peak needs both grid neighbours searchable (no isolated valid bins)
            let (a, b) = (idx[i], idx[j]);
            let framed = a > 0 && valid[a - 1] && b + 1 < valid.len() && valid[b + 1];
            if j + 1 < n && v[j + 1] < v[i] && framed {
                peaks.push((i + j) / 2);
            }
            i = j + 1;
        } else {
            i += 1;
        }
    }
    let prom = prominences(&v, &peaks);
    let mut cand: Vec<(usize, f64)> = peaks.iter().zip(prom).map(|(&p, pr)| (p, pr)).collect();
    cand.sort_by(|a, b| b.1.total_cmp(&a.1).then(v[b.0].total_cmp(&v[a.0])));
    cand.into_iter().map(|(p, pr)| (idx[p], pr)).collect()
}

/// Indices (ascending) of the `n_peaks` most prominent local maxima among the bins with
/// `valid[k]` whose prominence is at least `min_prominence_db`.
pub fn find_peaks(
    curve_db: &[f64],
    valid: &[bool],
    n_peaks: usize,
    min_prominence_db: f64,
) -> Vec<usize> {
    let mut out: Vec<usize> = peak_prominences(curve_db, valid)
        .into_iter()
        .filter(|&(_, pr)| pr >= min_prominence_db)
        .take(n_peaks)
        .map(|(k, _)| k)
        .collect();
    out.sort_unstable();
    out
}

/// Topographic prominence of each peak `p` of `v`: `v[p]` minus the higher of the minima
/// of `v` between `p` and the nearest strictly higher sample on each side (or the end).
/// O(n log n): nearest higher samples by a monotonic stack, minima by a segment tree.
fn prominences(v: &[f64], peaks: &[usize]) -> Vec<f64> {
    let n = v.len();
    let nearest_higher = |order: &mut dyn Iterator<Item = usize>| {
        let mut out = vec![None; n];
        let mut stack: Vec<usize> = Vec::new();
        for i in order {
            while stack.last().is_some_and(|&t| v[t] <= v[i]) {
                stack.pop();
            }
            out[i] = stack.last().copied();
            stack.push(i);
        }
        out
    };
    let left = nearest_higher(&mut (0..n));
    let right = nearest_higher(&mut (0..n).rev());
    // iterative segment tree of minima
    let mut tree = vec![f64::INFINITY; 2 * n];
    tree[n..].copy_from_slice(v);
    for i in (1..n).rev() {
        tree[i] = tree[2 * i].min(tree[2 * i + 1]);
    }
    let range_min = |lo: usize, hi: usize| {
        // min of v[lo..=hi]
        let (mut l, mut r, mut m) = (lo + n, hi + n + 1, f64::INFINITY);
        while l < r {
            if l & 1 == 1 {
                m = m.min(tree[l]);
                l += 1;
            }
            if r & 1 == 1 {
                r -= 1;
                m = m.min(tree[r]);
            }
            l /= 2;
            r /= 2;
        }
        m
    };
    peaks
        .iter()
        .map(|&p| {
            let lo = left[p].map_or(0, |l| l + 1);
            let hi = right[p].map_or(n - 1, |r| r - 1);
            v[p] - range_min(lo, p).max(range_min(p, hi))
        })
        .collect()
}

/// Half-power band around the peak at bin `peak` (see the module docs).
pub fn half_power_band(curve_db: &[f64], freq_hz: &[f64], valid: &[bool], peak: usize) -> Band {
    let level = curve_db[peak] - HALF_POWER_DB;
    let side = |dir: isize| -> (f64, bool) {
        let mut k = peak;
        let mut lowest = peak;
        loop {
            let next = k as isize + dir;
            if next < 0 || next as usize >= curve_db.len() || !valid[next as usize] {
                return (freq_hz[lowest], true);
            }
            let next = next as usize;
            let (a, b) = (curve_db[k], curve_db[next]);
            if b > curve_db[peak] {
                return (freq_hz[lowest], true);
            }
            if b <= level {
                let t = if a > b { (a - level) / (a - b) } else { 1.0 };
                return (freq_hz[k] + t * (freq_hz[next] - freq_hz[k]), false);
            }
            if b < curve_db[lowest] {
                lowest = next;
            }
            k = next;
        }
    };
    let (lo_hz, lc) = side(-1);
    let (hi_hz, hc) = side(1);
    Band {
        peak_hz: freq_hz[peak],
        peak_index: peak,
        lo_hz,
        hi_hz,
        clipped: lc || hc,
    }
}

/// Indices (ascending, unique) of the bins within `band_factor` times each half-power band.
pub fn select_points(freq_hz: &[f64], bands: &[Band], band_factor: f64) -> Vec<usize> {
    let mut sel = Vec::new();
    for b in bands {
        let lo = b.peak_hz - band_factor * (b.peak_hz - b.lo_hz);
        let hi = b.peak_hz + band_factor * (b.hi_hz - b.peak_hz);
        sel.extend(
            freq_hz
                .iter()
                .enumerate()
                .filter(|(_, &f)| f >= lo && f <= hi)
                .map(|(k, _)| k),
        );
        sel.push(b.peak_index);
    }
    sel.sort_unstable();
    sel.dedup();
    sel
}

/// Finds the bands of a test and the selected points. `input_power[k]` is the input's
/// (block-summed) auto-spectrum, `mean_coherence[k]` the coherence averaged over the
/// responses; `n_peaks` the number of resonances to find.
pub fn select_bands(
    freq_hz: &[f64],
    responses: &[&[Complex64]],
    input_power: &[f64],
    mean_coherence: &[f64],
    opts: &BandOptions,
    n_peaks: usize,
) -> Result<(Vec<Band>, Vec<usize>)> {
    if !(opts.band_factor.is_finite() && opts.band_factor > 0.0) {
        return Err(Error::Usage(format!(
            "band factor must be positive, got {}",
            opts.band_factor
        )));
    }
    if let Some((lo, hi)) = opts.range_hz {
        if lo.is_nan() || hi.is_nan() || lo >= hi {
            return Err(Error::Usage(format!(
                "band search range {lo}..{hi} Hz is empty"
            )));
        }
    }
    if responses.is_empty()
        || input_power.len() != freq_hz.len()
        || mean_coherence.len() != freq_hz.len()
    {
        return Err(Error::Usage(
            "band selection needs responses on the frequency grid".into(),
        ));
    }
    let max_p = input_power.iter().cloned().fold(0.0, f64::max);
    let floor = max_p * 10f64.powf(opts.min_input_db / 10.0);
    let (lo, hi) = opts.range_hz.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let valid: Vec<bool> = freq_hz
        .iter()
        .zip(input_power)
        .zip(mean_coherence)
        .map(|((&f, &p), &g)| {
            f > 0.0 && f >= lo && f <= hi && p >= floor && p > 0.0 && g >= opts.min_coherence
        })
        .collect();
    let curve = peak_curve_db(responses);
    let mut peaks: Vec<usize> = peak_prominences(&curve, &valid)
        .into_iter()
        .filter(|&(k, pr)| {
            pr >= opts.min_prominence_db && mean_coherence[k] >= opts.min_peak_coherence
        })
        .take(n_peaks)
        .map(|(k, _)| k)
        .collect();
    peaks.sort_unstable();
    let bands: Vec<Band> = peaks
        .iter()
        .map(|&p| half_power_band(&curve, freq_hz, &valid, p))
        .collect();
    let sel = select_points(freq_hz, &bands, opts.band_factor);
    Ok((bands, sel))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sdof_db(f: f64, fn_hz: f64, xi: f64) -> f64 {
        let r = f / fn_hz;
        -10.0 * ((1.0 - r * r).powi(2) + (2.0 * xi * r).powi(2)).log10()
    }

    #[test]
    fn prominence_picks_real_peaks_over_ripples() {
        let freq: Vec<f64> = (0..2000).map(|k| k as f64 * 0.005).collect();
        let curve: Vec<f64> = freq
            .iter()
            .enumerate()
            .map(|(k, &f)| {
                let ripple = 0.5 * ((k % 7) as f64 - 3.0).abs();
                sdof_db(f, 2.0, 0.01).max(sdof_db(f, 6.0, 0.02) - 10.0) + ripple
            })
            .collect();
        let valid = vec![true; freq.len()];
        let p = find_peaks(&curve, &valid, 2, 0.0);
        assert_eq!(p.len(), 2);
        assert!(
            (freq[p[0]] - 2.0).abs() < 0.02 && (freq[p[1]] - 6.0).abs() < 0.05,
            "{p:?}"
        );
    }

    #[test]
    fn fast_prominence_matches_naive_scan() {
        let v: Vec<f64> = (0..3000)
            .map(|i| ((i * i) as f64 * 0.0137).sin() * 3.0 + (i as f64 * 0.01).cos() * 5.0)
            .collect();
        let peaks: Vec<usize> = (1..v.len() - 1)
            .filter(|&i| v[i] > v[i - 1] && v[i] > v[i + 1])
            .collect();
        let fast = prominences(&v, &peaks);
        for (&p, &f) in peaks.iter().zip(&fast) {
            let h = v[p];
            let mut lm = h;
            for &x in v[..p].iter().rev() {
                if x > h {
                    break;
                }
                lm = lm.min(x);
            }
            let mut rm = h;
            for &x in &v[p + 1..] {
                if x > h {
                    break;
                }
                rm = rm.min(x);
            }
            assert_eq!(f, h - lm.max(rm), "peak {p}");
        }
    }

    #[test]
    fn band_of_sampled_sdof_and_selection() {
        let df = 0.001;
        let freq: Vec<f64> = (0..5000).map(|k| k as f64 * df).collect();
        let (fnh, xi) = (2.0, 0.01);
        let curve: Vec<f64> = freq.iter().map(|&f| sdof_db(f, fnh, xi)).collect();
        let valid = vec![true; freq.len()];
        let p = find_peaks(&curve, &valid, 1, 0.0)[0];
        let b = half_power_band(&curve, &freq, &valid, p);
        assert!(!b.clipped);
        // exact half-power points of |1/(1 - r^2 + 2 j xi r)|^2: r^2 = 1 - 2 xi^2 +- 2 xi sqrt(1 - xi^2)
        let r_lo = (1.0 - 2.0 * xi * xi - 2.0 * xi * (1.0 - xi * xi).sqrt()).sqrt();
        let r_hi = (1.0 - 2.0 * xi * xi + 2.0 * xi * (1.0 - xi * xi).sqrt()).sqrt();
        // linear interpolation in dB: error << df
        assert!((b.lo_hz - r_lo * fnh).abs() < 0.05 * df, "{}", b.lo_hz);
        assert!((b.hi_hz - r_hi * fnh).abs() < 0.05 * df);
        assert!((b.damping_ratio() - xi).abs() < 1e-4);
        let sel = select_points(&freq, &[b], 1.0);
        assert!((40..=41).contains(&sel.len()), "{}", sel.len());
        assert!((80..=81).contains(&select_points(&freq, &[b], 2.0).len()));
        // band clipped by the search edge
        let mut valid = vec![true; freq.len()];
        valid[..p - 3].iter_mut().for_each(|v| *v = false);
        let b = half_power_band(&curve, &freq, &valid, p);
        assert!(b.clipped && (b.lo_hz - freq[p - 3]).abs() < 1e-12);
    }

    #[test]
    fn select_bands_respects_range_and_input_power() {
        let freq: Vec<f64> = (0..4000).map(|k| k as f64 * 0.005).collect();
        let h: Vec<Complex64> = freq
            .iter()
            .map(|&f| {
                let s = Complex64::new(0.0, f);
                1.0 / (s * s + 0.02 * 3.0 * s + 9.0) + 0.3 / (s * s + 0.02 * 12.0 * s + 144.0)
            })
            .collect();
        let power: Vec<f64> = freq
            .iter()
            .map(|&f| if f < 10.0 { 1.0 } else { 1e-6 })
            .collect();
        let opts = BandOptions::default();
        let coh = vec![1.0; freq.len()];
        let (b, sel) = select_bands(&freq, &[&h], &power, &coh, &opts, 2).unwrap();
        // the 12 rad/s "Hz" resonance is outside the excited band
        assert_eq!(b.len(), 1);
        assert!((b[0].peak_hz - 3.0).abs() < 0.01);
        assert!(!sel.is_empty());
        let opts = BandOptions {
            range_hz: Some((4.0, 9.0)),
            ..BandOptions::default()
        };
        let (b, _) = select_bands(&freq, &[&h], &power, &coh, &opts, 2).unwrap();
        assert!(b.is_empty());
        let bad = BandOptions {
            band_factor: 0.0,
            ..BandOptions::default()
        };
        assert!(select_bands(&freq, &[&h], &power, &coh, &bad, 2).is_err());
        // incoherent bins are not searched either
        let low: Vec<f64> = freq
            .iter()
            .map(|&f| if f < 5.0 { 0.1 } else { 1.0 })
            .collect();
        let (b, _) = select_bands(&freq, &[&h], &power, &low, &BandOptions::default(), 2).unwrap();
        assert!(b.is_empty());
    }
}
