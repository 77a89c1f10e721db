//! One tempered run (a sequential Monte Carlo sampler over the power posteriors
//! `p_beta(z) ∝ L(z)^beta pi(z)`): the adaptive ladder, the resampling, the ensemble
//! moves at every temperature and the stepping-stone and thermodynamic-integration
//! estimates of that run. [`super::evidence`] runs several of these as replicates.

use std::sync::atomic::{AtomicU64, Ordering};

use rand::RngExt;
use serde::Serialize;

use super::evidence::{EvidenceOptions, EvidenceProgress, Stage, TemperedTarget};
use crate::error::{Error, Result};
use crate::mcmc::{walker_rng, Ensemble, LogDensity, Moves, Ranks};

/// The power posterior `beta ln L(z) + ln pi(z)` as a [`LogDensity`], with the two terms
/// `[ln L, ln pi]` as its pointwise values so that the ensemble keeps them per walker.
/// Its callers count the likelihood evaluations from the ensemble's finite
/// evaluations (a point's density is finite exactly when its prior is finite and its
/// likelihood was computed), so the count does not depend on which rank computed a
/// point.
pub(crate) struct Tempered<'a, T: TemperedTarget> {
    pub target: &'a T,
    pub beta: f64,
}

impl<T: TemperedTarget> LogDensity for Tempered<'_, T> {
    fn dim(&self) -> usize {
        self.target.dim()
    }
    fn ln_density(&self, z: &[f64]) -> Result<f64> {
        self.ln_density_with_pointwise(z, &mut [0.0; 2])
    }
    fn n_pointwise(&self) -> usize {
        2
    }
    fn ln_density_with_pointwise(&self, z: &[f64], terms: &mut [f64]) -> Result<f64> {
        let ln_prior = self.target.ln_prior(z);
        if ln_prior == f64::NEG_INFINITY {
            terms.fill(f64::NEG_INFINITY);
            return Ok(f64::NEG_INFINITY);
        }
        if !ln_prior.is_finite() {
            return Err(Error::Numerical(format!(
                "ln_prior is {ln_prior} at z = {z:?}; it must be finite or -inf"
            )));
        }
        let ln_l = self.target.ln_likelihood(z)?;
        if !ln_l.is_finite() {
            return Err(Error::Numerical(format!(
                "ln_likelihood is {ln_l} at z = {z:?} inside the prior support; it must be \
                 finite there (return an error for a failed model evaluation)"
            )));
        }
        if terms.len() == 2 {
            terms[0] = ln_l;
            terms[1] = ln_prior;
        }
        Ok(self.beta * ln_l + ln_prior)
    }
}

/// The ladder and estimates of one tempered run.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct TemperingRun {
    /// Stepping-stone estimate of `ln Z`: the sum of `ln_z_increments`.
    pub ln_z: f64,
    /// Thermodynamic-integration estimate of `ln Z` on the same ladder (corrected
    /// trapezoid rule, see [`super::evidence`]).
    pub ln_z_ti: f64,
    /// The temperatures, `betas[0] = 0`, last = 1.
    pub betas: Vec<f64>,
    /// `ln mean_j exp((beta_{k+1} - beta_k) ln L_j)` over the walkers at `beta_k`.
    pub ln_z_increments: Vec<f64>,
    /// Mean of `ln L` over the walkers at each temperature (after its moves).
    pub mean_ln_likelihood: Vec<f64>,
    /// Variance of `ln L` over the walkers at each temperature (after its moves).
    pub var_ln_likelihood: Vec<f64>,
    /// Acceptance fraction of the moves at each temperature (`NaN` at `beta = 0`, which
    /// uses independent prior draws).
    pub acceptance: Vec<f64>,
    /// Ensemble steps at each temperature (0 at `beta = 0`).
    pub steps: Vec<usize>,
    /// Likelihood evaluations of this run (tempering only).
    pub n_likelihood_evaluations: u64,
}

