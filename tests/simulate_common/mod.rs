//! Helpers shared by the simulator's integration tests: spectra and the FRFs a
//! first-order-hold simulation must reproduce, from direct solves.
#![allow(dead_code)]

use frfbayes::frf::direct;
use frfbayes::signal::spectra::Fft;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::PI;

/// Internal rate of the simulations in these tests.
pub const INTERNAL_RATE_HZ: f64 = 5000.0;

/// One-sided DFT of `x` (the library's real FFT, so each test binary does not compile
/// another copy of realfft's planner).
pub fn spectrum(x: &[f64]) -> Vec<Complex64> {
    Fft::new().forward(x, None, x.len()).unwrap()
}

/// `P(omega) sum_j (X(nu_j) - limit) sinc^2(nu_j h / 2) + limit` over the images
/// `nu_j = omega + j 2 pi / h`: the FRF seen through samples of a response to an input
/// whose pre-emphasised samples are joined by straight lines (the FOH), with
/// `X(-nu) = conj X(nu)`; `P = 1 + sin^2(omega h / 2) / 3` is the pre-emphasis' gain
/// ([`pre_emphasis`]) and `limit` the read-out's feedthrough, from the raw samples.
fn aliased(x: impl Fn(f64) -> Complex64, limit: f64, terms: i32, omega: f64) -> Complex64 {
    let h = 1.0 / INTERNAL_RATE_HZ;
    let ws = 2.0 * PI / h;
    pre_emphasis(omega)
        * (-terms..=terms)
            .map(|j| {
                let nu = omega + j as f64 * ws;
                let v = x(nu.abs());
                let v = if nu < 0.0 { v.conj() } else { v };
                let a = 0.5 * nu * h;
                let l = if a == 0.0 { 1.0 } else { (a.sin() / a).powi(2) };
                (v - limit) * l
            })
            .sum::<Complex64>()
        + limit
}

/// Gain `1 + sin^2(omega h / 2) / 3` of the simulator's pre-emphasis of its input
/// samples at the internal rate (`frfbayes::simulate::pre_emphasised`).
pub fn pre_emphasis(omega: f64) -> f64 {
    1.0 + (0.5 * omega / INTERNAL_RATE_HZ).sin().powi(2) / 3.0
}

/// FOH-sampled FRF of DOF `r` to a force on DOF `e`: receptance, or absolute
/// accelerance (`-nu^2` times it; its limit `(M^-1)_re` is summed exactly).
pub fn foh_frf(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    r: usize,
    e: usize,
    accel: bool,
    omega: f64,
) -> Complex64 {
    let limit = if accel {
        m.clone().try_inverse().unwrap()[(r, e)]
    } else {
        0.0
    };
    let x = |nu: f64| {
        let x = direct::receptance_matrix(m, k, c, nu).unwrap()[(r, e)];
        if accel {
            -nu * nu * x
        } else {
            x
        }
    };
    aliased(x, limit, if accel { 100 } else { 2 }, omega)
}

/// FOH-sampled FRF of DOF `r` to ground acceleration (paper Eq. 14): displacement
/// relative to the ground, or absolute acceleration (relative accelerance, whose limit
/// is `-iota_r`, plus the ground's own acceleration, sampled exactly).
pub fn foh_ground_frf(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    iota: &DVector<f64>,
    r: usize,
    accel: bool,
    omega: f64,
) -> Complex64 {
    let x = |nu: f64| {
        let x = direct::ground_receptance(m, k, c, iota, nu).unwrap()[r];
        if accel {
            -nu * nu * x
        } else {
            x
        }
    };
    if accel {
        aliased(x, -iota[r], 100, omega) + 1.0
    } else {
        aliased(x, 0.0, 2, omega)
    }
}

/// Largest magnitude of `frf` over the stop band of the anti-aliasing filter (250 Hz to
/// the internal Nyquist frequency): what decimation can fold into the record.
pub fn stop_band_peak(frf: impl Fn(f64) -> Complex64) -> f64 {
    (0..40)
        .map(|i| frf(2.0 * PI * (250.0 + 56.25 * i as f64)).norm())
        .fold(0.0, f64::max)
}

/// Bound on the error of an FRF estimated as `Y / U` from decimated records: images
/// folded by the 100 dB filter (ripple 1e-5, 9 x 1.5e-5 with the filter's gain over the
/// transition band; see simulate_frf.rs) relative to the input at the bin, plus rounding.
pub fn decimation_tolerance(g_stop: f64, expect: Complex64, u_max: f64, u_bin: f64) -> f64 {
    9.0 * 1.5e-5 * (g_stop + expect.norm()) * u_max / u_bin + 1e-9 * expect.norm()
}
