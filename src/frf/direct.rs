//! The direct inverse of the dynamic stiffness, paper Eq. (1):
//! `H(omega) = (K - omega^2 M + j omega C)^-1`, and the ground-excitation receptance of
//! Eq. (14), `H_ground = -H M iota`. It is the oracle for the modal sums and the forward
//! model for a general (non-proportional) viscous damping matrix `C`.

use super::{Excitation, FrfBlock};
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

fn dynamic_stiffness(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    omega_rad_s: f64,
) -> DMatrix<Complex64> {
    DMatrix::from_fn(k.nrows(), k.ncols(), |i, j| {
        Complex64::new(
            k[(i, j)] - omega_rad_s * omega_rad_s * m[(i, j)],
            omega_rad_s * c[(i, j)],
        )
    })
}

/// Receptance matrix at one frequency, Eq. (1).
pub fn receptance_matrix(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    omega_rad_s: f64,
) -> Result<DMatrix<Complex64>> {
    dynamic_stiffness(m, k, c, omega_rad_s)
        .try_inverse()
        .ok_or_else(|| {
            Error::Numerical(format!("dynamic stiffness singular at {omega_rad_s} rad/s"))
        })
}

/// Relative-displacement receptance to ground acceleration at one frequency, Eq. (14):
/// solves `(K - omega^2 M + j omega C) x = -M iota`.
pub fn ground_receptance(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    iota: &DVector<f64>,
    omega_rad_s: f64,
) -> Result<DVector<Complex64>> {
    let rhs = (m * iota).map(|v| Complex64::new(-v, 0.0));
    dynamic_stiffness(m, k, c, omega_rad_s)
        .lu()
        .solve(&rhs)
        .ok_or_else(|| {
            Error::Numerical(format!("dynamic stiffness singular at {omega_rad_s} rad/s"))
        })
}

/// Complex FRFs of `blocks` by direct solves, in the long-vector order of
/// [`super::ModalFrf`]. Works for any viscous `C`, proportional or not.
pub fn block_frfs(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    iota: &DVector<f64>,
    blocks: &[FrfBlock],
) -> Result<Vec<Complex64>> {
    let mut out = Vec::new();
    for b in blocks {
        let mut per_freq = Vec::with_capacity(b.omega_rad_s.len());
        for &w in &b.omega_rad_s {
            let h = receptance_matrix(m, k, c, w)?;
            let g = ground_receptance(m, k, c, iota, w)?;
            per_freq.push((h, g));
        }
        for p in &b.pairs {
            for (&w, (h, g)) in b.omega_rad_s.iter().zip(&per_freq) {
                let x = match p.excitation {
                    Excitation::Dof(e) => h[(p.response, e)],
                    Excitation::Ground => g[p.response],
                };
                out.push(x * p.kind.factor(w));
            }
        }
    }
    Ok(out)
}
