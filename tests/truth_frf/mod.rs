//! The analytic FRFs a simulated campaign's estimates stand for: the true model's modes
//! and damping, and the exponential window's exact effect.

use frfbayes::frf::{modal_frf, FrfPair};
use frfbayes::modal::Modes;
use frfbayes::signal::{windowed_modal_frf, InputKind, TestFrf};
use frfbayes::simulate::Simulator;
use num_complex::Complex64;
use std::f64::consts::PI;

/// True modes and modal damping coefficients `2 xi_i omega_i` of the simulated system.
pub fn true_modes(sim: &Simulator) -> (Modes, Vec<f64>) {
    let modes = sim.system().modes().unwrap();
    let c = modes
        .omega_rad_s
        .iter()
        .zip(sim.system().modal_damping_ratios().unwrap())
        .map(|(w, x)| 2.0 * x * w)
        .collect();
    (modes, c)
}

/// The analytic FRF an estimate stands for (hammer: at `s = j omega + 1/tau` when an
/// exponential window was applied, its exact effect).
pub fn analytic(est: &TestFrf, modes: &Modes, c: &[f64], pair: &FrfPair, f_hz: f64) -> Complex64 {
    let w = 2.0 * PI * f_hz;
    match (&est.input, est.exp_window_tau_s) {
        (InputKind::Force { .. }, Some(tau)) => windowed_modal_frf(modes, c, pair, w, tau),
        _ => modal_frf(modes, c, pair, w),
    }
}
