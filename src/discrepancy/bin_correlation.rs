//! The correlation of neighbouring bins, and the widening of effect posteriors it calls
//! for.
//!
//! The likelihood of [`super::posterior`] treats each point's error as independent once
//! the shared input-gain term is taken out. Neighbouring bins of one estimate are not
//! independent: the exponential and force windows smear each bin's noise over its
//! neighbours ([`crate::signal::correlation`]: `|c(d)| ~ 1 / sqrt(1 + (pi d tau / T)^2)`
//! for `exp(-t / tau)` over `T`, 0.69 at `d = 1` for the default hammer window), and a
//! parameter whose effect is smooth over frequency sums those errors coherently, so its
//! posterior is too narrow. The correlation is measured on the residuals rather than
//! taken from [`crate::signal::correlation::NoiseWindow`] because a diagnosis mixes
//! estimates (hammer blocks under a force and an exponential window, Welch-averaged
//! shake-table records, pooled noise estimates) and the residual carries all of them;
//! for one window the two agree (the test
//! `the_measured_correlation_of_windowed_noise_is_the_windows`).
//! Measured on the coverage case sensor_dynamics-c6 over 8 noise seeds (docs/diagnose.md, "Effect
//! intervals and neighbouring bins"): the estimates scattered 1.65 (frequency) and 1.69
//! (damping) times the posterior sd, their mean within 0.4 standard errors of the truth.
//!
//! The widening is the sandwich (Godambe) covariance of a misspecified independence
//! likelihood, `A^-1 B A^-1` with `A = J^T J` and `B = J^T R J`: `J` the Jacobian of the
//! whitened residuals ([`ModelPosterior::whitened_residuals`]) at the posterior mean, `R`
//! their correlation. `R` is measured on those residuals, as a function of the bin
//! distance `d` within one channel's estimate: `c(d) = E[r_k conj(r_l)] / E|r|^2` over
//! the pairs `d` bins apart, kept from `d = 1` up to the first distance where `|c(d)|` is
//! within `2 / sqrt(n_d)` of zero (`n_d` pairs). For circular complex residuals the real
//! pairs `(Re, Im)` of two points then have covariance `[[Re c, -Im c], [Im c, Re c]]`.
//! Each coordinate's draws are spread about their mean by the larger of
//! `sqrt((A^-1 B A^-1)_jj / (A^-1)_jj)` (the diagonal form of the curvature adjustment
//! of Ribatet, Cooley & Davison 2012) and `sqrt((A^-1 B A^-1)_jj) / s_j`, `s_j` the
//! draws' own sd, and never by less than 1: it widens and never narrows, and leaves the
//! mean in place. The second term makes the reported sd at least the sandwich sd, the
//! estimator's sampling sd under a misspecified likelihood (Müller 2013,
//! Econometrica 81:1805, replaces the posterior by the sandwich normal). The two
//! agree where the posterior is Gaussian with the curvature `A`; they differ where the
//! posterior is narrower than its curvature at the mode says; a coordinate whose draws
//! reach its box (the prior, not the likelihood, bounds it) keeps the ratio alone, as
//! the sandwich sd would spread it over the box. Measured on coverage
//! case base_flexibility-c1 (seed 9207, README "Effect intervals and neighbouring
//! bins"): along the base mass the log posterior falls by 0.77, 10.9 and 173 nats at
//! 0.5, 1 and 2 Laplace sd (a quadratic would give 0.125, 0.5 and 2), so the sampled sd
//! of `ln m_b` (0.019; 0.019 too by importance sampling from a t on Laplace's
//! Gaussian) is half Laplace's (0.038) and of `(A^-1)_jj`'s (0.044), while over 8 noise
//! seeds the estimate scattered by 0.067: the sandwich sd (0.072) and not the
//! posterior's is the estimator's scatter there.

use super::posterior::ModelPosterior;
use crate::error::Result;
use crate::mcmc::quantile;
use crate::update::lsq::{fd_jacobian, Bounds, FdScheme};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Largest bin distance whose correlation is measured.
pub const MAX_BIN_DISTANCE: usize = 16;

