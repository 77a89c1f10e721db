//! Small dense kernels of the trust-region reflective solver (the QR of the Jacobian
//! is in `qr.rs`): the exact trust-region subproblem by SVD (More's method, as in
//! MINPACK and scipy's `solve_lsq_trust_region`), and the one-dimensional helpers of the
//! reflective step selection. Everything after the QR works on `n x n` data.

use super::qr::dot;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, SVD};

/// Thin SVD of a small matrix, singular values descending: returns `(s, U, V)` with
/// `a = U diag(s) V^T`.
pub(crate) fn svd_descending(a: DMatrix<f64>) -> Result<(Vec<f64>, DMatrix<f64>, DMatrix<f64>)> {
    let svd = SVD::try_new_unordered(a, true, true, f64::EPSILON, 10_000).ok_or_else(|| {
        Error::Numerical("SVD of the trust-region system did not converge".into())
    })?;
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(Error::Numerical("SVD returned no singular vectors".into()));
    };
    let s = svd.singular_values;
    let mut order: Vec<usize> = (0..s.len()).collect();
    order.sort_by(|&i, &j| s[j].total_cmp(&s[i]));
    let s_sorted = order.iter().map(|&i| s[i]).collect();
    let u_sorted = DMatrix::from_fn(u.nrows(), order.len(), |r, c| u[(r, order[c])]);
    let v_sorted = DMatrix::from_fn(v_t.ncols(), order.len(), |r, c| v_t[(order[c], r)]);
    Ok((s_sorted, u_sorted, v_sorted))
}

/// Solves `min ||J p + f||` subject to `||p|| <= delta` given the SVD of `J`
/// (`s` descending, `v` the right singular vectors, `uf = U^T f`), by More's
/// safeguarded Newton iteration on the Levenberg-Marquardt parameter (relative accuracy
/// `rtol` on `||p||`, at most 10 iterations). `m` is the number of rows of the
/// original Jacobian (for the rank test). Returns `(p, lm_parameter)`.
pub(crate) fn solve_trust_region(
    m: usize,
    uf: &[f64],
    s: &[f64],
    v: &DMatrix<f64>,
    delta: f64,
    initial_lm: f64,
    p: &mut [f64],
) -> f64 {
    const RTOL: f64 = 0.01;
    const MAX_ITER: usize = 10;
    let n = s.len();
    let suf: Vec<f64> = s.iter().zip(uf).map(|(a, b)| a * b).collect();
    let phi_and_derivative = |lm: f64| {
        let mut norm2 = 0.0;
        let mut d3 = 0.0;
        for (&x, &si) in suf.iter().zip(s) {
            let den = si * si + lm;
            norm2 += (x / den).powi(2);
            d3 += x * x / den.powi(3);
        }
        let p_norm = norm2.sqrt();
        (p_norm - delta, -d3 / p_norm)
    };
    let full_rank = m >= n && n > 0 && s[n - 1] > f64::EPSILON * m as f64 * s[0];
    if full_rank {
        // Gauss-Newton step.
        mat_vec_scaled(v, |i| -uf[i] / s[i], p);
        if norm(p) <= delta {
            return 0.0;
        }
    }
    let mut upper = norm(&suf) / delta;
    let mut lower = if full_rank {
        let (phi, dphi) = phi_and_derivative(0.0);
        -phi / dphi
    } else {
        0.0
    };
    let reset = |lower: f64, upper: f64| (0.001 * upper).max((lower * upper).sqrt());
    let mut lm = if !full_rank && initial_lm == 0.0 {
        reset(lower, upper)
    } else {
        initial_lm
    };
    for _ in 0..MAX_ITER {
        if lm < lower || lm > upper {
            lm = reset(lower, upper);
        }
        let (phi, dphi) = phi_and_derivative(lm);
        if phi < 0.0 {
            upper = lm;
        }
        let ratio = phi / dphi;
        lower = lower.max(lm - ratio);
        lm -= (phi + delta) * ratio / delta;
        if phi.abs() < RTOL * delta {
            break;
        }
    }
    mat_vec_scaled(v, |i| -suf[i] / (s[i] * s[i] + lm), p);
    // Put p exactly on the trust-region boundary.
    let pn = norm(p);
    if pn > 0.0 {
        for x in p.iter_mut() {
            *x *= delta / pn;
        }
    }
    lm
}

/// `out = V c` with `c_i = coef(i)`.
fn mat_vec_scaled(v: &DMatrix<f64>, coef: impl Fn(usize) -> f64, out: &mut [f64]) {
    out.fill(0.0);
    for i in 0..v.ncols() {
        let c = coef(i);
        for (o, x) in out.iter_mut().zip(v.column(i).iter()) {
            *o += c * x;
        }
    }
}

/// Euclidean norm.
pub(crate) fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Largest `t >= 0` keeping `x + t s` inside the box, and for each variable whether
/// that bound is the one hit (sign of `s`), like scipy's `step_size_to_bound`.
pub(crate) fn step_size_to_bound(
    x: &[f64],
    s: &[f64],
    lower: &[f64],
    upper: &[f64],
    hits: &mut [i8],
) -> f64 {
    let step = |i: usize| {
        if s[i] == 0.0 {
            f64::INFINITY
        } else {
            ((lower[i] - x[i]) / s[i]).max((upper[i] - x[i]) / s[i])
        }
    };
    let min = (0..x.len()).map(step).fold(f64::INFINITY, f64::min);
    for (i, h) in hits.iter_mut().enumerate() {
        *h = if step(i) == min {
            s[i].signum() as i8
        } else {
            0
        };
    }
    min
}