/// Runs replicate `index` from prior draws to `beta = 1`; returns the run and the final
/// ensemble (at `beta = 1`, equally weighted) for posterior sampling.
pub(crate) fn temper<'a, T: TemperedTarget>(
    target: &'a T,
    opts: &EvidenceOptions,
    moves: &Moves,
    key: [u8; 32],
    index: usize,
    n_likelihood: &'a AtomicU64,
    progress: &mut Option<&mut dyn FnMut(EvidenceProgress)>,
) -> Result<(TemperingRun, Ensemble)> {
    let dim = target.dim();
    let w = opts.n_walkers;
    let mut rngs: Vec<_> = (0..w).map(|i| walker_rng(key, index, i)).collect();
    let mut positions = Vec::with_capacity(w * dim);
    for (i, rng) in rngs.iter_mut().enumerate() {
        let z = target.sample_prior(rng)?;
        if z.len() != dim {
            return Err(Error::Usage(format!(
                "sample_prior gave {} values, the target has {dim} parameters",
                z.len()
            )));
        }
        if target.ln_prior(&z) == f64::NEG_INFINITY {
            return Err(Error::Numerical(format!(
                "prior draw {i} at {z:?} has ln_prior = -inf: sample_prior and ln_prior \
                 disagree"
            )));
        }
        positions.extend(z);
    }
    let mut density = Tempered { target, beta: 0.0 };
    let mut ens = Ensemble::from_positions(&density, key, index, positions, rngs, true, &Ranks)?;
    n_likelihood.fetch_add(w as u64, Ordering::Relaxed);
    let (m0, v0) = ln_l_moments(&ens);
    let mut run = TemperingRun {
        ln_z: 0.0,
        ln_z_ti: 0.0,
        betas: vec![0.0],
        ln_z_increments: Vec::new(),
        mean_ln_likelihood: vec![m0],
        var_ln_likelihood: vec![v0],
        acceptance: vec![f64::NAN],
        steps: vec![0],
        n_likelihood_evaluations: 0,
    };
    while density.beta < 1.0 {
        if run.betas.len() > opts.max_temperatures {
            return Err(Error::Numerical(format!(
                "replicate {index}: {} temperatures reached beta = {:.3e} only; raise \
                 max_temperatures or lower target_cess",
                opts.max_temperatures, density.beta
            )));
        }
        let ln_l: Vec<f64> = ens.pointwise.chunks(2).map(|t| t[0]).collect();
        let beta = next_beta(&ln_l, density.beta, opts.target_cess).ok_or_else(|| {
            Error::Numerical(format!(
                "replicate {index}: the temperature ladder stalled at beta = {:e} (ln L \
                 spread over the walkers too large to resolve)",
                density.beta
            ))
        })?;
        let delta = beta - density.beta;
        let ln_w: Vec<f64> = ln_l.iter().map(|l| delta * l).collect();
        run.ln_z_increments
            .push(log_sum_exp(&ln_w) - (w as f64).ln());
        let metric = CloudMetric::of(&ens.positions, dim);
        let u: f64 = ens.rng.random();
        let parents = systematic_resample(&ln_w, u);
        resample(&mut ens, &parents);
        density.beta = beta;
        for (lp, t) in ens.ln_p.iter_mut().zip(ens.pointwise.chunks(2)) {
            *lp = beta * t[0] + t[1];
        }
        let start = ens.positions.clone();
        let accepted_before: u64 = ens.accepted.iter().sum();
        let mut steps = 0;
        while steps < opts.max_steps_per_temperature {
            let n = ens.step(&density, moves, true, true, &Ranks)?;
            n_likelihood.fetch_add(n, Ordering::Relaxed);
            steps += 1;
            if steps >= opts.min_steps_per_temperature
                && metric.mean_squared_jump(&start, &ens.positions) >= opts.jump_target
            {
                break;
            }
        }
        let accepted: u64 = ens.accepted.iter().sum::<u64>() - accepted_before;
        let (m, v) = ln_l_moments(&ens);
        run.betas.push(beta);
        run.mean_ln_likelihood.push(m);
        run.var_ln_likelihood.push(v);
        run.acceptance.push(accepted as f64 / (w * steps) as f64);
        run.steps.push(steps);
        run.ln_z = run.ln_z_increments.iter().sum();
        if let Some(cb) = progress.as_deref_mut() {
            cb(EvidenceProgress {
                replicate: index,
                n_replicates: opts.n_replicates,
                stage: Stage::Tempering {
                    temperature: run.betas.len() - 1,
                    beta,
                },
                ln_z_partial: run.ln_z,
                n_likelihood_evaluations: n_likelihood.load(Ordering::Relaxed),
            });
        }
    }
    run.ln_z_ti =
        thermodynamic_integral(&run.betas, &run.mean_ln_likelihood, &run.var_ln_likelihood);
    ens.accepted.fill(0);
    Ok((run, ens))
}

/// Squared distances in the metric of a walker cloud's covariance `C`:
/// `(x - y)^T C^-1 (x - y) / dim`, through the Cholesky factor of `C` (the diagonal of
/// `C` alone if `C` is singular).
struct CloudMetric {
    dim: usize,
    chol: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    var: Vec<f64>,
}

