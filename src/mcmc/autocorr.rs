//! Autocorrelation and the integrated autocorrelation time, as emcee computes them
//! (`emcee.autocorr`): the normalised autocorrelation of each walker's series,
//! averaged over walkers, then `tau(M) = 1 + 2 sum_{k=1}^{M} rho_k` with Sokal's
//! automatic window: the smallest `M` with `M >= c tau(M)`, `c = 5`.
//!
//! Autocovariances come from an FFT zero-padded to at least `2N` (any such length gives
//! the exact linear autocovariance; emcee pads to twice the next power of two, here the
//! next even 5-smooth length). As the inverse FFT is linear, the walkers' normalised
//! power spectra are summed first and transformed back once per parameter.

use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

/// Smallest even `m >= n` whose only prime factors are 2, 3 and 5.
fn good_fft_size(n: usize) -> usize {
    let mut m = n.max(2);
    loop {
        if m.is_multiple_of(2) {
            let mut r = m;
            for p in [2, 3, 5] {
                while r.is_multiple_of(p) {
                    r /= p;
                }
            }
            if r == 1 {
                return m;
            }
        }
        m += 1;
    }
}

/// Reusable FFT plans for series of one length.
pub(crate) struct AcovPlan {
    len: usize,
    fft_len: usize,
    forward: std::sync::Arc<dyn realfft::RealToComplex<f64>>,
    inverse: std::sync::Arc<dyn realfft::ComplexToReal<f64>>,
}

impl AcovPlan {
    pub(crate) fn new(len: usize) -> Self {
        let fft_len = good_fft_size(2 * len);
        let mut planner = RealFftPlanner::<f64>::new();
        AcovPlan {
            len,
            fft_len,
            forward: planner.plan_fft_forward(fft_len),
            inverse: planner.plan_fft_inverse(fft_len),
        }
    }

    /// Work buffers for [`AcovPlan::power_into`].
    fn buffers(&self) -> Buffers {
        Buffers {
            input: vec![0.0; self.fft_len],
            spectrum: vec![Complex::new(0.0, 0.0); self.fft_len / 2 + 1],
            scratch: self.forward.make_scratch_vec(),
        }
    }

    /// Fills `buf.input[..len]` with `fill`, then returns `sum (x - mean)^2` and leaves
    /// `|FFT(x - mean)|^2` (zero-padded) in `buf.spectrum[..].re`.
    fn power_into(&self, buf: &mut Buffers, fill: &dyn Fn(&mut [f64])) -> f64 {
        let n = self.len;
        fill(&mut buf.input[..n]);
        buf.input[n..].iter_mut().for_each(|v| *v = 0.0);
        let mean = buf.input[..n].iter().sum::<f64>() / n as f64;
        let mut ss = 0.0;
        for v in buf.input[..n].iter_mut() {
            *v -= mean;
            ss += *v * *v;
        }
        self.forward
            .process_with_scratch(&mut buf.input, &mut buf.spectrum, &mut buf.scratch)
            .expect("buffer lengths come from the plan");
        ss
    }

    /// Sum over series `0..n_series` (filled by `fill(i, buffer)`) of their power spectra,
    /// each divided by `weight(sum of squares)` (skipped when `None`); also returns how
    /// many were skipped. Fixed chunks summed in order, so the result does not depend on
    /// the number of threads.
    fn summed_power(
        &self,
        n_series: usize,
        fill: &(dyn Fn(usize, &mut [f64]) + Sync),
        weight: fn(f64) -> Option<f64>,
    ) -> (Vec<f64>, usize) {
        let chunks: Vec<usize> = (0..n_series).step_by(8).collect();
        let partial: Vec<(Vec<f64>, usize)> = chunks
            .par_iter()
            .map(|&first| {
                let mut buf = self.buffers();
                let mut sum = vec![0.0; self.fft_len / 2 + 1];
                let mut skipped = 0;
                for i in first..(first + 8).min(n_series) {
                    let ss = self.power_into(&mut buf, &|x| fill(i, x));
                    match weight(ss) {
                        Some(w) => sum
                            .iter_mut()
                            .zip(&buf.spectrum)
                            .for_each(|(a, c)| *a += c.norm_sqr() / w),
                        None => skipped += 1,
                    }
                }
                (sum, skipped)
            })
            .collect();
        let mut total = vec![0.0; self.fft_len / 2 + 1];
        let mut skipped = 0;
        for (p, k) in partial {
            total.iter_mut().zip(&p).for_each(|(a, b)| *a += b);
            skipped += k;
        }
        (total, skipped)
    }