/// One channel's estimate in the flat layout: its first point and each point's bin.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub start: usize,
    pub bins: Vec<usize>,
}

/// The runs of `post`'s flat layout (segment, then channel, then point).
pub fn runs(post: &ModelPosterior) -> Vec<Run> {
    let mut out = Vec::new();
    let mut start = 0;
    for seg in &post.data().segments {
        for ch in &seg.channels {
            out.push(Run {
                start,
                bins: ch.freq_index.clone(),
            });
            start += ch.freq_index.len();
        }
    }
    out
}

/// Pairs `(k, l, d)` of flat points of one run whose bins are `1..=max_d` apart.
fn pairs(runs: &[Run], max_d: usize) -> Vec<(usize, usize, usize)> {
    let mut out = Vec::new();
    for run in runs {
        let mut order: Vec<usize> = (0..run.bins.len()).collect();
        order.sort_by_key(|&j| run.bins[j]);
        for (a, &ja) in order.iter().enumerate() {
            for &jb in &order[a + 1..] {
                let d = run.bins[jb] - run.bins[ja];
                if d > max_d {
                    break;
                }
                if d > 0 {
                    out.push((run.start + ja, run.start + jb, d));
                }
            }
        }
    }
    out
}

/// `c(d)` for `d = 0..=max_d` of the complex residuals `r` (module docs); `c(0) = 1`,
/// and zero from the first distance whose estimate is within `2 / sqrt(n_d)` of zero.
pub fn bin_correlation(runs: &[Run], r: &[Complex64], max_d: usize) -> Vec<Complex64> {
    let n_points: usize = runs.iter().map(|run| run.bins.len()).sum();
    let power = runs
        .iter()
        .flat_map(|run| &r[run.start..run.start + run.bins.len()])
        .map(Complex64::norm_sqr)
        .sum::<f64>()
        / n_points.max(1) as f64;
    let mut sum = vec![Complex64::new(0.0, 0.0); max_d + 1];
    let mut count = vec![0usize; max_d + 1];
    for (k, l, d) in pairs(runs, max_d) {
        sum[d] += r[k] * r[l].conj();
        count[d] += 1;
    }
    let mut c = vec![Complex64::new(0.0, 0.0); max_d + 1];
    c[0] = Complex64::new(1.0, 0.0);
    if power <= 0.0 {
        return c;
    }
    for d in 1..=max_d {
        if count[d] == 0 {
            break;
        }
        let v = sum[d] / (count[d] as f64 * power);
        if v.norm() <= 2.0 / (count[d] as f64).sqrt() {
            break;
        }
        c[d] = v;
    }
    c
}

/// `B = J^T R J` for real residual rows `2 i` (Re) and `2 i + 1` (Im) of point `i`,
/// further rows independent (module docs). Formed as `J^T J + J^T (R - I) J` with
/// `(R - I) J` accumulated pair by pair, so its cost is linear in the pairs.
pub fn sandwich_meat(jac: &DMatrix<f64>, runs: &[Run], c: &[Complex64]) -> DMatrix<f64> {
    let p = jac.ncols();
    let mut rj = DMatrix::<f64>::zeros(jac.nrows(), p);
    for (k, l, d) in pairs(runs, c.len().saturating_sub(1)) {
        let (re, im) = (c[d].re, c[d].im);
        if re == 0.0 && im == 0.0 {
            continue;
        }
        let (k, l) = (2 * k, 2 * l);
        for j in 0..p {
            let (a, b) = (jac[(k, j)], jac[(k + 1, j)]);
            let (x, y) = (jac[(l, j)], jac[(l + 1, j)]);
            rj[(k, j)] += re * x - im * y;
            rj[(k + 1, j)] += im * x + re * y;
            rj[(l, j)] += re * a + im * b;
            rj[(l + 1, j)] += re * b - im * a;
        }
    }
    let b = jac.tr_mul(jac) + jac.tr_mul(&rj);
    (&b + b.transpose()) * 0.5
}