impl CloudMetric {
    fn of(positions: &[f64], dim: usize) -> Self {
        let n = positions.len() / dim;
        let x = nalgebra::DMatrix::from_row_slice(n, dim, positions);
        let mean = x.row_mean();
        let mut c = x;
        for mut row in c.row_iter_mut() {
            row -= &mean;
        }
        let cov = c.transpose() * &c / (n as f64 - 1.0);
        let var = (0..dim)
            .map(|i| cov[(i, i)].max(f64::MIN_POSITIVE))
            .collect();
        CloudMetric {
            dim,
            chol: nalgebra::Cholesky::new(cov),
            var,
        }
    }

    /// Mean over walkers of the squared jump from `start` to `now`, per dimension. For
    /// independent draws from a target of covariance `C` it is 2; a random walk of
    /// small steps grows it about linearly in the number of steps.
    fn mean_squared_jump(&self, start: &[f64], now: &[f64]) -> f64 {
        let d = self.dim;
        let n = start.len() / d;
        let mut total = 0.0;
        for (a, b) in start.chunks(d).zip(now.chunks(d)) {
            let diff = nalgebra::DVector::from_iterator(d, a.iter().zip(b).map(|(p, q)| q - p));
            total += match &self.chol {
                Some(ch) => ch
                    .l()
                    .solve_lower_triangular(&diff)
                    .map_or(f64::INFINITY, |v| v.norm_squared()),
                None => diff.iter().zip(&self.var).map(|(v, s)| v * v / s).sum(),
            };
        }
        total / (n * d) as f64
    }
}

/// Mean and variance (divisor n - 1) of `ln L` over the walkers.
fn ln_l_moments(ens: &Ensemble) -> (f64, f64) {
    let n = ens.n_walkers() as f64;
    let mean = ens.pointwise.chunks(2).map(|t| t[0]).sum::<f64>() / n;
    let ss: f64 = ens.pointwise.chunks(2).map(|t| (t[0] - mean).powi(2)).sum();
    (mean, ss / (n - 1.0))
}

/// Replaces every walker by its parent's state (position, densities); walkers keep
/// their own random streams, so duplicates separate at the next move.
fn resample(ens: &mut Ensemble, parents: &[usize]) {
    let dim = ens.dim;
    let (pos, ln_p, pw) = (
        ens.positions.clone(),
        ens.ln_p.clone(),
        ens.pointwise.clone(),
    );
    for (i, &a) in parents.iter().enumerate() {
        ens.positions[i * dim..(i + 1) * dim].copy_from_slice(&pos[a * dim..(a + 1) * dim]);
        ens.ln_p[i] = ln_p[a];
        ens.pointwise[2 * i..2 * i + 2].copy_from_slice(&pw[2 * a..2 * a + 2]);
    }
}

/// `ln sum exp(x)` without overflow.
pub(crate) fn log_sum_exp(x: &[f64]) -> f64 {
    let m = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if m == f64::NEG_INFINITY {
        return m;
    }
    m + x.iter().map(|v| (v - m).exp()).sum::<f64>().ln()
}

/// Effective sample size fraction `(sum w)^2 / (n sum w^2)` of the weights
/// `w_j = exp(delta ln L_j)` (the conditional ESS of Zhou, Johansen & Aston 2016 for
/// equally weighted walkers).
pub(crate) fn ess_fraction(ln_l: &[f64], delta: f64) -> f64 {
    let m = ln_l.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (mut s1, mut s2) = (0.0, 0.0);
    for l in ln_l {
        let w = (delta * (l - m)).exp();
        s1 += w;
        s2 += w * w;
    }
    s1 * s1 / (ln_l.len() as f64 * s2)
}

/// The next temperature: `1` if the ESS fraction of the step to 1 is at least
/// `target`, else the largest `beta' > beta` (bisection to relative precision 1e-12)
/// with ESS fraction `>= target`. `None` when no representable step qualifies.
pub(crate) fn next_beta(ln_l: &[f64], beta: f64, target: f64) -> Option<f64> {
    let full = 1.0 - beta;
    if ess_fraction(ln_l, full) >= target {
        return Some(1.0);
    }
    // The ESS fraction decreases in delta (it is 1 at delta = 0).
    let (mut lo, mut hi) = (0.0, full);
    for _ in 0..2000 {
        let mid = 0.5 * (lo + hi);
        if ess_fraction(ln_l, mid) >= target {
            lo = mid;
        } else {
            hi = mid;
        }
        if lo > 0.0 && hi - lo <= 1e-12 * hi {
            break;
        }
    }
    let next = beta + lo;
    (next > beta).then_some(next)
}

