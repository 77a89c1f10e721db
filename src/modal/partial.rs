//! Partial eigen-solutions of large sparse models: the lowest `m` eigenpairs of
//! `K(alpha) phi = lambda M(beta) phi` (paper Eqs. 20-22, `lambda = omega^2`) with `K`
//! symmetric positive (semi-)definite and `M` symmetric positive semi-definite, possibly
//! singular (massless rotational DOFs).
//!
//! Method: shift-invert. The operator `Op = (K - sigma M)^-1 M`, with `sigma` below the
//! lowest eigenvalue, maps eigenvalue `lambda` to `1 / (lambda - sigma)`: the wanted
//! pairs become the dominant ones, and the infinite eigenvalues of a singular `M` go to
//! 0. `K - sigma M` is factorised by faer's sparse Cholesky (the symbolic analysis, with
//! its fill-reducing ordering, once per pattern in [`PartialSolver::new`]; the numeric
//! factorisation once per evaluation). The search space `V` (`V^T M V = I`) starts from
//! `Op R` (R random, seeded) and grows by the residuals `Op x - theta x` of the Ritz
//! pairs not yet converged (a block shift-invert Lanczos / Davidson method; the
//! residuals are already `M`-orthogonal to `V`, so nothing is lost to cancellation),
//! kept `M`-orthonormal by block classical Gram-Schmidt done twice. Rayleigh-Ritz uses
//! the projected operator `H = V^T M Op V` (symmetric; `Op V` is stored, so residuals
//! cost no extra solve) and `lambda = sigma + 1 / theta`: projecting `K` instead
//! (`V^T K V`) loses about `eps ||K|| / lambda` to rounding (1e-9 on stiff models).
//! When the space reaches its cap it restarts from the current Ritz vectors (thick
//! restart).
//!
//! Every vector of the space lies in the range of `Op`, where `M` is definite and the
//! massless rows of `K x = lambda M x` hold (`K_s x = 0`): Rayleigh-Ritz there is
//! Rayleigh-Ritz on the statically condensed pencil, so no spurious (infinite)
//! eigenvalue can appear.
//!
//! Convergence: a Ritz pair `(theta, x)` of `Op`, `||x||_M = 1`, is converged when the
//! residual of the shift-invert problem relative to its eigenvalue,
//! `||Op x - theta x||_M / theta` (`= ||(K - sigma M)^-1 (K x - lambda M x)||_M` at
//! `theta = 1 / (lambda - sigma)`), is at most [`PartialOptions::tol`] (default 1e-10). The plain relative residual
//! `||K x - lambda M x|| / (|lambda| ||M x||)` is reported too, but cannot be the test:
//! on stiff models its rounding floor is about `eps ||K|| / lambda` (3e-7 on the bridge,
//! whose `K` has entries up to 1.8e6 on massless rotations), far above the accuracy the
//! eigenvalues and shapes actually reach (tests/partial_eigen.rs: the bridge's lowest
//! 10 within 5e-12 of a dense condensed solve, MAC above 1 - 4e-15).

mod basis;
mod iterate;

use crate::error::{Error, Result};
use crate::model::sparse::SparsePencil;
use basis::Basis;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use nalgebra::DMatrix;
use std::sync::Arc;

/// Settings of the partial eigen-solver.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialOptions {
    /// Shift `sigma` (rad^2/s^2), below the lowest eigenvalue. `None`: `-1e-6` times the
    /// smallest `K_ii / M_ii` over the DOFs with `M_ii > 0` (a Rayleigh quotient, so at
    /// least the lowest eigenvalue): just below zero on the model's own scale.
    pub shift_rad2_s2: Option<f64>,
    /// Relative residual at which a pair is converged (see the module docs).
    pub tol: f64,
    /// Largest search space, in vectors; `None`: `max(3 p, p + 20)` with `p = m +
    /// max(3, m / 2)` (the wanted pairs and a few guard pairs).
    pub max_basis: Option<usize>,
    /// Thick restarts allowed before giving up.
    pub max_restarts: usize,
    /// Seed of the random start block (results are reproducible).
    pub seed: u64,
}

impl Default for PartialOptions {
    fn default() -> Self {
        PartialOptions {
            shift_rad2_s2: None,
            tol: 1e-10,
            max_basis: None,
            max_restarts: 30,
            seed: 0x5eed,
        }
    }
}

