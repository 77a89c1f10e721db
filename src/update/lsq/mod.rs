//! Bounded nonlinear least squares: minimise `F(x) = 0.5 ||r(x)||^2` subject to
//! `lower <= x <= upper`.
//!
//! The problem is separate from the solver (as in argmin): a problem implements
//! [`LeastSquaresProblem`] (residuals and Jacobian, with a per-thread workspace so the
//! problem itself is shared read-only across threads); the solver [`Trf`] has
//! [`Trf::init`], [`Trf::next_iter`] and [`Trf::terminate`], and [`Trf::minimize`] runs
//! the loop. [`multistart`] runs many local solves in parallel.
//!
//! [`Trf`] is the trust-region reflective method of Branch, Coleman and Li (1999), as
//! implemented by scipy's `least_squares(method="trf", tr_solver="exact")`, whose
//! termination tests (`ftol`, `xtol`, `gtol`, evaluation budget) and defaults it
//! reproduces. The Jacobian is reduced by one Householder QR per iteration, so the
//! subproblem work is `O(n^3)` and independent of the number of residuals.
//!
//! A problem without an analytic Jacobian takes the finite-difference one of
//! [`fd_jacobian`] (scipy's step rule, every evaluation inside the bounds).

mod fd;
mod linalg;
mod multistart;
mod qr;
mod step;
mod trf;

pub use fd::{fd_jacobian, fd_jacobian_at, FdScheme};
pub use multistart::{
    latin_hypercube, multistart, multistart_from, start_points, MultistartOptions,
    MultistartResult, StartOutcome,
};
pub use trf::{Solution, Termination, Trf, TrfOptions, TrfState, XScale};

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// A least-squares problem `r: R^n -> R^m` with its Jacobian.
///
/// # Example
/// ```
/// use frfbayes::update::lsq::{Bounds, LeastSquaresProblem, Trf, TrfOptions};
/// use nalgebra::DMatrix;
///
/// /// r(x) = (x0 - 1, 10 (x1 - x0^2)): Rosenbrock's function.
/// struct Rosenbrock;
/// impl LeastSquaresProblem for Rosenbrock {
///     type Workspace = ();
///     fn n_params(&self) -> usize { 2 }
///     fn n_residuals(&self) -> usize { 2 }
///     fn workspace(&self) {}
///     fn residuals(&self, x: &[f64], _: &mut (), r: &mut [f64]) -> frfbayes::Result<()> {
///         r[0] = x[0] - 1.0;
///         r[1] = 10.0 * (x[1] - x[0] * x[0]);
///         Ok(())
///     }
///     fn jacobian(&self, x: &[f64], _: &mut (), j: &mut DMatrix<f64>) -> frfbayes::Result<()> {
///         j[(0, 0)] = 1.0;
///         j[(0, 1)] = 0.0;
///         j[(1, 0)] = -20.0 * x[0];
///         j[(1, 1)] = 10.0;
///         Ok(())
///     }
/// }
/// let bounds = Bounds::unbounded(2);
/// let sol = Trf::new(TrfOptions::default()).minimize(&Rosenbrock, &mut (), &[-1.2, 1.0], &bounds)?;
/// assert!((sol.x[0] - 1.0).abs() < 1e-6 && (sol.x[1] - 1.0).abs() < 1e-6);
/// # Ok::<(), frfbayes::Error>(())
/// ```
pub trait LeastSquaresProblem: Sync {
    /// Scratch memory for one thread of evaluations.
    type Workspace: Send;
    /// Number of variables `n`.
    fn n_params(&self) -> usize;
    /// Number of residuals `m`.
    fn n_residuals(&self) -> usize;
    /// A fresh workspace.
    fn workspace(&self) -> Self::Workspace;
    /// Residuals at `x` into `r` (length `m`). An `Err` (or a non-finite entry) at a
    /// trial point makes the solver shrink its step; at the start point it is returned.
    fn residuals(&self, x: &[f64], ws: &mut Self::Workspace, r: &mut [f64]) -> Result<()>;
    /// Jacobian `dr_i/dx_j` at `x` into `jac` (m x n).
    fn jacobian(&self, x: &[f64], ws: &mut Self::Workspace, jac: &mut DMatrix<f64>) -> Result<()>;
    /// [`Self::jacobian`] where the solver already holds `f`, the residuals at `x`: a
    /// finite-difference Jacobian ([`fd_jacobian_at`]) then need not evaluate them again
    /// (one evaluation of its `n + 1` saved, the result the same bits as long as
    /// [`Self::residuals`] is deterministic). By default `f` is not used.
    fn jacobian_at(
        &self,
        x: &[f64],
        f: &[f64],
        ws: &mut Self::Workspace,
        jac: &mut DMatrix<f64>,
    ) -> Result<()> {
        let _ = f;
        self.jacobian(x, ws, jac)
    }
}

/// A box `lower <= x <= upper`; infinite entries mean no bound.
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl Bounds {
    /// A box from its corners; requires `lower[i] < upper[i]` (no NaN).
    pub fn new(lower: Vec<f64>, upper: Vec<f64>) -> Result<Self> {
        if lower.len() != upper.len() {
            return Err(Error::Usage(format!(
                "{} lower bounds but {} upper bounds",
                lower.len(),
                upper.len()
            )));
        }
        for (i, (l, u)) in lower.iter().zip(&upper).enumerate() {
            if l.is_nan() || u.is_nan() || l >= u {
                return Err(Error::Usage(format!(
                    "variable {i}: lower bound {l} must be below upper bound {u}"
                )));
            }
        }
        Ok(Bounds { lower, upper })
    }

    /// No bounds in `n` dimensions.
    pub fn unbounded(n: usize) -> Self {
        Bounds {
            lower: vec![f64::NEG_INFINITY; n],
            upper: vec![f64::INFINITY; n],
        }
    }

    /// Lower corner.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// Upper corner.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }
    /// Dimension.
    pub fn len(&self) -> usize {
        self.lower.len()
    }
    /// True for a zero-dimensional box.
    pub fn is_empty(&self) -> bool {
        self.lower.is_empty()
    }
    /// True when every bound is finite (needed to sample starts).
    pub fn is_finite(&self) -> bool {
        self.lower.iter().chain(&self.upper).all(|v| v.is_finite())
    }

    /// Which bound, if any, each entry of `x` is on, within `rtol * max(1, |bound|)`
    /// (scipy's `find_active_constraints`).
    pub fn active(&self, x: &[f64], rtol: f64) -> Vec<Active> {
        x.iter()
            .zip(self.lower.iter().zip(&self.upper))
            .map(|(&x, (&l, &u))| {
                let (dl, du) = (x - l, u - x);
                if l.is_finite() && dl <= du.min(rtol * l.abs().max(1.0)) {
                    Active::Lower
                } else if u.is_finite() && du <= dl.min(rtol * u.abs().max(1.0)) {
                    Active::Upper
                } else {
                    Active::Free
                }
            })
            .collect()
    }
}

/// Where a variable ends relative to its bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Active {
    /// Strictly inside.
    Free,
    /// On its lower bound.
    Lower,
    /// On its upper bound.
    Upper,
}
