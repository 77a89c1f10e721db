//! The iteration of the partial eigen-solver: start block, Rayleigh-Ritz, convergence
//! test, expansion by `Op X`, thick restarts; and the returned pairs.

use super::basis::Pencil;
use super::{PartialEigen, PartialSolver, PartialWorkspace};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `||k x - lambda m x|| / (max(|lambda|, |sigma|) ||m x||)` from `k x` and `m x`.
fn relative_residual(kx: &[f64], mx: &[f64], lambda: f64, sigma: f64) -> f64 {
    let r: f64 = kx
        .iter()
        .zip(mx)
        .map(|(k, m)| (k - lambda * m).powi(2))
        .sum::<f64>()
        .sqrt();
    r / (lambda.abs().max(sigma.abs()) * dot(mx, mx).sqrt())
}

impl PartialSolver {
    /// Runs the iteration until the lowest `n_modes` Ritz pairs converge; leaves their
    /// Ritz values and operator residuals in `ws.lambda`, `ws.op_res` and their vectors
    /// in the first columns of `ws.x`. Returns the number of solves.
    pub(super) fn iterate(
        &self,
        n_modes: usize,
        rank: usize,
        sigma: f64,
        ws: &mut PartialWorkspace,
    ) -> Result<usize> {
        let n = self.pencil.n_dof();
        let p = (n_modes + (n_modes / 2).max(3)).min(rank);
        let cap = self.options.max_basis.unwrap_or((3 * p).max(p + 20));
        ws.basis.reset(n, cap.max(p) + p);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(self.options.seed);
        ws.block.clear();
        ws.block
            .extend((0..n * p).map(|_| rng.random_range(-1.0..1.0)));
        self.apply_op(p, ws);
        let mut n_solves = p;
        let mut cols: Vec<usize> = (0..p).collect();
        let mut restarts = 0;
        loop {
            let added = self.push_block(&cols, ws);
            n_solves += added;
            let d = ws.basis.dim();
            if d < n_modes {
                return Err(Error::Numerical(format!(
                    "partial eigen-solver: the search space stopped at {d} vectors, fewer \
                     than the {n_modes} modes requested: the pencil has fewer finite \
                     eigenvalues (M is singular)"
                )));
            }
            let (theta, y) = ws.basis.ritz();
            let pp = p.min(d);
            ws.basis
                .combine(&y, pp, [&mut ws.x, &mut ws.opx, &mut ws.mx]);
            let res = self.operator_residuals(&theta[..pp], ws);
            let tol = self.options.tol;
            cols = (0..pp)
                .filter(|&i| res[i].is_nan() || res[i] > tol)
                .collect();
            if cols.iter().all(|&i| i >= n_modes) {
                ws.lambda.clear();
                ws.lambda
                    .extend(theta[..n_modes].iter().map(|t| sigma + 1.0 / t));
                ws.op_res.clear();
                ws.op_res.extend_from_slice(&res[..n_modes]);
                return Ok(n_solves);
            }
            let stalled = added == 0;
            if stalled || (d + cols.len() > cap && d > pp) {
                restarts += 1;
                if stalled || restarts > self.options.max_restarts {
                    return Err(self.not_converged(n_modes, &res, restarts, n_solves, stalled));
                }
                ws.basis.restart(&ws.x, &ws.opx, &ws.mx, pp);
            }
        }
    }

    /// Appends the columns `cols` of `ws.block` to the basis with their `Op` images (one
    /// solve each); how many were independent.
    fn push_block(&self, cols: &[usize], ws: &mut PartialWorkspace) -> usize {
        let n = self.pencil.n_dof();
        let pencil = Pencil {
            sparse: &self.pencil,
            k: &ws.k,
            m: &ws.m,
        };
        let mut w = Vec::with_capacity(n * cols.len());
        for &c in cols {
            w.extend_from_slice(&ws.block[c * n..(c + 1) * n]);
        }
        let added = ws.basis.push_block(&mut w, cols.len(), &pencil);
        ws.block.clear();
        ws.block.extend_from_slice(ws.basis.pending());
        self.apply_op(added, ws);
        ws.basis.attach_op(&ws.block[..n * added]);
        added
    }

