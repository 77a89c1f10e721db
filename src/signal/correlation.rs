//! Correlation of noise between the DFT bins of a windowed record, and what it does to the
//! local-model noise estimate of [`super::noise`].
//!
//! White noise `n` of variance `s^2` times a window `w` (`N` samples, transform of
//! `n_fft >= N` points) has bin spectra `N_k` with
//!
//! `E[N_k conj(N_l)] = s^2 sum_n w_n^2 exp(-2 pi j (k - l) n / n_fft) = s^2 W c(k - l)`,
//!
//! `W = sum_n w_n^2`, `c(0) = 1` ([`NoiseWindow::correlation`]). A rectangular window
//! without padding gives independent bins (`c(d) = 0`); zero padding by `p` correlates bins
//! closer than `p`; the exponential window `exp(-t/tau)` over `T` s gives
//! `|c(d)| ~ 1 / sqrt(1 + (pi d tau / T)^2)`: 0.88 for adjacent bins when `tau = T / 6`
//! (a 20 s window over a 118 s record).
//!
//! A local model fitted over correlated bins absorbs part of the noise: with the model's
//! projection `P` over the window's `n` bins and the noise correlation matrix
//! `C_ij = c((i - j) step)`, `E[RSS] = sigma^2 tr((I - P) C)` instead of
//! `sigma^2 (n - p)`. [`WindowDof`] gives these normalisers (and the effective degrees of
//! freedom `tr(M)^2 / tr(M^2)`, `M = (I - P) C (I - P)`) for `K` blocks of constant input
//! over the window, where `P = (1/K) J (x) P_1` and
//! `tr(M_K) = (K - 1) n + tr(M_1)`, `tr(M_K^2) = (K - 1) tr(C^2) + tr(M_1^2)`.
//! For `tau = T / 6`, 9 adjacent bins and the quadratic model, `tr((I - P) C)` is 0.29 of
//! `n - p` with 1.8 effective degrees of freedom: taken as independent, the noise would be
//! underestimated 3.5x, and very unevenly. So the window is also spread out:
//! [`NoiseWindow::decorrelating_step`] is the smallest bin spacing with `|c| <= 0.5`
//! (4 bins for `tau = T / 6`: normaliser 0.86 of `n - p`, 4.7 effective degrees of
//! freedom), and the remaining correlation is normalised exactly.

use crate::error::{Error, Result};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Largest `|c(step)|` accepted between neighbouring bins of the local window.
pub const MAX_NEIGHBOUR_CORRELATION: f64 = 0.5;
/// Upper limit of [`NoiseWindow::decorrelating_step`].
const MAX_STEP: usize = 64;

/// The squared window of a transform, normalised to unit sum.
#[derive(Debug, Clone)]
pub struct NoiseWindow {
    w2: Vec<f64>,
    n_fft: usize,
}

impl NoiseWindow {
    /// `window` over the `len` samples transformed (`None`: rectangular), zero-padded to
    /// `n_fft`.
    pub fn new(window: Option<&[f64]>, len: usize, n_fft: usize) -> Result<Self> {
        let w2: Vec<f64> = match window {
            Some(w) if w.len() == len => w.iter().map(|v| v * v).collect(),
            Some(w) => {
                return Err(Error::Usage(format!(
                    "noise window of {} samples for a transform of {len}",
                    w.len()
                )))
            }
            None => vec![1.0; len],
        };
        let total: f64 = w2.iter().sum();
        if len == 0 || n_fft < len || total <= 0.0 || !total.is_finite() {
            return Err(Error::Usage(format!(
                "noise window: {len} samples, n_fft {n_fft}, power {total}"
            )));
        }
        Ok(NoiseWindow {
            w2: w2.iter().map(|v| v / total).collect(),
            n_fft,
        })
    }

