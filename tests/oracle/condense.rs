//! Static condensation of massless DOFs in nalgebra: an oracle independent of the crate's
//! faer-based condensed solver (`frfbayes::modal::condensed`), for the tests that check
//! partial and reduced eigensolvers against a full dense solve.
//!
//! With `s` the massless DOFs (zero rows of `M`) and `m` the others,
//! `K_c = K_mm - K_ms K_ss^-1 K_sm`, `M_c = M_mm` has exactly the finite eigenvalues of
//! `(K, M)` (Guyan reduction, exact when `M_ss = 0` and `M_sm = 0`).

use frfbayes::model::condense::massless_dofs;
use nalgebra::DMatrix;

/// A pencil with its massless DOFs condensed out.
pub struct Condensed {
    /// `K_mm - K_ms K_ss^-1 K_sm`.
    pub k: DMatrix<f64>,
    /// `M_mm`.
    pub m: DMatrix<f64>,
    /// The DOFs kept (with mass), ascending.
    pub kept: Vec<usize>,
    /// The DOFs condensed out (massless), ascending.
    #[allow(dead_code)]
    pub massless: Vec<usize>,
}

fn sub(a: &DMatrix<f64>, rows: &[usize], cols: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), cols.len(), |i, j| a[(rows[i], cols[j])])
}

/// Condenses the massless DOFs of `(k, m)`; `None` when `K` is singular on them.
pub fn condense(k: &DMatrix<f64>, m: &DMatrix<f64>) -> Option<Condensed> {
    let massless = massless_dofs(m);
    let kept: Vec<usize> = (0..m.nrows())
        .filter(|i| massless.binary_search(i).is_err())
        .collect();
    let mut kc = sub(k, &kept, &kept);
    if !massless.is_empty() {
        let chol = sub(k, &massless, &massless).cholesky()?;
        let ksm = sub(k, &massless, &kept);
        kc -= ksm.transpose() * chol.solve(&ksm);
        kc = (&kc + kc.transpose()) * 0.5;
    }
    Some(Condensed {
        m: sub(m, &kept, &kept),
        k: kc,
        kept,
        massless,
    })
}