/// Per-coordinate widening of `post`'s posterior `draws` (module docs): 1 for the error
/// floor, for a single draw, and where `A` is singular.
pub fn inflation(post: &ModelPosterior, draws: &[Vec<f64>]) -> Result<Vec<f64>> {
    let dim = post.dim();
    let mut out = vec![1.0; dim];
    if draws.len() < 2 {
        return Ok(out);
    }
    let mean = draws_mean(draws, dim);
    let ie = post.eta_index();
    let eta = mean[ie].exp();
    let free: Vec<usize> = (0..dim).filter(|&i| i != ie).collect();
    let (lo, hi) = post.bounds();
    let bounds = Bounds::new(
        free.iter().map(|&i| lo[i]).collect(),
        free.iter().map(|&i| hi[i]).collect(),
    )?;
    let n_res = post.n_whitened_residuals();
    let mut r = vec![0.0; n_res];
    post.whitened_residuals(&mean, eta, &mut r)?;
    let x: Vec<f64> = free.iter().map(|&i| mean[i]).collect();
    let mut z = mean.clone();
    let residuals = |x: &[f64], out: &mut [f64]| {
        for (&i, &v) in free.iter().zip(x) {
            z[i] = v;
        }
        post.whitened_residuals(&z, eta, out)
    };
    let mut jac = DMatrix::zeros(n_res, free.len());
    fd_jacobian(FdScheme::Forward, &x, &bounds, residuals, &mut jac)?;
    let runs = runs(post);
    let n_points = runs.iter().map(|run| run.bins.len()).sum::<usize>();
    let rc: Vec<Complex64> = (0..n_points)
        .map(|i| Complex64::new(r[2 * i], r[2 * i + 1]))
        .collect();
    let c = bin_correlation(&runs, &rc, MAX_BIN_DISTANCE);
    let Some((sandwich, independent)) = sandwich_variances(&jac, &runs, &c) else {
        return Ok(out);
    };
    for (j, &i) in free.iter().enumerate() {
        let mut column: Vec<f64> = draws.iter().map(|z| z[i]).collect();
        column.sort_by(f64::total_cmp);
        let (q_lo, q_hi) = (quantile(&column, 0.025), quantile(&column, 0.975));
        // A coordinate that its box bounds is not one whose likelihood dominates: its
        // sampled sd is the box's doing, and the sandwich sd would spread it over the
        // box; it keeps the ratio only.
        let sampled = if interval_reaches_box(q_lo, q_hi, lo[i], hi[i]) {
            f64::INFINITY
        } else {
            draws_sd(draws, i, mean[i])
        };
        out[i] = factor(sandwich[j], independent[j], sampled);
    }
    Ok(out)
}

/// Whether the interval `[q_lo, q_hi]` comes closer to `lo` or `hi` than its own width
/// (or than 0.1 % of the box): its mass runs into the box's end instead of being
/// identified inside it. The rule by which [`super::effect_summary`] finds an effect
/// piled at the end of its plausible range, and by which the widening leaves a
/// prior-bounded coordinate alone.
pub(super) fn interval_reaches_box(q_lo: f64, q_hi: f64, lo: f64, hi: f64) -> bool {
    let margin = (q_hi - q_lo).max(1e-3 * (hi - lo));
    q_lo < lo + margin || q_hi > hi - margin
}

/// The widening of one coordinate (module docs): the larger of `sqrt(S_jj / (A^-1)_jj)`
/// and `sqrt(S_jj) / sampled_sd`, and at least 1.
fn factor(sandwich: f64, independent: f64, sampled_sd: f64) -> f64 {
    let by_ratio = (sandwich / independent).sqrt();
    let by_sd = sandwich.sqrt() / sampled_sd;
    [by_ratio, by_sd]
        .into_iter()
        .filter(|f| f.is_finite())
        .fold(1.0, f64::max)
}