    /// `c(d) = sum_n w_n^2 exp(-2 pi j d n / n_fft) / sum_n w_n^2`.
    pub fn correlation(&self, d: usize) -> Complex64 {
        let step = Complex64::from_polar(
            1.0,
            -2.0 * std::f64::consts::PI * (d % self.n_fft) as f64 / self.n_fft as f64,
        );
        // exact rotation recomputed every 1024 samples (rounding of the running product)
        let mut sum = Complex64::new(0.0, 0.0);
        let mut rot = Complex64::new(1.0, 0.0);
        for (n, &v) in self.w2.iter().enumerate() {
            if n % 1024 == 0 {
                let ang =
                    -2.0 * std::f64::consts::PI * ((d * n) % self.n_fft) as f64 / self.n_fft as f64;
                rot = Complex64::from_polar(1.0, ang);
            }
            sum += v * rot;
            rot *= step;
        }
        sum
    }

    /// Smallest bin spacing `s >= 1` with `|c(s)| <= MAX_NEIGHBOUR_CORRELATION` (at most 64).
    pub fn decorrelating_step(&self) -> usize {
        (1..=MAX_STEP)
            .find(|&s| self.correlation(s).norm() <= MAX_NEIGHBOUR_CORRELATION)
            .unwrap_or(MAX_STEP)
    }

    /// `c(j step)` for `j = 0..=2 half_width` (the argument of
    /// [`super::noise::local_rational_noise`]).
    pub fn window_correlation(&self, half_width: usize, step: usize) -> Vec<Complex64> {
        (0..=2 * half_width)
            .map(|j| self.correlation(j * step))
            .collect()
    }
}

/// `c(d)` of a record of `record_s` seconds under the exponential window
/// `exp(-t / tau_s)` from its start (`None`: rectangular), on a grid of `df_hz` (`1 /
/// record_s` without zero padding): the continuous-time limit of
/// [`NoiseWindow::correlation`], `c(d) = a (1 - exp(-(a + j b) T)) / ((a + j b) (1 -
/// exp(-a T)))` with `a = 2 / tau`, `b = 2 pi d df`, `T = record_s` (`a -> 0`: `(1 -
/// exp(-j b T)) / (j b T)`). For the default whole-record hammer window (`T / tau =
/// ln 20`) adjacent bins have `|c(1)| = 0.69` and `Re c(1) = 0.48`.
pub fn exp_window_bin_correlation_complex(
    tau_s: Option<f64>,
    record_s: f64,
    df_hz: f64,
    d: usize,
) -> Complex64 {
    let one = Complex64::new(1.0, 0.0);
    if d == 0 {
        return one;
    }
    let b = 2.0 * std::f64::consts::PI * d as f64 * df_hz;
    let t = record_s;
    let jb = Complex64::new(0.0, b);
    let c = match tau_s.filter(|tau| tau.is_finite() && *tau > 0.0) {
        Some(tau) => {
            let a = Complex64::new(2.0 / tau, 0.0);
            a * (one - (-(a + jb) * t).exp()) / ((a + jb) * (1.0 - (-a.re * t).exp()))
        }
        None => (one - (-jb * t).exp()) / (jb * t),
    };
    if c.norm() > 1.0 {
        c / c.norm()
    } else {
        c
    }
}

/// Farthest bin lag of [`exp_window_bin_correlations`]. The exponential window's
/// `|c(d)|^2` falls as `1 / d^2`: beyond 256 bins the part of `sum |c(d)|^2` left out is
/// below 0.5 % of it.
pub const MAX_CORRELATED_BINS: usize = 256;

/// `c(d)`, `d = 0..=MAX_CORRELATED_BINS`, of [`exp_window_bin_correlation_complex`]: the
/// table the adequacy tests and the consistency checks use.
pub fn exp_window_bin_correlations(
    tau_s: Option<f64>,
    record_s: f64,
    df_hz: f64,
) -> Vec<Complex64> {
    (0..=MAX_CORRELATED_BINS)
        .map(|d| exp_window_bin_correlation_complex(tau_s, record_s, df_hz, d))
        .collect()
}

