//! The finite-difference Jacobian of a residual function, for problems without an
//! analytic one.
//!
//! Forward differences with scipy's step rule (`least_squares(jac="2-point")`):
//! `h_j = sqrt(eps) max(1, |x_j|)`, taken backwards when the forward point would leave
//! the box.

use super::Bounds;
use crate::error::Result;
use nalgebra::DMatrix;

/// `jac[(i, j)] = (f_i(x + h_j e_j) - f_i(x)) / h_j` with `f0 = f(x)` (see the module
/// docs for `h_j`).
pub fn fd_jacobian<F>(
    mut f: F,
    x: &[f64],
    f0: &[f64],
    bounds: &Bounds,
    jac: &mut DMatrix<f64>,
) -> Result<()>
where
    F: FnMut(&[f64], &mut [f64]) -> Result<()>,
{
    let mut xp = x.to_vec();
    let mut fp = vec![0.0; f0.len()];
    for j in 0..x.len() {
        let mut h = f64::EPSILON.sqrt() * x[j].abs().max(1.0);
        if x[j] + h > bounds.upper()[j] {
            h = -h;
        }
        xp[j] = x[j] + h;
        let h_exact = xp[j] - x[j];
        f(&xp, &mut fp)?;
        for i in 0..f0.len() {
            jac[(i, j)] = (fp[i] - f0[i]) / h_exact;
        }
        xp[j] = x[j];
    }
    Ok(())
}
