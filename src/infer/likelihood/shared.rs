//! Noise shared by a block's values at a known size, on top of their own noise scaled by
//! the block's `sigma`: `cov = sigma^2 D + L L^T` (`D = diag(sd_k^2)`, `L` the loadings,
//! `n x rank`), as one test's force noise is shared by every FRF value of the test.
//!
//! With the standardised residuals `d_k = r_k / sd_k`, `V = D^(-1/2) L` and the
//! eigen-decomposition `V^T V = Q diag(lambda) Q^T` (computed once), the rows of
//! `P = Q^T V^T` give `u = P d` and
//!
//! - `r^T cov^(-1) r = (d^T d - sum_i u_i^2 / (sigma^2 + lambda_i)) / sigma^2`,
//! - `ln det cov = ln det D + 2 n ln sigma + sum_i ln(1 + lambda_i / sigma^2)`
//!
//! (Woodbury and the matrix determinant lemma on `sigma^2 I + V V^T`), so an evaluation
//! costs `O(n rank)`. In the density's inner loop ([`SharedFactors::terms_of_det`]) one pass
//! forms the residuals and computes `d^T d` and every `u_i`, four values per step (AVX
//! when the CPU has it; the same operations in the same order either way, so the same
//! bits).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, SymmetricEigen};

/// Values per step of the residual kernel.
const L: usize = 4;

/// Ranks up to this are kept in registers (higher ranks take a general path).
const MAX_FIXED_RANK: usize = 4;

type Lanes = [f64; L];

/// The Woodbury factors of a block's shared noise (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SharedFactors {
    rank: usize,
    /// `P` by steps of [`L`] values: step `c`, row `i`, lane `l` at `p[c * rank + i][l]`
    /// is `P[i][c L + l]` (zero beyond the values).
    p: Vec<Lanes>,
    /// Eigenvalues `lambda_i` of `V^T V` (>= 0).
    lambda: Vec<f64>,
}

impl SharedFactors {
    /// The factors of loadings `loadings` (`n x rank`, row-major) on values with standard
    /// deviations `sd` (`n`).
    pub fn new(loadings: &[f64], rank: usize, sd: &[f64]) -> Result<Self> {
        let n = sd.len();
        if loadings.len() != n * rank {
            return Err(Error::Usage(format!(
                "{} shared-noise loadings for {n} values of rank {rank}",
                loadings.len()
            )));
        }
        if loadings.iter().any(|x| !x.is_finite()) {
            return Err(Error::Usage("shared-noise loadings must be finite".into()));
        }
        if rank == 0 {
            return Ok(SharedFactors {
                rank,
                p: Vec::new(),
                lambda: Vec::new(),
            });
        }
        let v = DMatrix::from_fn(n, rank, |k, r| loadings[k * rank + r] / sd[k]);
        let eig = SymmetricEigen::new(v.transpose() * &v);
        if eig.eigenvalues.iter().any(|x| !x.is_finite()) {
            return Err(Error::Numerical(
                "shared noise: non-finite eigenvalues of V^T V".into(),
            ));
        }
        let vq = &v * &eig.eigenvectors;
        let mut p = vec![[0.0; L]; n.div_ceil(L) * rank];
        for k in 0..n {
            for i in 0..rank {
                p[(k / L) * rank + i][k % L] = vq[(k, i)];
            }
        }
        Ok(SharedFactors {
            rank,
            p,
            lambda: eig.eigenvalues.iter().map(|x| x.max(0.0)).collect(),
        })
    }

    /// Columns of `L`.
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Eigenvalues `lambda_i` of `V^T V`.
    pub fn lambda(&self) -> &[f64] {
        &self.lambda
    }

    /// `(d^T d, sum_i u_i^2 / (s2 + lambda_i), sum_i ln(1 + lambda_i / s2))` for the
    /// standardised residuals `d` at `sigma^2 = s2`, value by value.
    pub fn terms(&self, d: &[f64], s2: f64) -> (f64, f64, f64) {
        let (ss, correction, det) = self.terms_det(d, s2);
        (ss, correction, det.ln())
    }