/// Roots `t_neg <= t_pos` of `||x + t s|| = delta` for `x` inside the region.
pub(crate) fn intersect_trust_region(x: &[f64], s: &[f64], delta: f64) -> (f64, f64) {
    let a = dot(s, s);
    let b = dot(x, s);
    // Clamp: x may sit on the boundary up to rounding.
    let c = (dot(x, x) - delta * delta).min(0.0);
    let d = (b * b - a * c).sqrt();
    let q = -(b + d.copysign(b));
    if q == 0.0 {
        return (0.0, 0.0);
    }
    let (t1, t2) = (q / a, c / q);
    if t1 < t2 {
        (t1, t2)
    } else {
        (t2, t1)
    }
}

/// The quadratic model `0.5 s^T (R^T R + diag) s + g^T s` (R is the n x n factor of J).
pub(crate) fn evaluate_quadratic(
    r: &DMatrix<f64>,
    g: &[f64],
    s: &[f64],
    diag: &[f64],
    work: &mut [f64],
) -> f64 {
    mat_vec(r, s, work);
    let q = dot(work, work) + s.iter().zip(diag).map(|(x, d)| x * x * d).sum::<f64>();
    0.5 * q + dot(s, g)
}

/// Coefficients `(a, b, c)` of the model along `s0 + t s` (`s0 = 0` when `None`):
/// `a t^2 + b t + c`.
pub(crate) fn quadratic_1d(
    r: &DMatrix<f64>,
    g: &[f64],
    s: &[f64],
    s0: Option<&[f64]>,
    diag: &[f64],
    work: &mut [f64],
    work2: &mut [f64],
) -> (f64, f64, f64) {
    mat_vec(r, s, work);
    let a = 0.5 * (dot(work, work) + s.iter().zip(diag).map(|(x, d)| x * x * d).sum::<f64>());
    let mut b = dot(g, s);
    let mut c = 0.0;
    if let Some(s0) = s0 {
        mat_vec(r, s0, work2);
        b += dot(work, work2)
            + s0.iter()
                .zip(s)
                .zip(diag)
                .map(|((p, q), d)| p * q * d)
                .sum::<f64>();
        c = 0.5 * (dot(work2, work2) + s0.iter().zip(diag).map(|(x, d)| x * x * d).sum::<f64>())
            + dot(g, s0);
    }
    (a, b, c)
}

/// Minimiser of `a t^2 + b t + c` over `[lo, hi]`: `(t, value)`.
pub(crate) fn minimize_quadratic_1d(a: f64, b: f64, c: f64, lo: f64, hi: f64) -> (f64, f64) {
    let f = |t: f64| t * (a * t + b) + c;
    let mut best = (lo, f(lo));
    let mut consider = |t: f64| {
        let v = f(t);
        if v < best.1 {
            best = (t, v);
        }
    };
    consider(hi);
    if a != 0.0 {
        let t = -0.5 * b / a;
        if lo < t && t < hi {
            consider(t);
        }
    }
    best
}

/// `out = R x` for a square `R`.
fn mat_vec(r: &DMatrix<f64>, x: &[f64], out: &mut [f64]) {
    out.fill(0.0);
    for (c, &xc) in x.iter().enumerate() {
        if xc != 0.0 {
            for (o, v) in out.iter_mut().zip(r.column(c).iter()) {
                *o += v * xc;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trust_region_step_matches_constrained_minimiser() {
        // J = diag(3, 1), f = (3, 1): GN step (-1, -1) of norm sqrt 2.
        let s = [3.0, 1.0];
        let v = DMatrix::identity(2, 2);
        let uf = [3.0, 1.0];
        let mut p = [0.0; 2];
        let lm = solve_trust_region(2, &uf, &s, &v, 2.0, 0.0, &mut p);
        assert_eq!(lm, 0.0);
        assert!((p[0] + 1.0).abs() < 1e-14 && (p[1] + 1.0).abs() < 1e-14);
        // A binding region: the solution is p(lm) = -V (s uf / (s^2 + lm)) with
        // ||p|| = delta for the returned multiplier lm > 0.
        let delta = 0.5;
        let lm = solve_trust_region(2, &uf, &s, &v, delta, 0.0, &mut p);
        assert!((norm(&p) - delta).abs() < 1e-12);
        assert!(lm > 0.0);
        let p_exact: Vec<f64> = (0..2).map(|i| -s[i] * uf[i] / (s[i] * s[i] + lm)).collect();
        // More's iteration stops at 1% accuracy in ||p||; the direction is then close.
        let cos = dot(&p, &p_exact) / (norm(&p) * norm(&p_exact));
        assert!(cos > 0.999, "cos {cos}");
    }

    #[test]
    fn one_dimensional_helpers() {
        let (t, v) = minimize_quadratic_1d(1.0, -2.0, 0.0, 0.0, 5.0);
        assert_eq!((t, v), (1.0, -1.0));
        let (t, _) = minimize_quadratic_1d(1.0, -2.0, 0.0, 2.0, 5.0);
        assert_eq!(t, 2.0);
        let (tn, tp) = intersect_trust_region(&[0.0, 0.0], &[1.0, 0.0], 2.0);
        assert_eq!((tn, tp), (-2.0, 2.0));
        let mut hits = [0i8; 2];
        let t = step_size_to_bound(
            &[0.0, 0.0],
            &[1.0, -2.0],
            &[-1.0, -1.0],
            &[1.0, 1.0],
            &mut hits,
        );
        assert_eq!(t, 0.5);
        assert_eq!(hits, [0, -1]);
    }
}
