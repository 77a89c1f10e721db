//! The Gaussian log-likelihood's sums over the residuals, with each test's shared
//! force noise at its known size and the sampled noise scale on the per-point part only.
//!
//! A run of points with shared noise has covariance `Sigma = s^2 D + L L^T`
//! (`D = diag(sigma_k^2)`, `L` its loadings, [`CorrelatedNoise`]). With the standardised
//! residuals `d_k = r_k / sigma_k`, `V = D^(-1/2) L` and the eigen-decomposition
//! `V^T V = Q diag(lambda) Q^T` (computed once), the rows of `P = Q^T V^T` give
//! `u = P d` and
//!
//! - `r^T Sigma^(-1) r = (d^T d - sum_i u_i^2 / (s^2 + lambda_i)) / s^2`,
//! - `ln det Sigma = ln det D + 2 n ln s + sum_i ln(1 + lambda_i / s^2)`
//!
//! (Woodbury and the matrix determinant lemma on `s^2 I + V V^T`). Runs without shared
//! noise are the same with rank 0. One pass over the points computes `d^T d` and every
//! `u` (the residual formed once), four points per step (AVX when the CPU has it; the
//! same operations in the same order either way, so the same bits).

use super::data::CorrelatedNoise;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, SymmetricEigen};

/// Points per step of the residual kernel.
const L: usize = 4;

/// Shared ranks up to this are kept in registers (higher ranks take a general path).
const MAX_FIXED_RANK: usize = 4;

type Lanes = [f64; L];

/// One run of consecutive points: independent (rank 0) or with shared noise.
#[derive(Debug, Clone)]
struct Segment {
    start: usize,
    len: usize,
    rank: usize,
    /// Per-point form: `P` by steps of [`L`] points, step `c`, row `i`, lane `l` at
    /// `p[c * rank + i][l]` = `P[i][c L + l]` (zero beyond the run). Per-bin form
    /// ([`Self::bins`]): the same by steps of [`L`] bins of `P_bin`.
    p: Vec<Lanes>,
    /// Eigenvalues `lambda_i` of `V^T V` (>= 0).
    lambda: Vec<f64>,
    /// When the run is one test's block whose loadings are the same per-bin vector `A_b`
    /// for every pair up to a factor (`L_(j,b) = f_(j,b) A_b`, the force noise's
    /// error is common to all responses): `u = P_bin g` with `g_b = sum_j c_(j,b) d_(j,b)`,
    /// `c = f / sigma`, `P_bin = Q^T A^T` (one multiply-add per point instead of `rank`).
    bins: Option<PerBin>,
}

/// The per-bin form of a run (see [`Segment::bins`]); points are pair-major.
#[derive(Debug, Clone)]
struct PerBin {
    n_pairs: usize,
    n_bins: usize,
    /// `c_(j,b)` in point order.
    c: Vec<f64>,
}

/// The sums of one evaluation: `d^T d`, `sum_i u_i^2 / (s^2 + lambda_i)` and
/// `sum_i ln(1 + lambda_i / s^2)` over every run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Sums {
    pub ss: f64,
    pub correction: f64,
    pub ln_det: f64,
}

/// The runs of points of a posterior's data, in order, covering every point.
#[derive(Debug, Clone)]
pub(super) struct ResidualLayout {
    segments: Vec<Segment>,
}

impl ResidualLayout {
    /// Runs of `n` points: one per block of `correlated` (in order, not overlapping; the
    /// data validated them) and independent runs between them. `shapes`: pairs and bins
    /// of each block of the long vector (pair-major), for the per-bin form.
    pub fn new(
        n: usize,
        correlated: &[CorrelatedNoise],
        sigma: &[f64],
        shapes: &[(usize, usize)],
    ) -> Result<Self> {
        let mut segments = Vec::new();
        let mut at = 0;
        let plain = |start: usize, len: usize| Segment {
            start,
            len,
            rank: 0,
            p: Vec::new(),
            lambda: Vec::new(),
            bins: None,
        };
        let mut block_starts = Vec::new();
        let mut s = 0;
        for &(n_pairs, n_bins) in shapes {
            block_starts.push((s, n_pairs, n_bins));
            s += n_pairs * n_bins;
        }
        for c in correlated {
            if c.start > at {
                segments.push(plain(at, c.start - at));
            }
            let shape = block_starts
                .iter()
                .find(|&&(s, p, b)| s == c.start && p * b == c.len)
                .map(|&(_, p, b)| (p, b));
            segments.push(shared_segment(c, sigma, shape)?);
            at = c.start + c.len;
        }
        if n > at {
            segments.push(plain(at, n - at));
        }
        Ok(ResidualLayout { segments })
    }