/// `|c(d)|` of [`exp_window_bin_correlation_complex`].
pub fn exp_window_bin_correlation(tau_s: Option<f64>, record_s: f64, df_hz: f64, d: usize) -> f64 {
    exp_window_bin_correlation_complex(tau_s, record_s, df_hz, d).norm()
}

/// Correlation of the relative magnitude errors of an estimate at two bins whose complex
/// noise correlates as `c` (`c(d)` of the later bin against the earlier,
/// [`exp_window_bin_correlation_complex`]) and whose phase turns by `turn_rad` from the
/// earlier to the later: `Re(c exp(-j turn))`. The relative error of `|H1|` is
/// `Re(N_k / Y_k)`, the noise over the response spectrum, and for circular noise
/// `cov(Re a, Re b) = Re E[a conj(b)] / 2`. At most `|c|`; with the default hammer window
/// `Re c(1) = 0.48` where the phase is flat, less where it turns through a resonance.
pub fn magnitude_bin_correlation(c: Complex64, turn_rad: f64) -> f64 {
    (c * Complex64::from_polar(1.0, -turn_rad)).re
}

/// Residual normalisers of the local models over correlated bins (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowDof {
    /// `E[RSS] / sigma^2` of the quadratic (3-parameter) model.
    pub residual_polynomial: f64,
    /// `E[RSS] / sigma^2` of the rational (4-parameter) model, with `u^3` standing in for
    /// its data-dependent fourth column.
    pub residual_rational: f64,
    /// Effective complex degrees of freedom of the quadratic model's noise estimate.
    pub effective: f64,
}

impl WindowDof {
    /// For `n_blocks` blocks of windows of `2 half_width + 1` bins with correlation
    /// `corr[j] = c(j step)` (`None`: independent bins, normalisers `K n - p`).
    pub fn new(corr: Option<&[Complex64]>, half_width: usize, n_blocks: usize) -> Result<Self> {
        let n = 2 * half_width + 1;
        let k = n_blocks as f64;
        let c = match corr {
            Some(c) if c.len() == n => c,
            Some(c) => {
                return Err(Error::Usage(format!(
                    "window correlation of {} lags for {n} bins",
                    c.len()
                )))
            }
            None => {
                let kn = k * n as f64;
                return Ok(WindowDof {
                    residual_polynomial: kn - 3.0,
                    residual_rational: kn - 4.0,
                    effective: kn - 3.0,
                });
            }
        };
        let cm = DMatrix::from_fn(n, n, |i, j| if i >= j { c[i - j] } else { c[j - i].conj() });
        let (tr_m3, tr_m3_sq) = projected_traces(&cm, half_width, 3)?;
        let (tr_m4, _) = projected_traces(&cm, half_width, 4)?;
        let tr_c2 = (&cm * &cm).trace().re;
        let rest = (k - 1.0) * n as f64;
        Ok(WindowDof {
            residual_polynomial: rest + tr_m3,
            residual_rational: rest + tr_m4,
            effective: (rest + tr_m3).powi(2) / ((k - 1.0) * tr_c2 + tr_m3_sq),
        })
    }
}

/// `tr(M)` and `tr(M^2)` for `M = (I - P) C (I - P)`, `P` the projection on the
/// polynomials of degree `< p` in `u = (i - m) / m`.
fn projected_traces(c: &DMatrix<Complex64>, m: usize, p: usize) -> Result<(f64, f64)> {
    let n = c.nrows();
    let v = DMatrix::from_fn(n, p, |i, q| {
        Complex64::new(
            ((i as f64 - m as f64) / m.max(1) as f64).powi(q as i32),
            0.0,
        )
    });
    let vh = v.adjoint();
    let gram = (&vh * &v)
        .try_inverse()
        .ok_or_else(|| Error::Numerical("local model basis is singular".into()))?;
    let proj = &v * gram * vh;
    let ip = DMatrix::<Complex64>::identity(n, n) - proj;
    let mm = &ip * c * &ip;
    Ok((mm.trace().re, (&mm * &mm).trace().re))
}

