//! The pole checks of [`super`] (`impact_level`, `hammer_vs_shake`, `drift`): one pole per
//! band and segment ([`super::pole_fit::fit_pole`]), compared across segments.

use super::checks::result;
use super::pole_fit::{fit_pole, PoleData, PoleFit};
use super::segment::{band_window, SegmentFrf};
use super::{
    CheckDetails, CheckKind, CheckResult, Compared, ConsistencyOptions, ModeComparison,
    PoleEstimate,
};
use std::f64::consts::PI;

/// Relative distance within which a band of one test is the same mode as a reference band.
const MODE_MATCH_REL: f64 = 0.05;
/// Pole of band `band` of a segment from all its channels (receptance-like values,
/// [`SegmentFrf::receptance_like`]), without the exponential window.
fn segment_pole(
    seg: &SegmentFrf,
    band: usize,
    opts: &ConsistencyOptions,
) -> crate::Result<PoleFit> {
    let bins = band_window(&seg.freq_hz, &seg.bands, band, opts.window_half_widths);
    let mut data = Vec::new();
    for c in 0..seg.channels.len() {
        let mut d = PoleData {
            omega_rad_s: Vec::new(),
            h: Vec::new(),
            sigma: Vec::new(),
        };
        for k in bins.clone() {
            let eps = seg.channels[c].rel_std[k];
            let h = seg.receptance_like(c, k);
            if eps < opts.max_rel_std && h.is_finite() && h.norm() > 0.0 && eps > 0.0 {
                d.omega_rad_s.push(2.0 * PI * seg.freq_hz[k]);
                d.sigma.push(eps * h.norm());
                d.h.push(h);
            }
        }
        // a channel needs more real data than its 6 linear parameters plus a margin
        if d.h.len() >= 6 {
            data.push(d);
        }
    }
    let b = &seg.bands[band];
    let (w0, xi0) = (2.0 * PI * b.peak_hz, b.damping_ratio().max(1e-3));
    let mut fit = fit_pole(&data, w0, xi0)?;
    let (f_lo, f_hi) = (seg.freq_hz[bins.start], seg.freq_hz[bins.end - 1]);
    let f_fit = fit.omega_n_rad_s / (2.0 * PI);
    if !(f_lo..=f_hi).contains(&f_fit) || fit.xi > 0.3 {
        return Err(crate::Error::Numerical(format!(
            "pole fit left the band: {f_fit:.3} Hz, xi {:.3} (window {f_lo:.3}-{f_hi:.3} Hz)",
            fit.xi
        )));
    }
    // The channels' errors are not independent where the input's noise dominates (shake
    // table near resonance: `H_c (1 - N_in / F_in)` with one `N_in` for all channels), and
    // the joint fit's standard errors then are too small by up to sqrt(channels). The
    // joint fit cannot be more precise than its best channel when the errors are shared,
    // so its standard errors are raised to the smallest single-channel ones.
    let single: Vec<PoleFit> = data
        .iter()
        .filter_map(|d| fit_pole(std::slice::from_ref(d), fit.omega_n_rad_s, fit.xi).ok())
        .collect();
    let min_w = single
        .iter()
        .map(|p| p.omega_n_se_rad_s)
        .fold(f64::INFINITY, f64::min);
    let min_x = single.iter().map(|p| p.xi_se).fold(f64::INFINITY, f64::min);
    if min_w.is_finite() && min_x.is_finite() {
        let (sw, sx) = (fit.omega_n_se_rad_s.max(min_w), fit.xi_se.max(min_x));
        fit.corr *= fit.omega_n_se_rad_s * fit.xi_se / (sw * sx);
        fit.omega_n_se_rad_s = sw;
        fit.xi_se = sx;
    }
    Ok(fit
        .with_smooth_error(opts.estimator_rel_error)
        .unwindowed(seg.exp_window_tau_s))
}

fn pole_estimate(label: &str, p: &PoleFit) -> PoleEstimate {
    PoleEstimate {
        segment: label.to_string(),
        freq_hz: p.omega_n_rad_s / (2.0 * PI),
        freq_se_hz: p.omega_n_se_rad_s / (2.0 * PI),
        xi: p.xi,
        xi_se: p.xi_se,
    }
}

/// Mahalanobis distance of the difference of two independent poles (frequency and
/// damping, each with its own 2 x 2 covariance): chi^2 with 2 dof under equality.
fn pole_distance(a: &PoleFit, b: &PoleFit) -> f64 {
    let cov = |p: &PoleFit| {
        nalgebra::Matrix2::new(
            p.omega_n_se_rad_s.powi(2),
            p.corr * p.omega_n_se_rad_s * p.xi_se,
            p.corr * p.omega_n_se_rad_s * p.xi_se,
            p.xi_se.powi(2),
        )
    };
    let d = nalgebra::Vector2::new(a.omega_n_rad_s - b.omega_n_rad_s, a.xi - b.xi);
    match (cov(a) + cov(b)).try_inverse() {
        Some(inv) => (d.transpose() * inv * d)[(0, 0)],
        None => f64::NAN,
    }
}

