//! Shake-table (chirp + ring-down) estimation: the full-record estimator against the exact
//! discretisation, and the measured peak bias of Welch segmentation.

mod signal_common;

use frfbayes::frf::{modal_frf, Excitation, FrfKind, FrfPair};
use frfbayes::signal::bands::half_power_band;
use frfbayes::signal::sweep::{welch_frf, WelchOptions};
use frfbayes::signal::{estimate_test, EstimateOptions, InputKind};
use num_complex::Complex64;
use signal_common::*;
use std::f64::consts::PI;

const FS: f64 = 500.0;
const XI: [f64; 4] = [0.01, 0.005, 0.005, 0.002];

/// The campaign's drive: chirp 0-10 Hz over 60 s, 1 s tapers, 130 s record.
fn shake(xi: &[f64]) -> (frfbayes::io::Test, frfbayes::modal::Modes, Vec<f64>) {
    let (modes, c) = frame(xi);
    let ag = chirp(FS, 60.0, 10.0, 130.0, 1.0);
    let (disp, acc) = simulate(&modes, &c, Excitation::Ground, &ag, 1.0 / FS);
    (shake_test("sim-shake", FS, ag, disp, acc), modes, c)
}

/// With 5 % damping the ring-down is complete (`exp(-sigma 70 s) < 1e-8`): the full-record
/// estimate must equal the exact discrete-time FRF wherever the chirp has power, for the
/// relative accelerance (acc - ground) and the receptance (Eq. 14).
#[test]
fn full_record_is_exact_for_a_decayed_transient() {
    let (test, modes, c) = shake(&[0.05; 4]);
    let est = estimate_test(&test, &EstimateOptions::default()).unwrap();
    let dt = 1.0 / FS;
    assert_eq!(est.n_averages, 1);
    assert_eq!(est.exp_window_tau_s, None);
    assert!(matches!(est.input, InputKind::Ground { .. }));
    for r in &est.responses {
        let pair = r.pair(&est.input).unwrap();
        assert_eq!(pair.excitation, Excitation::Ground);
        let band: Vec<usize> = (0..est.freq_hz.len())
            .filter(|&k| (0.3..=9.7).contains(&est.freq_hz[k]))
            .collect();
        let hd: Vec<Complex64> = band
            .iter()
            .map(|&k| {
                let zeta = Complex64::new(0.0, 2.0 * PI * est.freq_hz[k] * dt).exp();
                discrete_frf(&modes, &c, &pair, zeta, dt)
            })
            .collect();
        let scale = hd.iter().map(|h| h.norm()).fold(0.0, f64::max);
        for (&k, hd) in band.iter().zip(&hd) {
            assert!(
                (r.h1[k] - hd).norm() <= 1e-7 * scale,
                "{} {} Hz: {} vs {}",
                r.channel.name,
                est.freq_hz[k],
                r.h1[k],
                hd
            );
            assert!(
                (r.h1[k] - r.h2[k]).norm() <= 1e-12 * scale,
                "one block: H2 = H1"
            );
        }
    }
}

/// Relative error of `|H|` at the bin nearest each natural frequency, and of the largest
/// `|H|` within +-2 half-power bandwidths against the true (continuous) peak.
fn peak_errors(
    freq_hz: &[f64],
    h: &[Complex64],
    modes: &frfbayes::modal::Modes,
    c: &[f64],
    pair: &FrfPair,
) -> Vec<(f64, f64, f64, f64)> {
    (0..modes.n_modes())
        .map(|i| {
            let fn_hz = modes.omega_rad_s[i] / (2.0 * PI);
            let xi = c[i] / (2.0 * modes.omega_rad_s[i]);
            let k = freq_hz
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - fn_hz).abs().total_cmp(&(b.1 - fn_hz).abs()))
                .unwrap()
                .0;
            let truth = |f: f64| modal_frf(modes, c, pair, 2.0 * PI * f).norm();
            let at_fn = h[k].norm() / truth(freq_hz[k]) - 1.0;
            let half = 2.0 * 2.0 * xi * fn_hz;
            let est_peak = freq_hz
                .iter()
                .zip(h)
                .filter(|(f, _)| (*f - fn_hz).abs() <= half)
                .map(|(_, v)| v.norm())
                .fold(0.0, f64::max);
            let true_peak = (0..=2000)
                .map(|j| truth(fn_hz - half + 2.0 * half * j as f64 / 2000.0))
                .fold(0.0, f64::max);
            // apparent damping from the estimator's own half-power band
            let curve: Vec<f64> = h.iter().map(|v| 20.0 * v.norm().log10()).collect();
            let valid = vec![true; h.len()];
            let b = half_power_band(&curve, freq_hz, &valid, k_peak(freq_hz, h, fn_hz, half));
            // the same half-power estimate on the true FRF sampled on the same grid
            let h_true: Vec<Complex64> = freq_hz
                .iter()
                .map(|&f| modal_frf(modes, c, pair, 2.0 * PI * f))
                .collect();
            let curve: Vec<f64> = h_true.iter().map(|v| 20.0 * v.norm().log10()).collect();
            let bt = half_power_band(
                &curve,
                freq_hz,
                &valid,
                k_peak(freq_hz, &h_true, fn_hz, half),
            );
            (
                at_fn,
                est_peak / true_peak - 1.0,
                b.damping_ratio(),
                bt.damping_ratio(),
            )
        })
        .collect()
}

