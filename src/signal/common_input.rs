//! The error the input channel's noise puts on every response of a whole-record
//! (shake-table) estimate at once, estimated from the responses' local residuals.
//!
//! With the measured input `X = G + N_x` (true ground acceleration `G`, sensor noise
//! `N_x`) and a response `Y_i = H_i G + N_i`, the single-record `H1 = Y_i / X` is
//! `H_i (1 + delta) + N_i / X` to first order, `delta = -N_x / X`: one relative error per
//! bin, the same for every channel. (An accelerometer made relative to the table, `Y_i -
//! X`, carries `N_i - H_i N_x` with `H_i` the absolute accelerance, so the same `delta`
//! multiplies the absolute ratio.) The coherence of each channel contains `delta`'s
//! variance but says nothing of its being shared; a likelihood that takes the channels'
//! errors as independent counts it once per channel, and where it looks like a shift of a
//! resonance (every channel's ratio moves by the same factor near a mode) it moves
//! frequency-like parameters by several of their posterior sds (docs/diagnose.md).
//!
//! `E|delta_k|^2 = S_x / |X_k|^2` with `S_x` the noise's power per bin. `S_x` is read from
//! the residuals of each channel's local polynomial model (`Y ~ X (a + b u + c u^2)` over
//! the `2m + 1` bins of [`LocalModel`], the same design for every channel): divided by the
//! channel's carrier `H_i` (the absolute ratio at the bin), the residuals of two channels
//! share `P delta` (`P` the projection off the design), so `E[sum_l e_i conj(e_j) /
//! (H_i conj(H_j))] = S_x tr(P C)` for `i != j` (`C` the window's bin correlation), while
//! their own noises average out. The pairs are combined with inverse-variance weights
//! `1 / (v_i v_j)` (`v_i` the channel's own relative residual power) and the estimate is
//! averaged over [`SMOOTH_WINDOWS`] windows each side (a sensor's noise spectrum is
//! smooth; `|X_k|^2`, which is not, stays per bin).

use super::local_coherence::LocalModel;
use nalgebra::{Matrix3, Vector3};
use num_complex::Complex64;

/// Local windows averaged on each side of a bin in the estimate of the noise power.
pub const SMOOTH_WINDOWS: usize = 2;

/// `E|delta_k|^2` at the first `n_keep` bins (NaN where no window fits or fewer than two
/// channels have power): `x` the input's spectrum, `y[i]` response `i`'s, `absolute[i]`
/// whether its carrier is its ratio plus one (an accelerometer made relative to the
/// table). One block (a whole-record estimate).
pub(super) fn common_input_rel_var(
    local: &LocalModel,
    x: &[Complex64],
    y: &[&[Complex64]],
    absolute: &[bool],
    n_keep: usize,
) -> Vec<f64> {
    let n_bins = local.n_local.min(x.len());
    let windows: Vec<Option<Window>> = (0..n_bins)
        .map(|k| window_products(local, x, y, absolute, k))
        .collect();
    let reach = SMOOTH_WINDOWS * (2 * local.half_width_bins + 1) * local.step;
    (0..n_keep)
        .map(|k| {
            let p = x.get(k).map_or(0.0, |v| v.norm_sqr());
            let lo = k.saturating_sub(reach).min(n_bins);
            let hi = (k + reach + 1).min(n_bins);
            match smoothed_power(&windows[lo..hi], y.len()) {
                Some(s) if p > 0.0 => s.max(0.0) / p,
                _ => f64::NAN,
            }
        })
        .collect()
}

/// One window's residual products: per channel its relative residual power `v_i` (None
/// where its carrier vanishes), per pair `i < j` (row-major over the upper triangle) `Re
/// sum_l e_i conj(e_j) / dof`.
struct Window {
    power: Vec<Option<f64>>,
    cross: Vec<f64>,
}

/// `S_x` over a run of windows: the pairs' products weighted by `1 / (v_i v_j)` with the
/// channels' powers averaged over the run (weights from the window's own residuals
/// would fall where its common error is large, and bias the estimate low).
fn smoothed_power(windows: &[Option<Window>], n_channels: usize) -> Option<f64> {
    let mut mean = vec![(0.0, 0usize); n_channels];
    for w in windows.iter().flatten() {
        for (m, v) in mean.iter_mut().zip(&w.power) {
            if let Some(v) = v {
                m.0 += v;
                m.1 += 1;
            }
        }
    }
    let (mut s, mut total) = (0.0, 0.0);
    for w in windows.iter().flatten() {
        let mut pair = 0;
        for i in 0..n_channels {
            for j in i + 1..n_channels {
                let both = w.power[i].is_some() && w.power[j].is_some();
                let (mi, mj) = (mean[i], mean[j]);
                if both && mi.0 > 0.0 && mj.0 > 0.0 {
                    let weight = (mi.1 as f64 / mi.0) * (mj.1 as f64 / mj.0);
                    s += weight * w.cross[pair];
                    total += weight;
                }
                pair += 1;
            }
        }
    }
    (total > 0.0).then(|| s / total)
}

