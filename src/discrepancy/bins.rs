//! The frequencies of a diagnosis.
//!
//! Per group of segments sharing a grid (all hammer blocks; each shake-table test): all
//! bins within `band_factor` half-power half-widths of every resonance found in any
//! segment of the group (at most `max_band_points` per band), plus `off_band_points`
//! log-spaced bins, all within `freq_range_rel` times the nominal model's lowest and
//! highest natural frequencies and where every segment's input is within
//! `min_input_db` of its maximum. A channel keeps a point only where its coherence is at
//! least `min_coherence` (below it H1 is noise-dominated and its error model poor).

use super::data::DataOptions;
use crate::signal::{Band, TestFrf};

/// Valid bins of one estimate: inside `range` and with input within `min_input_db`.
fn valid_bins(frf: &TestFrf, range: (f64, f64), min_input_db: f64) -> Vec<bool> {
    let max_p = frf.input_power.iter().cloned().fold(0.0, f64::max);
    let floor = max_p * 10f64.powf(min_input_db / 10.0);
    frf.freq_hz
        .iter()
        .zip(&frf.input_power)
        .map(|(&f, &p)| f >= range.0 && f <= range.1 && p >= floor && p > 0.0)
        .collect()
}

/// Frequencies (Hz) `[lo, hi]` of `band` widened to `factor` half-power half-widths.
pub(super) fn band_span(band: &Band, factor: f64) -> (f64, f64) {
    (
        band.peak_hz - factor * (band.peak_hz - band.lo_hz),
        band.peak_hz + factor * (band.hi_hz - band.peak_hz),
    )
}

/// The selected bins of a group of estimates on one grid (see the module docs).
pub(super) fn select_bins(frfs: &[&TestFrf], range: (f64, f64), o: &DataOptions) -> Vec<usize> {
    let freq = &frfs[0].freq_hz;
    let n = freq.len();
    let mut valid = vec![true; n];
    for f in frfs {
        for (v, ok) in valid
            .iter_mut()
            .zip(valid_bins(f, range, o.estimate.bands.min_input_db))
        {
            *v &= ok;
        }
    }
    let mut sel: Vec<usize> = Vec::new();
    for f in frfs {
        for b in &f.bands {
            let (lo, hi) = band_span(b, o.band_factor);
            let bins: Vec<usize> = (0..n)
                .filter(|&k| valid[k] && freq[k] >= lo && freq[k] <= hi)
                .collect();
            let step = bins.len().div_ceil(o.max_band_points.max(1)).max(1);
            sel.extend(bins.iter().step_by(step));
        }
    }
    let valid_idx: Vec<usize> = (0..n).filter(|&k| valid[k]).collect();
    if let (Some(&first), Some(&last)) = (valid_idx.first(), valid_idx.last()) {
        let (a, b) = (freq[first].max(1e-12).ln(), freq[last].ln());
        let m = o.off_band_points;
        for i in 0..m {
            let target = if m == 1 {
                a
            } else {
                a + (b - a) * i as f64 / (m - 1) as f64
            }
            .exp();
            // Nearest valid bin.
            let pos = valid_idx.partition_point(|&k| freq[k] < target);
            let cand = [pos.checked_sub(1), Some(pos)]
                .into_iter()
                .flatten()
                .filter(|&p| p < valid_idx.len())
                .min_by(|&p, &q| {
                    (freq[valid_idx[p]] - target)
                        .abs()
                        .total_cmp(&(freq[valid_idx[q]] - target).abs())
                });
            if let Some(p) = cand {
                sel.push(valid_idx[p]);
            }
        }
    }
    sel.sort_unstable();
    sel.dedup();
    sel
}
