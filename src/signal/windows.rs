//! Time windows and what they do to FRFs.
//!
//! - [`force_window`]: rectangular around the impact pulse with cosine tapers, zero
//!   elsewhere. It removes the force channel's noise outside the impact (noise that would
//!   otherwise inflate `Gff` and bias H1 low) and leaves the pulse untouched.
//! - [`ExpWindow`] / [`exponential_window`]: `w(t) = exp(-t / tau)` from the start of a
//!   block, applied to force and response alike. It forces the response to decay within
//!   the block (no truncation leakage) at the price of extra apparent damping.
//!
//! ## What the exponential window does, exactly
//!
//! For signals that start at the block origin, the transform of `x(t) e^{-t/tau}` is
//! `X(omega - j/tau)`. Applied to force and response, the windowed FRF is therefore the
//! analytic FRF evaluated at the complex frequency `omega - j/tau`:
//!
//! `H_w(omega) = H(omega - j/tau)` (every pole `p_i = -xi_i omega_i + j omega_d,i` moves
//! to `p_i - 1/tau`).
//!
//! So the measured decay rate is `sigma_i = xi_i omega_i + 1/tau` and, to first order,
//! `xi_true = xi_meas - 1 / (tau omega_i)` ([`correct_exp_window_damping`];
//! [`unwindowed_pole`] is the exact inverse). Model-side code can instead apply the same
//! window to the model: [`windowed_modal_frf`] evaluates the modal sum at
//! `omega - j/tau`, and [`exp_window_modal_parameters`] gives the equivalent real modal
//! parameters for the fast receptance sum.

use crate::error::{Error, Result};
use crate::frf::{modal_coefficient, FrfKind, FrfPair};
use crate::modal::Modes;
use num_complex::Complex64;

/// Exponential window choice for impact blocks.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExpWindow {
    /// No exponential window (rectangular block).
    None,
    /// `w(t) = exp(-t / tau_s)`.
    TauS(f64),
    /// Choose `tau` so that the window falls to `end_level` (0 < end_level < 1) at the end
    /// of the block: `tau = T / ln(1 / end_level)`.
    EndLevel(f64),
}

impl ExpWindow {
    /// The time constant in s for a block of `block_s` seconds (`None` for no window).
    pub fn tau_s(self, block_s: f64) -> Result<Option<f64>> {
        match self {
            ExpWindow::None => Ok(None),
            ExpWindow::TauS(tau) if tau.is_finite() && tau > 0.0 => Ok(Some(tau)),
            ExpWindow::TauS(tau) => Err(Error::Usage(format!(
                "exponential window time constant must be positive and finite, got {tau} s"
            ))),
            ExpWindow::EndLevel(e) if e > 0.0 && e < 1.0 && block_s > 0.0 => {
                Ok(Some(block_s / (1.0 / e).ln()))
            }
            ExpWindow::EndLevel(e) => Err(Error::Usage(format!(
                "exponential window end level must be in (0, 1), got {e} (block {block_s} s)"
            ))),
        }
    }
}

/// `w[n] = exp(-n dt / tau_s)`, `n = 0..len`.
pub fn exponential_window(len: usize, dt_s: f64, tau_s: f64) -> Vec<f64> {
    let r = (-dt_s / tau_s).exp();
    let mut w = Vec::with_capacity(len);
    let mut v = 1.0;
    for n in 0..len {
        // recompute every 1024 samples to keep the product exact to rounding
        if n % 1024 == 0 {
            v = (-(n as f64) * dt_s / tau_s).exp();
        }
        w.push(v);
        v *= r;
    }
    w
}

/// Force window over `len` samples: 1 on `[start, end]` (inclusive sample indices),
/// raised-cosine tapers of `taper` samples on either side, 0 elsewhere.
pub fn force_window(len: usize, start: usize, end: usize, taper: usize) -> Vec<f64> {
    let mut w = vec![0.0; len];
    if len == 0 || start > end || start >= len {
        return w;
    }
    let end = end.min(len - 1);
    w[start..=end].iter_mut().for_each(|v| *v = 1.0);
    for i in 1..=taper {
        // 0.5 (1 + cos(pi i / (taper + 1))): 1 at the flat part, -> 0 beyond the taper
        let v = 0.5 * (1.0 + (std::f64::consts::PI * i as f64 / (taper + 1) as f64).cos());
        if let Some(k) = start.checked_sub(i) {
            w[k] = v;
        }
        if end + i < len {
            w[end + i] = v;
        }
    }
    w
}

