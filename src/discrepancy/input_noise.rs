//! The correlated relative error that the input channel's noise puts on the ratios of a
//! single-impact hammer segment (see [`InputGainBasis`]).

use crate::io::{Quantity, Test};
use crate::signal::hammer::detect_impacts;
use crate::signal::EstimateOptions;
use num_complex::Complex64;

/// The input channel's noise inside the force window of one impact block, `N_F`, makes
/// every ratio of the segment `H (1 + delta(omega))` with `delta = -N_F / F`: one smooth
/// random function of frequency shared by all channels (the window is ~0.1 s long, so
/// `delta` is correlated over ~10 Hz). The coherence, from local models over a few bins,
/// cannot see it. Its covariance is known: with window weights `v_n` (force window times
/// exponential window), force noise `sigma_n` (1.4826 MAD) and the measured windowed
/// force spectrum `F_k`,
/// `E[delta_k conj(delta_l)] = sigma_n^2 sum_n v_n^2 e^{-j (omega_k - omega_l) t_n} /
/// (F_k conj(F_l)) = (B B^*)_kl`, `B_kn = sigma_n v_n e^{-j omega_k t_n} / F_k`.
/// Stored as its leading eigen-directions `C ~ U U^*` (`U = B V_r`, eigenvalues of
/// `B^* B` above `1e-4` of the largest, at most [`MAX_GAIN_RANK`]); measured on the
/// benchmark's 20 N impacts: 0.7 % rms.
#[derive(Debug, Clone, PartialEq)]
pub struct InputGainBasis {
    pub rank: usize,
    /// `U`, frequency-major: `u[k * rank + m]` for the segment's frequency `k`.
    pub u: Vec<Complex64>,
}

/// Largest rank kept of an [`InputGainBasis`].
pub const MAX_GAIN_RANK: usize = 16;

/// The [`InputGainBasis`] of a single-impact block `[start, start + len)` of `t`, at
/// `freq_hz`, replicating the hammer estimator's windows.
pub(super) fn input_gain_basis(
    t: &Test,
    start: usize,
    len: usize,
    tau_s: Option<f64>,
    freq_hz: &[f64],
    est: &EstimateOptions,
) -> Option<InputGainBasis> {
    use crate::signal::hammer::median;
    use crate::signal::windows::{exponential_window, force_window};
    let fi = t.find(Quantity::Force)?;
    let f = &t.data[fi];
    let fs = t.sample_rate_hz;
    let base = median(f);
    let dev: Vec<f64> = f.iter().map(|v| (v - base).abs()).collect();
    let sigma = 1.4826 * median(&dev);
    let impact = detect_impacts(f, fs, &est.hammer).into_iter().next()?;
    if sigma.is_nan() || sigma <= 0.0 || start + len > f.len() || impact.trigger < start {
        return None;
    }
    let margin = (est.hammer.force_margin_s * fs).round() as usize;
    let taper = (est.hammer.force_taper_s * fs).round() as usize;
    let lo = impact.trigger.saturating_sub(margin).max(start) - start;
    let hi = (impact.pulse_end + margin - start).min(len - 1);
    let mut w = if est.hammer.force_window {
        force_window(len, lo, hi, taper)
    } else {
        vec![1.0; len]
    };
    if let Some(tau) = tau_s {
        let e = exponential_window(len, 1.0 / fs, tau);
        w.iter_mut().zip(&e).for_each(|(a, b)| *a *= b);
    }
    let support: Vec<usize> = (0..len).filter(|&n| w[n] != 0.0).collect();
    if support.is_empty() || support.len() > 4096 {
        return None;
    }
    let m = freq_hz.len();
    let l = support.len();
    let mut b = nalgebra::DMatrix::<Complex64>::zeros(m, l);
    for (k, &fk) in freq_hz.iter().enumerate() {
        let w_k = 2.0 * std::f64::consts::PI * fk;
        let rot: Vec<Complex64> = support
            .iter()
            .map(|&n| Complex64::from_polar(1.0, -w_k * n as f64 / fs))
            .collect();
        let big_f: Complex64 = support
            .iter()
            .zip(&rot)
            .map(|(&n, e)| e * ((f[start + n] - base) * w[n]))
            .sum();
        if big_f.norm() == 0.0 {
            return None;
        }
        for (j, (&n, e)) in support.iter().zip(&rot).enumerate() {
            b[(k, j)] = e * (sigma * w[n]) / big_f;
        }
    }
    let bh = b.adjoint() * &b;
    let eig = bh.symmetric_eigen();
    let mut order: Vec<usize> = (0..l).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let top = eig.eigenvalues[order[0]];
    if top.is_nan() || top <= 0.0 {
        return None;
    }
    let keep: Vec<usize> = order
        .into_iter()
        .take(MAX_GAIN_RANK)
        .filter(|&i| eig.eigenvalues[i] > 1e-4 * top)
        .collect();
    let r = keep.len();
    let mut u = vec![Complex64::new(0.0, 0.0); m * r];
    for (c, &i) in keep.iter().enumerate() {
        let col = &b * eig.eigenvectors.column(i);
        for k in 0..m {
            u[k * r + c] = col[k];
        }
    }
    Some(InputGainBasis { rank: r, u })
}
