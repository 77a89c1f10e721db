//! The exact lowest modes of a pencil with massless DOFs, by static condensation and a
//! dense faer eigen-solution (paper Eq. 22b on the condensed pencil).
//!
//! With `s` the massless DOFs (zero rows of `M`) and `m` the others,
//! `K_c = K_mm - K_ms K_ss^-1 K_sm`, `M_c = M_mm` has exactly the finite eigenvalues of
//! `(K, M)`, and a mode's massless part is `phi_s = -K_ss^-1 K_sm phi_m`
//! ([`crate::model::condense`]). `M_c = L L^T`, `L^-1 K_c L^-T` is symmetric; its
//! eigenvectors `v` give `phi_m = L^-T v`, mass-normalised. This is the reference
//! ("full") solve that partial and reduced solvers are checked against; it costs
//! `O(n^3)` per call.

use super::dense::{
    cholesky_in_place, matmul, solve_lower, solve_lower_transpose, symmetric_eigen, symmetrise,
};
use crate::error::{Error, Result};
use crate::model::condense::massless_dofs;
use faer::Mat;
use nalgebra::DMatrix;

/// The lowest modes of `(K, M)`: eigenvalues `omega^2` (rad^2/s^2, ascending) and
/// mass-normalised shapes over every DOF (columns).
#[derive(Debug, Clone)]
pub struct FullModes {
    pub eigenvalues: Vec<f64>,
    pub shapes: DMatrix<f64>,
}

fn sub(a: &DMatrix<f64>, rows: &[usize], cols: &[usize]) -> Mat<f64> {
    Mat::from_fn(rows.len(), cols.len(), |i, j| a[(rows[i], cols[j])])
}

/// The `n_modes` lowest modes of `(k, m)`, `m` positive semi-definite with its zero rows
/// condensed out. [`Error::Model`] when `K` is not positive definite on the massless
/// DOFs or `M` not on the others.
pub fn lowest_modes_condensed(
    k: &DMatrix<f64>,
    m: &DMatrix<f64>,
    n_modes: usize,
) -> Result<FullModes> {
    let n = k.nrows();
    let massless = massless_dofs(m);
    let kept: Vec<usize> = (0..n)
        .filter(|i| massless.binary_search(i).is_err())
        .collect();
    if n_modes > kept.len() {
        return Err(Error::Usage(format!(
            "{n_modes} modes requested of a pencil with {} DOFs with mass",
            kept.len()
        )));
    }
    let mut kc = sub(k, &kept, &kept);
    // x = K_ss^-1 K_sm, so that phi_s = -x phi_m.
    let mut x = Mat::<f64>::zeros(massless.len(), kept.len());
    if !massless.is_empty() {
        let mut lss = sub(k, &massless, &massless);
        cholesky_in_place(&mut lss).ok_or_else(|| {
            Error::Model(format!(
                "K is not positive definite on the {} massless DOFs (e.g. DOF {})",
                massless.len(),
                massless[0] + 1
            ))
        })?;
        let ksm = sub(k, &massless, &kept);
        x.copy_from(&ksm);
        solve_lower(lss.as_ref(), x.as_mut());
        solve_lower_transpose(lss.as_ref(), x.as_mut());
        matmul(kc.as_mut(), true, ksm.transpose(), x.as_ref(), -1.0);
    }
    let mut l = sub(m, &kept, &kept);
    cholesky_in_place(&mut l)
        .ok_or_else(|| Error::Model("M is not positive definite on its DOFs with mass".into()))?;
    // A = L^-1 K_c L^-T.
    solve_lower(l.as_ref(), kc.as_mut());
    let mut a = kc.transpose().to_owned();
    solve_lower(l.as_ref(), a.as_mut());
    symmetrise(&mut a);
    let (values, v) = symmetric_eigen(a.as_ref())?;
    let mut phi_m = v.subcols(0, n_modes).to_owned();
    solve_lower_transpose(l.as_ref(), phi_m.as_mut());
    let mut phi_s = Mat::<f64>::zeros(massless.len(), n_modes);
    if !massless.is_empty() {
        matmul(phi_s.as_mut(), false, x.as_ref(), phi_m.as_ref(), -1.0);
    }
    let mut shapes = DMatrix::zeros(n, n_modes);
    for j in 0..n_modes {
        for (r, &d) in kept.iter().enumerate() {
            shapes[(d, j)] = phi_m[(r, j)];
        }
        for (r, &d) in massless.iter().enumerate() {
            shapes[(d, j)] = phi_s[(r, j)];
        }
    }
    Ok(FullModes {
        eigenvalues: values[..n_modes].to_vec(),
        shapes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Oracle: a pencil whose massless DOFs carry stiffness gives, per mode, a zero
    /// residual `K phi - lambda M phi` on every DOF (the massless rows included), and
    /// `Phi^T M Phi = I`; with a small mass added on the massless DOFs the eigenvalues
    /// of nalgebra's full solve approach the condensed ones.
    #[test]
    fn condensed_modes_solve_the_full_pencil() {
        let n = 12;
        let mut k = DMatrix::zeros(n, n);
        for i in 0..n - 1 {
            let s = 100.0 + 10.0 * i as f64;
            k[(i, i)] += s;
            k[(i + 1, i + 1)] += s;
            k[(i, i + 1)] -= 0.7 * s;
            k[(i + 1, i)] -= 0.7 * s;
        }
        k[(0, 0)] += 50.0;
        let mut m = DMatrix::zeros(n, n);
        for i in (0..n).step_by(2) {
            m[(i, i)] = 1.0 + 0.1 * i as f64;
        }
        let modes = lowest_modes_condensed(&k, &m, 4).unwrap();
        for j in 0..4 {
            let phi = modes.shapes.column(j);
            let r = &k * phi - &m * phi * modes.eigenvalues[j];
            assert!(r.amax() < 1e-9 * k.amax(), "mode {j}: {}", r.amax());
        }
        let g = modes.shapes.transpose() * &m * &modes.shapes;
        assert!((g - DMatrix::identity(4, 4)).amax() < 1e-12);
        assert!(modes.eigenvalues.windows(2).all(|w| w[0] < w[1]));
        let mut m_eps = m.clone();
        for i in (1..n).step_by(2) {
            m_eps[(i, i)] = 1e-9;
        }
        let full = nalgebra::linalg::Cholesky::new(m_eps.clone()).unwrap();
        let l_inv = full.l().try_inverse().unwrap();
        let a = &l_inv * &k * l_inv.transpose();
        let mut ev: Vec<f64> = a.symmetric_eigenvalues().iter().copied().collect();
        ev.sort_by(f64::total_cmp);
        for (e, m) in ev.iter().zip(&modes.eigenvalues) {
            assert!((e / m - 1.0).abs() < 1e-6);
        }
        let mut bad = k.clone();
        bad[(1, 1)] = -1e6;
        assert!(matches!(
            lowest_modes_condensed(&bad, &m, 2),
            Err(Error::Model(_))
        ));
    }
}
