//! Anti-aliasing and resampling: a linear-phase (symmetric, odd-length) windowed-sinc
//! FIR low-pass with a Kaiser window, applied with zero delay and evaluated only at the
//! kept samples (decimation by an integer factor).
//!
//! Design (Kaiser's formulas, Oppenheim & Schafer sec. 7.5.3): for a transition band
//! `[f_pass, f_stop]` at input rate `fs` and attenuation `A` dB, the ripple is
//! `delta = 10^(-A/20)` in *both* bands (pass-band gain within `1 +- delta`, stop-band
//! gain below `delta`), the window parameter `beta = 0.1102 (A - 8.7)` (A > 50), the
//! length `N = ceil((A - 7.95) / (2.285 * 2 pi (f_stop - f_pass) / fs)) + 1` (made odd),
//! and the ideal cut-off sits mid-transition. The taps are scaled to unit DC gain.
//!
//! The simulator uses `f_pass = passband_fraction * f_out / 2`, `f_stop = f_out / 2`: the
//! defaults (0.8, 100 dB) give a pass band to 200 Hz at 500 Hz output with
//! +-1e-5 (8.7e-5 dB) ripple, and everything from 250 Hz up attenuated by 100 dB, so only
//! the 200-250 Hz band of the written record can hold (attenuated) aliases. The same
//! filter is applied to every channel, inputs included, so FRFs are unaffected.

use crate::error::{Error, Result};
use num_complex::Complex64;
use std::f64::consts::PI;

/// A zero-phase FIR low-pass followed by keeping every `factor`-th sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Decimator {
    /// Symmetric taps, odd length; the centre tap is at time zero.
    taps: Vec<f64>,
    factor: usize,
}

impl Decimator {
    /// Designs the Kaiser low-pass for input rate `input_rate_hz`, decimation `factor`,
    /// pass band to `passband_edge_hz`, stop band from `stopband_edge_hz` attenuated by
    /// `attenuation_db`. `factor == 1` gives the identity (no filter).
    pub fn kaiser(
        input_rate_hz: f64,
        factor: usize,
        passband_edge_hz: f64,
        stopband_edge_hz: f64,
        attenuation_db: f64,
    ) -> Result<Self> {
        if factor == 0 {
            return Err(Error::Usage("decimation factor must be at least 1".into()));
        }
        if factor == 1 {
            return Ok(Decimator {
                taps: vec![1.0],
                factor,
            });
        }
        if !(0.0 < passband_edge_hz
            && passband_edge_hz < stopband_edge_hz
            && stopband_edge_hz <= 0.5 * input_rate_hz)
        {
            return Err(Error::Usage(format!(
                "anti-aliasing bands must satisfy 0 < {passband_edge_hz} < {stopband_edge_hz} <= {} Hz",
                0.5 * input_rate_hz
            )));
        }
        if !(21.0..=200.0).contains(&attenuation_db) {
            return Err(Error::Usage(format!(
                "stop-band attenuation {attenuation_db} dB outside [21, 200]"
            )));
        }
        let a = attenuation_db;
        let beta = if a > 50.0 {
            0.1102 * (a - 8.7)
        } else {
            0.5842 * (a - 21.0).powf(0.4) + 0.07886 * (a - 21.0)
        };
        let dw = 2.0 * PI * (stopband_edge_hz - passband_edge_hz) / input_rate_hz;
        let mut n = ((a - 7.95) / (2.285 * dw)).ceil() as usize + 1;
        if n.is_multiple_of(2) {
            n += 1;
        }
        let half = (n / 2) as f64;
        let fc = 0.5 * (passband_edge_hz + stopband_edge_hz) / input_rate_hz; // cycles/sample
        let i0_beta = bessel_i0(beta);
        let mut taps: Vec<f64> = (0..n)
            .map(|i| {
                let m = i as f64 - half;
                let sinc = if m == 0.0 {
                    2.0 * fc
                } else {
                    (2.0 * PI * fc * m).sin() / (PI * m)
                };
                let r = m / half;
                sinc * bessel_i0(beta * (1.0 - r * r).max(0.0).sqrt()) / i0_beta
            })
            .collect();
        let dc: f64 = taps.iter().sum();
        taps.iter_mut().for_each(|t| *t /= dc);
        Ok(Decimator { taps, factor })
    }

    /// The filter taps (centre tap at index `len / 2`).
    pub fn taps(&self) -> &[f64] {
        &self.taps
    }

    /// Decimation factor.
    pub fn factor(&self) -> usize {
        self.factor
    }

    /// Input samples needed after the last kept sample (half the filter length).
    pub fn half_len(&self) -> usize {
        self.taps.len() / 2
    }

