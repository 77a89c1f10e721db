//! The correlated relative error that the input channel's noise puts on the ratios of a
//! single-impact hammer segment (see [`InputGainBasis`]).

use crate::io::{Quantity, Test};
use crate::signal::hammer::{detect_impacts, Impact};
use crate::signal::EstimateOptions;
use num_complex::Complex64;

/// The input channel's noise inside the force window of one impact block, `N_F`, makes
/// every ratio of the segment `H (1 + delta(omega))` with `delta = -N_F / F`: one smooth
/// random function of frequency shared by all channels (the window is ~0.1 s long, so
/// `delta` is correlated over ~10 Hz). The coherence, from local models over a few bins,
/// cannot see it. Its covariance is known: with window weights `v_n` (force window times
/// exponential window) on the window's support, the force noise's covariance there
/// `Sigma_nm = R(t_n - t_m)` (its autocovariance, measured on the quiet part of the
/// record: [`quiet_autocovariance`]) and the measured windowed force spectrum `F_k`,
/// `E[delta_k conj(delta_l)] = sum_nm A_kn Sigma_nm conj(A_lm) = (B B^*)_kl` with
/// `A_kn = v_n e^{-j omega_k t_n} / F_k` and `B = A L`, `Sigma = L L^T`. For white noise
/// `L = sigma I`; red noise (a force sensor's drift, an amplifier's 1/f noise) puts its
/// power where the band is, `(1 + phi) / (1 - phi)` times white noise's of the same sd
/// at low frequency for an AR(1) of coefficient `phi` (19 at `phi = 0.9`), and the white
/// model would miss the gain error by that factor in variance.
/// Stored as its leading eigen-directions `C ~ U U^*` (`U = B V_r`, eigenvalues of
/// `B^* B` above `1e-4` of the largest, at most [`MAX_GAIN_RANK`]); measured on the
/// benchmark's 20 N impacts: 0.7 % rms.
///
/// A whole-record (shake-table) estimate has the same kind of error, `delta_k = -N_x / X`
/// ([`crate::signal::TestFrf::common_input_rel_var`]), but independent between bins:
/// [`InputGainBasis::PerBin`], one coefficient per frequency.
#[derive(Debug, Clone, PartialEq)]
pub enum InputGainBasis {
    /// A single impact's: smooth in frequency, `C ~ U U^*` of low rank.
    Smooth {
        rank: usize,
        /// `U`, frequency-major: `u[k * rank + m]` for the segment's frequency `k`.
        u: Vec<Complex64>,
    },
    /// A whole-record estimate's: `sd[k]^2 = E|delta_k|^2` at the segment's frequency
    /// `k`, independent between frequencies (`U = diag(sd)`).
    PerBin { sd: Vec<f64> },
}

impl InputGainBasis {
    /// `E|delta_k|^2`, the relative error's variance at frequency `k`.
    pub fn variance(&self, k: usize) -> f64 {
        match self {
            InputGainBasis::Smooth { rank, u } => u[k * rank..(k + 1) * rank]
                .iter()
                .map(|v| v.norm_sqr())
                .sum(),
            InputGainBasis::PerBin { sd } => sd[k] * sd[k],
        }
    }

    /// A point's own relative error variance at frequency `k`, given `total_rel_var`,
    /// the `eps^2` of its coherence. A whole-record estimate's coherence holds the shared
    /// per-bin error too, so its own part is `eps^2 - E|delta_k|^2 / 2`, at least
    /// `1 - MAX_COMMON_SHARE` of it. A single impact's coherence counts the force noise as
    /// if it were white (`signal::noise::add_smooth_input_noise`) where this basis
    /// carries its measured, often red, spectrum: the point keeps its whole `eps^2`, and
    /// the force noise is counted twice on purpose (subtracting the basis' variance took
    /// far too much at low frequency under red noise: 3 false alarms in 23 null
    /// campaigns; `docs/diagnose.md`, "The hammer's variance split").
    pub fn own_rel_var(&self, k: usize, total_rel_var: f64) -> f64 {
        match self {
            InputGainBasis::Smooth { .. } => total_rel_var,
            InputGainBasis::PerBin { .. } => {
                let shared = 0.5 * self.variance(k);
                (total_rel_var - shared).max((1.0 - MAX_COMMON_SHARE) * total_rel_var)
            }
        }
    }
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
    let fi = t.find(Quantity::Force)?;
    let f = &t.data[fi];
    let fs = t.sample_rate_hz;
    let base = median(f);
    let impacts = detect_impacts(f, fs, &est.hammer);
    let impact = impacts.first()?;
    if start + len > f.len() || impact.trigger < start {
        return None;
    }
    let w = block_window(len, start, impact, tau_s, fs, est);
    let support: Vec<usize> = (0..len).filter(|&n| w[n] != 0.0).collect();
    if support.is_empty() || support.len() > 4096 {
        return None;
    }
    let span = support[support.len() - 1] - support[0];
    let guard = est.hammer.force_guard_samples(fs);
    let acov = quiet_autocovariance(f, base, &impacts, guard, span)?;
    let noise_factor = toeplitz_factor(&acov, &support)?;
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
            b[(k, j)] = e * w[n] / big_f;
        }
    }
    let b = b * noise_factor.map(|x| Complex64::new(x, 0.0));
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
    Some(InputGainBasis::Smooth { rank: r, u })
}