    /// [`Self::terms`] with `prod_i (1 + lambda_i / s2)` in place of its logarithm: any
    /// rank, the residuals given (the chained blocks' path and ranks above
    /// [`MAX_FIXED_RANK`]), by steps of [`L`] values as [`project`] sums them.
    fn terms_det(&self, d: &[f64], s2: f64) -> (f64, f64, f64) {
        let mut u = vec![0.0; self.rank];
        let ss = project_residuals(self, d, &mut u);
        let (correction, det) = self.woodbury(&u, s2);
        (ss, correction, det)
    }

    /// [`Self::terms`] of the residuals `d_k = (a_k - t_k) w_k`, formed in one pass with
    /// the sums, four values per step (the density's inner loop), with the determinant
    /// ratio `prod_i (1 + lambda_i / s2)` in place of its logarithm (so that a caller
    /// summing many blocks takes one logarithm).
    pub fn terms_of_det(&self, a: &[f64], t: &[f64], w: &[f64], s2: f64) -> (f64, f64, f64) {
        if self.rank > MAX_FIXED_RANK {
            let d: Vec<f64> = (0..a.len()).map(|k| (a[k] - t[k]) * w[k]).collect();
            return self.terms_det(&d, s2);
        }
        let mut u = [0.0; MAX_FIXED_RANK];
        let ss = project(self, a, t, w, &mut u);
        let (correction, det) = self.woodbury(&u[..self.rank], s2);
        (ss, correction, det)
    }

    /// Whitens standardised residuals `d` (or a Jacobian column of them) in place at
    /// `sigma^2 = s2`: `d <- W d` with `W = I - sum_i a_i P_i P_i^T / lambda_i`,
    /// `a_i = 1 - sigma / sqrt(sigma^2 + lambda_i)`, so that `|W d|^2 = d^T d - sum_i
    /// u_i^2 / (s2 + lambda_i)`, the Woodbury quadratic form times `sigma^2` (the rows
    /// `P_i` are orthogonal with `|P_i|^2 = lambda_i`, so `W` acts on each direction
    /// alone: `(1 - a_i)^2 = sigma^2 / (sigma^2 + lambda_i)`). Least squares on
    /// `W d / sigma` is then this block's maximum likelihood at fixed `sigma`.
    pub fn whiten(&self, d: &mut [f64], s2: f64) {
        for (i, &lambda) in self.lambda.iter().enumerate() {
            if lambda <= 0.0 {
                continue;
            }
            let p = |k: usize| self.p[(k / L) * self.rank + i][k % L];
            let u: f64 = d.iter().enumerate().map(|(k, d)| p(k) * d).sum();
            let a = 1.0 - (s2 / (s2 + lambda)).sqrt();
            let c = a * u / lambda;
            d.iter_mut().enumerate().for_each(|(k, d)| *d -= c * p(k));
        }
    }

    /// `sum_i u_i^2 / (s2 + lambda_i)` and `prod_i (1 + lambda_i / s2)`.
    fn woodbury(&self, u: &[f64], s2: f64) -> (f64, f64) {
        let mut correction = 0.0;
        let mut prod = 1.0;
        for (&u, &lambda) in u.iter().zip(&self.lambda) {
            let q = s2 + lambda;
            correction += u * u / q;
            prod *= q / s2;
        }
        (correction, prod)
    }
}

/// `d^T d` and `u = P d` (into `u[..rank]`) of `d = (a - t) w`, rank at most
/// [`MAX_FIXED_RANK`].
fn project(
    f: &SharedFactors,
    a: &[f64],
    t: &[f64],
    w: &[f64],
    u: &mut [f64; MAX_FIXED_RANK],
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX, checked just above.
        return unsafe { project_avx(f, a, t, w, u) };
    }
    project_any(f, a, t, w, u)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn project_avx(
    f: &SharedFactors,
    a: &[f64],
    t: &[f64],
    w: &[f64],
    u: &mut [f64; MAX_FIXED_RANK],
) -> f64 {
    project_any(f, a, t, w, u)
}