/// The residual products of the window around bin `k`; `None` where no window fits.
fn window_products(
    local: &LocalModel,
    x: &[Complex64],
    y: &[&[Complex64]],
    absolute: &[bool],
    k: usize,
) -> Option<Window> {
    let (m, step, n_bins) = (
        local.half_width_bins,
        local.step,
        local.n_local.min(x.len()),
    );
    let width = 2 * m + 1;
    let c = m
        .min(k / step)
        .max((2 * m).saturating_sub((n_bins - 1 - k) / step));
    if c > k / step || k + (2 * m - c) * step >= n_bins || x[k].norm_sqr() == 0.0 {
        return None;
    }
    let bins: Vec<usize> = (0..width).map(|i| k - c * step + i * step).collect();
    let design: Vec<[Complex64; 3]> = bins
        .iter()
        .map(|&j| {
            let u = (j as f64 - k as f64) / (m * step) as f64;
            [x[j], x[j] * u, x[j] * (u * u)]
        })
        .collect();
    let proj = Projection::new(&design)?;
    let dof = proj.trace_with(&local.corr);
    if dof <= 0.0 {
        return None;
    }
    // Each channel's residuals over its carrier.
    let rel: Vec<Option<Vec<Complex64>>> = y
        .iter()
        .zip(absolute)
        .map(|(yi, &abs)| {
            let carrier = yi[k] / x[k] + if abs { 1.0 } else { 0.0 };
            (carrier.norm_sqr() > 0.0 && carrier.is_finite()).then(|| {
                let e = proj.residual(&bins.iter().map(|&j| yi[j]).collect::<Vec<_>>());
                e.into_iter().map(|v| v / carrier).collect()
            })
        })
        .collect();
    let power = rel
        .iter()
        .map(|e| {
            let v = e.as_ref()?.iter().map(|v| v.norm_sqr()).sum::<f64>() / dof;
            (v > 0.0 && v.is_finite()).then_some(v)
        })
        .collect::<Vec<_>>();
    let mut cross = Vec::with_capacity(y.len() * y.len().saturating_sub(1) / 2);
    for i in 0..y.len() {
        for j in i + 1..y.len() {
            let t = match (&rel[i], &rel[j]) {
                (Some(a), Some(b)) => a.iter().zip(b).map(|(a, b)| (a * b.conj()).re).sum(),
                _ => 0.0,
            };
            cross.push(t / dof);
        }
    }
    Some(Window { power, cross })
}

/// The least-squares projection off one window's design `A` (`width x 3`).
struct Projection<'a> {
    design: &'a [[Complex64; 3]],
    gram_inv: Matrix3<Complex64>,
}

impl<'a> Projection<'a> {
    fn new(design: &'a [[Complex64; 3]]) -> Option<Self> {
        let mut gram = Matrix3::<Complex64>::zeros();
        for row in design {
            for a in 0..3 {
                for b in 0..3 {
                    gram[(a, b)] += row[a].conj() * row[b];
                }
            }
        }
        Some(Projection {
            design,
            gram_inv: gram.try_inverse()?,
        })
    }

    /// `y - A (A^* A)^-1 A^* y`.
    fn residual(&self, y: &[Complex64]) -> Vec<Complex64> {
        let mut aty = Vector3::<Complex64>::zeros();
        for (row, v) in self.design.iter().zip(y) {
            for a in 0..3 {
                aty[a] += row[a].conj() * v;
            }
        }
        let coef = self.gram_inv * aty;
        self.design
            .iter()
            .zip(y)
            .map(|(row, v)| v - (row[0] * coef[0] + row[1] * coef[1] + row[2] * coef[2]))
            .collect()
    }

