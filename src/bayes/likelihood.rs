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
    /// `P` by steps of [`L`] points: step `c`, row `i`, lane `l` at `p[c * rank + i][l]`
    /// is `P[i][c L + l]` (zero beyond the run).
    p: Vec<Lanes>,
    /// Eigenvalues `lambda_i` of `V^T V` (>= 0).
    lambda: Vec<f64>,
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
    /// data validated them) and independent runs between them.
    pub fn new(n: usize, correlated: &[CorrelatedNoise], sigma: &[f64]) -> Result<Self> {
        let mut segments = Vec::new();
        let mut at = 0;
        let plain = |start: usize, len: usize| Segment {
            start,
            len,
            rank: 0,
            p: Vec::new(),
            lambda: Vec::new(),
        };
        for c in correlated {
            if c.start > at {
                segments.push(plain(at, c.start - at));
            }
            segments.push(shared_segment(c, sigma)?);
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
/// `P = Q^T V^T` laid out by steps of [`L`] points.
fn shared_segment(c: &CorrelatedNoise, sigma: &[f64]) -> Result<Segment> {
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
    let vq = &v * &eig.eigenvectors;
    let steps = len.div_ceil(L);
    let mut p = vec![[0.0; L]; steps * rank];
    for k in 0..len {
        for i in 0..rank {
            p[(k / L) * rank + i][k % L] = vq[(k, i)];
        }
    }
    Ok(Segment {
        start: c.start,
        len,
        rank,
        p,
        lambda: eig.eigenvalues.iter().map(|x| x.max(0.0)).collect(),
    })
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
        out.ss += match seg.rank {
            0 => segment_fixed::<0>(seg, a, t, w, &mut u),
            1 => segment_fixed::<1>(seg, a, t, w, &mut u),
            2 => segment_fixed::<2>(seg, a, t, w, &mut u),
            3 => segment_fixed::<3>(seg, a, t, w, &mut u),
            4 => segment_fixed::<4>(seg, a, t, w, &mut u),
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

/// [`segment_fixed`] for any rank (`u` of length `seg.rank`), point by point.
fn segment_dyn(seg: &Segment, a: &[f64], t: &[f64], w: &[f64], u: &mut [f64]) -> f64 {
    let rank = seg.rank;
    u.iter_mut().for_each(|v| *v = 0.0);
    let mut ss = 0.0;
    for k in 0..a.len() {
        let d = (a[k] - t[k]) * w[k];
        ss += d * d;
        for (i, u) in u.iter_mut().enumerate() {
            *u += seg.p[(k / L) * rank + i][k % L] * d;
        }
    }
    ss
}
