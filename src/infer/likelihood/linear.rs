//! Observations linear in unknown coefficients that are integrated out
//! ([`super::BlockKind::LinearMarginal`]).
//!
//! The predictions hold `k` columns `g_j` of length `m` (column-major); with whitening
//! weights `w_i`, `G~_ij = w_i g_ij` and `y~_i = w_i y_i`. Given `sigma`, the model
//! `y~ = G~ c + sigma e`, `e ~ N(0, I)`, is linear in `c`; under a flat prior on `c`
//!
//! `int N(y~; G~ c, sigma^2 I) dc = (2 pi sigma^2)^(-(m-k)/2) det(G~^T G~)^(-1/2)
//!  exp(-||r||^2 / (2 sigma^2))`,
//!
//! `r = y~ - G~ c^`, `c^ = (G~^T G~)^-1 G~^T y~` (the weighted least-squares solution):
//! a Gaussian block with `m - k` degrees of freedom and the model-dependent term
//! `-ln det(G~^T G~) / 2` ([`super::Block::ln_marginal`]). Given the rest, `c` is
//! Gaussian with mean `c^` and covariance `sigma^2 (G~^T G~)^-1`.
//!
//! This is variable projection (Golub & Pereyra 1973): the sampler and the solver see
//! only the nonlinear coordinates. A real channel gain (one column, the model's own
//! prediction) and complex modal residues (two real columns `g`, `j g` per complex
//! unknown) are both instances.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// The weighted least-squares solution of a linear-marginal block.
#[derive(Debug, Clone)]
pub struct LinearFit {
    /// `c^`.
    pub coefficients: Vec<f64>,
    /// Cholesky factor of `G~^T G~` (`k x k`).
    pub normal: Cholesky<f64, Dyn>,
    /// `||y~ - G~ c^||^2`.
    pub rss: f64,
    /// `ln det(G~^T G~)`.
    pub ln_det: f64,
}

impl LinearFit {
    /// A draw of `c` given the rest: `c^ + sigma L^-T z` for standard normal `z`
    /// (`G~^T G~ = L L^T`), so its covariance is `sigma^2 (G~^T G~)^-1`.
    pub fn conditional_draw(&self, sigma: f64, z: &[f64]) -> Vec<f64> {
        let mut v = DVector::from_column_slice(z);
        self.normal.l_dirty().tr_solve_lower_triangular_mut(&mut v);
        self.coefficients
            .iter()
            .zip(v.iter())
            .map(|(c, d)| c + sigma * d)
            .collect()
    }
}

/// The whitened design `G~` (`m x k`) of predictions `p` (`k` columns, column-major).
fn design(p: &[f64], inv_sd: &[f64], k: usize) -> DMatrix<f64> {
    let m = inv_sd.len();
    let w = DVector::from_column_slice(inv_sd);
    let mut g = DMatrix::from_column_slice(m, k, &p[..m * k]);
    for mut col in g.column_iter_mut() {
        col.component_mul_assign(&w);
    }
    g
}

/// The solution and the residual `y~ - G~ c^` from the design `g`.
fn solve(g: &DMatrix<f64>, observed: &[f64]) -> Option<(LinearFit, DVector<f64>)> {
    let y = DVector::from_column_slice(observed);
    let normal = Cholesky::new(g.tr_mul(g))?;
    let ln_det = 2.0
        * normal
            .l_dirty()
            .diagonal()
            .iter()
            .map(|d| d.ln())
            .sum::<f64>();
    if !ln_det.is_finite() {
        return None;
    }
    let c = normal.solve(&g.tr_mul(&y));
    let mut r = y;
    r.gemv(-1.0, g, &c, 1.0);
    let fit = LinearFit {
        coefficients: c.iter().copied().collect(),
        normal,
        rss: r.norm_squared(),
        ln_det,
    };
    Some((fit, r))
}

/// `c^`, the normal matrix's factor and the residual norm for predictions `p` (`k`
/// columns of `inv_sd.len()` entries); `None` when `G~` is rank-deficient.
pub fn fit(p: &[f64], inv_sd: &[f64], observed: &[f64], k: usize) -> Option<LinearFit> {
    solve(&design(p, inv_sd, k), observed).map(|(f, _)| f)
}

/// `r = y~ - G~ c^` into `out`, returning `ln det(G~^T G~)`; `y~` itself and `None`
/// when `G~` is rank-deficient.
pub fn residuals(
    p: &[f64],
    inv_sd: &[f64],
    observed: &[f64],
    k: usize,
    out: &mut [f64],
) -> Option<f64> {
    match solve(&design(p, inv_sd, k), observed) {
        Some((f, r)) => {
            out.copy_from_slice(r.as_slice());
            Some(f.ln_det)
        }
        None => {
            out.copy_from_slice(observed);
            None
        }
    }
}