/// Seeded oracle noise for the tests of correlated bins: white noise of unit variance
/// over a record of `record_s` s at `fs_hz`, under the default whole-record hammer
/// window `exp(-t / tau)` with `T / tau = ln 20`, transformed directly at `n_bins`
/// neighbouring bins from `first_bin`; each bin scaled to unit variance per component.
#[cfg(test)]
pub(crate) struct WindowedNoise {
    pub tau_s: f64,
    pub df_hz: f64,
    twiddle: Vec<Vec<Complex64>>,
    scale: f64,
    n_samples: usize,
}

#[cfg(test)]
impl WindowedNoise {
    pub fn new(fs_hz: f64, record_s: f64, first_bin: usize, n_bins: usize) -> Self {
        let n_samples = (fs_hz * record_s) as usize;
        let tau_s = record_s / 20f64.ln();
        let w: Vec<f64> = (0..n_samples)
            .map(|i| (-(i as f64 / fs_hz) / tau_s).exp())
            .collect();
        let w2: f64 = w.iter().map(|v| v * v).sum();
        let twiddle = (0..n_bins)
            .map(|k| {
                let omega = 2.0 * std::f64::consts::PI * (first_bin + k) as f64 / n_samples as f64;
                (0..n_samples)
                    .map(|t| Complex64::from_polar(w[t], -omega * t as f64))
                    .collect()
            })
            .collect();
        WindowedNoise {
            tau_s,
            df_hz: 1.0 / record_s,
            twiddle,
            // E|N_k|^2 = w2 for unit white noise: parts of variance w2 / 2
            scale: (w2 / 2.0).sqrt(),
            n_samples,
        }
    }

    /// One draw of the `n_bins` spectra.
    pub fn draw(&self, rng: &mut impl rand::Rng) -> Vec<Complex64> {
        use rand_distr::{Distribution, StandardNormal};
        let x: Vec<f64> = (0..self.n_samples)
            .map(|_| StandardNormal.sample(rng))
            .collect();
        self.twiddle
            .iter()
            .map(|tw| tw.iter().zip(&x).map(|(t, x)| t * x).sum::<Complex64>() / self.scale)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::windows::exponential_window;

    /// Oracle: white noise through the default hammer window, transformed directly at 60
    /// bins across a resonance (the windowed pole spans about a bin, so the estimate's
    /// phase turns by pi within a few bins), 3,000 seeded draws, for one impact at the
    /// record's start and for a second impact of a quarter of its windowed amplitude 0.6
    /// of the record later (the input's phase then wobbles by up to 0.5 rad from bin to
    /// bin). At every pair of neighbouring bins the sample correlation of the relative
    /// magnitude errors is [`magnitude_bin_correlation`] of the window's `c(1)`, turned by
    /// the input's phase, within 4.5 of its sampling sd `(1 - rho^2) / sqrt(n)` (3.2 and
    /// 3.0 measured over the 59 pairs); the window's modulus `|c(1)| = 0.69` misses by
    /// more than 10 of them near the peak, and leaving out the input's turn misses the
    /// two-impact record by more than 10 as well.
    #[test]
    fn magnitude_errors_correlate_as_the_turned_window() {
        use rand::SeedableRng;
        let (first_bin, n) = (20, 60);
        let noise = WindowedNoise::new(250.0, 4.0, first_bin, n);
        let c1 = exp_window_bin_correlation_complex(Some(noise.tau_s), 4.0, noise.df_hz, 1);
        let two_pi = 2.0 * std::f64::consts::PI;
        let (wn, xi) = (two_pi * 12.5, 0.01);
        let h: Vec<Complex64> = (0..n)
            .map(|k| {
                let om = two_pi * noise.df_hz * (first_bin + k) as f64;
                let s = Complex64::new(om, -1.0 / noise.tau_s);
                Complex64::new(wn * wn, 0.0)
                    / (wn * wn - s * s + Complex64::new(0.0, 2.0 * xi * wn) * s)
            })
            .collect();
        for second_impact in [0.0, 0.25] {
            let force: Vec<Complex64> = (0..n)
                .map(|k| {
                    let turn = -two_pi * 0.6 * (first_bin + k) as f64;
                    1.0 + Complex64::from_polar(second_impact, turn)
                })
                .collect();
            let y: Vec<Complex64> = h.iter().zip(&force).map(|(h, f)| h * f).collect();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20261202);
            let draws = 3000;
            let (mut sxy, mut sxx) = (vec![0.0; n], vec![0.0; n]);
            for _ in 0..draws {
                let e: Vec<f64> = noise
                    .draw(&mut rng)
                    .iter()
                    .zip(&y)
                    .map(|(nk, yk)| (yk + 0.001 * nk).norm() / yk.norm() - 1.0)
                    .collect();
                for k in 0..n {
                    sxx[k] += e[k] * e[k];
                    if k > 0 {
                        sxy[k] += e[k] * e[k - 1];
                    }
                }
            }
            let se = |r: f64| (1.0 - r * r) / (draws as f64).sqrt();
            let (mut worst, mut modulus, mut without_input) = (0.0f64, 0.0f64, 0.0f64);
            for k in 1..n {
                let sample = sxy[k] / (sxx[k] * sxx[k - 1]).sqrt();
                let input =
                    force[k].conj() * force[k - 1] / (force[k].norm() * force[k - 1].norm());
                let turn = h[k].arg() - h[k - 1].arg();
                let rho = magnitude_bin_correlation(c1 * input, turn);
                worst = worst.max((sample - rho).abs() / se(rho));
                modulus = modulus.max((sample - c1.norm()).abs() / se(c1.norm()));
                let bare = magnitude_bin_correlation(c1, turn);
                without_input = without_input.max((sample - bare).abs() / se(bare));
            }
            eprintln!(
                "second impact {second_impact}: worst |error| / sd: turned {worst:.2}, \
                 modulus {modulus:.1}, without the input's turn {without_input:.1}"
            );
            assert!(worst < 4.5, "{worst}");
            assert!(modulus > 10.0, "{modulus}");
            if second_impact > 0.0 {
                assert!(without_input > 10.0, "{without_input}");
            }
        }
    }

