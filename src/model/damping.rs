//! Damping models: Rayleigh (paper Eq. 2) and Caughey through modal damping ratios
//! (Eqs. 8-9). A general (non-proportional) viscous `C` is passed as a matrix to the
//! direct solve in [`crate::frf::direct`].

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// Proportional damping, expressed so that every mode i gets a modal damping
/// coefficient `c_i = 2 xi_i omega_i` (rad/s) in the modal sums (Eqs. 7, 10, 15, 16).
#[derive(Debug, Clone, PartialEq)]
pub enum Damping {
    /// `C = a0 M + a1 K` (Eq. 2): `2 xi_i omega_i = a0 + a1 omega_i^2` (Eq. 7).
    Rayleigh { a0_per_s: f64, a1_s: f64 },
    /// Caughey damping given by its modal damping ratios `xi_i` (Eqs. 9-10), one per
    /// retained mode.
    Caughey { xi: Vec<f64> },
}

impl Damping {
    /// Modal damping coefficients `c_i = 2 xi_i omega_i` (rad/s) for natural
    /// frequencies `omega_rad_s`, written into `out` (same length).
    ///
    /// Caughey damping needs at least as many ratios as modes.
    #[inline]
    pub fn modal_coefficients(&self, omega_rad_s: &[f64], out: &mut [f64]) -> Result<()> {
        match self {
            Damping::Rayleigh { a0_per_s, a1_s } => {
                for (c, w) in out.iter_mut().zip(omega_rad_s) {
                    *c = a0_per_s + a1_s * w * w;
                }
            }
            Damping::Caughey { xi } => {
                if xi.len() < omega_rad_s.len() {
                    return Err(Error::Usage(format!(
                        "Caughey damping has {} ratios for {} modes",
                        xi.len(),
                        omega_rad_s.len()
                    )));
                }
                for ((c, w), x) in out.iter_mut().zip(omega_rad_s).zip(xi) {
                    *c = 2.0 * x * w;
                }
            }
        }
        Ok(())
    }

    /// Modal damping ratios `xi_i` at natural frequencies `omega_rad_s`.
    pub fn damping_ratios(&self, omega_rad_s: &[f64]) -> Result<Vec<f64>> {
        let mut c = vec![0.0; omega_rad_s.len()];
        self.modal_coefficients(omega_rad_s, &mut c)?;
        Ok(c.iter()
            .zip(omega_rad_s)
            .map(|(c, w)| c / (2.0 * w))
            .collect())
    }

    /// Number of damping variables (2 for Rayleigh, one per mode for Caughey).
    pub fn n_params(&self) -> usize {
        match self {
            Damping::Rayleigh { .. } => 2,
            Damping::Caughey { xi } => xi.len(),
        }
    }
}

/// `C = a0 M + a1 K`, paper Eq. (2).
pub fn rayleigh_damping_matrix(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    a0_per_s: f64,
    a1_s: f64,
) -> DMatrix<f64> {
    m * a0_per_s + k * a1_s
}

/// Caughey series coefficients `a_l` (l = 0..n-1) that give damping ratios `xi` at
/// natural frequencies `omega_rad_s`: solves Eq. (9), `xi_i = 1/2 sum_l a_l omega_i^(2l-1)`.
pub fn caughey_coefficients(omega_rad_s: &[f64], xi: &[f64]) -> Result<Vec<f64>> {
    let n = omega_rad_s.len();
    if xi.len() != n {
        return Err(Error::Usage(format!(
            "{} damping ratios for {n} frequencies",
            xi.len()
        )));
    }
    let v = DMatrix::from_fn(n, n, |i, l| 0.5 * omega_rad_s[i].powi(2 * l as i32 - 1));
    let rhs = DVector::from_column_slice(xi);
    let a = v.lu().solve(&rhs).ok_or_else(|| {
        Error::Numerical("Caughey system is singular (repeated frequencies?)".into())
    })?;
    Ok(a.iter().copied().collect())
}

/// `C = M sum_l a_l (M^-1 K)^l`, paper Eq. (8).
pub fn caughey_damping_matrix(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    a: &[f64],
) -> Result<DMatrix<f64>> {
    let m_inv_k = m
        .clone()
        .lu()
        .solve(k)
        .ok_or_else(|| Error::Numerical("M is singular".into()))?;
    let n = m.nrows();
    let mut power = DMatrix::<f64>::identity(n, n);
    let mut sum = DMatrix::<f64>::zeros(n, n);
    for &al in a {
        sum += &power * al;
        power = &power * &m_inv_k;
    }
    Ok(m * sum)
}