/// The diagonals of the sandwich covariance `A^-1 B A^-1` and of `A^-1`, `A = J^T J`,
/// `B = J^T R J` with `R` from `c(d)` along `runs`; `None` where `A` is singular.
pub fn sandwich_variances(
    jac: &DMatrix<f64>,
    runs: &[Run],
    c: &[Complex64],
) -> Option<(Vec<f64>, Vec<f64>)> {
    let a_inv = jac.tr_mul(jac).cholesky().map(|ch| ch.inverse())?;
    let s = &a_inv * sandwich_meat(jac, runs, c) * &a_inv;
    Some((
        s.diagonal().iter().copied().collect(),
        a_inv.diagonal().iter().copied().collect(),
    ))
}

/// The sample sd of coordinate `i` of `draws` about `mean`.
fn draws_sd(draws: &[Vec<f64>], i: usize, mean: f64) -> f64 {
    let ss: f64 = draws.iter().map(|z| (z[i] - mean).powi(2)).sum();
    (ss / (draws.len().max(2) - 1) as f64).sqrt()
}

/// `draws` spread about their mean by `factors`, each coordinate kept in `[lo, hi]`.
pub fn widened(draws: &[Vec<f64>], factors: &[f64], lo: &[f64], hi: &[f64]) -> Vec<Vec<f64>> {
    let mean = draws_mean(draws, factors.len());
    draws
        .iter()
        .map(|z| {
            (0..z.len())
                .map(|i| (mean[i] + factors[i] * (z[i] - mean[i])).clamp(lo[i], hi[i]))
                .collect()
        })
        .collect()
}

