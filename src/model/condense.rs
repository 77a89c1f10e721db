//! Massless DOFs and their static condensation.
//!
//! FE models with lumped masses carry no mass on rotational DOFs: the bridge of
//! `../shared/data/real/bridge-fe` has 474 of its 946 DOFs with a zero row in `M`. `M` is
//! then only positive semi-definite and the pencil `(K, M)` has `n - n_massless` finite
//! eigenvalues. Condensing the massless DOFs `s` onto the others `m`,
//! `K_c = K_mm - K_ms K_ss^-1 K_sm`, `M_c = M_mm`, gives exactly those eigenvalues, with
//! the massless part of each mode `phi_s = -K_ss^-1 K_sm phi_m` (Guyan reduction, exact
//! when `M_ss = 0` and `M_sm = 0`).
//!
//! This module finds the massless DOFs and checks that the condensation is well posed;
//! the condensed pencil is formed in one place, `crate::modal::condensed` (faer), and
//! the tests check it against an independent nalgebra oracle (`tests/oracle`).

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// DOFs (0-based, ascending) whose row of `m` is entirely zero.
pub fn massless_dofs(m: &DMatrix<f64>) -> Vec<usize> {
    (0..m.nrows())
        .filter(|&i| m.row(i).iter().all(|&x| x == 0.0))
        .collect()
}

fn sub(a: &DMatrix<f64>, rows: &[usize], cols: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), cols.len(), |i, j| a[(rows[i], cols[j])])
}

/// Checks that `(k, m)` can be condensed and solved: `K` positive definite on the
/// massless DOFs (else a massless mechanism makes the condensation, and the model,
/// ill-posed) and `M` positive definite on the others. The condensed pencil itself is
/// formed by the eigensolver that needs it ([`crate::modal`]'s condensed solve).
pub fn check_condensable(k: &DMatrix<f64>, m: &DMatrix<f64>) -> Result<()> {
    let massless = massless_dofs(m);
    let kept: Vec<usize> = (0..m.nrows())
        .filter(|i| massless.binary_search(i).is_err())
        .collect();
    if !massless.is_empty() && sub(k, &massless, &massless).cholesky().is_none() {
        return Err(Error::Model(format!(
            "K is not positive definite on the {} massless DOFs (zero rows of M, e.g. DOF \
             {}): they cannot be condensed; give them mass or stiffness",
            massless.len(),
            massless[0] + 1
        )));
    }
    if sub(m, &kept, &kept).cholesky().is_none() {
        return Err(Error::Model(format!(
            "M is not positive definite on its {} DOFs with mass",
            kept.len()
        )));
    }
    Ok(())
}