    /// `Re tr(P C)`, `P = I - A (A^* A)^-1 A^*`, `C_ab = corr[a - b]` (`a >= b`, the
    /// conjugate above the diagonal): `E sum_l |(P n)_l|^2` in units of the noise's power
    /// per bin.
    fn trace_with(&self, corr: &[Complex64]) -> f64 {
        let width = self.design.len();
        let c = |a: usize, b: usize| match a >= b {
            true => corr[a - b],
            false => corr[b - a].conj(),
        };
        let mut hat_c = Complex64::new(0.0, 0.0);
        for a in 0..width {
            let left = Vector3::from_fn(|p, _| self.design[a][p]).transpose() * self.gram_inv;
            for b in 0..width {
                let hat_ab: Complex64 = (0..3).map(|q| left[q] * self.design[b][q].conj()).sum();
                hat_c += hat_ab * c(b, a);
            }
        }
        width as f64 * corr[0].re - hat_c.re
    }
}

#[cfg(test)]
mod tests {
    use crate::io::{Channel, Quantity, Test, TestKind};
    use crate::signal::sweep::full_record_spectra;
    use crate::signal::{estimate_test, EstimateOptions};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    const FS_HZ: f64 = 100.0;
    const SIGMA_X: f64 = 0.05;

    fn channel(name: &str, quantity: Quantity, floor: usize) -> Channel {
        Channel {
            name: name.into(),
            quantity,
            floor,
            unit: "m/s^2".into(),
        }
    }

    /// A shake-table record: broadband ground motion `g` (sd 1) measured with white noise
    /// of sd `SIGMA_X`, and four accelerometers `a_i g[n] + b_i g[n - 1]` (smooth
    /// absolute accelerances) with their own white noise of sd `sigma_y`.
    fn record(rng: &mut ChaCha8Rng, sigma_y: f64) -> (Test, Vec<f64>) {
        let n = (120.0 * FS_HZ) as usize;
        let mut normal = |sd: f64| -> Vec<f64> {
            (0..n)
                .map(|_| sd * rng.sample::<f64, _>(StandardNormal))
                .collect()
        };
        let g = normal(1.0);
        let noise_x = normal(SIGMA_X);
        let mut channels = vec![channel("ground", Quantity::GroundAcceleration, 0)];
        let mut data = vec![g.iter().zip(&noise_x).map(|(a, b)| a + b).collect()];
        for (i, (a, b)) in [(1.0, 0.5), (2.0, -1.0), (0.5, 1.5), (3.0, 0.2)]
            .iter()
            .enumerate()
        {
            let noise_y = normal(sigma_y);
            let y = (0..n)
                .map(|t| a * g[t] + b * if t > 0 { g[t - 1] } else { 0.0 } + noise_y[t])
                .collect();
            channels.push(channel(
                &format!("acc{}", i + 1),
                Quantity::Acceleration,
                i + 1,
            ));
            data.push(y);
        }
        let test = Test {
            name: "shake".into(),
            kind: TestKind::ShakeTable,
            sample_rate_hz: FS_HZ,
            channels,
            data,
        };
        (test, noise_x)
    }

    /// Oracle: the estimated noise power per bin, `E|delta_k|^2 |X_k|^2`, against the
    /// input noise's own power per bin (its transform, averaged over the band), with the
    /// output channels as noisy as the input and 4 times noisier. The estimate averages
    /// about 45 bins x 6 pairs of about 6 degrees of freedom; over the 5,800 bins of the
    /// band its mean's relative sd is below 2 %: tolerance 8 %. A likelihood that took the
    /// channels as independent has this term at 0, and the test then fails.
    #[test]
    fn common_input_noise_power_matches_the_input_noise() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for sigma_y in [SIGMA_X, 4.0 * SIGMA_X] {
            let (test, noise_x) = record(&mut rng, sigma_y);
            let frf = estimate_test(&test, &EstimateOptions::default()).unwrap();
            let x = full_record_spectra(&test.data[0], &[], 1).unwrap().input;
            let truth = full_record_spectra(&noise_x, &[], 1).unwrap().input;
            let n = frf.common_input_rel_var.len();
            assert_eq!(n, frf.freq_hz.len());
            let band = n / 20..n - n / 20;
            let estimate: f64 = band
                .clone()
                .map(|k| frf.common_input_rel_var[k] * x[k].norm_sqr())
                .sum::<f64>();
            let power: f64 = band.clone().map(|k| truth[k].norm_sqr()).sum();
            let ratio = estimate / power;
            eprintln!("sigma_y {sigma_y}: estimated / true input noise power {ratio:.3}");
            assert!(
                (ratio - 1.0).abs() < 0.08,
                "sigma_y {sigma_y}: ratio {ratio}"
            );
        }
    }
}