#[inline(always)]
fn project_any(
    f: &SharedFactors,
    a: &[f64],
    t: &[f64],
    w: &[f64],
    u: &mut [f64; MAX_FIXED_RANK],
) -> f64 {
    match f.rank {
        0 => project_fixed::<0>(&f.p, a, t, w, u),
        1 => project_fixed::<1>(&f.p, a, t, w, u),
        2 => project_fixed::<2>(&f.p, a, t, w, u),
        3 => project_fixed::<3>(&f.p, a, t, w, u),
        _ => project_fixed::<4>(&f.p, a, t, w, u),
    }
}

/// `d^T d` and `u = P d` (into `u`, of length the rank) of given residuals `d`, any
/// rank: four partial sums per quantity, added pairwise at the end, AVX when the CPU
/// has it (the same operations in the same order either way).
fn project_residuals(f: &SharedFactors, d: &[f64], u: &mut [f64]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX, checked just above.
        return unsafe { project_residuals_avx(f, d, u) };
    }
    project_residuals_any(f, d, u)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn project_residuals_avx(f: &SharedFactors, d: &[f64], u: &mut [f64]) -> f64 {
    project_residuals_any(f, d, u)
}

/// Ranks up to this take [`project_residuals_in`] with the partial sums on the stack
/// (the shared force noise of a hammer test at full rank: 9 components on the
/// four-story campaign).
const MAX_STACK_RANK: usize = 16;

#[inline(always)]
fn project_residuals_any(f: &SharedFactors, d: &[f64], u: &mut [f64]) -> f64 {
    if f.rank <= MAX_STACK_RANK {
        let mut acc = [[0.0; L]; MAX_STACK_RANK];
        project_residuals_in(f, d, u, &mut acc[..f.rank])
    } else {
        let mut acc = vec![[0.0; L]; f.rank];
        project_residuals_in(f, d, u, &mut acc)
    }
}

