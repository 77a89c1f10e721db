//! The ratio checks of [`super`] (`acc_vs_disp`, `reciprocity`) and shared helpers; each
//! check appends its results (verdicts are set by the caller
//! after the Holm adjustment) or a reason why it could not run.

use super::fit::{fit_ratio, RatioPoints};
use super::segment::{band_window, SegmentFrf};
use super::{
    CheckDetails, CheckKind, CheckResult, Compared, ConsistencyOptions, NullDistribution, Verdict,
};
use crate::io::Quantity;
use crate::signal::correlation::exp_window_bin_correlations;
use crate::signal::InputKind;
use num_complex::Complex64;
use std::f64::consts::PI;

pub(super) fn result(
    kind: CheckKind,
    what: String,
    compared: Compared,
    statistic: f64,
    dof: usize,
    summary: String,
    details: CheckDetails,
) -> CheckResult {
    let null = NullDistribution::ChiSquared { dof };
    CheckResult {
        kind,
        name: format!("{} {what}", kind.name()),
        compared,
        statistic,
        null,
        p_value: null.p_value(statistic),
        p_adjusted: f64::NAN,
        verdict: Verdict::Consistent,
        summary,
        details,
    }
}

/// Bins of all band windows of a segment, ascending, and the bands' edges (Hz).
fn window_bins(seg: &SegmentFrf, opts: &ConsistencyOptions) -> (Vec<usize>, Vec<(f64, f64)>) {
    let mut bins = Vec::new();
    let mut edges = Vec::new();
    for i in 0..seg.bands.len() {
        let r = band_window(&seg.freq_hz, &seg.bands, i, opts.window_half_widths);
        if !r.is_empty() {
            edges.push((seg.freq_hz[r.start], seg.freq_hz[r.end - 1]));
            bins.extend(r);
        }
    }
    (bins, edges)
}

/// `c(d)`, `d = 0..=MAX_CORRELATED_BINS`, of the noise of neighbouring bins of a
/// segment's estimates: its exponential window (none for the shake-table records) over
/// the transformed record, `1 / (df x zero padding)` s
/// ([`exp_window_bin_correlations`]). `[1]` (independent) where there is no
/// window and no padding, or the grid is too short to tell.
fn bin_correlation(seg: &SegmentFrf, opts: &ConsistencyOptions) -> Vec<Complex64> {
    let pad = opts.estimate.zero_pad_factor.max(1);
    let df_hz = match seg.freq_hz.as_slice() {
        [f0, f1, ..] if f1 > f0 => f1 - f0,
        _ => return vec![Complex64::new(1.0, 0.0)],
    };
    if seg.exp_window_tau_s.is_none() && pad == 1 {
        return vec![Complex64::new(1.0, 0.0)];
    }
    exp_window_bin_correlations(seg.exp_window_tau_s, 1.0 / (df_hz * pad as f64), df_hz)
}

fn ms(x: f64) -> f64 {
    1e3 * x
}

fn ratio_summary(f: &super::RatioFit, num: &str, den: &str) -> String {
    format!(
        "{num} / {den}: delay {:.2} +- {:.2} ms ({num} lags if positive), phase at 0 Hz {:.1} +- {:.1} deg, \
         gain at 0 Hz {:+.2} +- {:.2} %, gain change to {:.2} Hz {:+.2} +- {:.2} % ({} points, scale {:.2})",
        ms(f.delay_s),
        ms(f.delay_se_s),
        f.phase0_rad.to_degrees(),
        f.phase0_se_rad.to_degrees(),
        100.0 * f.ln_gain0,
        100.0 * f.ln_gain0_se,
        f.freq_max_hz,
        100.0 * f.ln_gain_change,
        100.0 * f.ln_gain_change_se,
        f.n_points,
        f.scale
    )
}