fn k_peak(freq_hz: &[f64], h: &[Complex64], fn_hz: f64, half: f64) -> usize {
    (0..h.len())
        .filter(|&k| (freq_hz[k] - fn_hz).abs() <= half)
        .max_by(|&a, &b| h[a].norm().total_cmp(&h[b].norm()))
        .unwrap()
}

/// Realistic damping (1 %, 0.5 %, 0.5 %, 0.2 %). The full-record estimate is exact but for
/// the tail beyond 130 s: mode j is crossed at `t_j = 6 f_j` s and rings down for
/// `130 - t_j` s, so the tail is `exp(-sigma_j (130 - t_j))` of it (< 0.2 %). Welch (8 Hann
/// segments of 28.9 s, 50 % overlap) is measured against the same truth and must be shown
/// badly biased at the peaks. Figures printed here are quoted in `src/signal/sweep.rs`.
#[test]
fn full_record_accuracy_and_welch_peak_bias() {
    let (test, modes, c) = shake(&XI);
    let est = estimate_test(&test, &EstimateOptions::default()).unwrap();
    let est_pad = estimate_test(
        &test,
        &EstimateOptions {
            zero_pad_factor: 4,
            ..EstimateOptions::default()
        },
    )
    .unwrap();
    let ground = test.data[0].clone();
    let acc4_rel: Vec<f64> = test.data[4]
        .iter()
        .zip(&ground)
        .map(|(a, g)| a - g)
        .collect();
    let disp4 = test.data[8].clone();
    for (name, kind, rel) in [
        ("acc4", FrfKind::Accelerance, &acc4_rel),
        ("disp4", FrfKind::Receptance, &disp4),
    ] {
        let pair = FrfPair {
            response: 3,
            excitation: Excitation::Ground,
            kind,
        };
        let r = est.response(name).unwrap();
        assert_eq!(r.kind, kind);
        let full = peak_errors(&est.freq_hz, &r.h1, &modes, &c, &pair);
        let rp = est_pad.response(name).unwrap();
        let padded = peak_errors(&est_pad.freq_hz, &rp.h1, &modes, &c, &pair);
        for (i, e) in padded.iter().enumerate() {
            println!(
                "{name} mode {}: full-record zero-padded x4: at f_n {:+.4} peak {:+.4} xi_hp {:.4} (true FRF: {:.4})",
                i + 1,
                e.0,
                e.1,
                e.2,
                e.3
            );
            // padding interpolates the (decayed) record's spectrum exactly: true peak height
            // within the tail bound; half-power damping differs from xi by the other
            // modes' background (0.28 % for the 0.2 % mode 4 of acc4), not by the estimator
            assert!(e.1.abs() < 0.01 && (e.2 - e.3).abs() < 0.02 * e.3, "{e:?}");
        }
        for (n_seg, overlap) in [(8, 0.5), (4, 0.5)] {
            let w = welch_frf(
                &ground,
                rel,
                FS,
                &WelchOptions {
                    n_segments: n_seg,
                    overlap,
                },
            )
            .unwrap();
            let welch = peak_errors(&w.freq_hz, &w.h1, &modes, &c, &pair);
            println!(
                "{name}: Welch {n_seg} segments of {:.1} s",
                w.segment_len as f64 / FS
            );
            for i in 0..4 {
                println!(
                    "  mode {} ({:.3} Hz, xi {}): full-record at f_n {:+.4} peak {:+.4} xi_hp {:.4} (true FRF {:.4}) | Welch at f_n {:+.4} peak {:+.4} xi_hp {:.4} (true FRF {:.4})",
                    i + 1,
                    modes.omega_rad_s[i] / (2.0 * PI),
                    XI[i],
                    full[i].0,
                    full[i].1,
                    full[i].2,
                    full[i].3,
                    welch[i].0,
                    welch[i].1,
                    welch[i].2,
                    welch[i].3
                );
            }
            if n_seg == 8 {
                // Welch misses every peak height by more than a quarter (measured: see
                // sweep.rs), while the full-record estimate is within the tail bound below
                assert!(welch.iter().all(|e| e.1.abs() > 0.25), "{welch:?}");
            }
        }
        for (i, e) in full.iter().enumerate() {
            let fn_hz = modes.omega_rad_s[i] / (2.0 * PI);
            let tail = (-XI[i] * modes.omega_rad_s[i] * (130.0 - 6.0 * fn_hz)).exp();
            assert!(e.0.abs() <= 3.0 * tail + 1e-3, "{name} mode {i}: {e:?}");
        }
    }
}