/// Weighted mean of `ln |H_1 / H_0|` over a band window and all channels, in dB.
fn band_ratio_db(
    s0: &SegmentFrf,
    s1: &SegmentFrf,
    band: usize,
    opts: &ConsistencyOptions,
) -> Option<f64> {
    let bins = band_window(&s0.freq_hz, &s0.bands, band, opts.window_half_widths);
    let (mut num, mut den) = (0.0, 0.0);
    for (c0, c1) in s0.channels.iter().zip(&s1.channels) {
        for k in bins.clone() {
            let (e0, e1) = (c0.rel_std[k], c1.rel_std[k]);
            if e0 < opts.max_rel_std && e1 < opts.max_rel_std {
                let w = 1.0 / (e0 * e0 + e1 * e1);
                num += w * (c1.h[k] / c0.h[k]).norm().ln();
                den += w;
            }
        }
    }
    (den > 0.0).then(|| 20.0 * num / den / std::f64::consts::LN_10)
}

/// (b) Weakest against strongest impact of each hammer test: every band's pole (2 dof per
/// band: frequency and damping) and the mean FRF ratio.
pub fn impact_level(
    impacts: &[Vec<SegmentFrf>],
    opts: &ConsistencyOptions,
    out: &mut Vec<CheckResult>,
    skipped: &mut Vec<String>,
) {
    for segs in impacts {
        if segs.len() < 2 {
            if let Some(s) = segs.first() {
                skipped.push(format!("impact_level {}: fewer than two impacts", s.test));
            }
            continue;
        }
        let force = |s: &SegmentFrf| s.peak_force_n.unwrap_or(0.0);
        let weak = segs
            .iter()
            .min_by(|a, b| force(a).total_cmp(&force(b)))
            .unwrap_or(&segs[0]);
        let strong = segs
            .iter()
            .max_by(|a, b| force(a).total_cmp(&force(b)))
            .unwrap_or(&segs[0]);
        if force(strong) < 1.5 * force(weak) {
            skipped.push(format!(
                "impact_level {}: impacts within a factor 1.5 in force ({:.1} / {:.1} N)",
                weak.test,
                force(weak),
                force(strong)
            ));
            continue;
        }
        let mut modes = Vec::new();
        let mut chi2 = 0.0;
        let mut edges = Vec::new();
        for band in 0..weak.bands.len() {
            match (
                segment_pole(weak, band, opts),
                segment_pole(strong, band, opts),
            ) {
                (Ok(pw), Ok(ps)) => {
                    let c = pole_distance(&ps, &pw);
                    if !c.is_finite() {
                        continue;
                    }
                    chi2 += c;
                    let df = ps.omega_n_rad_s - pw.omega_n_rad_s;
                    let se = (ps.omega_n_se_rad_s.powi(2) + pw.omega_n_se_rad_s.powi(2)).sqrt();
                    let b = &weak.bands[band];
                    edges.push((b.lo_hz, b.hi_hz));
                    modes.push(ModeComparison {
                        mode: band + 1,
                        estimates: vec![
                            pole_estimate(&weak.label, &pw),
                            pole_estimate(&strong.label, &ps),
                        ],
                        freq_shift_rel: df / pw.omega_n_rad_s,
                        freq_shift_z: df / se,
                        chi2: c,
                        ratio_db: band_ratio_db(weak, strong, band, opts),
                    });
                }
                (Err(e), _) | (_, Err(e)) => {
                    skipped.push(format!("impact_level {} band {}: {e}", weak.test, band + 1))
                }
            }
        }
        if modes.is_empty() {
            continue;
        }
        let summary = format!(
            "{} ({:.0} N) vs {} ({:.0} N): frequency shift {}",
            strong.label,
            force(strong),
            weak.label,
            force(weak),
            modes
                .iter()
                .map(|m| format!(
                    "mode {} {:+.3} % (z {:+.1})",
                    m.mode,
                    100.0 * m.freq_shift_rel,
                    m.freq_shift_z
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
        let dof = 2 * modes.len();
        out.push(result(
            CheckKind::ImpactLevel,
            weak.test.clone(),
            Compared {
                segments: vec![weak.label.clone(), strong.label.clone()],
                channels: weak
                    .channels
                    .iter()
                    .map(|c| c.channel.name.clone())
                    .collect(),
                bands_hz: edges,
            },
            chi2,
            dof,
            summary,
            CheckDetails::Modes { modes },
        ));
    }
}

/// Poles of every segment for a common list of modes.
pub struct TestPoles {
    /// Peak frequency of each mode, Hz: the bands of the segment with the most bands.
    pub peaks_hz: Vec<f64>,
    /// `[segment][mode]`, bands matched to modes by peak frequency.
    pub poles: Vec<Vec<Option<PoleFit>>>,
}

impl TestPoles {
    fn mode_name(&self, mode: usize) -> String {
        format!("mode {} ({:.2} Hz)", mode + 1, self.peaks_hz[mode])
    }
}

/// Fits the poles of every segment ([`TestPoles`]).
pub fn test_poles(
    segments: &[SegmentFrf],
    opts: &ConsistencyOptions,
    skipped: &mut Vec<String>,
) -> TestPoles {
    let Some(reference) = segments.iter().max_by_key(|s| s.bands.len()) else {
        return TestPoles {
            peaks_hz: Vec::new(),
            poles: Vec::new(),
        };
    };
    let peaks: Vec<f64> = reference.bands.iter().map(|b| b.peak_hz).collect();
    use rayon::prelude::*;
    let fits: Vec<(Vec<Option<PoleFit>>, Vec<String>)> = segments
        .par_iter()
        .map(|seg| {
            let mut row = vec![None; peaks.len()];
            let mut notes = Vec::new();
            for (band, b) in seg.bands.iter().enumerate() {
                let Some((mode, _)) = peaks
                    .iter()
                    .enumerate()
                    .map(|(i, &p)| (i, (b.peak_hz - p).abs() / p))
                    .filter(|&(_, d)| d < MODE_MATCH_REL)
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                else {
                    continue;
                };
                match segment_pole(seg, band, opts) {
                    Ok(p) => row[mode] = Some(p),
                    Err(e) => notes.push(format!("pole of {} band {}: {e}", seg.label, band + 1)),
                }
            }
            (row, notes)
        })
        .collect();
    let poles = fits
        .into_iter()
        .map(|(row, notes)| {
            skipped.extend(notes);
            row
        })
        .collect();
    TestPoles {
        peaks_hz: peaks,
        poles,
    }
}

/// Inverse-variance weighted mean with its standard error, inflated by the Birge ratio of
/// the spread (`sqrt(max(1, chi^2 / (n - 1)))`); returns (mean, se, chi^2 of the spread).
fn weighted_mean(values: &[(f64, f64)]) -> (f64, f64, f64) {
    let w: f64 = values.iter().map(|(_, s)| 1.0 / (s * s)).sum();
    let mean = values.iter().map(|(v, s)| v / (s * s)).sum::<f64>() / w;
    let chi2: f64 = values.iter().map(|(v, s)| ((v - mean) / s).powi(2)).sum();
    let birge = if values.len() > 1 {
        (chi2 / (values.len() - 1) as f64).max(1.0)
    } else {
        1.0
    };
    (mean, (birge / w).sqrt(), chi2)
}

/// (c) Poles from the hammer tests (combined by weighted mean, its standard error inflated
/// by their own spread) against the shake-table test's, one check per mode (frequency and
/// damping: 2 dof).
pub fn hammer_vs_shake(
    segments: &[SegmentFrf],
    tp: &TestPoles,
    out: &mut Vec<CheckResult>,
    skipped: &mut Vec<String>,
) {
    let poles = &tp.poles;
    let n_modes = tp.peaks_hz.len();
    let hammer: Vec<usize> = (0..segments.len())
        .filter(|&i| !segments[i].is_shake_table())
        .collect();
    let shake: Vec<usize> = (0..segments.len())
        .filter(|&i| segments[i].is_shake_table())
        .collect();
    if hammer.is_empty() || shake.is_empty() {
        skipped.push("hammer_vs_shake: needs hammer and shake-table tests".into());
        return;
    }
    for &si in &shake {
        for (mode, ps) in poles[si].iter().enumerate().take(n_modes) {
            let Some(ps) = *ps else { continue };
            let hp: Vec<(usize, PoleFit)> = hammer
                .iter()
                .filter_map(|&h| poles[h][mode].map(|p| (h, p)))
                .collect();
            if hp.is_empty() {
                continue;
            }
            let (fh, fh_se, _) = weighted_mean(
                &hp.iter()
                    .map(|(_, p)| (p.omega_n_rad_s, p.omega_n_se_rad_s))
                    .collect::<Vec<_>>(),
            );
            let (xh, xh_se, _) =
                weighted_mean(&hp.iter().map(|(_, p)| (p.xi, p.xi_se)).collect::<Vec<_>>());
            let zf = (ps.omega_n_rad_s - fh) / (ps.omega_n_se_rad_s.powi(2) + fh_se.powi(2)).sqrt();
            let zx = (ps.xi - xh) / (ps.xi_se.powi(2) + xh_se.powi(2)).sqrt();
            let chi2 = zf * zf + zx * zx;
            let hammer_est = PoleEstimate {
                segment: "hammer (weighted mean)".into(),
                freq_hz: fh / (2.0 * PI),
                freq_se_hz: fh_se / (2.0 * PI),
                xi: xh,
                xi_se: xh_se,
            };
            let shake_est = pole_estimate(&segments[si].label, &ps);
            let summary = format!(
                "{}: shake table {:.4} +- {:.4} Hz, xi {:.3} +- {:.3} %; hammer {:.4} +- {:.4} Hz, xi {:.3} +- {:.3} % (z_f {:+.1}, z_xi {:+.1})",
                tp.mode_name(mode),
                shake_est.freq_hz,
                shake_est.freq_se_hz,
                100.0 * shake_est.xi,
                100.0 * shake_est.xi_se,
                hammer_est.freq_hz,
                hammer_est.freq_se_hz,
                100.0 * hammer_est.xi,
                100.0 * hammer_est.xi_se,
                zf,
                zx
            );
            let mut segs: Vec<String> =
                hp.iter().map(|(h, _)| segments[*h].label.clone()).collect();
            segs.push(segments[si].label.clone());
            out.push(result(
                CheckKind::HammerVsShake,
                tp.mode_name(mode),
                Compared {
                    segments: segs,
                    channels: Vec::new(),
                    bands_hz: Vec::new(),
                },
                chi2,
                2,
                summary,
                CheckDetails::Modes {
                    modes: vec![ModeComparison {
                        mode: mode + 1,
                        freq_shift_rel: (ps.omega_n_rad_s - fh) / fh,
                        freq_shift_z: zf,
                        chi2,
                        ratio_db: None,
                        estimates: vec![hammer_est, shake_est],
                    }],
                },
            ));
        }
    }
}

/// (e) Drift of each mode's pole across the hammer tests: spread of frequency and damping
/// about their weighted means, chi^2 with `2 (T - 1)` dof for `T` tests.
#[allow(clippy::needless_range_loop)] // `mode` indexes every segment's row
pub fn drift(
    segments: &[SegmentFrf],
    tp: &TestPoles,
    out: &mut Vec<CheckResult>,
    skipped: &mut Vec<String>,
) {
    let poles = &tp.poles;
    let n_modes = tp.peaks_hz.len();
    let hammer: Vec<usize> = (0..segments.len())
        .filter(|&i| !segments[i].is_shake_table())
        .collect();
    if hammer.len() < 2 {
        skipped.push("drift: needs at least two hammer tests".into());
        return;
    }
    for mode in 0..n_modes {
        let hp: Vec<(usize, PoleFit)> = hammer
            .iter()
            .filter_map(|&h| poles[h][mode].map(|p| (h, p)))
            .collect();
        if hp.len() < 2 {
            continue;
        }
        let (fm, _, cf) = weighted_mean(
            &hp.iter()
                .map(|(_, p)| (p.omega_n_rad_s, p.omega_n_se_rad_s))
                .collect::<Vec<_>>(),
        );
        let (_, _, cx) =
            weighted_mean(&hp.iter().map(|(_, p)| (p.xi, p.xi_se)).collect::<Vec<_>>());
        let estimates: Vec<PoleEstimate> = hp
            .iter()
            .map(|(h, p)| pole_estimate(&segments[*h].label, p))
            .collect();
        let (imax, dmax) = hp
            .iter()
            .enumerate()
            .map(|(i, (_, p))| (i, (p.omega_n_rad_s - fm) / p.omega_n_se_rad_s))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .unwrap_or((0, 0.0));
        let summary = format!(
            "{}: {}; frequency spread chi^2 {:.1}, damping spread chi^2 {:.1} ({} dof each)",
            tp.mode_name(mode),
            estimates
                .iter()
                .map(|e| format!(
                    "{} {:.4} +- {:.4} Hz xi {:.3} %",
                    e.segment,
                    e.freq_hz,
                    e.freq_se_hz,
                    100.0 * e.xi
                ))
                .collect::<Vec<_>>()
                .join("; "),
            cf,
            cx,
            hp.len() - 1
        );
        out.push(result(
            CheckKind::Drift,
            tp.mode_name(mode),
            Compared {
                segments: estimates.iter().map(|e| e.segment.clone()).collect(),
                channels: Vec::new(),
                bands_hz: Vec::new(),
            },
            cf + cx,
            2 * (hp.len() - 1),
            summary,
            CheckDetails::Modes {
                modes: vec![ModeComparison {
                    mode: mode + 1,
                    freq_shift_rel: (hp[imax].1.omega_n_rad_s - fm) / fm,
                    freq_shift_z: dmax,
                    chi2: cf + cx,
                    ratio_db: None,
                    estimates,
                }],
            },
        ));
    }
}