    /// [`Sums`] of the residuals `(a_k - t_k) w_k` (`w_k = 1 / sigma_k`) at `s^2 = s2`.
    pub fn sums(&self, a: &[f64], t: &[f64], w: &[f64], s2: f64) -> Sums {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX, checked just above.
            return unsafe { sums_avx(self, a, t, w, s2) };
        }
        sums_all(self, a, t, w, s2)
    }

    /// Adds to `pointwise` each run's `0.5 (correction / s^2 - ln_det)`, spread evenly
    /// over its points (its `d_k` terms are the caller's).
    pub fn spread_shared(&self, a: &[f64], t: &[f64], w: &[f64], s2: f64, pointwise: &mut [f64]) {
        for seg in self.segments.iter().filter(|s| s.rank > 0) {
            let range = seg.start..seg.start + seg.len;
            let mut u = vec![0.0; seg.rank];
            segment_dyn(
                seg,
                &a[range.clone()],
                &t[range.clone()],
                &w[range.clone()],
                &mut u,
            );
            let (correction, ln_det) = shared_terms(seg, &u, s2);
            let each = 0.5 * (correction / s2 - ln_det) / seg.len as f64;
            pointwise[range].iter_mut().for_each(|v| *v += each);
        }
    }
}

/// The run of a block of shared noise: `V = D^(-1/2) L`, `V^T V = Q diag(lambda) Q^T`,
/// `P = Q^T V^T` laid out by steps of [`L`] points, or the per-bin form when `shape`
/// (pairs, bins) is given and the loadings factor ([`per_bin_factor`]).
fn shared_segment(
    c: &CorrelatedNoise,
    sigma: &[f64],
    shape: Option<(usize, usize)>,
) -> Result<Segment> {
    let (len, rank) = (c.len, c.rank);
    let v = DMatrix::from_fn(len, rank, |k, r| {
        c.loadings[k * rank + r] / sigma[c.start + k]
    });
    let eig = SymmetricEigen::new(v.transpose() * &v);
    if eig.eigenvalues.iter().any(|x| !x.is_finite()) {
        return Err(Error::Numerical(
            "shared noise: non-finite eigenvalues of V^T V".into(),
        ));
    }
    let q = &eig.eigenvectors;
    let factor = shape.and_then(|(n_pairs, n_bins)| per_bin_factor(c, n_pairs, n_bins));
    let (rows, pm, bins) = match factor {
        Some((n_pairs, n_bins, f)) => {
            // P_bin = Q^T A^T, A the first pair's rows
            let a = DMatrix::from_row_slice(n_bins, rank, &c.loadings[..n_bins * rank]);
            let cw = f
                .iter()
                .enumerate()
                .map(|(k, f)| f / sigma[c.start + k])
                .collect();
            let bins = PerBin {
                n_pairs,
                n_bins,
                c: cw,
            };
            (n_bins, a * q, Some(bins))
        }
        None => (len, &v * q, None),
    };
    let mut p = vec![[0.0; L]; rows.div_ceil(L) * rank];
    for k in 0..rows {
        for i in 0..rank {
            p[(k / L) * rank + i][k % L] = pm[(k, i)];
        }
    }
    Ok(Segment {
        start: c.start,
        len,
        rank,
        p,
        lambda: eig.eigenvalues.iter().map(|x| x.max(0.0)).collect(),
        bins,
    })
}