/// Systematic resampling (Kitagawa 1996): parent indices of `n` walkers from
/// log weights, with one uniform `u` in `[0, 1)`. Walker `i` gets `floor(n w_i)` or
/// `ceil(n w_i)` copies (normalised weights `w_i`).
pub(crate) fn systematic_resample(ln_w: &[f64], u: f64) -> Vec<usize> {
    let n = ln_w.len();
    let m = ln_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = ln_w.iter().map(|l| (l - m).exp()).collect();
    let total: f64 = w.iter().sum();
    let mut parents = Vec::with_capacity(n);
    let (mut i, mut cum) = (0, w[0]);
    for j in 0..n {
        let point = (j as f64 + u) / n as f64 * total;
        while cum <= point && i + 1 < n {
            i += 1;
            cum += w[i];
        }
        parents.push(i);
    }
    parents
}

/// Thermodynamic integration `ln Z = int_0^1 E_beta[ln L] d beta` on the ladder by the
/// trapezoid rule with the end-point derivative correction (Friel, Hurn & Wyse 2014):
/// `sum_k h_k (E_k + E_{k+1}) / 2 - h_k^2 (V_{k+1} - V_k) / 12`, since
/// `d E_beta[ln L] / d beta = Var_beta[ln L] = V`; the error is `O(h^5)` per interval
/// instead of `O(h^3)`.
pub(crate) fn thermodynamic_integral(betas: &[f64], mean: &[f64], var: &[f64]) -> f64 {
    (0..betas.len() - 1)
        .map(|k| {
            let h = betas[k + 1] - betas[k];
            h * 0.5 * (mean[k] + mean[k + 1]) - h * h * (var[k + 1] - var[k]) / 12.0
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn systematic_resampling_gives_floor_or_ceil_copies() {
        let w = [0.1, 0.4, 0.05, 0.3, 0.15];
        let ln_w: Vec<f64> = w.iter().map(|v: &f64| v.ln() + 700.0).collect();
        for u in [0.0, 0.13, 0.5, 0.999] {
            let p = systematic_resample(&ln_w, u);
            assert_eq!(p.len(), 5);
            assert!(p.windows(2).all(|x| x[0] <= x[1]));
            for (i, wi) in w.iter().enumerate() {
                let copies = p.iter().filter(|&&a| a == i).count() as f64;
                let expected = 5.0 * wi;
                assert!(
                    copies >= expected.floor() && copies <= expected.ceil(),
                    "{u} {i}"
                );
            }
        }
    }

    #[test]
    fn next_beta_hits_the_target_ess() {
        // ln L spread of 1e5 (as prior draws of a sharp likelihood): the step is tiny
        // but the ESS fraction at the returned beta equals the target to 1e-9.
        let ln_l: Vec<f64> = (0..64)
            .map(|i| -1e5 * ((i * 37 % 64) as f64 / 64.0))
            .collect();
        let b = next_beta(&ln_l, 0.0, 0.6).unwrap();
        assert!(b > 0.0 && b < 1e-3);
        assert!((ess_fraction(&ln_l, b) - 0.6).abs() < 1e-9);
        // Flat ln L: straight to 1.
        assert_eq!(next_beta(&[-3.0; 8], 0.2, 0.6), Some(1.0));
    }

    #[test]
    fn corrected_trapezoid_is_exact_for_cubics() {
        // E(beta) = beta^3: V = 3 beta^2; the corrected trapezoid rule is exact for
        // cubics (Euler-Maclaurin), the integral is 1/4.
        let betas = [0.0, 0.1, 0.35, 0.7, 1.0];
        let mean: Vec<f64> = betas.iter().map(|b| b * b * b).collect();
        let var: Vec<f64> = betas.iter().map(|b| 3.0 * b * b).collect();
        assert!((thermodynamic_integral(&betas, &mean, &var) - 0.25).abs() < 1e-15);
    }

    #[test]
    fn log_sum_exp_is_stable() {
        assert!((log_sum_exp(&[1000.0, 1000.0]) - (1000.0 + 2f64.ln())).abs() < 1e-12);
        assert_eq!(log_sum_exp(&[f64::NEG_INFINITY; 3]), f64::NEG_INFINITY);
    }
}