/// The lowest eigenpairs of a pencil.
#[derive(Debug, Clone)]
pub struct PartialEigen {
    /// Eigenvalues `lambda = omega^2` in rad^2/s^2, ascending.
    pub eigenvalues_rad2_s2: Vec<f64>,
    /// Shapes as columns (n_dof x m), `Phi^T M Phi = I`; each shape's largest-magnitude
    /// entry is positive.
    pub phi: DMatrix<f64>,
    /// Relative residual `||K phi - lambda M phi|| / (max(|lambda|, |sigma|) ||M phi||)`
    /// of each pair, recomputed from the returned shapes (for information: its rounding
    /// floor is about `eps ||K|| / lambda`, 1e-7 on stiff models).
    pub relative_residual: Vec<f64>,
    /// The residual of each pair in the shift-invert problem (the convergence test, at
    /// most [`PartialOptions::tol`]; module docs).
    pub operator_residual: Vec<f64>,
    /// The shift used (rad^2/s^2).
    pub shift_rad2_s2: f64,
    /// Solves with the factorised `K - sigma M` (one per vector).
    pub n_solves: usize,
}

impl PartialEigen {
    /// Natural frequencies in rad/s (`sqrt(max(lambda, 0))`).
    pub fn omega_rad_s(&self) -> Vec<f64> {
        self.eigenvalues_rad2_s2
            .iter()
            .map(|l| l.max(0.0).sqrt())
            .collect()
    }
}

/// Shift-invert partial eigen-solver of one sparse pencil: the symbolic factorisation
/// of its pattern, shared (read only) by every thread; each thread brings a
/// [`PartialWorkspace`] with the numeric factor and the search space.
#[derive(Debug, Clone)]
pub struct PartialSolver {
    pencil: Arc<SparsePencil>,
    symbolic: Arc<SymbolicCholesky<usize>>,
    options: PartialOptions,
}

/// Scratch memory of one thread of a [`PartialSolver`].
#[derive(Default)]
pub struct PartialWorkspace {
    k: Vec<f64>,
    m: Vec<f64>,
    shifted: Vec<f64>,
    factor: Vec<f64>,
    diag_k: Vec<f64>,
    diag_m: Vec<f64>,
    basis: Basis,
    /// Ritz vectors and their images under Op and M (n x p, column-major).
    x: Vec<f64>,
    opx: Vec<f64>,
    mx: Vec<f64>,
    /// Block of vectors being pushed through `Op`.
    block: Vec<f64>,
    /// One vector of scratch.
    tmp: Vec<f64>,
    /// Ritz values of the wanted pairs and their operator residuals.
    lambda: Vec<f64>,
    op_res: Vec<f64>,
    stack: Option<MemBuffer>,
}

impl std::fmt::Debug for PartialWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PartialWorkspace")
            .field("basis_dim", &self.basis.dim())
            .finish_non_exhaustive()
    }
}

/// A pattern as faer's symbolic view.
fn faer_pattern(p: &crate::model::sparse::CscPattern) -> SymbolicSparseColMatRef<'_, usize> {
    SymbolicSparseColMatRef::new_checked(p.n(), p.n(), p.col_ptr(), None, p.row_idx())
}

impl PartialSolver {
    /// The solver of `pencil`: analyses its stiffness pattern (fill-reducing ordering and
    /// symbolic Cholesky factorisation of `K - sigma M`, lower triangle).
    pub fn new(pencil: Arc<SparsePencil>, options: PartialOptions) -> Result<Self> {
        if !(options.tol > 0.0 && options.tol < 1.0) {
            return Err(Error::Usage(format!(
                "partial eigen-solver: tolerance must be in (0, 1), got {}",
                options.tol
            )));
        }
        let symbolic = factorize_symbolic_cholesky(
            faer_pattern(pencil.stiffness_pattern()),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| Error::Numerical(format!("symbolic Cholesky factorisation: {e:?}")))?;
        Ok(PartialSolver {
            pencil,
            symbolic: Arc::new(symbolic),
            options,
        })
    }

    /// The pencil.
    pub fn pencil(&self) -> &SparsePencil {
        &self.pencil
    }
    /// The settings.
    pub fn options(&self) -> &PartialOptions {
        &self.options
    }
    /// Non-zeros of the Cholesky factor (its size, a measure of the solve cost).
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// A fresh workspace.
    pub fn workspace(&self) -> PartialWorkspace {
        PartialWorkspace::default()
    }

    /// The lowest `n_modes` eigenpairs of `K(alpha) phi = lambda M(beta) phi`.
    ///
    /// Errors: [`Error::Usage`] for parameter vectors of the wrong length or non-finite
    /// entries, or more modes than DOFs with mass (the rank of a diagonal `M`, a bound
    /// on it otherwise); [`Error::Numerical`] when `K - sigma M` is not positive definite
    /// (does not factor), when the space runs out before `n_modes` pairs (fewer finite
    /// eigenvalues), or without convergence within the restarts.
    pub fn solve(
        &self,
        alpha: &[f64],
        beta: &[f64],
        n_modes: usize,
        ws: &mut PartialWorkspace,
    ) -> Result<PartialEigen> {
        let sp = &*self.pencil;
        if alpha.len() != sp.n_alpha() || beta.len() != sp.n_beta() {
            return Err(Error::Usage(format!(
                "partial eigen-solver: {} alphas and {} betas given, the model has {} and {}",
                alpha.len(),
                beta.len(),
                sp.n_alpha(),
                sp.n_beta()
            )));
        }
        if let Some(x) = alpha.iter().chain(beta).find(|x| !x.is_finite()) {
            return Err(Error::Usage(format!(
                "partial eigen-solver: non-finite parameter {x}"
            )));
        }
        sp.stiffness_values(alpha, &mut ws.k);
        sp.mass_values(beta, &mut ws.m);
        let rank = self.check_rank(n_modes, ws)?;
        if n_modes == 0 {
            return Ok(self.finish(0, 0.0, 0, ws));
        }
        let sigma = self.shift(ws);
        self.factorise(sigma, ws)?;
        let n_solves = self.iterate(n_modes, rank, sigma, ws)?;
        Ok(self.finish(n_modes, sigma, n_solves, ws))
    }

