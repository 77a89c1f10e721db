//! The correlated input-gain error of a hammer segment in the likelihood of
//! [`super::posterior::ModelPosterior`]: its basis on the flat layout and the small
//! Woodbury solve `G = I + V^* D^-1 V` (see that module's docs).

use super::per_thread::PerThread;
use num_complex::Complex64;
use std::sync::Arc;

/// A segment's [`super::data::InputGainBasis`] on the flat layout.
#[derive(Debug, Clone)]
pub(super) struct GainSegment {
    /// Number of gain coefficients.
    pub(super) rank: usize,
    /// Smooth: `U` frequency-major (`n_freq x rank`); per bin: its diagonal (`rank =
    /// n_freq`).
    pub(super) u: Vec<Complex64>,
    pub(super) per_bin: bool,
    pub(super) n_freq: usize,
    /// Flat range of the segment's points and the frequency index of each.
    pub(super) start: usize,
    pub(super) freq_of: Vec<u32>,
}

impl GainSegment {
    /// `U_k g`, the relative error at frequency `k` of the coefficients `g`.
    pub(super) fn term(&self, k: usize, g: &[Complex64]) -> Complex64 {
        match self.per_bin {
            true => self.u[k] * g[k],
            false => {
                let uk = &self.u[k * self.rank..(k + 1) * self.rank];
                uk.iter().zip(g).map(|(a, b)| a * b).sum()
            }
        }
    }
}

/// `G = I + sum_k w_k U_k^* U_k` of one segment, factored: it depends on the weights
/// `w_k = sum_(i at k) |c_i|^2 / (2 sigma_i^2)` only (carrier `c`, error floor in
/// `sigma`), not on the residual, so one factor serves every prediction at the same
/// error floor and carrier ([`GainCache`]).
#[derive(Debug, Clone)]
pub(super) struct GainFactor {
    /// Per-bin basis: `G`'s diagonal; smooth basis: `L` of `G = L L^*`, row-major
    /// `rank x rank`.
    kind: FactorKind,
    /// `ln det G`.
    pub(super) ln_det: f64,
}

#[derive(Debug, Clone)]
enum FactorKind {
    Diagonal(Vec<f64>),
    Cholesky(Vec<Complex64>),
}

/// Factors `G` of `gs` at the weights `w` (per segment frequency).
pub(super) fn gain_factor(gs: &GainSegment, w: &[f64]) -> GainFactor {
    if gs.per_bin {
        let mut ln_det = 0.0;
        let diag = (0..gs.n_freq)
            .map(|k| {
                let gkk = 1.0 + w[k] * gs.u[k].norm_sqr();
                ln_det += gkk.ln();
                gkk
            })
            .collect();
        return GainFactor {
            kind: FactorKind::Diagonal(diag),
            ln_det,
        };
    }
    let r = gs.rank;
    let mut g = vec![Complex64::new(0.0, 0.0); r * r];
    for i in 0..r {
        g[i * r + i] = Complex64::new(1.0, 0.0);
    }
    for (k, &wk) in w.iter().enumerate().take(gs.n_freq) {
        let uk = &gs.u[k * r..(k + 1) * r];
        if wk != 0.0 {
            for m in 0..r {
                let cm = uk[m].conj() * wk;
                for n in m..r {
                    g[m * r + n] += cm * uk[n];
                }
            }
        }
    }
    // Cholesky G = L L^* (upper triangle filled; Hermitian positive definite).
    let mut l = vec![Complex64::new(0.0, 0.0); r * r];
    let mut ln_det = 0.0;
    for j in 0..r {
        let mut d = g[j * r + j].re;
        for k in 0..j {
            d -= l[j * r + k].norm_sqr();
        }
        let d = d.max(1e-300).sqrt();
        ln_det += 2.0 * d.ln();
        l[j * r + j] = Complex64::new(d, 0.0);
        for i in j + 1..r {
            // G_ij with i > j is conj(G_ji) (upper triangle stored).
            let mut v = g[j * r + i].conj();
            for k in 0..j {
                v -= l[i * r + k] * l[j * r + k].conj();
            }
            l[i * r + j] = v / d;
        }
    }
    GainFactor {
        kind: FactorKind::Cholesky(l),
        ln_det,
    }
}