/// Rows of `scale * d r / d theta` from `dp` (`d p / d theta`, rows `off..off + k m`):
/// with `A = G~^T G~`, `dc = A^-1 (dG~^T r - G~^T dG~ c^)` (the derivative of the normal
/// equations) and `dr = -dG~ c^ - G~ dc` (the exact variable-projection Jacobian).
pub fn residual_jacobian(
    p: &[f64],
    inv_sd: &[f64],
    observed: &[f64],
    k: usize,
    dp: (&DMatrix<f64>, usize),
    scale: f64,
    (row0, jac): (usize, &mut DMatrix<f64>),
) {
    let (dpred, off) = dp;
    let m = inv_sd.len();
    let g = design(p, inv_sd, k);
    let Some((f, r)) = solve(&g, observed) else {
        for t in 0..dpred.ncols() {
            for i in 0..m {
                jac[(row0 + i, t)] = 0.0;
            }
        }
        return;
    };
    let c = DVector::from_column_slice(&f.coefficients);
    for t in 0..dpred.ncols() {
        let dg = DMatrix::from_fn(m, k, |i, j| inv_sd[i] * dpred[(off + j * m + i, t)]);
        let u = &dg * &c;
        let dc = f.normal.solve(&(dg.tr_mul(&r) - g.tr_mul(&u)));
        let dr = -(u + &g * dc);
        for i in 0..m {
            jac[(row0 + i, t)] = scale * dr[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three real columns: the block's Gaussian integral over `c` against a direct
    /// evaluation of `ln int N(y~; G~ c, sigma^2 I) dc` by the formula for a Gaussian in
    /// `c` (completing the square by an independent route: the QR factor of `G~`), and
    /// the conditional draw's covariance against `sigma^2 (G~^T G~)^-1`.
    #[test]
    fn three_columns_give_the_gaussian_integral() {
        let m = 7;
        let p: Vec<f64> = (0..3 * m)
            .map(|q| ((q * 7 + 3) as f64 * 0.37).sin() + 0.1 * q as f64 / m as f64)
            .collect();
        let inv_sd: Vec<f64> = (0..m).map(|i| 1.0 + 0.1 * i as f64).collect();
        let y: Vec<f64> = (0..m).map(|i| (i as f64 * 0.9).cos() * inv_sd[i]).collect();
        let f = fit(&p, &inv_sd, &y, 3).unwrap();
        let gt = DMatrix::from_fn(m, 3, |i, j| p[j * m + i] * inv_sd[i]);
        let qr = gt.clone().qr();
        let r = qr.r();
        let ln_det_qr: f64 = 2.0 * r.diagonal().iter().map(|d| d.abs().ln()).sum::<f64>();
        assert!((f.ln_det - ln_det_qr).abs() < 1e-12);
        let yv = DVector::from_column_slice(&y);
        let c_qr = r
            .solve_upper_triangular(&(qr.q().transpose() * &yv))
            .unwrap();
        let rss_qr = (&yv - &gt * &c_qr).norm_squared();
        assert!((f.rss - rss_qr).abs() < 1e-12 * rss_qr.max(1.0));
        let mut out = vec![0.0; m];
        residuals(&p, &inv_sd, &y, 3, &mut out);
        let ss: f64 = out.iter().map(|v| v * v).sum();
        assert!((ss - rss_qr).abs() < 1e-12 * rss_qr.max(1.0));
        // Covariance of the draw map: L^-T L^-1 = (G~^T G~)^-1, column by column.
        let inv = (gt.transpose() * &gt).try_inverse().unwrap();
        let sigma = 0.7;
        for a in 0..3 {
            for b in 0..3 {
                let mut cov = 0.0;
                for q in 0..3 {
                    let e = |i: usize| if i == q { 1.0 } else { 0.0 };
                    let z: Vec<f64> = (0..3).map(e).collect();
                    let d = f.conditional_draw(sigma, &z);
                    cov += (d[a] - f.coefficients[a]) * (d[b] - f.coefficients[b]);
                }
                assert!((cov - sigma * sigma * inv[(a, b)]).abs() < 1e-12);
            }
        }
    }

    /// The variable-projection Jacobian against central differences, two columns whose
    /// entries depend on two parameters.
    #[test]
    fn residual_jacobian_matches_differences() {
        let m = 6;
        let pred = |t: &[f64]| -> Vec<f64> {
            let mut v = Vec::new();
            for i in 0..m {
                v.push((t[0] * i as f64).sin() + t[1]);
            }
            for i in 0..m {
                v.push(1.0 / (1.0 + t[0] * t[1] * i as f64));
            }
            v
        };
        let inv_sd: Vec<f64> = (0..m).map(|i| 1.0 + 0.2 * i as f64).collect();
        let y: Vec<f64> = (0..m).map(|i| 0.3 * i as f64 - 0.5).collect();
        let t = [0.8, 0.3];
        let h = 1e-6;
        let dpred = DMatrix::from_fn(2 * m, 2, |q, j| {
            let (mut up, mut dn) = (t, t);
            up[j] += h;
            dn[j] -= h;
            (pred(&up)[q] - pred(&dn)[q]) / (2.0 * h)
        });
        let mut jac = DMatrix::zeros(m, 2);
        residual_jacobian(&pred(&t), &inv_sd, &y, 2, (&dpred, 0), 1.0, (0, &mut jac));
        for j in 0..2 {
            let (mut up, mut dn) = (t, t);
            up[j] += h;
            dn[j] -= h;
            let (mut ru, mut rd) = (vec![0.0; m], vec![0.0; m]);
            residuals(&pred(&up), &inv_sd, &y, 2, &mut ru);
            residuals(&pred(&dn), &inv_sd, &y, 2, &mut rd);
            for i in 0..m {
                let fd = (ru[i] - rd[i]) / (2.0 * h);
                assert!(
                    (jac[(i, j)] - fd).abs() < 1e-6,
                    "({i},{j}) {} {fd}",
                    jac[(i, j)]
                );
            }
        }
    }
}