/// The [`InputGainBasis::PerBin`] of a whole-record segment: `E|delta|^2` from the
/// estimate (`rel_var`, per segment frequency; NaN: not estimated, taken as 0), at most
/// [`MAX_COMMON_SHARE`] of the smallest total relative error `2 eps^2` of the channels
/// at that frequency (`rel_err_at[k]`; the estimate is noisy, and the common error cannot
/// be larger than any channel's whole error). `None` when it is zero everywhere.
pub(super) fn per_bin_basis(rel_var: &[f64], min_rel_err: &[f64]) -> Option<InputGainBasis> {
    let sd: Vec<f64> = rel_var
        .iter()
        .zip(min_rel_err)
        .map(|(&v, &e)| {
            let cap = MAX_COMMON_SHARE * 2.0 * e * e;
            match v.is_finite() && v > 0.0 && cap.is_finite() {
                true => v.min(cap).sqrt(),
                false => 0.0,
            }
        })
        .collect();
    sd.iter()
        .any(|&v| v > 0.0)
        .then_some(InputGainBasis::PerBin { sd })
}

/// Largest share of a point's total error variance that a correlated input error may
/// take ([`per_bin_basis`], and the posterior's split of each point's variance).
pub const MAX_COMMON_SHARE: f64 = 0.9;

/// The estimator's weights on a single-impact block of `len` samples from `start`: the
/// force window around `impact` (when the estimator uses one) times the exponential
/// window of time constant `tau_s`.
fn block_window(
    len: usize,
    start: usize,
    impact: &Impact,
    tau_s: Option<f64>,
    fs: f64,
    est: &EstimateOptions,
) -> Vec<f64> {
    use crate::signal::windows::{exponential_window, force_window};
    let (margin, taper) = est.hammer.force_window_samples(fs);
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
    w
}

/// The force channel's noise autocovariance `R(m)`, `m = 0..=max_lag` samples, from the
/// quiet part of `f` (offset `base`): every pair of samples farther than `guard` from
/// every impact's pulse. The biased estimator (the sum over the pairs divided by the
/// number of quiet samples), whose Toeplitz matrices are positive semi-definite on a
/// contiguous stretch. `None` with fewer than `4 (max_lag + 1)` quiet samples or no
/// noise at all.
pub(super) fn quiet_autocovariance(
    f: &[f64],
    base: f64,
    impacts: &[Impact],
    guard: usize,
    max_lag: usize,
) -> Option<Vec<f64>> {
    let quiet: Vec<bool> = (0..f.len())
        .map(|n| {
            impacts
                .iter()
                .all(|i| n + guard < i.trigger || n > i.pulse_end + guard)
        })
        .collect();
    let n_quiet = quiet.iter().filter(|&&q| q).count();
    if n_quiet < 4 * (max_lag + 1) {
        return None;
    }
    let x: Vec<f64> = f.iter().map(|v| v - base).collect();
    let acov: Vec<f64> = (0..=max_lag)
        .map(|m| {
            let sum: f64 = (0..f.len().saturating_sub(m))
                .filter(|&n| quiet[n] && quiet[n + m])
                .map(|n| x[n] * x[n + m])
                .sum();
            sum / n_quiet as f64
        })
        .collect();
    (acov[0] > 0.0 && acov[0].is_finite()).then_some(acov)
}