/// [`project_residuals`] with zeroed partial sums `acc`, one per rank.
#[inline(always)]
fn project_residuals_in(f: &SharedFactors, d: &[f64], u: &mut [f64], acc: &mut [Lanes]) -> f64 {
    let r = f.rank;
    let mut ss = [0.0; L];
    let (full, rest) = d.split_at(d.len() / L * L);
    for (c, chunk) in full.chunks_exact(L).enumerate() {
        let dl = [chunk[0], chunk[1], chunk[2], chunk[3]];
        accumulate(&dl, &f.p[c * r..c * r + r], &mut ss, acc);
    }
    if !rest.is_empty() {
        let mut dl = [0.0; L];
        dl[..rest.len()].copy_from_slice(rest);
        let c = full.len() / L;
        accumulate(&dl, &f.p[c * r..c * r + r], &mut ss, acc);
    }
    for (u, acc) in u.iter_mut().zip(acc.iter()) {
        *u = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
    (ss[0] + ss[1]) + (ss[2] + ss[3])
}

/// One step of [`L`] values: `d = (a - t) w`, `ss += d^2`, `acc_i += P_i d`.
#[inline(always)]
fn step<const R: usize>(
    a: &[f64],
    t: &[f64],
    w: &[f64],
    p: &[Lanes],
    ss: &mut Lanes,
    acc: &mut [Lanes; R],
) {
    let mut d = [0.0; L];
    for l in 0..L {
        d[l] = (a[l] - t[l]) * w[l];
    }
    accumulate(&d, p, ss, acc);
}

/// `ss += d^2`, `acc_i += P_i d` for one step of [`L`] residuals `d` (both kernels).
#[inline(always)]
fn accumulate(d: &Lanes, p: &[Lanes], ss: &mut Lanes, acc: &mut [Lanes]) {
    for l in 0..L {
        ss[l] += d[l] * d[l];
    }
    for (acc, p) in acc.iter_mut().zip(p) {
        for l in 0..L {
            acc[l] += p[l] * d[l];
        }
    }
}

/// [`project`] for rank `R`: four partial sums per quantity, added pairwise at the end;
/// a last partial step padded with `w = 0`.
#[inline(always)]
fn project_fixed<const R: usize>(
    p: &[Lanes],
    a: &[f64],
    t: &[f64],
    w: &[f64],
    u: &mut [f64; MAX_FIXED_RANK],
) -> f64 {
    let n = a.len() / L * L;
    let mut ss = [0.0; L];
    let mut acc = [[0.0; L]; R];
    let full = a[..n]
        .chunks_exact(L)
        .zip(t[..n].chunks_exact(L))
        .zip(w[..n].chunks_exact(L));
    for (c, ((a, t), w)) in full.enumerate() {
        let p = if R == 0 {
            &[][..]
        } else {
            &p[c * R..c * R + R]
        };
        step::<R>(a, t, w, p, &mut ss, &mut acc);
    }
    if n < a.len() {
        let (mut at, mut tt, mut wt) = ([0.0; L], [0.0; L], [0.0; L]);
        let rest = a.len() - n;
        at[..rest].copy_from_slice(&a[n..]);
        tt[..rest].copy_from_slice(&t[n..]);
        wt[..rest].copy_from_slice(&w[n..]);
        let c = n / L;
        let p = if R == 0 {
            &[][..]
        } else {
            &p[c * R..c * R + R]
        };
        step::<R>(&at, &tt, &wt, p, &mut ss, &mut acc);
    }
    for (u, acc) in u.iter_mut().zip(&acc) {
        *u = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
    (ss[0] + ss[1]) + (ss[2] + ss[3])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::infer::likelihood::{Block, Correlation, NoiseScale, Transform};

    /// Oracle: the block's log-likelihood equals the dense Gaussian log density
    /// `-n/2 ln 2 pi - ln det(cov)/2 - r^T cov^-1 r / 2` with
    /// `cov = sigma^2 D^(1/2) C D^(1/2) + L L^T` (`D = diag(sd^2)`, `C` the correlation
    /// of a bin chain, the identity without one), for ranks 0 to 5, 9 and 17 (the kernels
    /// of fixed rank, the general one on the stack and on the heap; 17 above the 11
    /// values, so some eigenvalues are zero), both transforms, with and without the chain, and
    /// several noise scales; the pointwise terms sum to it.
    #[test]
    fn shared_noise_block_is_the_dense_gaussian_density() {
        let rho: Vec<f64> = (0..11)
            .map(|k| {
                if k % 6 == 0 {
                    0.0
                } else {
                    0.3 + 0.05 * k as f64
                }
            })
            .collect();
        for chain in [&[][..], &rho[..]] {
            shared_noise_block_matches_dense(chain);
        }
    }

    fn shared_noise_block_matches_dense(chain: &[f64]) {
        let corr = |i: usize, j: usize| match chain.is_empty() {
            true => f64::from(u8::from(i == j)),
            false => (i.min(j) + 1..=i.max(j)).map(|k| chain[k]).product::<f64>(),
        };
        let n = 11;
        let obs: Vec<f64> = (0..n).map(|k| 1.0 + 0.3 * (k as f64).sin().abs()).collect();
        let pred: Vec<f64> = (0..n)
            .map(|k| obs[k] * (1.0 + 0.02 * (k as f64 * 1.7).cos()))
            .collect();
        let sd: Vec<f64> = (0..n).map(|k| 0.01 + 0.002 * k as f64).collect();
        for rank in [0, 1, 2, 3, 4, 5, 9, 17] {
            let loadings: Vec<f64> = (0..n * rank)
                .map(|i| 0.008 * ((i as f64 * 0.9).sin() + 0.3))
                .collect();
            for transform in [Transform::Identity, Transform::Ln] {
                let correlation = Correlation {
                    shared: Some((&loadings, rank)),
                    chain,
                };
                let scale = NoiseScale::Sampled(0);
                let b =
                    Block::correlated_values("s", 0..n, &obs, &sd, transform, correlation, scale)
                        .unwrap();
                let mut r = vec![0.0; n];
                b.residuals(&pred, &mut r);
                for sigma in [0.3, 1.0, 2.5] {
                    let got = b.ln_likelihood(&r, sigma);
                    let fused = b
                        .ln_likelihood_fused_det(&pred, (sigma, sigma.ln()), b.ln_norm())
                        .map(|(l, det)| l - 0.5 * det.ln());
                    match (transform, chain.is_empty(), fused) {
                        (Transform::Identity, true, Some(fused)) => {
                            assert!((fused - got).abs() <= 1e-12 * got.abs().max(1.0))
                        }
                        (Transform::Ln, _, None) | (_, false, None) => {}
                        (_, _, fused) => panic!("{transform:?}: fused {fused:?}"),
                    }
                    let mut pointwise = vec![0.0; n];
                    b.ln_likelihood_pointwise(&r, sigma, &mut pointwise);
                    let sum: f64 = pointwise.iter().sum();
                    assert!((sum - got).abs() <= 1e-12 * got.abs().max(1.0));
                    let cov = DMatrix::from_fn(n, n, |i, j| {
                        let own = sigma * sigma * sd[i] * sd[j] * corr(i, j);
                        own + (0..rank)
                            .map(|c| loadings[i * rank + c] * loadings[j * rank + c])
                            .sum::<f64>()
                    });
                    let e = nalgebra::DVector::from_fn(n, |k, _| match transform {
                        Transform::Ln => pred[k].ln() - obs[k].ln(),
                        _ => pred[k] - obs[k],
                    });
                    let chol = cov.cholesky().unwrap();
                    let ln_det: f64 = 2.0 * chol.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
                    let quad = e.dot(&chol.solve(&e));
                    let dense = -0.5 * n as f64 * (2.0 * std::f64::consts::PI).ln()
                        - 0.5 * ln_det
                        - 0.5 * quad;
                    assert!(
                        (got - dense).abs() <= 1e-10 * dense.abs().max(1.0),
                        "rank {rank} {transform:?} chain {} sigma {sigma}: {got} vs {dense}",
                        !chain.is_empty()
                    );
                }
            }
        }
    }

    /// Oracle: `|W d|^2` of [`SharedFactors::whiten`] is the Woodbury quadratic form
    /// `d^T d - sum_i u_i^2 / (s2 + lambda_i)` for ranks 0 to 5, 9 and 17 and several
    /// scales.
    #[test]
    fn whitened_residuals_give_the_woodbury_quadratic_form() {
        let n = 13;
        let d: Vec<f64> = (0..n).map(|k| (k as f64 * 1.3).sin() + 0.2).collect();
        for rank in [0, 1, 2, 3, 4, 5, 9, 17] {
            let loadings: Vec<f64> = (0..n * rank)
                .map(|i| 0.8 * ((i as f64 * 0.7).cos() + 0.4))
                .collect();
            let f = SharedFactors::new(&loadings, rank, &vec![1.0; n]).unwrap();
            for s2 in [0.09, 1.0, 6.25] {
                let (ss, correction, _) = f.terms(&d, s2);
                let mut w = d.clone();
                f.whiten(&mut w, s2);
                let got: f64 = w.iter().map(|v| v * v).sum();
                let want = ss - correction;
                assert!(
                    (got - want).abs() <= 1e-12 * ss,
                    "rank {rank} s2 {s2}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn rejects_loadings_of_the_wrong_size() {
        let err = SharedFactors::new(&[1.0; 5], 2, &[1.0; 3]).unwrap_err();
        assert!(err.to_string().contains("rank 2"), "{err}");
    }
}