/// `f` with `L_(j,b) = f_(j,b) A_b` (`A_b` the first pair's row of bin `b`, `f_(0,b) = 1`)
/// within 1e-12 of each row's norm, if the run of `n_pairs x n_bins` points factors so.
fn per_bin_factor(
    c: &CorrelatedNoise,
    n_pairs: usize,
    n_bins: usize,
) -> Option<(usize, usize, Vec<f64>)> {
    let rank = c.rank;
    let row = |k: usize| &c.loadings[k * rank..(k + 1) * rank];
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| a * b).sum::<f64>();
    let mut f = Vec::with_capacity(c.len);
    for k in 0..n_pairs * n_bins {
        let (x, a) = (row(k), row(k % n_bins));
        let aa = dot(a, a);
        let fk = if aa > 0.0 { dot(x, a) / aa } else { 0.0 };
        let err = x
            .iter()
            .zip(a)
            .map(|(x, a)| (x - fk * a).powi(2))
            .sum::<f64>();
        if err > 1e-24 * dot(x, x) || (aa == 0.0 && dot(x, x) > 0.0) {
            return None;
        }
        f.push(fk);
    }
    Some((n_pairs, n_bins, f))
}

/// `sum_i u_i^2 / (s^2 + lambda_i)` and `sum_i ln(1 + lambda_i / s^2)` of one run.
#[inline(always)]
fn shared_terms(seg: &Segment, u: &[f64], s2: f64) -> (f64, f64) {
    let mut correction = 0.0;
    let mut prod = 1.0;
    for (&u, &lambda) in u.iter().zip(&seg.lambda) {
        let q = s2 + lambda;
        correction += u * u / q;
        prod *= q / s2;
    }
    (correction, prod.ln())
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn sums_avx(layout: &ResidualLayout, a: &[f64], t: &[f64], w: &[f64], s2: f64) -> Sums {
    sums_all(layout, a, t, w, s2)
}

/// [`ResidualLayout::sums`], run by run. The log determinants of all runs multiply into
/// one product (each factor `1 + lambda_i / s^2 >= 1`), whose logarithm is taken once
/// (and on the way, should it grow beyond 1e250).
#[inline(always)]
fn sums_all(layout: &ResidualLayout, a: &[f64], t: &[f64], w: &[f64], s2: f64) -> Sums {
    let mut out = Sums {
        ss: 0.0,
        correction: 0.0,
        ln_det: 0.0,
    };
    let mut prod = 1.0;
    for seg in &layout.segments {
        let range = seg.start..seg.start + seg.len;
        let (a, t, w) = (&a[range.clone()], &t[range.clone()], &w[range]);
        let mut u = [0.0; MAX_FIXED_RANK];
        out.ss += match (seg.rank, &seg.bins) {
            (0, _) => segment_fixed::<0>(seg, a, t, w, &mut u),
            (1, Some(b)) => segment_bins::<1>(seg, b, a, t, w, &mut u),
            (2, Some(b)) => segment_bins::<2>(seg, b, a, t, w, &mut u),
            (3, Some(b)) => segment_bins::<3>(seg, b, a, t, w, &mut u),
            (4, Some(b)) => segment_bins::<4>(seg, b, a, t, w, &mut u),
            (1, None) => segment_fixed::<1>(seg, a, t, w, &mut u),
            (2, None) => segment_fixed::<2>(seg, a, t, w, &mut u),
            (3, None) => segment_fixed::<3>(seg, a, t, w, &mut u),
            (4, None) => segment_fixed::<4>(seg, a, t, w, &mut u),
            _ => {
                let mut u = vec![0.0; seg.rank];
                let ss = segment_dyn(seg, a, t, w, &mut u);
                let (c, d) = shared_terms(seg, &u, s2);
                out.correction += c;
                out.ln_det += d;
                out.ss += ss;
                continue;
            }
        };
        for (&u, &lambda) in u[..seg.rank].iter().zip(&seg.lambda) {
            let q = s2 + lambda;
            out.correction += u * u / q;
            prod *= q / s2;
        }
        if prod > 1e250 {
            out.ln_det += prod.ln();
            prod = 1.0;
        }
    }
    out.ln_det += prod.ln();
    out
}

/// One step of [`L`] points: `d = (a - t) w`, `ss += d^2`, `acc_i += P_i d`.
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
        ss[l] += d[l] * d[l];
    }
    for (acc, p) in acc.iter_mut().zip(p) {
        for l in 0..L {
            acc[l] += p[l] * d[l];
        }
    }
}

