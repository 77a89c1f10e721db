//! The correlated input-gain error of a hammer segment in the likelihood of
//! [`super::posterior::ModelPosterior`]: its basis on the flat layout and the small
//! Woodbury solve `G = I + V^* D^-1 V` (see that module's docs).

use num_complex::Complex64;

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

/// [`gain_solve`] of a per-bin basis: `G` is diagonal.
fn diagonal_solve(gs: &GainSegment, w: &[f64], bk: &[Complex64]) -> (Vec<Complex64>, f64, f64) {
    let (mut quad, mut ln_det) = (0.0, 0.0);
    let g = (0..gs.n_freq)
        .map(|k| {
            let gkk = 1.0 + w[k] * gs.u[k].norm_sqr();
            let b = gs.u[k].conj() * bk[k];
            quad += b.norm_sqr() / gkk;
            ln_det += gkk.ln();
            b / gkk
        })
        .collect();
    (g, quad, ln_det)
}

/// `G = I + sum_k w_k U_k^* U_k`, `b = sum_k U_k^* b_k`; returns `g = G^-1 b`,
/// `b^* G^-1 b` and `ln det G` (see the module docs).
pub(super) fn gain_solve(
    gs: &GainSegment,
    w: &[f64],
    bk: &[Complex64],
) -> (Vec<Complex64>, f64, f64) {
    if gs.per_bin {
        return diagonal_solve(gs, w, bk);
    }
    let r = gs.rank;
    let mut g = vec![Complex64::new(0.0, 0.0); r * r];
    let mut b = vec![Complex64::new(0.0, 0.0); r];
    for i in 0..r {
        g[i * r + i] = Complex64::new(1.0, 0.0);
    }
    for k in 0..gs.n_freq {
        let uk = &gs.u[k * r..(k + 1) * r];
        if w[k] != 0.0 {
            for m in 0..r {
                let cm = uk[m].conj() * w[k];
                for n in m..r {
                    g[m * r + n] += cm * uk[n];
                }
            }
        }
        for m in 0..r {
            b[m] += uk[m].conj() * bk[k];
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
    // Solve L y = b, then L^* x = y.
    let mut y = b.clone();
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
    (x, quad, ln_det)
}
