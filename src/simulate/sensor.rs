//! Sensors as a chain of stages per channel: the physical quantity at the internal rate
//! goes through each [`SensorStage`] in order (sensor dynamics and timing effects at the
//! internal rate, then anti-aliasing and decimation, then noise at the output rate).

use super::antialias::Decimator;
use crate::error::{Error, Result};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::sync::Arc;

/// Uniformly sampled samples of one channel, starting at `t = 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct Signal {
    pub samples: Vec<f64>,
    pub rate_hz: f64,
}

/// One transformation of a channel's signal.
pub trait SensorStage: std::fmt::Debug + Send + Sync {
    /// Transforms `signal`; may change its rate and length.
    fn apply(&self, signal: Signal) -> Result<Signal>;

    /// Samples this stage needs past the end of the record to be exact to its end (a
    /// stage that reads ahead in time); the simulation runs that much longer.
    fn lookahead_samples(&self, _rate_hz: f64) -> usize {
        0
    }
}

/// Anti-aliasing low-pass and decimation to `n_out` samples (see [`Decimator`]).
#[derive(Debug, Clone)]
pub struct Decimate {
    pub decimator: Arc<Decimator>,
    pub n_out: usize,
}

impl SensorStage for Decimate {
    fn apply(&self, signal: Signal) -> Result<Signal> {
        let needed = (self.n_out.max(1) - 1) * self.decimator.factor() + 1;
        if signal.samples.len() < needed {
            return Err(Error::Usage(format!(
                "decimation to {} samples needs {needed} input samples, got {}",
                self.n_out,
                signal.samples.len()
            )));
        }
        Ok(Signal {
            samples: self.decimator.apply(&signal.samples, self.n_out),
            rate_hz: signal.rate_hz / self.decimator.factor() as f64,
        })
    }
}

/// Additive stationary Gaussian noise of standard deviation `std` (in the channel's
/// unit): white when `ar1 = 0`, otherwise the first-order autoregression
/// `n_t = ar1 n_(t-1) + sqrt(1 - ar1^2) std e_t` started from its stationary law
/// (`n_0 = std e_0`), so every sample has sd `std` and lag-k correlation `ar1^k`.
/// The innovations `e_t` are drawn from `ChaCha8Rng` seeded with `seed` on stream
/// `stream`, so each channel's noise depends only on the seed and its own stream,
/// whatever the order or thread in which channels are simulated; white noise is the
/// same draws as before the coefficient existed.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianNoise {
    pub std: f64,
    pub seed: u64,
    pub stream: u64,
    /// Lag-one autocorrelation at the signal's rate, in `[0, 1)`.
    pub ar1: f64,
}

impl SensorStage for GaussianNoise {
    fn apply(&self, mut signal: Signal) -> Result<Signal> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(self.stream);
        let innovation = (1.0 - self.ar1 * self.ar1).sqrt();
        let mut previous: Option<f64> = None;
        for v in &mut signal.samples {
            let z: f64 = rng.sample(StandardNormal);
            let n = match previous {
                Some(p) if self.ar1 != 0.0 => self.ar1 * p + innovation * z,
                _ => z,
            };
            previous = Some(n);
            *v += self.std * n;
        }
        Ok(signal)
    }
}

/// A stable 64-bit stream number for a channel: FNV-1a of `test/channel`. Stable across
/// platforms and Rust versions (unlike `DefaultHasher`), so a seed reproduces a campaign.
pub fn noise_stream(test: &str, channel: &str) -> u64 {
    fnv1a64(test.bytes().chain([b'/']).chain(channel.bytes()))
}

