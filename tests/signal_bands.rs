//! Half-power band selection on estimated FRFs (paper section 3.1).

mod signal_common;

use frfbayes::frf::Excitation;
use frfbayes::signal::{estimate_test, BandOptions, EstimateOptions, ExpWindow, HammerOptions};
use signal_common::*;

/// Noise-free SDOF hammer test, fully decayed block, no exponential window.
fn sdof_estimate(fn_hz: f64, xi: f64, bands: BandOptions) -> frfbayes::signal::TestFrf {
    let fs = 100.0;
    let (modes, c) = sdof(fn_hz, xi);
    let n = 30_000; // 300 s: exp(-xi omega 299 s) < 1e-4 for the cases below
    let mut f = vec![0.0; n];
    add_pulse(&mut f, 100, 3, 5.0);
    let (disp, acc) = simulate(&modes, &c, Excitation::Dof(0), &f, 1.0 / fs);
    let test = hammer_test("sdof", 1, fs, f, disp, acc);
    let opts = EstimateOptions {
        hammer: HammerOptions {
            exp_window: ExpWindow::None,
            ..HammerOptions::default()
        },
        bands,
        ..EstimateOptions::default()
    };
    estimate_test(&test, &opts).unwrap()
}

/// The half-power bandwidth of an SDOF is `2 xi f_n` (to `O(xi^2)`); estimated on the bin
/// grid it must agree within one bin.
#[test]
fn half_power_band_of_sdof_is_two_xi_fn_within_resolution() {
    for (fn_hz, xi) in [(3.0, 0.01), (3.0, 0.002), (0.9, 0.01), (5.7, 0.004)] {
        let est = sdof_estimate(fn_hz, xi, BandOptions::default());
        let df = est.freq_hz[1];
        assert_eq!(est.bands.len(), 1, "one floor -> one peak by default");
        let b = est.bands[0];
        assert!(!b.clipped);
        println!(
            "f_n {fn_hz} xi {xi}: peak {:.4} band {:.4}..{:.4} width {:.5} (2 xi f_n {:.5}, df {df:.5})",
            b.peak_hz,
            b.lo_hz,
            b.hi_hz,
            b.bandwidth_hz(),
            2.0 * xi * fn_hz
        );
        assert!((b.peak_hz - fn_hz).abs() <= df);
        assert!((b.bandwidth_hz() - 2.0 * xi * fn_hz).abs() <= df);
        assert!(b.lo_hz < fn_hz && b.hi_hz > fn_hz);
        // selected points: the bins inside the band (at least the peak bin)
        for &k in &est.selected {
            let f = est.freq_hz[k];
            assert!((f >= b.lo_hz && f <= b.hi_hz) || k == b.peak_index);
        }
        let expected = (b.bandwidth_hz() / df).floor() as usize;
        assert!(est.selected.len() >= expected.max(1) && est.selected.len() <= expected + 2);
    }
}

#[test]
fn band_factor_and_range_options() {
    let base = sdof_estimate(3.0, 0.01, BandOptions::default());
    let wide = sdof_estimate(
        3.0,
        0.01,
        BandOptions {
            band_factor: 3.0,
            ..BandOptions::default()
        },
    );
    let df = base.freq_hz[1];
    let b = wide.bands[0];
    let lo = b.peak_hz - 3.0 * (b.peak_hz - b.lo_hz);
    let hi = b.peak_hz + 3.0 * (b.hi_hz - b.peak_hz);
    let first = wide.freq_hz[wide.selected[0]];
    let last = wide.freq_hz[*wide.selected.last().unwrap()];
    assert!(first >= lo && first - lo <= df && hi >= last && hi - last <= df);
    assert!(wide.selected.len() >= 3 * base.selected.len() - 3);
    // a search range without the resonance finds no band and selects nothing
    let none = sdof_estimate(
        3.0,
        0.01,
        BandOptions {
            range_hz: Some((4.0, 10.0)),
            ..BandOptions::default()
        },
    );
    assert!(none.bands.is_empty() && none.selected.is_empty());
    let bad = EstimateOptions {
        bands: BandOptions {
            range_hz: Some((5.0, 1.0)),
            ..BandOptions::default()
        },
        ..EstimateOptions::default()
    };
    let (modes, c) = sdof(3.0, 0.01);
    let mut f = vec![0.0; 5000];
    add_pulse(&mut f, 100, 3, 5.0);
    let (disp, acc) = simulate(&modes, &c, Excitation::Dof(0), &f, 0.01);
    assert!(estimate_test(&hammer_test("x", 1, 100.0, f, disp, acc), &bad).is_err());
}