/// (a) Accelerance against `(j w)^2` x receptance on the same floor and test. Hammer:
/// `r = A / ((j w)^2 D)` with `w = omega - j/tau` (exact for windowed estimates). Shake
/// table: the estimates are relative to the ground, so the absolute ratio is
/// `r = (A_rel + 1) / ((j omega)^2 D_rel + 1)`; a factor on the accelerometer multiplies
/// the numerator exactly. `sigma^2 = eps_num^2 + eps_den^2` with each `eps` rescaled to the
/// value actually divided (`eps |A_rel| / |A_rel + 1|` etc.).
pub fn acc_vs_disp(
    segments: &[SegmentFrf],
    opts: &ConsistencyOptions,
    out: &mut Vec<CheckResult>,
    skipped: &mut Vec<String>,
) {
    for seg in segments {
        let (bins, edges) = window_bins(seg, opts);
        let corr = bin_correlation(seg, opts);
        let mut floors: Vec<usize> = seg.channels.iter().map(|c| c.channel.floor).collect();
        floors.sort_unstable();
        floors.dedup();
        for floor in floors {
            let (Some(a), Some(d)) = (
                seg.on_floor(Quantity::Acceleration, floor),
                seg.on_floor(Quantity::Displacement, floor),
            ) else {
                continue;
            };
            let mut pts = RatioPoints::default();
            for &k in &bins {
                let (ea, ed) = (a.rel_std[k], d.rel_std[k]);
                if !(ea < opts.max_rel_std && ed < opts.max_rel_std) {
                    continue;
                }
                let w = seg.complex_omega(k);
                let jw2 = -(w * w);
                let (num, den, sn, sd) = if seg.is_shake_table() {
                    let one = Complex64::new(1.0, 0.0);
                    let (n, dd) = (a.h[k] + one, jw2 * d.h[k] + one);
                    (
                        n,
                        dd,
                        ea * a.h[k].norm() / n.norm(),
                        ed * (jw2 * d.h[k]).norm() / dd.norm(),
                    )
                } else {
                    (a.h[k], jw2 * d.h[k], ea, ed)
                };
                let ratio = num / den;
                let sigma = sn.hypot(sd);
                if ratio.is_finite() && ratio.norm() > 0.0 && sigma > 0.0 && sigma.is_finite() {
                    pts.push(w.re, k, (num, sn), (den, sd));
                }
            }
            let what = format!("{} floor {floor}", seg.label);
            // No smooth-error allowance: both channels come from the same blocks, windows
            // and force, and measure the same floor's motion, so the estimator's smooth
            // error (ring-down, tail cut, force window) is common to both and cancels in
            // the ratio. Measured on the 30 null campaigns with no allowance at all: 0 of
            // their 600 acc_vs_disp checks inconsistent (reciprocity: 97 of 360, between
            // tests, where it does not cancel).
            match fit_ratio(&pts, &corr, 0.0) {
                Ok(f) => out.push(result(
                    CheckKind::AccVsDisp,
                    what,
                    Compared {
                        segments: vec![seg.label.clone()],
                        channels: vec![a.channel.name.clone(), d.channel.name.clone()],
                        bands_hz: edges.clone(),
                    },
                    f.wald_chi2,
                    4,
                    ratio_summary(&f, &a.channel.name, &d.channel.name),
                    CheckDetails::Ratio(f),
                )),
                Err(e) => skipped.push(format!("{} {what}: {e}", CheckKind::AccVsDisp.name())),
            }
        }
    }
}

/// `H` and `eps` of a channel at `freq_hz`, linearly interpolated between bins.
fn interp(seg: &SegmentFrf, c: usize, freq_hz: f64) -> Option<(Complex64, f64)> {
    let f = &seg.freq_hz;
    let j = f.partition_point(|&v| v <= freq_hz);
    if j == 0 || j >= f.len() {
        return None;
    }
    let t = (freq_hz - f[j - 1]) / (f[j] - f[j - 1]);
    let ch = &seg.channels[c];
    let h = ch.h[j - 1] * (1.0 - t) + ch.h[j] * t;
    let e = ch.rel_std[j - 1].max(ch.rel_std[j]);
    Some((h, e))
}

/// (d) Reciprocity `H_re = H_er` between hammer tests: response at floor r with the force
/// at floor e against response at e with the force at r, same quantity, on the band
/// windows of the first test (the second test interpolated to its frequencies when the
/// grids differ; the two tests' exponential windows differ only through their block
/// lengths).
pub fn reciprocity(
    segments: &[SegmentFrf],
    opts: &ConsistencyOptions,
    out: &mut Vec<CheckResult>,
    skipped: &mut Vec<String>,
) {
    let force_floor = |s: &SegmentFrf| match &s.input {
        InputKind::Force { floor, .. } => Some(*floor),
        InputKind::Ground { .. } => None,
    };
    for (i, se) in segments.iter().enumerate() {
        let Some(e) = force_floor(se) else { continue };
        let corr = bin_correlation(se, opts);
        for sr in &segments[i + 1..] {
            let Some(r) = force_floor(sr) else { continue };
            if r == e {
                continue;
            }
            for q in [Quantity::Acceleration, Quantity::Displacement] {
                let ci = se
                    .channels
                    .iter()
                    .position(|c| c.channel.quantity == q && c.channel.floor == r);
                let cj = sr
                    .channels
                    .iter()
                    .position(|c| c.channel.quantity == q && c.channel.floor == e);
                let (Some(ci), Some(cj)) = (ci, cj) else {
                    continue;
                };
                let (bins, edges) = window_bins(se, opts);
                let mut pts = RatioPoints::default();
                for k in bins {
                    let (h1, e1) = (se.channels[ci].h[k], se.channels[ci].rel_std[k]);
                    let Some((h2, e2)) = interp(sr, cj, se.freq_hz[k]) else {
                        continue;
                    };
                    if e1 < opts.max_rel_std && e2 < opts.max_rel_std && h2.norm() > 0.0 {
                        pts.push(2.0 * PI * se.freq_hz[k], k, (h1, e1), (h2, e2));
                    }
                }
                let (n1, n2) = (&se.channels[ci].channel.name, &sr.channels[cj].channel.name);
                let what = format!("{} {n1} / {} {n2}", se.label, sr.label);
                match fit_ratio(
                    &pts,
                    &corr,
                    std::f64::consts::SQRT_2 * opts.estimator_rel_error,
                ) {
                    Ok(f) => out.push(result(
                        CheckKind::Reciprocity,
                        what,
                        Compared {
                            segments: vec![se.label.clone(), sr.label.clone()],
                            channels: vec![n1.clone(), n2.clone()],
                            bands_hz: edges,
                        },
                        f.wald_chi2,
                        4,
                        ratio_summary(
                            &f,
                            &format!("H({r},{e}) [{n1}]"),
                            &format!("H({e},{r}) [{n2}]"),
                        ),
                        CheckDetails::Ratio(f),
                    )),
                    Err(err) => skipped.push(format!("reciprocity {what}: {err}")),
                }
            }
        }
    }
}