/// 64-bit FNV-1a hash.
fn fnv1a64(bytes: impl Iterator<Item = u8>) -> u64 {
    bytes.fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Runs `signal` through `stages` in order.
pub fn run_chain(stages: &[Arc<dyn SensorStage>], signal: Signal) -> Result<Signal> {
    stages.iter().try_fold(signal, |s, stage| stage.apply(s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_has_its_standard_deviation_and_depends_only_on_seed_and_stream() {
        let n = 200_000;
        let zero = Signal {
            samples: vec![0.0; n],
            rate_hz: 500.0,
        };
        let noise = GaussianNoise {
            std: 0.005,
            seed: 7,
            stream: noise_stream("hammer-floor1", "acc1"),
            ar1: 0.0,
        };
        let a = noise.apply(zero.clone()).unwrap().samples;
        let b = noise.apply(zero.clone()).unwrap().samples;
        assert_eq!(a, b);
        // Sample std of n Gaussian draws: standard error of s^2 is sigma^2 sqrt(2/n), so
        // |s/sigma - 1| < 5 sqrt(1/(2n)) = 0.0079 with overwhelming probability; the mean
        // has standard error sigma/sqrt(n), bound 5 sigma/sqrt(n).
        let mean = a.iter().sum::<f64>() / n as f64;
        let var = a.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        assert!((var.sqrt() / 0.005 - 1.0).abs() < 5.0 * (0.5 / n as f64).sqrt());
        assert!(mean.abs() < 5.0 * 0.005 / (n as f64).sqrt());
        let other = GaussianNoise {
            stream: noise_stream("hammer-floor1", "acc2"),
            ..noise.clone()
        };
        let c = other.apply(zero).unwrap().samples;
        // Independent streams: sample correlation within 5/sqrt(n).
        let corr = a.iter().zip(&c).map(|(x, y)| x * y).sum::<f64>() / (n as f64 * 0.005 * 0.005);
        assert!(corr.abs() < 5.0 / (n as f64).sqrt(), "{corr}");
    }

    #[test]
    fn red_noise_has_its_standard_deviation_and_lag_correlations() {
        let (n, phi, sd) = (200_000, 0.9, 0.005);
        let zero = Signal {
            samples: vec![0.0; n],
            rate_hz: 500.0,
        };
        let noise = GaussianNoise {
            std: sd,
            seed: 11,
            stream: noise_stream("hammer-floor2", "acc3"),
            ar1: phi,
        };
        let a = noise.apply(zero).unwrap().samples;
        let lag = |k: usize| {
            a.iter().zip(&a[k..]).map(|(x, y)| x * y).sum::<f64>() / ((n - k) as f64 * sd * sd)
        };
        // AR(1) theory (Bartlett): var(s^2 / sigma^2) = 2 (1 + phi^2) / ((1 - phi^2) n),
        // var(r_1) = (1 - phi^2) / n; 5 sd bounds.
        let s2 = lag(0);
        let sd_s2 = (2.0 * (1.0 + phi * phi) / ((1.0 - phi * phi) * n as f64)).sqrt();
        assert!((s2 - 1.0).abs() < 5.0 * sd_s2, "{s2}");
        let r1 = lag(1) / s2;
        assert!(
            (r1 - phi).abs() < 5.0 * ((1.0 - phi * phi) / n as f64).sqrt(),
            "{r1}"
        );
        // Lag 2: phi^2, with Bartlett's variance for an AR(1),
        // ((1 + phi^2) (1 + phi^4) / (1 - phi^2) - 4 phi^4) / n.
        let r2 = lag(2) / s2;
        let (p2, p4) = (phi * phi, phi.powi(4));
        let var_r2 = ((1.0 + p2) * (1.0 + p4) / (1.0 - p2) - 4.0 * p4) / n as f64;
        assert!((r2 - p2).abs() < 5.0 * var_r2.sqrt(), "{r2}");
        // White noise with ar1 = 0 is uncorrelated at lag one.
        let white = GaussianNoise { ar1: 0.0, ..noise };
        let w = white
            .apply(Signal {
                samples: vec![0.0; n],
                rate_hz: 500.0,
            })
            .unwrap()
            .samples;
        let w1 = w.iter().zip(&w[1..]).map(|(x, y)| x * y).sum::<f64>() / (n as f64 * sd * sd);
        assert!(w1.abs() < 5.0 / (n as f64).sqrt(), "{w1}");
    }

    #[test]
    fn stream_numbers_are_stable() {
        // FNV-1a 64 reference values: "" -> offset basis, "a" -> 0xaf63dc4c8601ec8c.
        assert_eq!(fnv1a64("".bytes()), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64("a".bytes()), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(noise_stream("t", "x"), fnv1a64("t/x".bytes()));
        assert_ne!(noise_stream("t", "acc1"), noise_stream("t", "acc2"));
        assert_ne!(noise_stream("ab", "c"), noise_stream("a", "bc"));
        assert_eq!(noise_stream("t", "x"), noise_stream("t", "x"));
    }
}
