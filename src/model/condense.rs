//! Massless DOFs and their static condensation.
//!
//! FE models with lumped masses carry no mass on rotational DOFs: the bridge of
//! `../shared/data/real/bridge-fe` has 474 of its 946 DOFs with a zero row in `M`. `M` is
//! then only positive semi-definite and the pencil `(K, M)` has `n - n_massless` finite
//! eigenvalues. Condensing the massless DOFs `s` onto the others `m`,
//! `K_c = K_mm - K_ms K_ss^-1 K_sm`, `M_c = M_mm`, gives exactly those eigenvalues, with
//! the massless part of each mode `phi_s = -K_ss^-1 K_sm phi_m` (Guyan reduction, exact
//! when `M_ss = 0` and `M_sm = 0`).

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// DOFs (0-based, ascending) whose row of `m` is entirely zero.
pub fn massless_dofs(m: &DMatrix<f64>) -> Vec<usize> {
    (0..m.nrows())
        .filter(|&i| m.row(i).iter().all(|&x| x == 0.0))
        .collect()
}

/// A pencil with its massless DOFs condensed out.
#[derive(Debug, Clone)]
pub struct Condensed {
    /// `K_mm - K_ms K_ss^-1 K_sm`.
    pub k: DMatrix<f64>,
    /// `M_mm`.
    pub m: DMatrix<f64>,
    /// The DOFs kept (with mass), ascending.
    pub kept: Vec<usize>,
    /// The DOFs condensed out (massless), ascending.
    pub massless: Vec<usize>,
}

fn sub(a: &DMatrix<f64>, rows: &[usize], cols: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), cols.len(), |i, j| a[(rows[i], cols[j])])
}

/// Condenses the massless DOFs of `(k, m)`. Errors when `K` is singular on them (a
/// massless mechanism: the condensation, and the model, are then ill-posed).
pub fn condense(k: &DMatrix<f64>, m: &DMatrix<f64>) -> Result<Condensed> {
    let massless = massless_dofs(m);
    let kept: Vec<usize> = (0..m.nrows())
        .filter(|i| massless.binary_search(i).is_err())
        .collect();
    let mut kc = sub(k, &kept, &kept);
    if !massless.is_empty() {
        let kss = sub(k, &massless, &massless);
        let chol = kss.cholesky().ok_or_else(|| {
            Error::Model(format!(
                "K is not positive definite on the {} massless DOFs (zero rows of M, e.g. DOF \
                 {}): they cannot be condensed; give them mass or stiffness",
                massless.len(),
                massless[0] + 1
            ))
        })?;
        let ksm = sub(k, &massless, &kept);
        kc -= ksm.transpose() * chol.solve(&ksm);
        kc = (&kc + kc.transpose()) * 0.5;
    }
    Ok(Condensed {
        m: sub(m, &kept, &kept),
        k: kc,
        kept,
        massless,
    })
}