    /// Rows of `M` with a non-zero entry (a bound on its rank; the rank when `M` is
    /// diagonal); errors when `n_modes` exceeds it.
    fn check_rank(&self, n_modes: usize, ws: &PartialWorkspace) -> Result<usize> {
        let mp = self.pencil.mass_pattern();
        let mut has_mass = vec![false; mp.n()];
        for (&i, &v) in mp.row_idx().iter().zip(&ws.m) {
            has_mass[i] |= v != 0.0;
        }
        let rank = has_mass.iter().filter(|&&b| b).count();
        if n_modes > rank {
            return Err(Error::Usage(format!(
                "{n_modes} modes requested, but only {rank} DOFs have mass: the pencil has \
                 at most {rank} finite eigenvalues"
            )));
        }
        Ok(rank)
    }

    /// The user's shift, or `-1e-6 min K_ii / M_ii` over DOFs with mass.
    fn shift(&self, ws: &mut PartialWorkspace) -> f64 {
        if let Some(s) = self.options.shift_rad2_s2 {
            return s;
        }
        self.pencil.stiffness_diagonal(&ws.k, &mut ws.diag_k);
        self.pencil.mass_diagonal(&ws.m, &mut ws.diag_m);
        let rho = ws
            .diag_k
            .iter()
            .zip(&ws.diag_m)
            .filter(|(k, m)| **m > 0.0 && **k > 0.0)
            .map(|(k, m)| k / m)
            .fold(f64::INFINITY, f64::min);
        -1e-6 * if rho.is_finite() { rho } else { 1.0 }
    }

    /// Numeric Cholesky factorisation of `K - sigma M` into the workspace.
    fn factorise(&self, sigma: f64, ws: &mut PartialWorkspace) -> Result<()> {
        let sp = &*self.pencil;
        sp.shifted_values(&ws.k, &ws.m, sigma, &mut ws.shifted);
        ws.factor.resize(self.symbolic.len_val(), 0.0);
        let req = self
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let stack = stack_for(&mut ws.stack, req);
        let a = SparseColMatRef::new(faer_pattern(sp.stiffness_pattern()), &ws.shifted);
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut ws.factor,
                a,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                stack,
                Default::default(),
            )
            .map_err(|e| {
                Error::Numerical(format!(
                    "K - sigma M (sigma = {sigma:e} rad^2/s^2) is not positive definite \
                     ({e}): K is indefinite or singular on the massless DOFs, or the shift \
                     is not below the lowest eigenvalue"
                ))
            })?;
        Ok(())
    }

    /// `block <- Op block = (K - sigma M)^-1 M block` for `cols` columns.
    fn apply_op(&self, cols: usize, ws: &mut PartialWorkspace) {
        let n = self.pencil.n_dof();
        let PartialWorkspace {
            m,
            factor,
            block,
            tmp,
            stack,
            ..
        } = ws;
        tmp.resize(n, 0.0);
        for c in 0..cols {
            let col = &mut block[c * n..(c + 1) * n];
            self.pencil.mass_pattern().mul(m, col, tmp);
            col.copy_from_slice(tmp);
        }
        self.solve_with(factor, stack, &mut block[..n * cols], cols);
    }

    /// `rhs <- (K - sigma M)^-1 rhs` for `cols` columns (column-major).
    fn solve_with(
        &self,
        factor: &[f64],
        stack: &mut Option<MemBuffer>,
        rhs: &mut [f64],
        cols: usize,
    ) {
        let n = self.pencil.n_dof();
        let req = self.symbolic.solve_in_place_scratch::<f64>(cols, Par::Seq);
        LltRef::new(&self.symbolic, factor).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, cols),
            Par::Seq,
            stack_for(stack, req),
        );
    }
}

/// A stack of at least `req`, reusing `buf` when it is large enough.
fn stack_for(buf: &mut Option<MemBuffer>, req: StackReq) -> &mut MemStack {
    let fits = buf.as_mut().is_some_and(|b| MemStack::new(b).can_hold(req));
    if !fits {
        *buf = Some(MemBuffer::new(req));
    }
    MemStack::new(buf.as_mut().expect("just allocated"))
}