    /// Inverse transform of a real power spectrum, scaled by `scale`, first `len` lags.
    fn back(&self, power: &[f64], scale: f64) -> Vec<f64> {
        let mut spectrum: Vec<Complex<f64>> = power.iter().map(|&p| Complex::new(p, 0.0)).collect();
        let mut out = vec![0.0; self.fft_len];
        self.inverse
            .process(&mut spectrum, &mut out)
            .expect("buffer lengths come from the plan");
        // realfft's inverse is unnormalised: divide by the FFT length.
        let scale = scale / self.fft_len as f64;
        out.truncate(self.len);
        out.iter_mut().for_each(|v| *v *= scale);
        out
    }

    /// Biased autocovariance `acov_k = (1/N) sum_{t=0}^{N-1-k} (x_t - x̄)(x_{t+k} - x̄)`,
    /// `k = 0..N-1` (Geyer 1992; Stan and the `posterior` package use the same).
    #[cfg(test)]
    pub(crate) fn autocovariance(&self, x: &[f64]) -> Vec<f64> {
        self.mean_autocovariance(&[x])
    }

    /// Mean over `series` of their biased autocovariances.
    pub(crate) fn mean_autocovariance(&self, series: &[&[f64]]) -> Vec<f64> {
        self.mean_autocovariance_with(series.len(), &|i, out| out.copy_from_slice(series[i]))
    }

    /// [`AcovPlan::mean_autocovariance`] of series produced by `fill(i, buffer)`.
    pub(crate) fn mean_autocovariance_with(
        &self,
        n_series: usize,
        fill: &(dyn Fn(usize, &mut [f64]) + Sync),
    ) -> Vec<f64> {
        if self.len == 0 || n_series == 0 {
            return vec![f64::NAN; self.len];
        }
        let (total, _) = self.summed_power(n_series, fill, |_| Some(1.0));
        self.back(&total, 1.0 / (n_series * self.len) as f64)
    }

    /// Normalised autocorrelation `rho_k = acov_k / acov_0` (emcee's `function_1d`).
    /// A constant series (a walker that never moved) is perfectly correlated: all ones.
    pub(crate) fn autocorrelation(&self, x: &[f64]) -> Vec<f64> {
        self.mean_autocorrelation_with(1, &|_, out| out.copy_from_slice(x))
    }

    /// Mean over series `0..n_series` (filled by `fill(i, buffer)`) of their normalised
    /// autocorrelations; as the inverse FFT is linear, the normalised power spectra are
    /// summed and transformed back once.
    pub(crate) fn mean_autocorrelation_with(
        &self,
        n_series: usize,
        fill: &(dyn Fn(usize, &mut [f64]) + Sync),
    ) -> Vec<f64> {
        if self.len == 0 || n_series == 0 {
            return vec![f64::NAN; self.len];
        }
        // acf = IFFT(|F|^2) / (fft_len * sum of squares): normalise before summing.
        let (total, constant) =
            self.summed_power(n_series, fill, |ss| if ss > 0.0 { Some(ss) } else { None });
        let m = n_series as f64;
        let mut acf = self.back(&total, 1.0 / m);
        acf.iter_mut().for_each(|v| *v += constant as f64 / m);
        acf
    }
}