    /// `||s_i||_M / theta_i`, `s_i = Op x_i - theta_i x_i`, for the Ritz pairs
    /// `(theta_i, x_i)` (`x_i` in `ws.x`, `||x_i||_M = 1`, `Op x_i` in `ws.opx`): the
    /// residual of the shift-invert eigenproblem relative to its eigenvalue (see the
    /// module docs). The `s_i` go to `ws.block`: they are the next expansion (Galerkin:
    /// `M`-orthogonal to the basis already, so they lose nothing to cancellation when
    /// orthogonalised, unlike `Op x_i` of a nearly converged `x_i`).
    fn operator_residuals(&self, theta: &[f64], ws: &mut PartialWorkspace) -> Vec<f64> {
        let n = self.pencil.n_dof();
        ws.tmp.resize(n, 0.0);
        ws.block.clear();
        ws.block.resize(n * theta.len(), 0.0);
        theta
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let c = i * n..(i + 1) * n;
                let s = &mut ws.block[c.clone()];
                s.iter_mut()
                    .zip(&ws.opx[c.clone()])
                    .zip(&ws.x[c])
                    .for_each(|((s, w), x)| *s = w - t * x);
                self.pencil.mass_pattern().mul(&ws.m, s, &mut ws.tmp);
                dot(s, &ws.tmp).max(0.0).sqrt() / t.abs()
            })
            .collect()
    }

    fn not_converged(
        &self,
        n_modes: usize,
        res: &[f64],
        restarts: usize,
        n_solves: usize,
        stalled: bool,
    ) -> Error {
        let tol = self.options.tol;
        let done = res[..n_modes].iter().filter(|&&r| r <= tol).count();
        let worst = res[..n_modes].iter().fold(0.0_f64, |a, &b| a.max(b));
        Error::Numerical(format!(
            "partial eigen-solver: {done} of the {n_modes} lowest eigenpairs converged to \
             the operator residual {tol:e} ({}, {restarts} restarts, {n_solves} solves); \
             worst residual {worst:.3e}",
            if stalled {
                "the search space stopped growing"
            } else {
                "restarts exhausted"
            }
        ))
    }

    /// The converged pairs of `ws`: `M`-normalised shapes with their largest entry
    /// positive, residuals recomputed with `K` and `M`.
    pub(super) fn finish(
        &self,
        n_modes: usize,
        sigma: f64,
        n_solves: usize,
        ws: &mut PartialWorkspace,
    ) -> PartialEigen {
        let n = self.pencil.n_dof();
        let pencil = Pencil {
            sparse: &self.pencil,
            k: &ws.k,
            m: &ws.m,
        };
        let mut phi = DMatrix::zeros(n, n_modes);
        let mut residual = Vec::with_capacity(n_modes);
        let (mut kx, mut mx) = (vec![0.0; n], vec![0.0; n]);
        for i in 0..n_modes {
            let x = &ws.x[i * n..(i + 1) * n];
            pencil.m_mul(x, &mut mx);
            pencil.k_mul(x, &mut kx);
            let imax = (0..n)
                .max_by(|&a, &b| x[a].abs().total_cmp(&x[b].abs()).then(b.cmp(&a)))
                .unwrap_or(0);
            let scale = x[imax].signum() / dot(x, &mx).sqrt();
            phi.column_mut(i)
                .iter_mut()
                .zip(x)
                .for_each(|(p, v)| *p = v * scale);
            residual.push(relative_residual(&kx, &mx, ws.lambda[i], sigma));
        }
        PartialEigen {
            eigenvalues_rad2_s2: ws.lambda[..n_modes].to_vec(),
            phi,
            relative_residual: residual,
            operator_residual: ws.op_res[..n_modes].to_vec(),
            shift_rad2_s2: sigma,
            n_solves,
        }
    }
}