/// Periodic Hann window of `len` samples (used by the Welch comparison estimator).
pub fn hann(len: usize) -> Vec<f64> {
    (0..len)
        .map(|n| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * n as f64 / len as f64).cos())
        .collect()
}

/// First-order damping correction for an exponential window:
/// `xi_true = xi_meas - 1 / (tau omega)` (the window adds `1/tau` to every decay rate
/// `sigma_i = xi_i omega_i`). `omega_rad_s` is the mode's natural frequency.
pub fn correct_exp_window_damping(xi_meas: f64, omega_rad_s: f64, tau_s: f64) -> f64 {
    xi_meas - 1.0 / (tau_s * omega_rad_s)
}

/// Exact inverse of the window's pole shift. A pole identified from a windowed FRF with
/// natural frequency `omega_n_meas` (= |p'|) and damping ratio `xi_meas` is
/// `p' = -xi_meas omega_n_meas + j omega_d`; the true pole is `p' + 1/tau` (same
/// `omega_d`). Returns the true `(omega_n_rad_s, xi)`.
pub fn unwindowed_pole(omega_n_meas_rad_s: f64, xi_meas: f64, tau_s: f64) -> (f64, f64) {
    let sigma = xi_meas * omega_n_meas_rad_s - 1.0 / tau_s;
    let omega_d2 = omega_n_meas_rad_s * omega_n_meas_rad_s * (1.0 - xi_meas * xi_meas);
    let omega_n = (sigma * sigma + omega_d2).sqrt();
    (omega_n, sigma / omega_n)
}

/// `(j w)^p` for a complex frequency `w`: the kind factor of an FRF at `w`.
#[inline]
pub fn kind_factor_complex(kind: FrfKind, w: Complex64) -> Complex64 {
    let jw = Complex64::new(0.0, 1.0) * w;
    match kind {
        FrfKind::Receptance => Complex64::new(1.0, 0.0),
        FrfKind::Mobility => jw,
        FrfKind::Accelerance => jw * jw,
    }
}

/// The analytic FRF of a pair, as it appears after an exponential window of time constant
/// `tau_s`: the modal sum (Eqs. 7, 10, 15, 16, with `modal_c[i] = 2 xi_i omega_i`)
/// evaluated at the complex frequency `w = omega - j/tau`, times `(j w)^p`.
/// With `tau_s = f64::INFINITY` it equals [`crate::frf::modal_frf`].
pub fn windowed_modal_frf(
    modes: &Modes,
    modal_c: &[f64],
    pair: &FrfPair,
    omega_rad_s: f64,
    tau_s: f64,
) -> Complex64 {
    let w = Complex64::new(omega_rad_s, -1.0 / tau_s);
    let mut h = Complex64::new(0.0, 0.0);
    for (i, (&wn, &c)) in modes.omega_rad_s.iter().zip(modal_c).enumerate() {
        let den = wn * wn - w * w + Complex64::new(0.0, c) * w;
        h += modal_coefficient(modes, pair, i) / den;
    }
    h * kind_factor_complex(pair.kind, w)
}