/// A square root `L` (`L L^T = Sigma`) of the noise covariance on the samples `support`,
/// `Sigma_ij = R(|support_i - support_j|)`: its eigenvectors scaled by the square roots
/// of its eigenvalues, those below zero (sampling error of `R`) set to zero.
fn toeplitz_factor(acov: &[f64], support: &[usize]) -> Option<nalgebra::DMatrix<f64>> {
    let l = support.len();
    let sigma = nalgebra::DMatrix::from_fn(l, l, |i, j| {
        acov.get(support[i].abs_diff(support[j]))
            .copied()
            .unwrap_or(0.0)
    });
    let eig = sigma.symmetric_eigen();
    let roots = eig.eigenvalues.map(|v| v.max(0.0).sqrt());
    let factor = eig.eigenvectors * nalgebra::DMatrix::from_diagonal(&roots);
    factor.iter().all(|v| v.is_finite()).then_some(factor)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{Channel, TestKind};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    const FS_HZ: f64 = 500.0;
    const SIGMA_N: f64 = 0.02;
    const PHI: f64 = 0.9;

    /// Stationary AR(1) noise of sd `SIGMA_N` and coefficient `PHI`.
    fn ar1(n: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let mut x = SIGMA_N * rng.sample::<f64, _>(StandardNormal);
        let innovation = SIGMA_N * (1.0 - PHI * PHI).sqrt();
        (0..n)
            .map(|_| {
                let out = x;
                x = PHI * x + innovation * rng.sample::<f64, _>(StandardNormal);
                out
            })
            .collect()
    }

    /// Oracle: the basis' covariance `U U^*` of the relative error `-N_F / F` against a
    /// Monte Carlo over fresh red noise in the force window (the record's own force
    /// spectrum held fixed, as the basis holds it). Tolerance: the Monte Carlo's
    /// relative sd `sqrt(2 / reps)` (2.6 %) and the autocovariance's from the 118 s
    /// quiet record (about `sqrt(2 x span / N)`, 4 %), four of each. The white model
    /// (`R(0)` alone) misses it by a factor above 5 at 1 Hz, so the test can fail.
    #[test]
    fn red_force_noise_gain_error_matches_monte_carlo() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let n = (120.0 * FS_HZ) as usize;
        let mut force = ar1(n, &mut rng);
        let hit = (2.0 * FS_HZ) as usize;
        for (i, v) in [40.0, 100.0, 40.0].iter().enumerate() {
            force[hit + i] += v;
        }
        let test = Test {
            name: "hammer".into(),
            kind: TestKind::Hammer { excited_floor: 1 },
            sample_rate_hz: FS_HZ,
            channels: vec![Channel {
                name: "force".into(),
                quantity: Quantity::Force,
                floor: 1,
                unit: "N".into(),
            }],
            data: vec![force.clone()],
        };
        let (start, len, tau_s) = (hit - FS_HZ as usize, 30_000, Some(10.0));
        let freq_hz = [1.0, 3.0, 6.0];
        let est = EstimateOptions::default();
        let basis = input_gain_basis(&test, start, len, tau_s, &freq_hz, &est).unwrap();
        let InputGainBasis::Smooth { rank, u } = basis else {
            panic!("an impact's basis is smooth");
        };
        let cov = |k: usize, l: usize| -> Complex64 {
            (0..rank)
                .map(|m| u[k * rank + m] * u[l * rank + m].conj())
                .sum()
        };
        let impact = &detect_impacts(&force, FS_HZ, &est.hammer)[0];
        let w = block_window(len, start, impact, tau_s, FS_HZ, &est);
        let support: Vec<usize> = (0..len).filter(|&i| w[i] != 0.0).collect();
        let base = crate::signal::hammer::median(&force);
        let spectrum = |x: &dyn Fn(usize) -> f64, f_hz: f64| -> Complex64 {
            let omega = 2.0 * std::f64::consts::PI * f_hz;
            support
                .iter()
                .map(|&i| Complex64::from_polar(x(i) * w[i], -omega * i as f64 / FS_HZ))
                .sum()
        };
        let big_f: Vec<Complex64> = freq_hz
            .iter()
            .map(|&f| spectrum(&|i| force[start + i] - base, f))
            .collect();
        let reps = 3000;
        let mut mc = [[Complex64::new(0.0, 0.0); 3]; 3];
        for _ in 0..reps {
            let noise = ar1(len, &mut rng);
            let delta: Vec<Complex64> = freq_hz
                .iter()
                .zip(&big_f)
                .map(|(&f, big)| -spectrum(&|i| noise[i], f) / big)
                .collect();
            for k in 0..3 {
                for l in 0..3 {
                    mc[k][l] += delta[k] * delta[l].conj() / reps as f64;
                }
            }
        }
        let tol = 4.0 * (2.0 / reps as f64).sqrt() + 4.0 * 0.04;
        for k in 0..3 {
            let ratio = cov(k, k).re / mc[k][k].re;
            eprintln!("{} Hz: basis / Monte Carlo variance {ratio:.3}", freq_hz[k]);
            assert!(
                (ratio - 1.0).abs() < tol,
                "{} Hz: basis / MC {ratio}",
                freq_hz[k]
            );
        }
        let (c01, m01) = (cov(0, 1), mc[0][1]);
        let rel = (c01 - m01).norm() / (mc[0][0].re * mc[1][1].re).sqrt();
        assert!(rel < tol, "1-3 Hz covariance off by {rel} of the sds");
        let white: f64 = support
            .iter()
            .map(|&i| (SIGMA_N * w[i]).powi(2))
            .sum::<f64>()
            / big_f[0].norm_sqr();
        eprintln!("1 Hz: red / white variance {:.1}", mc[0][0].re / white);
        assert!(
            mc[0][0].re / white > 5.0,
            "red / white {}",
            mc[0][0].re / white
        );
    }
}
