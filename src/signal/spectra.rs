//! Discrete Fourier transforms of blocks and the averaged spectra behind H1, H2 and the
//! ordinary coherence.
//!
//! Conventions: `X_k = sum_n x_n exp(-2 pi j k n / N)` over the zero-padded block of
//! `N = n_fft` samples (realfft, unnormalised), bins `k = 0..=N/2` at `k fs / N` Hz.
//! Spectra are block sums, unnormalised: `Gff_k = sum_b |F_b,k|^2`,
//! `Gfy_k = sum_b conj(F_b,k) Y_b,k`, `Gyy_k = sum_b |Y_b,k|^2`. Only ratios of them are
//! used, so the one-sided / PSD scale factors cancel.
//!
//! - H1 = Gfy / Gff: unbiased by output noise, biased low by input noise.
//! - H2 = Gyy / conj(Gfy) (= Gyy / Gyf): unbiased by input noise, biased high by output
//!   noise.
//! - ordinary coherence `gamma^2 = |Gfy|^2 / (Gff Gyy) = H1 / H2`. With one block it is 1
//!   by construction (and H1 = H2), and with few blocks it is biased high
//!   (`E[gamma^2] >= 1/n` even for unrelated signals); see [`super::noise`] for the
//!   estimate used with few blocks.

use crate::error::{Error, Result};
use num_complex::Complex64;
use realfft::RealFftPlanner;

/// Forward real FFTs with cached plans.
pub struct Fft {
    planner: RealFftPlanner<f64>,
}

impl std::fmt::Debug for Fft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Fft")
    }
}

impl Default for Fft {
    fn default() -> Self {
        Fft {
            planner: RealFftPlanner::new(),
        }
    }
}

impl Fft {
    /// A planner with an empty plan cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// DFT of `x` (optionally multiplied sample by sample by `window`, which must then have
    /// the length of `x`) zero-padded to `n_fft >= x.len()`; returns the `n_fft/2 + 1`
    /// non-negative-frequency bins.
    pub fn forward(
        &mut self,
        x: &[f64],
        window: Option<&[f64]>,
        n_fft: usize,
    ) -> Result<Vec<Complex64>> {
        if n_fft < x.len() || n_fft == 0 {
            return Err(Error::Usage(format!(
                "FFT length {n_fft} shorter than the block ({} samples)",
                x.len()
            )));
        }
        let plan = self.planner.plan_fft_forward(n_fft);
        let mut input = plan.make_input_vec();
        match window {
            Some(w) => {
                if w.len() != x.len() {
                    return Err(Error::Usage(format!(
                        "window of {} samples for a block of {}",
                        w.len(),
                        x.len()
                    )));
                }
                for ((o, &v), &wv) in input.iter_mut().zip(x).zip(w) {
                    *o = v * wv;
                }
            }
            None => input[..x.len()].copy_from_slice(x),
        }
        let mut out = plan.make_output_vec();
        plan.process(&mut input, &mut out)
            .map_err(|e| Error::Numerical(format!("FFT failed: {e}")))?;
        Ok(out)
    }

    /// Inverse of [`Self::forward`] without window or padding: the `n_fft` real samples
    /// `x_n = (1/N) sum_k X_k exp(2 pi j k n / N)` of the half spectrum `spectrum`
    /// (`n_fft/2 + 1` bins; the imaginary parts of bin 0 and, for even `n_fft`, of the
    /// Nyquist bin are ignored, as for any real signal).
    pub fn inverse(&mut self, spectrum: &[Complex64], n_fft: usize) -> Result<Vec<f64>> {
        if n_fft == 0 || spectrum.len() != n_fft / 2 + 1 {
            return Err(Error::Usage(format!(
                "inverse FFT of {n_fft} points needs {} bins, got {}",
                n_fft / 2 + 1,
                spectrum.len()
            )));
        }
        let plan = self.planner.plan_fft_inverse(n_fft);
        let mut input = spectrum.to_vec();
        input[0].im = 0.0;
        if n_fft.is_multiple_of(2) {
            input[n_fft / 2].im = 0.0;
        }
        let mut out = plan.make_output_vec();
        plan.process(&mut input, &mut out)
            .map_err(|e| Error::Numerical(format!("inverse FFT failed: {e}")))?;
        let scale = 1.0 / n_fft as f64;
        out.iter_mut().for_each(|v| *v *= scale);
        Ok(out)
    }
}

/// Frequencies of the bins of an `n_fft`-point transform at `sample_rate_hz`.
pub fn bin_freq_hz(n_fft: usize, sample_rate_hz: f64) -> Vec<f64> {
    (0..=n_fft / 2)
        .map(|k| k as f64 * sample_rate_hz / n_fft as f64)
        .collect()
}

/// Block-summed auto- and cross-spectra of one input and one output.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossSpectra {
    /// `sum_b |F_b|^2`.
    pub gff: Vec<f64>,
    /// `sum_b conj(F_b) Y_b`.
    pub gfy: Vec<Complex64>,
    /// `sum_b |Y_b|^2`.
    pub gyy: Vec<f64>,
    /// Number of blocks summed.
    pub n_blocks: usize,
}