/// With `b = sum_k U_k^* b_k`: `g = G^-1 b` and `b^* G^-1 b`, `G` factored as `f`.
pub(super) fn gain_apply(
    gs: &GainSegment,
    f: &GainFactor,
    bk: &[Complex64],
) -> (Vec<Complex64>, f64) {
    match &f.kind {
        FactorKind::Diagonal(diag) => {
            let mut quad = 0.0;
            let g = (0..gs.n_freq)
                .map(|k| {
                    let b = gs.u[k].conj() * bk[k];
                    quad += b.norm_sqr() / diag[k];
                    b / diag[k]
                })
                .collect();
            (g, quad)
        }
        FactorKind::Cholesky(l) => {
            let r = gs.rank;
            let mut b = vec![Complex64::new(0.0, 0.0); r];
            for (k, &bkk) in bk.iter().enumerate().take(gs.n_freq) {
                let uk = &gs.u[k * r..(k + 1) * r];
                for m in 0..r {
                    b[m] += uk[m].conj() * bkk;
                }
            }
            // Solve L y = b, then L^* x = y.
            let mut y = b;
            for i in 0..r {
                let mut v = y[i];
                for k in 0..i {
                    v -= l[i * r + k] * y[k];
                }
                y[i] = v / l[i * r + i].re;
            }
            let quad: f64 = y.iter().map(|v| v.norm_sqr()).sum();
            let mut x = y;
            for i in (0..r).rev() {
                let mut v = x[i];
                for k in i + 1..r {
                    v -= l[k * r + i].conj() * x[k];
                }
                x[i] = v / l[i * r + i].re;
            }
            (x, quad)
        }
    }
}

/// What the factors of `G` were built for: the error floor (its bits) and the carrier
/// (the measured ratios, `None`, fixed in a posterior, or a plug-in prediction, kept
/// alive here so that its address cannot be reused by another while it is the key).
type GainKey = (u64, Option<Arc<Vec<Complex64>>>);

/// Each thread's factors of `G` for every gain segment at the last error floor and
/// carrier it evaluated. A least-squares fit holds `eta` fixed while it moves the
/// model (`super::fit`), so its residual and Jacobian evaluations reuse one set: the
/// `O(M r^2)` assembly and the Cholesky drop out and `O(N + M r)` remain. Results are
/// bit for bit those of factoring anew (the same arithmetic, done once). A clone starts
/// empty.
#[derive(Default, Clone, Debug)]
pub(super) struct GainCache(PerThread<GainKey, Vec<GainFactor>>);

impl GainCache {
    /// `apply(factors)` with this thread's factors at (`eta`, `plug_in`; `None`: the
    /// measured ratios), built by `build` when this thread last built them for another
    /// key.
    pub(super) fn with<R>(
        &self,
        eta: f64,
        plug_in: Option<&Arc<Vec<Complex64>>>,
        build: impl FnOnce() -> Vec<GainFactor>,
        apply: impl FnOnce(&[GainFactor]) -> R,
    ) -> R {
        let bits = eta.to_bits();
        let is_key = |(kept_bits, kept_plug_in): &GainKey| {
            *kept_bits == bits
                && match (kept_plug_in, plug_in) {
                    (None, None) => true,
                    (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                    _ => false,
                }
        };
        self.0
            .with(is_key, || (bits, plug_in.cloned()), build, |f| apply(f))
    }

    /// Factor sets built so far, over all threads.
    #[cfg(test)]
    pub(super) fn builds(&self) -> usize {
        self.0.builds()
    }
}