    /// Gain of the (zero-phase, so real) filter at `freq_hz` for input rate `input_rate_hz`.
    pub fn gain(&self, freq_hz: f64, input_rate_hz: f64) -> f64 {
        let half = self.half_len() as f64;
        let w = 2.0 * PI * freq_hz / input_rate_hz;
        let h: Complex64 = self
            .taps
            .iter()
            .enumerate()
            .map(|(i, &t)| Complex64::from_polar(t, -w * (i as f64 - half)))
            .sum();
        h.re
    }

    /// Output sample j is `sum_i taps[i] x[j factor - half + i]`, with `x` zero outside
    /// its range (the system is at rest before `t = 0`; the caller simulates
    /// [`Self::half_len`] samples past the record so its end is exact). Returns `n_out`
    /// samples.
    pub fn apply(&self, x: &[f64], n_out: usize) -> Vec<f64> {
        let half = self.half_len();
        let n = self.taps.len();
        (0..n_out)
            .map(|j| {
                let c = j * self.factor;
                // x index = c - half + i, for i in [lo, hi)
                let lo = half.saturating_sub(c);
                let hi = n.min((x.len() + half).saturating_sub(c));
                if lo >= hi {
                    return 0.0;
                }
                let start = c + lo - half;
                dot4(&self.taps[lo..hi], &x[start..start + (hi - lo)])
            })
            .collect()
    }
}

/// Dot product with four accumulators (lets the compiler vectorise).
fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Modified Bessel function of the first kind, order zero, by its power series
/// `sum_k ((x/2)^k / k!)^2` (all terms positive, so no cancellation).
pub fn bessel_i0(x: f64) -> f64 {
    let q = 0.25 * x * x;
    let mut term = 1.0;
    let mut sum = 1.0;
    let mut k = 1.0;
    while term > 1e-17 * sum {
        term *= q / (k * k);
        sum += term;
        k += 1.0;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bessel_i0_reference_values() {
        // Abramowitz & Stegun table 9.8: I0(1) = 1.266065878, I0(5) = 27.23987182.
        assert!((bessel_i0(0.0) - 1.0).abs() < 1e-16);
        assert!((bessel_i0(1.0) - 1.266_065_877_752_008_4).abs() < 1e-14);
        assert!((bessel_i0(5.0) - 27.239_871_823_604_45).abs() < 1e-11);
    }

    #[test]
    fn kaiser_meets_its_ripple_specification() {
        let fs = 5000.0;
        for (att, frac) in [(100.0, 0.8), (60.0, 0.6), (120.0, 0.9)] {
            let f_stop = 250.0;
            let f_pass = frac * f_stop;
            let d = Decimator::kaiser(fs, 10, f_pass, f_stop, att).unwrap();
            assert_eq!(d.taps().len() % 2, 1);
            let delta = 10f64.powf(-att / 20.0);
            // Kaiser's formulas are empirical: allow 1.5 delta (checked densely).
            let tol = 1.5 * delta;
            for i in 0..=2000 {
                let f = f_pass * i as f64 / 2000.0;
                let g = d.gain(f, fs);
                assert!((g - 1.0).abs() <= tol, "{att} dB: pass {f} Hz gain {g}");
            }
            for i in 0..=4000 {
                let f = f_stop + (0.5 * fs - f_stop) * i as f64 / 4000.0;
                let g = d.gain(f, fs);
                assert!(g.abs() <= tol, "{att} dB: stop {f} Hz gain {g:e}");
            }
        }
    }

    #[test]
    fn decimation_keeps_centred_samples_of_a_passband_sinusoid() {
        let fs = 5000.0;
        let d = Decimator::kaiser(fs, 10, 200.0, 250.0, 100.0).unwrap();
        let f = 37.0;
        let n_out = 400;
        let n_in = (n_out - 1) * 10 + 1 + d.half_len();
        let x: Vec<f64> = (0..n_in)
            .map(|k| (2.0 * PI * f * k as f64 / fs + 0.3).sin())
            .collect();
        let y = d.apply(&x, n_out);
        let gain = d.gain(f, fs);
        // Away from the start (where the zero padding cuts the sinusoid) the output is
        // the input scaled by the real gain, at the same instants (zero phase).
        for (j, v) in y.iter().enumerate().skip(d.half_len() / 10 + 1) {
            let expect = gain * (2.0 * PI * f * j as f64 / 500.0 + 0.3).sin();
            assert!((v - expect).abs() < 1e-12, "{j}: {v} vs {expect}");
        }
        assert_eq!(y.len(), n_out);
        let id = Decimator::kaiser(fs, 1, 200.0, 250.0, 100.0).unwrap();
        assert_eq!(id.apply(&x[..10], 10), x[..10].to_vec());
    }
}