struct Buffers {
    input: Vec<f64>,
    spectrum: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
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
/// // White noise has tau = 1; with N = 4096 and window M ~ 5, sd(tau_hat) ~
/// // sqrt(2 (2M + 1) / N) ~ 0.07 (Sokal), so 0.3 is a 4-sd tolerance.
/// use frfbayes::mcmc::integrated_time;
/// use rand::{RngExt, SeedableRng};
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
/// let x: Vec<f64> = (0..4096).map(|_| rng.random::<f64>()).collect();
/// let t = integrated_time(&[&x[..]], 5.0);
/// assert!((t.tau - 1.0).abs() < 0.3);
/// ```
pub fn integrated_time(series: &[&[f64]], c: f64) -> TauEstimate {
    let n = series.first().map_or(0, |s| s.len());
    assert!(
        series.iter().all(|s| s.len() == n),
        "all series must have the same length"
    );
    integrated_time_with(n, series.len(), &|i, out| out.copy_from_slice(series[i]), c)
}

/// [`integrated_time`] of `n_series` series of length `n` produced by `fill(i, buffer)`.
pub(crate) fn integrated_time_with(
    n: usize,
    n_series: usize,
    fill: &(dyn Fn(usize, &mut [f64]) + Sync),
    c: f64,
) -> TauEstimate {
    let mean = AcovPlan::new(n).mean_autocorrelation_with(n_series, fill);
    sokal_window(&mean, c)
}

/// [`integrated_time`] of every parameter of `n_walkers` walkers: `fill(i, block)`
/// writes walker `i`'s states row-major `(step, parameter)` into `block` (`n x dim`).
/// Reading each walker once keeps memory traffic low for long chains.
pub(crate) fn integrated_times_by_walker(
    n: usize,
    dim: usize,
    n_walkers: usize,
    fill: &(dyn Fn(usize, &mut [f64]) + Sync),
    c: f64,
) -> Vec<TauEstimate> {
    if n == 0 || n_walkers == 0 {
        return vec![sokal_window(&[], c); dim];
    }
    let plan = AcovPlan::new(n);
    let half = plan.fft_len / 2 + 1;
    let chunks: Vec<usize> = (0..n_walkers).step_by(8).collect();
    // Per chunk: per parameter, the sum of normalised power spectra and the number of
    // constant series. Fixed chunks, summed in order: thread-count independent.
    let partial: Vec<(Vec<f64>, Vec<usize>)> = chunks
        .par_iter()
        .map(|&first| {
            let mut buf = plan.buffers();
            let mut block = vec![0.0; n * dim];
            let mut sums = vec![0.0; dim * half];
            let mut constant = vec![0; dim];
            for i in first..(first + 8).min(n_walkers) {
                fill(i, &mut block);
                for d in 0..dim {
                    let ss = plan.power_into(&mut buf, &|x| {
                        for (t, v) in x.iter_mut().enumerate() {
                            *v = block[t * dim + d];
                        }
                    });
                    if ss > 0.0 {
                        sums[d * half..(d + 1) * half]
                            .iter_mut()
                            .zip(&buf.spectrum)
                            .for_each(|(a, c)| *a += c.norm_sqr() / ss);
                    } else {
                        constant[d] += 1;
                    }
                }
            }
            (sums, constant)
        })
        .collect();
    let mut sums = vec![0.0; dim * half];
    let mut constant = vec![0; dim];
    for (s, k) in partial {
        sums.iter_mut().zip(&s).for_each(|(a, b)| *a += b);
        constant.iter_mut().zip(&k).for_each(|(a, b)| *a += b);
    }
    let m = n_walkers as f64;
    (0..dim)
        .into_par_iter()
        .map(|d| {
            let mut acf = plan.back(&sums[d * half..(d + 1) * half], 1.0 / m);
            acf.iter_mut().for_each(|v| *v += constant[d] as f64 / m);
            sokal_window(&acf, c)
        })
        .collect()
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
        let x: Vec<f64> = (0..37)
            .map(|i| ((i * 7919) % 31) as f64 * 0.1 + (i as f64).sin())
            .collect();
        let n = x.len();
        let mean = x.iter().sum::<f64>() / n as f64;
        let acov = AcovPlan::new(n).autocovariance(&x);
        for k in 0..n {
            let direct: f64 = (0..n - k)
                .map(|t| (x[t] - mean) * (x[t + k] - mean))
                .sum::<f64>()
                / n as f64;
            assert!((acov[k] - direct).abs() < 1e-12, "lag {k}");
        }
    }

    #[test]
    fn mean_autocorrelation_averages_normalised_acfs() {
        let a: Vec<f64> = (0..50).map(|i| ((i * 37) % 11) as f64).collect();
        let b: Vec<f64> = (0..50).map(|i| (i as f64 * 0.3).cos() * 100.0).collect();
        let c = vec![2.0; 50]; // constant: acf of ones
        let plan = AcovPlan::new(50);
        let (ra, rb) = (plan.autocorrelation(&a), plan.autocorrelation(&b));
        assert!((ra[0] - 1.0).abs() < 1e-12 && (rb[0] - 1.0).abs() < 1e-12);
        let all = [&a[..], &b[..], &c[..]];
        let mean = plan.mean_autocorrelation_with(3, &|i, out| out.copy_from_slice(all[i]));
        for k in 0..50 {
            assert!(
                (mean[k] - (ra[k] + rb[k] + 1.0) / 3.0).abs() < 1e-12,
                "lag {k}"
            );
        }
        assert_eq!(good_fft_size(2 * 37), 80);
        let mean_cov = plan.mean_autocovariance(&[&a, &b]);
        let (ca, cb) = (plan.autocovariance(&a), plan.autocovariance(&b));
        for k in 0..50 {
            assert!(
                (mean_cov[k] - (ca[k] + cb[k]) / 2.0).abs() < 1e-9,
                "lag {k}"
            );
        }
    }

    #[test]
    fn by_walker_matches_per_parameter() {
        // 3 walkers x 2 parameters, 64 steps.
        let x: Vec<Vec<f64>> = (0..6)
            .map(|s| {
                (0..64)
                    .map(|t| ((t * (s + 3) * 7919) % 101) as f64 + 0.1 * t as f64)
                    .collect()
            })
            .collect();
        let taus = integrated_times_by_walker(
            64,
            2,
            3,
            &|i, block| {
                for t in 0..64 {
                    block[t * 2] = x[2 * i][t];
                    block[t * 2 + 1] = x[2 * i + 1][t];
                }
            },
            5.0,
        );
        for d in 0..2 {
            let series: Vec<&[f64]> = (0..3).map(|i| x[2 * i + d].as_slice()).collect();
            let direct = integrated_time(&series, 5.0);
            assert!((taus[d].tau - direct.tau).abs() < 1e-12);
            assert_eq!(taus[d].window, direct.window);
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
