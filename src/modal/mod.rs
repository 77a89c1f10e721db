//! Modal analysis: the generalised symmetric eigenproblem `K phi = omega^2 M phi`
//! (paper Eq. 22b), mass-normalised modes (`Phi^T M Phi = I`), ascending order, and the
//! modal assurance criterion.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// Undamped modes of a model, ascending in frequency, mass-normalised.
#[derive(Debug, Clone)]
pub struct Modes {
    /// Natural frequencies `omega_n,i` in rad/s.
    pub omega_rad_s: Vec<f64>,
    /// Mode shapes as columns (n_dof x n_modes); `Phi^T M Phi = I`. Each mode's
    /// largest-magnitude entry is positive, so signs are reproducible.
    pub phi: DMatrix<f64>,
    /// Ground-excitation participation `Gamma_i = phi_i^T M iota` (Eq. 15:
    /// `sum_e m_e phi_e,i` for a lumped-mass shear frame).
    pub participation: Vec<f64>,
}

impl Modes {
    /// Solves `K phi = omega^2 M phi` and keeps the first `n_modes` modes (all when `None`).
    /// `ground_influence` is the rigid-body vector `iota` of ground motion.
    pub fn solve(
        k: &DMatrix<f64>,
        m: &DMatrix<f64>,
        ground_influence: &DVector<f64>,
        n_modes: Option<usize>,
    ) -> Result<Self> {
        let n = k.nrows();
        let n_modes = n_modes.unwrap_or(n).min(n);
        let chol = m
            .clone()
            .cholesky()
            .ok_or_else(|| Error::Numerical("mass matrix is not positive definite".into()))?;
        // A = L^-1 K L^-T, symmetric; phi = L^-T v.
        let l = chol.l();
        let y = l
            .solve_lower_triangular(k)
            .ok_or_else(|| Error::Numerical("singular Cholesky factor".into()))?;
        let a = l
            .solve_lower_triangular(&y.transpose())
            .ok_or_else(|| Error::Numerical("singular Cholesky factor".into()))?;
        let a = (&a + a.transpose()) * 0.5;
        let eig = a.symmetric_eigen();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
        let lt = l.transpose();
        let mut phi = DMatrix::zeros(n, n_modes);
        let mut omega_rad_s = Vec::with_capacity(n_modes);
        for (col, &i) in order.iter().take(n_modes).enumerate() {
            let lam = eig.eigenvalues[i];
            if !lam.is_finite() {
                return Err(Error::Numerical("non-finite eigenvalue".into()));
            }
            omega_rad_s.push(lam.max(0.0).sqrt());
            let v = lt
                .solve_upper_triangular(&eig.eigenvectors.column(i).into_owned())
                .ok_or_else(|| Error::Numerical("singular Cholesky factor".into()))?;
            let imax = v.iamax();
            let sign = if v[imax] < 0.0 { -1.0 } else { 1.0 };
            phi.set_column(col, &(v * sign));
        }
        let m_iota = m * ground_influence;
        let participation = (0..n_modes).map(|i| phi.column(i).dot(&m_iota)).collect();
        Ok(Modes {
            omega_rad_s,
            phi,
            participation,
        })
    }

    /// Number of retained modes.
    pub fn n_modes(&self) -> usize {
        self.omega_rad_s.len()
    }

    /// Natural frequencies in Hz.
    pub fn freq_hz(&self) -> Vec<f64> {
        self.omega_rad_s
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect()
    }
}

/// Modal assurance criterion between two real shapes: `(a.b)^2 / ((a.a)(b.b))`.
pub fn mac(a: &[f64], b: &[f64]) -> f64 {
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
    let den = dot(a, a) * dot(b, b);
    if den == 0.0 {
        0.0
    } else {
        dot(a, b).powi(2) / den
    }
}

/// MAC matrix between the columns of two shape matrices (rows: DOFs).
pub fn mac_matrix(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(a.ncols(), b.ncols(), |i, j| {
        mac(a.column(i).as_slice(), b.column(j).as_slice())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::StructuralModel;

    #[test]
    fn two_dof_closed_form_and_normalisation() {
        // m = 1, k = 1 chain: omega^2 = (3 -+ sqrt 5)/2.
        let model = StructuralModel::shear_frame(&[1.0, 1.0], &[1.0, 1.0]).unwrap();
        let (k, m) = (model.stiffness(&[0.0, 0.0]), model.mass(&[0.0, 0.0]));
        let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
        let w2: Vec<f64> = modes.omega_rad_s.iter().map(|w| w * w).collect();
        assert!((w2[0] - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-12);
        assert!((w2[1] - (3.0 + 5f64.sqrt()) / 2.0).abs() < 1e-12);
        let ptmp = modes.phi.transpose() * &m * &modes.phi;
        assert!((ptmp - DMatrix::identity(2, 2)).amax() < 1e-12);
        let ptkp = modes.phi.transpose() * &k * &modes.phi;
        assert!((ptkp - DMatrix::from_diagonal(&DVector::from_vec(w2))).amax() < 1e-12);
        assert!(
            (mac(
                modes.phi.column(0).as_slice(),
                modes.phi.column(0).as_slice()
            ) - 1.0)
                .abs()
                < 1e-14
        );
        assert!(
            mac(
                modes.phi.column(0).as_slice(),
                modes.phi.column(1).as_slice()
            ) < 1.0
        );
        let trunc = Modes::solve(&k, &m, model.ground_influence(), Some(1)).unwrap();
        assert_eq!(trunc.n_modes(), 1);
        assert_eq!(trunc.phi.ncols(), 1);
    }
}
