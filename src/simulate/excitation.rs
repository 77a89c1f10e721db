//! Excitations defined in continuous time, then sampled at the internal rate (the
//! simulation joins the samples by straight lines, see [`super::discrete`]).

use super::config::{ChirpSpec, ImpactSpec};
use std::f64::consts::PI;

/// An input signal of continuous time; zero before `t = 0`.
pub trait Excitation: std::fmt::Debug + Send + Sync {
    /// Value at `t_s` (N for forces, m/s^2 for ground acceleration).
    fn value(&self, t_s: f64) -> f64;

    /// `n` samples at `rate_hz`, starting at `t = 0`.
    fn sample(&self, rate_hz: f64, n: usize) -> Vec<f64> {
        (0..n).map(|k| self.value(k as f64 / rate_hz)).collect()
    }
}

/// Hammer impacts: half-sine force pulses `F sin(pi (t - t0) / T)` on `[t0, t0 + T]`.
#[derive(Debug, Clone, PartialEq)]
pub struct HalfSinePulses {
    pub pulse_duration_s: f64,
    pub impacts: Vec<ImpactSpec>,
}

impl Excitation for HalfSinePulses {
    fn value(&self, t_s: f64) -> f64 {
        self.impacts
            .iter()
            .map(|imp| {
                let tau = t_s - imp.time_s;
                if (0.0..=self.pulse_duration_s).contains(&tau) {
                    imp.peak_force_n * (PI * tau / self.pulse_duration_s).sin()
                } else {
                    0.0
                }
            })
            .sum()
    }
}

/// Ground acceleration: a linear chirp from `f0_hz` to `f1_hz` over the sweep,
/// `a_g = A w(tau) sin(2 pi (f0 tau + (f1 - f0) tau^2 / (2 T)))`, `tau = t - start`, with
/// raised-cosine tapers `w` of length `taper_s` at both ends, and zero outside the sweep
/// (the ring-down).
#[derive(Debug, Clone, PartialEq)]
pub struct Chirp(pub ChirpSpec);

impl Chirp {
    /// Instantaneous frequency at `t_s` within the sweep.
    pub fn frequency_hz(&self, t_s: f64) -> f64 {
        let c = &self.0;
        c.f0_hz + (c.f1_hz - c.f0_hz) * (t_s - c.start_s) / c.sweep_duration_s
    }
}

impl Excitation for Chirp {
    fn value(&self, t_s: f64) -> f64 {
        let c = &self.0;
        let sweep = c.sweep_duration_s;
        let tau = t_s - c.start_s;
        if !(0.0..=sweep).contains(&tau) {
            return 0.0;
        }
        let edge = tau.min(sweep - tau);
        let w = if edge < c.taper_s {
            0.5 * (1.0 - (PI * edge / c.taper_s).cos())
        } else {
            1.0
        };
        let phase = 2.0 * PI * (c.f0_hz * tau + 0.5 * (c.f1_hz - c.f0_hz) * tau * tau / sweep);
        c.amplitude_m_per_s2 * w * phase.sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_sine_impulse_and_support() {
        let p = HalfSinePulses {
            pulse_duration_s: 0.003,
            impacts: vec![
                ImpactSpec {
                    time_s: 0.5,
                    peak_force_n: 50.0,
                },
                ImpactSpec {
                    time_s: 1.0,
                    peak_force_n: -20.0,
                },
            ],
        };
        // Trapezoid rule on a fine grid; the error of the rule is O(h^2) ~ 1e-9 relative.
        let rate = 1e6;
        let x = p.sample(rate, 2_000_000);
        let area_first: f64 = x[..750_000].iter().sum::<f64>() / rate;
        let area_second: f64 = x[750_000..].iter().sum::<f64>() / rate;
        let expect = |f: f64| 2.0 * f * 0.003 / PI;
        assert!((area_first - expect(50.0)).abs() < 1e-6 * expect(50.0));
        assert!((area_second - expect(-20.0)).abs() < 1e-6 * 20.0 * 0.003);
        assert_eq!(p.value(0.4999), 0.0);
        assert_eq!(p.value(0.5031), 0.0);
        assert!((p.value(0.5015) - 50.0).abs() < 1e-12);
    }

    #[test]
    fn chirp_frequency_taper_and_ring_down() {
        let c = Chirp(ChirpSpec {
            f0_hz: 0.0,
            f1_hz: 10.0,
            start_s: 0.5,
            sweep_duration_s: 60.0,
            taper_s: 1.0,
            amplitude_m_per_s2: 0.08,
        });
        assert_eq!(c.value(0.49), 0.0);
        assert_eq!(c.value(60.51), 0.0);
        // Tapers start and end at zero.
        assert!(c.value(0.5).abs() < 1e-15 && c.value(60.5).abs() < 1e-12);
        let rate = 10_000.0;
        let x = c.sample(rate, (61.0 * rate) as usize);
        assert!(x.iter().all(|v| v.abs() <= 0.08 + 1e-15));
        // Zero-crossing count between 30.5 s and 40.5 s: the phase advances by
        // int f dt = (5 + 6.6667) / 2 * 10 = 58.33 cycles, i.e. 116.7 half cycles.
        let (a, b) = ((30.5 * rate) as usize, (40.5 * rate) as usize);
        let crossings = x[a..b]
            .windows(2)
            .filter(|w| (w[0] < 0.0) != (w[1] < 0.0))
            .count() as f64;
        assert!((crossings - 116.67).abs() <= 1.0, "{crossings}");
        assert!((c.frequency_hz(30.5) - 5.0).abs() < 1e-12);
        // Full amplitude reached between the tapers.
        let peak = x[(20.0 * rate) as usize..(21.0 * rate) as usize]
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        assert!((peak - 0.08).abs() < 1e-5);
    }
}