    #[test]
    fn rectangular_and_padded_windows() {
        let w = NoiseWindow::new(None, 100, 100).unwrap();
        assert!((w.correlation(0) - 1.0).norm() < 1e-12);
        assert!(w.correlation(1).norm() < 1e-12 && w.correlation(7).norm() < 1e-12);
        assert_eq!(w.decorrelating_step(), 1);
        // padded x2: c(1) = (1 - e^{-j pi}) / (100 (1 - e^{-j pi / 100})) ~ 2 / (j pi)
        let w = NoiseWindow::new(None, 100, 200).unwrap();
        assert!((w.correlation(1).norm() - std::f64::consts::FRAC_2_PI).abs() < 1e-3);
        assert!(w.correlation(2).norm() < 1e-12);
        assert_eq!(w.decorrelating_step(), 2);
        assert!(NoiseWindow::new(Some(&[1.0; 3]), 4, 4).is_err());
    }

    /// Oracle: the continuous-time `c(d)` against the discrete sum of
    /// [`NoiseWindow::correlation`] (exponential, rectangular, padded), to the sampling
    /// error `O(dt / tau)`.
    #[test]
    fn continuous_bin_correlation_matches_the_discrete_window() {
        let (n, dt) = (11_800usize, 0.01);
        let t = n as f64 * dt;
        for tau in [t / 20f64.ln(), 20.0, f64::INFINITY] {
            let w = exponential_window(n, dt, tau);
            for pad in [1usize, 2] {
                let nw = NoiseWindow::new(Some(&w), n, pad * n).unwrap();
                let df = 1.0 / (pad as f64 * t);
                let tau_opt = tau.is_finite().then_some(tau);
                for d in [1usize, 2, 3, 8, 25] {
                    let cont = exp_window_bin_correlation_complex(tau_opt, t, df, d);
                    let disc = nw.correlation(d);
                    assert!(
                        (cont - disc).norm() < 2e-3,
                        "tau {tau} pad {pad} d {d}: {cont} {disc}"
                    );
                }
            }
        }
        // T / tau = ln 20: |c(1)| = 1 / sqrt(1 + (pi / ln 20)^2) to O(exp(-2 T / tau))
        let c1 = exp_window_bin_correlation(Some(t / 20f64.ln()), t, 1.0 / t, 1);
        let approx = 1.0 / (1.0 + (std::f64::consts::PI / 20f64.ln()).powi(2)).sqrt();
        assert!((c1 - approx).abs() < 1e-3, "{c1} {approx}");
        assert_eq!(exp_window_bin_correlation(None, t, 1.0 / t, 0), 1.0);
        assert!(exp_window_bin_correlation(None, t, 1.0 / t, 1) < 1e-12);
    }

