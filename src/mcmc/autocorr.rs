//! Autocorrelation and the integrated autocorrelation time, as emcee computes them
//! (`emcee.autocorr`): the normalised autocorrelation of each walker's series by FFT
//! (zero-padded to twice the next power of two), averaged over walkers, then
//! `tau(M) = 1 + 2 sum_{k=1}^{M} rho_k` with Sokal's automatic window: the smallest
//! `M` with `M >= c tau(M)`, `c = 5`.

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use rayon::prelude::*;

/// Reusable FFT plans for series of one length.
pub(crate) struct AcovPlan {
    len: usize,
    fft_len: usize,
    forward: std::sync::Arc<dyn realfft::RealToComplex<f64>>,
    inverse: std::sync::Arc<dyn realfft::ComplexToReal<f64>>,
}

impl AcovPlan {
    pub(crate) fn new(len: usize) -> Self {
        let fft_len = 2 * len.max(1).next_power_of_two();
        let mut planner = RealFftPlanner::<f64>::new();
        AcovPlan {
            len,
            fft_len,
            forward: planner.plan_fft_forward(fft_len),
            inverse: planner.plan_fft_inverse(fft_len),
        }
    }

    /// Biased autocovariance `acov_k = (1/N) sum_{t=0}^{N-1-k} (x_t - x̄)(x_{t+k} - x̄)`,
    /// `k = 0..N-1` (Geyer 1992; Stan and the `posterior` package use the same).
    pub(crate) fn autocovariance(&self, x: &[f64]) -> Vec<f64> {
        assert_eq!(x.len(), self.len, "series length differs from the plan");
        let n = x.len();
        if n == 0 {
            return Vec::new();
        }
        let mean = x.iter().sum::<f64>() / n as f64;
        let mut input = vec![0.0; self.fft_len];
        for (i, v) in x.iter().enumerate() {
            input[i] = v - mean;
        }
        let mut spectrum = vec![Complex::new(0.0, 0.0); self.fft_len / 2 + 1];
        self.forward
            .process(&mut input, &mut spectrum)
            .expect("buffer lengths come from the plan");
        for c in spectrum.iter_mut() {
            *c = Complex::new(c.norm_sqr(), 0.0);
        }
        self.inverse
            .process(&mut spectrum, &mut input)
            .expect("buffer lengths come from the plan");
        // realfft's inverse is unnormalised: divide by the FFT length, then by N.
        let scale = 1.0 / (self.fft_len as f64 * n as f64);
        input.truncate(n);
        for v in input.iter_mut() {
            *v *= scale;
        }
        input
    }

    /// Normalised autocorrelation `rho_k = acov_k / acov_0` (emcee's `function_1d`).
    /// A constant series (a walker that never moved) is perfectly correlated: all ones.
    pub(crate) fn autocorrelation(&self, x: &[f64]) -> Vec<f64> {
        let mut acf = self.autocovariance(x);
        match acf.first().copied() {
            Some(c0) if c0 > 0.0 => acf.iter_mut().for_each(|v| *v /= c0),
            _ => acf.iter_mut().for_each(|v| *v = 1.0),
        }
        acf
    }
}

/// Normalised autocorrelation function of one series (emcee's `function_1d`).
pub fn autocorrelation(x: &[f64]) -> Vec<f64> {
    AcovPlan::new(x.len()).autocorrelation(x)
}

/// Integrated autocorrelation time of one parameter from several walkers' series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TauEstimate {
    /// `tau` in samples of the series.
    pub tau: f64,
    /// Sokal window `M`.
    pub window: usize,
    /// False when no lag satisfied `M >= c tau(M)` (the series is too short; the last
    /// lag was used, so `tau` is a lower bound). emcee returns `tau = 1` in that case.
    pub window_found: bool,
}

impl TauEstimate {
    /// emcee's `tol` check: is the series longer than `tol * tau`?
    pub fn is_reliable(&self, n: usize, tol: f64) -> bool {
        self.window_found && tol * self.tau < n as f64
    }
}

/// emcee's `integrated_time` for one parameter: autocorrelation averaged over the given
/// equal-length series (walkers), then Sokal's window with constant `c` (5 in emcee).
///
/// ```
/// // White noise has tau ~ 1.
/// use frfbayes::mcmc::integrated_time;
/// let x: Vec<f64> = (0..4096u64).map(|i| ((i * 2654435761) % 1000) as f64).collect();
/// let t = integrated_time(&[&x[..]], 5.0);
/// assert!((t.tau - 1.0).abs() < 0.3);
/// ```
pub fn integrated_time(series: &[&[f64]], c: f64) -> TauEstimate {
    let n = series.first().map_or(0, |s| s.len());
    assert!(
        series.iter().all(|s| s.len() == n),
        "all series must have the same length"
    );
    let plan = AcovPlan::new(n);
    let acfs: Vec<Vec<f64>> = series
        .par_iter()
        .map(|s| plan.autocorrelation(s))
        .collect();
    let mut mean = vec![0.0; n];
    for acf in &acfs {
        for (m, a) in mean.iter_mut().zip(acf) {
            *m += a;
        }
    }
    for m in mean.iter_mut() {
        *m /= series.len() as f64;
    }
    sokal_window(&mean, c)
}

/// `taus[M] = 2 sum_{k=0}^{M} rho_k - 1`; window = first `M` with `M >= c taus[M]`.
pub(crate) fn sokal_window(rho: &[f64], c: f64) -> TauEstimate {
    let mut cum = 0.0;
    let mut last = f64::NAN;
    for (m, r) in rho.iter().enumerate() {
        cum += r;
        let tau = 2.0 * cum - 1.0;
        if (m as f64) >= c * tau {
            return TauEstimate {
                tau,
                window: m,
                window_found: true,
            };
        }
        last = tau;
    }
    TauEstimate {
        tau: last,
        window: rho.len().saturating_sub(1),
        window_found: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_autocovariance_matches_the_direct_sum() {
        let x: Vec<f64> = (0..37).map(|i| ((i * 7919) % 31) as f64 * 0.1 + (i as f64).sin()).collect();
        let n = x.len();
        let mean = x.iter().sum::<f64>() / n as f64;
        let acov = AcovPlan::new(n).autocovariance(&x);
        for k in 0..n {
            let direct: f64 = (0..n - k).map(|t| (x[t] - mean) * (x[t + k] - mean)).sum::<f64>()
                / n as f64;
            assert!((acov[k] - direct).abs() < 1e-12, "lag {k}");
        }
    }

    #[test]
    fn sokal_window_on_a_known_acf() {
        // rho_k = 0.5^k: tau(M) = 1 + 2 (1 - 0.5^M) -> 3; first M >= 5 tau(M) is 15.
        let rho: Vec<f64> = (0..100).map(|k| 0.5f64.powi(k)).collect();
        let t = sokal_window(&rho, 5.0);
        assert_eq!(t.window, 15);
        assert!((t.tau - (3.0 - 2.0 * 0.5f64.powi(15))).abs() < 1e-12);
        let short = sokal_window(&rho[..10], 5.0);
        assert!(!short.window_found);
    }
}