/// `d^T d` of one run and its `u = P d` in `u[..R]` (four partial sums per quantity,
/// added pairwise at the end; a last partial step padded with `w = 0`).
#[inline(always)]
fn segment_fixed<const R: usize>(
    seg: &Segment,
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
            &seg.p[c * R..c * R + R]
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
            &seg.p[c * R..c * R + R]
        };
        step::<R>(&at, &tt, &wt, p, &mut ss, &mut acc);
    }
    for (u, acc) in u.iter_mut().zip(&acc) {
        *u = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
    (ss[0] + ss[1]) + (ss[2] + ss[3])
}

/// Per-bin form of [`segment_fixed`] ([`Segment::bins`]): by steps of [`L`] bins, over
/// the pairs, `d = (a - t) w`, `ss += d^2`, `g += c d`; then `acc_i += P_bin,i g`.
#[inline(always)]
fn segment_bins<const R: usize>(
    seg: &Segment,
    bins: &PerBin,
    a: &[f64],
    t: &[f64],
    w: &[f64],
    u: &mut [f64; MAX_FIXED_RANK],
) -> f64 {
    let nb = bins.n_bins;
    let mut ss = [0.0; L];
    let mut acc = [[0.0; L]; R];
    for (step, p) in seg.p.chunks_exact(R).enumerate() {
        let b0 = step * L;
        let mut g = [0.0; L];
        for j in 0..bins.n_pairs {
            let k = j * nb + b0;
            if b0 + L <= nb {
                let c = &bins.c[k..k + L];
                bin_step(&a[k..k + L], &t[k..k + L], &w[k..k + L], c, &mut ss, &mut g);
            } else {
                // a last partial step, padded with w = c = 0
                let m = nb - b0;
                let mut x = [[0.0; L]; 4];
                x[0][..m].copy_from_slice(&a[k..k + m]);
                x[1][..m].copy_from_slice(&t[k..k + m]);
                x[2][..m].copy_from_slice(&w[k..k + m]);
                x[3][..m].copy_from_slice(&bins.c[k..k + m]);
                bin_step(&x[0], &x[1], &x[2], &x[3], &mut ss, &mut g);
            }
        }
        for (acc, p) in acc.iter_mut().zip(p) {
            for l in 0..L {
                acc[l] += p[l] * g[l];
            }
        }
    }
    for (u, acc) in u.iter_mut().zip(&acc) {
        *u = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    }
    (ss[0] + ss[1]) + (ss[2] + ss[3])
}

/// One pair's step of [`L`] bins: `d = (a - t) w`, `ss += d^2`, `g += c d`.
#[inline(always)]
fn bin_step(a: &[f64], t: &[f64], w: &[f64], c: &[f64], ss: &mut Lanes, g: &mut Lanes) {
    for l in 0..L {
        let d = (a[l] - t[l]) * w[l];
        ss[l] += d * d;
        g[l] += c[l] * d;
    }
}