/// The mean of each of the first `dim` coordinates of `draws`.
fn draws_mean(draws: &[Vec<f64>], dim: usize) -> Vec<f64> {
    let n = draws.len().max(1) as f64;
    (0..dim)
        .map(|i| draws.iter().map(|z| z[i]).sum::<f64>() / n)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn normal(rng: &mut ChaCha8Rng) -> f64 {
        StandardNormal.sample(rng)
    }

    /// Complex AR(1) noise along each run, `r_k = phi r_{k-1} + sqrt(1 - |phi|^2) e_k`:
    /// `c(d) = phi^d` at adjacent bins.
    fn ar1(runs: &[Run], phi: Complex64, rng: &mut ChaCha8Rng) -> Vec<Complex64> {
        let n: usize = runs.iter().map(|r| r.bins.len()).sum();
        let mut out = vec![Complex64::new(0.0, 0.0); n];
        let s = (1.0 - phi.norm_sqr()).sqrt();
        for run in runs {
            let mut prev = Complex64::new(normal(rng), normal(rng)) / 2f64.sqrt();
            for k in 0..run.bins.len() {
                let e = Complex64::new(normal(rng), normal(rng)) / 2f64.sqrt();
                prev = if k == 0 { prev } else { phi * prev + s * e };
                out[run.start + k] = prev;
            }
        }
        out
    }

    fn contiguous_runs(n_runs: usize, len: usize) -> Vec<Run> {
        (0..n_runs)
            .map(|i| Run {
                start: i * len,
                bins: (10..10 + len).collect(),
            })
            .collect()
    }

    #[test]
    fn the_measured_correlation_is_the_ar1_coefficients_power() {
        // 40 runs of 200: 7,960 pairs at d = 1, so the estimate's sd is about 0.011.
        let runs = contiguous_runs(40, 200);
        let phi = Complex64::from_polar(0.6, 0.4);
        let mut rng = ChaCha8Rng::seed_from_u64(20261129);
        let r = ar1(&runs, phi, &mut rng);
        let c = bin_correlation(&runs, &r, MAX_BIN_DISTANCE);
        for (d, got) in c.iter().enumerate().skip(1).take(3) {
            // E[r_k conj(r_{k+d})] = conj(phi)^d.
            let want = phi.conj().powi(d as i32);
            assert!((got - want).norm() < 0.05, "d {d}: {got} vs {want}");
        }
        // Independent noise: nothing past d = 0 is kept (or a chance value near 2 sd).
        let white = ar1(&runs, Complex64::new(0.0, 0.0), &mut rng);
        let c = bin_correlation(&runs, &white, MAX_BIN_DISTANCE);
        assert!(c[1..].iter().all(|v| v.norm() < 0.04), "{c:?}");
    }

    #[test]
    fn the_measured_correlation_of_windowed_noise_is_the_windows() {
        // White noise under the exponential window exp(-t / tau), tau = T / ln 20 (the
        // default hammer window), transformed without padding: c(d) = conj of
        // `NoiseWindow::correlation(d)` (which is E[N_k conj(N_{k-d})]).
        use crate::signal::correlation::NoiseWindow;
        use rustfft::FftPlanner;
        let (len, n_records) = (256, 200);
        let tau = len as f64 / 20f64.ln();
        let w: Vec<f64> = (0..len).map(|n| (-(n as f64) / tau).exp()).collect();
        let fft = FftPlanner::new().plan_fft_forward(len);
        let mut rng = ChaCha8Rng::seed_from_u64(20261130);
        let bins: Vec<usize> = (5..100).collect();
        let mut r = Vec::new();
        let mut runs = Vec::new();
        for _ in 0..n_records {
            let mut x: Vec<Complex64> = w
                .iter()
                .map(|&wn| Complex64::new(wn * normal(&mut rng), 0.0))
                .collect();
            fft.process(&mut x);
            runs.push(Run {
                start: r.len(),
                bins: bins.clone(),
            });
            r.extend(bins.iter().map(|&k| x[k]));
        }
        let c = bin_correlation(&runs, &r, 4);
        let theory = NoiseWindow::new(Some(&w), len, len).unwrap();
        // 200 x 94 pairs at d = 1: the estimate's sd is about 0.007.
        for (d, got) in c.iter().enumerate().skip(1).take(3) {
            let want = theory.correlation(d).conj();
            assert!((got - want).norm() < 0.04, "d {d}: {got} vs {want}");
        }
        assert!(c[1].norm() > 0.6, "{}", c[1]);
    }

    #[test]
    fn the_reported_sd_is_at_least_the_sandwich_sd() {
        // Gaussian posterior with the curvature A: the sandwich ratio alone.
        assert!((factor(4.0, 1.0, 1.0) - 2.0).abs() < 1e-12);
        // Draws narrower than A says (0.5 against 2): spread to the sandwich sd, 2 / 0.5.
        assert!((factor(4.0, 4.0, 0.5) - 4.0).abs() < 1e-12);
        // Draws wider than the sandwich sd (a prior, a plateau): left alone.
        assert_eq!(factor(1.0, 4.0, 2.0), 1.0);
        // Degenerate draws or a singular curvature never narrow and never blow up.
        assert_eq!(factor(4.0, 4.0, 0.0), 1.0);
        assert_eq!(factor(f64::NAN, 1.0, 1.0), 1.0);
    }

    #[test]
    fn an_interval_within_its_width_of_the_box_reaches_it() {
        assert!(!interval_reaches_box(0.45, 0.55, 0.0, 1.0));
        // [0.005, 0.195] of a [0, 1] box: closer to the lower end than its width.
        assert!(interval_reaches_box(0.005, 0.195, 0.0, 1.0));
        assert!(interval_reaches_box(0.805, 0.995, 0.0, 1.0));
        // A point-like interval still needs 0.1 % of the box.
        assert!(interval_reaches_box(0.9995, 0.9995, 0.0, 1.0));
    }

    #[test]
    fn the_pair_sum_meat_equals_the_dense_quadratic_form() {
        // Runs with gaps and unsorted bins, two gain rows at the end.
        let runs = vec![
            Run {
                start: 0,
                bins: vec![5, 3, 4, 9, 20],
            },
            Run {
                start: 5,
                bins: vec![1, 2, 3],
            },
        ];
        let n_rows = 2 * 8 + 2;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let jac = DMatrix::from_fn(n_rows, 3, |_, _| normal(&mut rng));
        let c = vec![
            Complex64::new(1.0, 0.0),
            Complex64::new(0.5, 0.2),
            Complex64::new(0.2, -0.1),
        ];
        let mut dense = DMatrix::<f64>::identity(n_rows, n_rows);
        for run in &runs {
            for (a, &ba) in run.bins.iter().enumerate() {
                for (b, &bb) in run.bins.iter().enumerate() {
                    let d = ba as i64 - bb as i64;
                    if d == 0 || d.unsigned_abs() as usize >= c.len() {
                        continue;
                    }
                    // E[r_k conj(r_l)] for bin(k) < bin(l) is c(d); the other order its
                    // conjugate.
                    let (k, l) = (run.start + a, run.start + b);
                    let v = if d < 0 {
                        c[(-d) as usize]
                    } else {
                        c[d as usize].conj()
                    };
                    dense[(2 * k, 2 * l)] = v.re;
                    dense[(2 * k + 1, 2 * l + 1)] = v.re;
                    dense[(2 * k, 2 * l + 1)] = -v.im;
                    dense[(2 * k + 1, 2 * l)] = v.im;
                }
            }
        }
        let want = jac.transpose() * dense * &jac;
        let got = sandwich_meat(&jac, &runs, &c);
        assert!(
            (&got - &want).norm() < 1e-12 * want.norm(),
            "{got} vs {want}"
        );
    }

    #[test]
    fn the_widening_matches_the_scatter_of_least_squares_under_correlated_noise() {
        // A smooth two-parameter linear model on 30 runs of 100 bins; its least-squares
        // estimate under AR(1) noise scatters by the sandwich, not by (J^T J)^-1.
        let runs = contiguous_runs(30, 100);
        let n = 30 * 100;
        let jac = DMatrix::from_fn(2 * n, 2, |row, col| {
            let k = (row / 2) % 100;
            match (col, row % 2) {
                (0, 0) => 1.0,
                (1, 0) => k as f64 / 100.0,
                _ => 0.0,
            }
        });
        let phi = Complex64::new(0.7, 0.0);
        let c: Vec<Complex64> = (0..=MAX_BIN_DISTANCE).map(|d| phi.powi(d as i32)).collect();
        let (sandwich, independent) = sandwich_variances(&jac, &runs, &c).unwrap();
        let f: Vec<f64> = (0..2)
            .map(|j| factor(sandwich[j], independent[j], f64::INFINITY))
            .collect();
        // Independent-noise sd times the widening against the seeded scatter of the fit.
        let a_inv = jac.tr_mul(&jac).try_inverse().unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let reps = 400;
        let mut sq = [0.0; 2];
        for _ in 0..reps {
            let r = ar1(&runs, phi, &mut rng);
            let y = nalgebra::DVector::from_fn(2 * n, |row, _| {
                let v = r[row / 2];
                // Real parts carry the model; unit variance per real component.
                if row % 2 == 0 {
                    v.re * 2f64.sqrt()
                } else {
                    v.im * 2f64.sqrt()
                }
            });
            let est = &a_inv * jac.tr_mul(&y);
            sq[0] += est[0] * est[0];
            sq[1] += est[1] * est[1];
        }
        for j in 0..2 {
            let scatter = (sq[j] / reps as f64).sqrt();
            let predicted = a_inv[(j, j)].sqrt() * f[j];
            // 400 draws: the sd's own relative error is about 1 / sqrt(800) = 3.5 %.
            assert!(
                (scatter / predicted - 1.0).abs() < 0.12,
                "coordinate {j}: scatter {scatter}, predicted {predicted}, widening {}",
                f[j]
            );
            assert!(f[j] > 1.5, "AR(1) at 0.7 should widen: {}", f[j]);
        }
    }
}