    #[test]
    fn exponential_window_correlation_matches_closed_form() {
        // sum_n r^n e^{-j theta n} = (1 - r^N e^{-j theta N}) / (1 - r e^{-j theta}),
        // r = exp(-2 dt / tau), theta = 2 pi d / N
        let (n, dt, tau) = (5000usize, 0.01, 10.0);
        let w = exponential_window(n, dt, tau);
        let nw = NoiseWindow::new(Some(&w), n, n).unwrap();
        let r: f64 = (-2.0 * dt / tau).exp();
        let total = (1.0 - r.powi(n as i32)) / (1.0 - r);
        for d in [1usize, 3, 10] {
            let th = 2.0 * std::f64::consts::PI * d as f64 / n as f64;
            let exact = (1.0 - r.powi(n as i32) * Complex64::from_polar(1.0, -th * n as f64))
                / (1.0 - r * Complex64::from_polar(1.0, -th))
                / total;
            assert!((nw.correlation(d) - exact).norm() < 1e-10, "{d}");
        }
        // T / tau = 5: |c(d)| ~ 1 / sqrt(1 + (pi d / 5)^2) <= 0.5 from d = 3
        assert_eq!(nw.decorrelating_step(), 3);
    }

    #[test]
    fn window_dof_reduces_to_white_and_follows_theory() {
        let white = WindowDof::new(None, 4, 2).unwrap();
        assert_eq!(white.residual_polynomial, 15.0);
        assert_eq!(white.residual_rational, 14.0);
        let ident: Vec<Complex64> = (0..9)
            .map(|j| Complex64::new(if j == 0 { 1.0 } else { 0.0 }, 0.0))
            .collect();
        for k in [1, 3] {
            let d = WindowDof::new(Some(&ident), 4, k).unwrap();
            let white = WindowDof::new(None, 4, k).unwrap();
            assert!((d.residual_polynomial - white.residual_polynomial).abs() < 1e-9);
            assert!((d.residual_rational - white.residual_rational).abs() < 1e-9);
            assert!((d.effective - white.effective).abs() < 1e-9);
        }
        // c(d) = 1 / (1 + j pi d / 6): adjacent bins of a tau = T/6 window (module docs)
        let c: Vec<Complex64> = (0..9)
            .map(|j| 1.0 / Complex64::new(1.0, std::f64::consts::PI * j as f64 / 6.0))
            .collect();
        // oracle: the same traces by plain dense algebra outside this crate (Python, 9 x 9
        // complex matrices): tr(M) / 6 = 0.286607, tr(M)^2 / tr(M^2) = 1.842507
        let d = WindowDof::new(Some(&c), 4, 1).unwrap();
        assert!(
            (d.residual_polynomial / 6.0 - 0.286607).abs() < 1e-5,
            "{d:?}"
        );
        assert!((d.effective - 1.842507).abs() < 1e-5, "{d:?}");
        assert!(WindowDof::new(Some(&c[..3]), 4, 1).is_err());
    }
}