/// [`segment_fixed`] or [`segment_bins`] for any rank (`u` of length `seg.rank`), point
/// by point.
fn segment_dyn(seg: &Segment, a: &[f64], t: &[f64], w: &[f64], u: &mut [f64]) -> f64 {
    let rank = seg.rank;
    u.iter_mut().for_each(|v| *v = 0.0);
    let mut ss = 0.0;
    for k in 0..a.len() {
        let d = (a[k] - t[k]) * w[k];
        ss += d * d;
        let (row, scale) = match &seg.bins {
            Some(b) => (k % b.n_bins, b.c[k]),
            None => (k, 1.0),
        };
        for (i, u) in u.iter_mut().enumerate() {
            *u += seg.p[(row / L) * rank + i][row % L] * scale * d;
        }
    }
    ss
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Blocks of 3 pairs x 7 bins, 2 x 4 and 1 x 9 (partial steps everywhere); shared
    /// noise on the first block (per-bin loadings `f_(j,b) A_b`) and on the last 8 points
    /// (random loadings, not a whole block: the per-point form).
    fn problem(rank: usize, rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<CorrelatedNoise>, Vec<f64>) {
        let shapes = [(3, 7), (2, 4), (1, 9)];
        let n = 21 + 8 + 9;
        let sigma: Vec<f64> = (0..n).map(|_| 0.5 + rng.random::<f64>()).collect();
        let a: Vec<f64> = (0..7 * rank).map(|_| rng.random::<f64>() - 0.5).collect();
        let f: Vec<f64> = (0..21).map(|_| 0.5 + rng.random::<f64>()).collect();
        let first = (0..21 * rank)
            .map(|i| f[i / rank] * a[(i / rank % 7) * rank + i % rank])
            .collect();
        let last = (0..8 * rank).map(|_| rng.random::<f64>() - 0.5).collect();
        let correlated = vec![
            CorrelatedNoise {
                start: 0,
                len: 21,
                rank,
                loadings: first,
            },
            CorrelatedNoise {
                start: 30,
                len: 8,
                rank,
                loadings: last,
            },
        ];
        assert_eq!(shapes.iter().map(|(p, b)| p * b).sum::<usize>(), n);
        (
            sigma,
            correlated,
            (0..n).map(|_| rng.random::<f64>() - 0.5).collect(),
        )
    }

    /// [`ResidualLayout::sums`] against the dense `r^T Sigma^-1 r` and `ln det Sigma`,
    /// `Sigma = s^2 diag(sigma^2) + L L^T` (Cholesky), for ranks 1-5 (fixed and general
    /// kernels, per-bin and per-point forms) and two noise scales.
    #[test]
    fn sums_are_the_dense_quadratic_form_and_determinant() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for rank in 1..=5 {
            let (sigma, correlated, r) = problem(rank, &mut rng);
            let n = sigma.len();
            let shapes = [(3, 7), (2, 4), (1, 9)];
            let layout = ResidualLayout::new(n, &correlated, &sigma, &shapes).unwrap();
            assert!(layout.segments[0].bins.is_some() && layout.segments[2].bins.is_none());
            let w: Vec<f64> = sigma.iter().map(|s| 1.0 / s).collect();
            for s in [0.3, 1.7] {
                let mut cov = DMatrix::from_diagonal(&DVector::from_iterator(
                    n,
                    sigma.iter().map(|v| s * s * v * v),
                ));
                for c in &correlated {
                    let l = DMatrix::from_row_slice(c.len, c.rank, &c.loadings);
                    let mut sub = cov.view_mut((c.start, c.start), (c.len, c.len));
                    sub += &l * l.transpose();
                }
                let r = DVector::from_column_slice(&r);
                let chol = cov.cholesky().unwrap();
                let quad = r.dot(&chol.solve(&r));
                let ln_det: f64 = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
                let zeros = vec![0.0; n];
                let sums = layout.sums(r.as_slice(), &zeros, &w, s * s);
                let got_quad = (sums.ss - sums.correction) / (s * s);
                let got_det = sums.ln_det + sigma.iter().map(|v| (s * s * v * v).ln()).sum::<f64>();
                assert!(
                    (got_quad - quad).abs() < 1e-10 * quad,
                    "rank {rank}, s {s}: {got_quad} vs {quad}"
                );
                assert!(
                    (got_det - ln_det).abs() < 1e-10 * ln_det.abs().max(1.0),
                    "rank {rank}, s {s}: {got_det} vs {ln_det}"
                );
                // the general kernel and the spread pointwise terms agree with it
                let mut pw = vec![0.0; n];
                layout.spread_shared(r.as_slice(), &zeros, &w, s * s, &mut pw);
                let spread: f64 = pw.iter().sum();
                let expect = 0.5 * (sums.correction / (s * s) - sums.ln_det);
                assert!((spread - expect).abs() < 1e-10 * expect.abs().max(1.0));
            }
        }
    }
}