/// Equivalent real modal parameters of an exponentially windowed receptance: with
/// `eps = 1/tau`, `omega_i^2 - (omega - j eps)^2 + j c_i (omega - j eps)
/// = (omega_i^2 + eps^2 + c_i eps) - omega^2 + j (c_i + 2 eps) omega`, so the windowed
/// receptance is the ordinary modal sum with `omega_i' = sqrt(omega_i^2 + eps^2 + c_i eps)`
/// and `c_i' = c_i + 2 eps` (same mode-shape coefficients). Mobility and accelerance
/// additionally take the factor `(j omega + eps)^p` instead of `(j omega)^p`, i.e.
/// magnitudes scale by `(omega^2 + eps^2)^(p/2)`. Returns `(omega', c')`.
pub fn exp_window_modal_parameters(
    omega_rad_s: &[f64],
    modal_c: &[f64],
    tau_s: f64,
) -> (Vec<f64>, Vec<f64>) {
    let eps = 1.0 / tau_s;
    omega_rad_s
        .iter()
        .zip(modal_c)
        .map(|(&w, &c)| ((w * w + eps * eps + c * eps).sqrt(), c + 2.0 * eps))
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::{modal_frf, Excitation};
    use crate::model::{Damping, StructuralModel};

    #[test]
    fn end_level_sets_tau() {
        let tau = ExpWindow::EndLevel(0.01).tau_s(46.0).unwrap().unwrap();
        assert!((tau - 46.0 / 100f64.ln()).abs() < 1e-12);
        let w = exponential_window(5001, 0.01, tau);
        assert!((w[4600] - 0.01).abs() < 1e-12);
        assert!(ExpWindow::EndLevel(1.5).tau_s(10.0).is_err());
        assert!(ExpWindow::TauS(-1.0).tau_s(10.0).is_err());
        assert_eq!(ExpWindow::None.tau_s(10.0).unwrap(), None);
    }

    #[test]
    fn exponential_window_matches_direct_formula() {
        let w = exponential_window(10_000, 0.002, 3.7);
        for (n, &v) in w.iter().enumerate() {
            let exact = (-(n as f64) * 0.002 / 3.7).exp();
            assert!((v - exact).abs() <= 1e-13 * exact.max(1e-300), "n={n}");
        }
    }

    #[test]
    fn force_window_shape() {
        let w = force_window(20, 8, 10, 3);
        assert_eq!(&w[8..=10], &[1.0, 1.0, 1.0]);
        assert_eq!(w[4], 0.0);
        assert_eq!(w[14], 0.0);
        assert!(w[5] > 0.0 && w[5] < w[6] && w[6] < w[7] && w[7] < 1.0);
        assert!((w[7] - w[11]).abs() < 1e-15);
        // taper at the edges is clipped, not wrapped
        let w = force_window(6, 0, 5, 4);
        assert!(w.iter().all(|&v| v == 1.0));
    }

    #[test]
    fn damping_correction_inverts_the_window() {
        let (wn, xi, tau): (f64, f64, f64) = (2.0 * std::f64::consts::PI * 0.9, 0.01, 12.0);
        // windowed pole: sigma' = xi wn + 1/tau, omega_d unchanged
        let wd = wn * (1.0 - xi * xi).sqrt();
        let sigma_w = xi * wn + 1.0 / tau;
        let wn_w = (sigma_w * sigma_w + wd * wd).sqrt();
        let xi_w = sigma_w / wn_w;
        let (wn_back, xi_back) = unwindowed_pole(wn_w, xi_w, tau);
        assert!((wn_back - wn).abs() < 1e-12 && (xi_back - xi).abs() < 1e-14);
        // first-order formula: error O((1/(tau wn))^2)
        let first = correct_exp_window_damping(xi_w, wn, tau);
        let e = 1.0 / (tau * wn);
        assert!((first - xi).abs() < e * e, "{first} vs {xi}");
    }

    #[test]
    fn windowed_modal_frf_equals_shifted_parameters_and_reduces_to_modal_frf() {
        let model =
            StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0]).unwrap();
        let k = model.stiffness(&model.alpha_zero());
        let m = model.mass(&model.beta_zero());
        let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
        let mut c = vec![0.0; 4];
        Damping::Caughey {
            xi: vec![0.01, 0.005, 0.004, 0.002],
        }
        .modal_coefficients(&modes.omega_rad_s, &mut c)
        .unwrap();
        let tau = 9.0;
        let (wp, cp) = exp_window_modal_parameters(&modes.omega_rad_s, &c, tau);
        let mut shifted = modes.clone();
        shifted.omega_rad_s = wp;
        for excitation in [Excitation::Dof(1), Excitation::Ground] {
            for kind in [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance] {
                let pair = FrfPair {
                    response: 3,
                    excitation,
                    kind,
                };
                for &f in &[0.5, 0.93, 2.7, 5.0, 7.3] {
                    let w = 2.0 * std::f64::consts::PI * f;
                    let a = windowed_modal_frf(&modes, &c, &pair, w, tau);
                    let rec = FrfPair {
                        kind: FrfKind::Receptance,
                        ..pair
                    };
                    let b = modal_frf(&shifted, &cp, &rec, w)
                        * Complex64::new(1.0 / tau, w).powi(kind.power());
                    assert!((a - b).norm() <= 1e-12 * a.norm(), "{f} {kind:?}");
                    let plain = windowed_modal_frf(&modes, &c, &pair, w, f64::INFINITY);
                    let reference = modal_frf(&modes, &c, &pair, w);
                    assert!((plain - reference).norm() <= 1e-12 * reference.norm());
                }
            }
        }
    }
}