impl CrossSpectra {
    /// Sums over blocks; `f_blocks[b]` and `y_blocks[b]` are the spectra of block `b`.
    pub fn from_blocks(f_blocks: &[Vec<Complex64>], y_blocks: &[Vec<Complex64>]) -> Result<Self> {
        let n_bins = f_blocks.first().map_or(0, Vec::len);
        if f_blocks.len() != y_blocks.len()
            || f_blocks.iter().chain(y_blocks).any(|b| b.len() != n_bins)
        {
            return Err(Error::Usage(
                "input and output block spectra differ in count or length".into(),
            ));
        }
        let mut s = CrossSpectra {
            gff: vec![0.0; n_bins],
            gfy: vec![Complex64::new(0.0, 0.0); n_bins],
            gyy: vec![0.0; n_bins],
            n_blocks: f_blocks.len(),
        };
        for (fb, yb) in f_blocks.iter().zip(y_blocks) {
            for k in 0..n_bins {
                let (f, y) = (fb[k], yb[k]);
                s.gff[k] += f.norm_sqr();
                s.gfy[k] += f.conj() * y;
                s.gyy[k] += y.norm_sqr();
            }
        }
        Ok(s)
    }

    /// `H1 = Gfy / Gff`; 0 where the input has no power (see [`Self::null_input`]).
    pub fn h1(&self) -> Vec<Complex64> {
        let floor = self.null_floor();
        self.gfy
            .iter()
            .zip(&self.gff)
            .map(|(&g, &p)| {
                if p > floor {
                    g / p
                } else {
                    Complex64::new(0.0, 0.0)
                }
            })
            .collect()
    }

    /// `H2 = Gyy / conj(Gfy)`; 0 where the input or the cross spectrum has no power.
    pub fn h2(&self) -> Vec<Complex64> {
        let floor = self.null_floor();
        self.gfy
            .iter()
            .zip(&self.gff)
            .zip(&self.gyy)
            .map(|((&g, &p), &q)| {
                if p > floor && g.norm_sqr() > 0.0 {
                    q / g.conj()
                } else {
                    Complex64::new(0.0, 0.0)
                }
            })
            .collect()
    }

    /// Ordinary coherence `|Gfy|^2 / (Gff Gyy)` in [0, 1]; 0 where either power is null.
    /// Identically 1 for a single block.
    pub fn ordinary_coherence(&self) -> Vec<f64> {
        let floor = self.null_floor();
        self.gfy
            .iter()
            .zip(&self.gff)
            .zip(&self.gyy)
            .map(|((&g, &p), &q)| {
                if p > floor && q > 0.0 {
                    (g.norm_sqr() / (p * q)).min(1.0)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// Per bin: true where the input power is at or below `1e-28` of its maximum (rounding
    /// level of the FFT): there the ratio estimators are undefined and are reported as 0.
    pub fn null_input(&self) -> Vec<bool> {
        let floor = self.null_floor();
        self.gff.iter().map(|&p| p <= floor).collect()
    }

    fn null_floor(&self) -> f64 {
        let max = self.gff.iter().cloned().fold(0.0, f64::max);
        max * 1e-28
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_matches_naive_dft_with_padding_and_window() {
        let x: Vec<f64> = (0..37)
            .map(|n| ((n * n) as f64 * 0.37).sin() + 0.1 * n as f64)
            .collect();
        let w: Vec<f64> = (0..37).map(|n| 1.0 - n as f64 / 50.0).collect();
        let n_fft = 64;
        let got = Fft::new().forward(&x, Some(&w), n_fft).unwrap();
        assert_eq!(got.len(), 33);
        for (k, g) in got.iter().enumerate() {
            let mut s = Complex64::new(0.0, 0.0);
            for n in 0..x.len() {
                let ang = -2.0 * std::f64::consts::PI * (k * n) as f64 / n_fft as f64;
                s += x[n] * w[n] * Complex64::from_polar(1.0, ang);
            }
            assert!((s - g).norm() < 1e-12, "bin {k}");
        }
        assert!(Fft::new().forward(&x, None, 16).is_err());
        for n in [64, 63] {
            let back = Fft::new()
                .inverse(&Fft::new().forward(&x, None, n).unwrap(), n)
                .unwrap();
            for (i, b) in back.iter().enumerate() {
                let v = if i < x.len() { x[i] } else { 0.0 };
                assert!((b - v).abs() < 1e-12, "{n} {i}");
            }
        }
        assert!(Fft::new().inverse(&got, 60).is_err());
        assert!(Fft::new().forward(&x, Some(&w[..5]), 64).is_err());
    }

    #[test]
    fn h1_h2_coherence_identities() {
        let f = vec![vec![Complex64::new(1.0, 2.0), Complex64::new(0.0, 0.0)]];
        let h = Complex64::new(-0.3, 0.8);
        let y = vec![vec![f[0][0] * h, Complex64::new(1.0, 0.0)]];
        let s = CrossSpectra::from_blocks(&f, &y).unwrap();
        assert!((s.h1()[0] - h).norm() < 1e-15);
        assert!((s.h2()[0] - h).norm() < 1e-15);
        assert_eq!(s.ordinary_coherence()[0], 1.0);
        // null input bin: reported as 0, not NaN
        assert_eq!(s.h1()[1], Complex64::new(0.0, 0.0));
        assert_eq!(s.ordinary_coherence()[1], 0.0);
        assert_eq!(s.null_input(), vec![false, true]);
        // two blocks with output noise: gamma^2 = H1 / H2 (real, < 1)
        let f = vec![
            vec![Complex64::new(1.0, 0.0)],
            vec![Complex64::new(0.0, 1.0)],
        ];
        let y = vec![
            vec![Complex64::new(2.0, 0.1)],
            vec![Complex64::new(0.3, 1.9)],
        ];
        let s = CrossSpectra::from_blocks(&f, &y).unwrap();
        let ratio = s.h1()[0] / s.h2()[0];
        assert!(ratio.im.abs() < 1e-15);
        assert!((ratio.re - s.ordinary_coherence()[0]).abs() < 1e-15 && ratio.re < 1.0);
    }
}
