//! Analytical derivatives of FRF magnitudes with respect to the updating variables.
//!
//! With `lambda_i = omega_i^2` and mass-normalised `phi_i` of `K(alpha) phi = lambda
//! M(beta) phi` (Eq. 22b), for a structural variable p with `dK = dK/dp`, `dM = dM/dp`
//! (`K0_r` for alpha_r, `M0_r` for beta_r; Eqs. 20-21):
//! - eigenvalues: `d lambda_i = phi_i^T (dK - lambda_i dM) phi_i`;
//! - eigenvectors (Fox & Kapoor's modal expansion over *all* modes, exact because
//!   [`Modes::solve`] is a dense solver that always yields the full basis, even when
//!   the FRF sum keeps fewer modes): `d phi_i = sum_{j != i} phi_j phi_j^T (dK -
//!   lambda_i dM) phi_i / (lambda_i - lambda_j) - 1/2 (phi_i^T dM phi_i) phi_i`;
//! - participation `Gamma_i = phi_i^T M iota`: `d Gamma_i = d phi_i^T M iota +
//!   phi_i^T dM iota`.
//!
//! The modal sum `S = sum_i a_i / D_i` with `D_i = lambda_i - omega^2 + j c_i omega`,
//! coefficients `a_i = phi_ri phi_ei` (Eqs. 7, 10) or `-phi_ri Gamma_i` (Eqs. 15, 16),
//! and modal damping `c_i = a0 + a1 lambda_i` (Rayleigh) or `2 xi_i omega_i` (Caughey)
//! has `dS = sum_i [da_i / D_i - a_i (d lambda_i + j omega dc_i) / D_i^2]`. The FRF is
//! `H = (j omega)^p S` (Eqs. 11-12), so `|H| = omega^p |S|` and
//! `d|H| = omega^p Re(conj(S) dS) / |S|` (Eq. 17).

use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock};
use crate::modal::Modes;
use crate::model::{Damping, StructuralModel};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// Relative gap below which two eigenvalues count as repeated (derivatives of the
/// modes are then undefined).
pub const REPEATED_EIGENVALUE_RTOL: f64 = 1e-10;

/// Scratch memory of [`magnitude_jacobian`].
#[derive(Debug, Clone, Default)]
pub(crate) struct SensitivityWorkspace {
    dlam: Vec<f64>,
    dphi: Vec<f64>,
    dgam: Vec<f64>,
    poles: Vec<Complex64>,
    poles2: Vec<Complex64>,
    coef: Vec<f64>,
    dcoef: Vec<f64>,
    c: Vec<f64>,
    dc_dlam: Vec<f64>,
    b: Vec<Complex64>,
}

/// Mode-shape, eigenvalue and participation derivatives for every structural variable
/// (alpha then beta), for the first `m` modes, into `ws.dlam` (`p*m + i`), `ws.dphi`
/// (`(p*m + i)*n + dof`) and `ws.dgam` (`p*m + i`).
fn eigen_derivatives(
    model: &StructuralModel,
    mass: &DMatrix<f64>,
    modes: &Modes,
    m: usize,
    ws: &mut SensitivityWorkspace,
) -> Result<()> {
    let n = modes.phi.nrows();
    let n_all = modes.n_modes();
    let n_s = model.n_alpha() + model.n_beta();
    let lam: Vec<f64> = modes.omega_rad_s.iter().map(|w| w * w).collect();
    let lam_max = lam.iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
    for i in 0..m {
        for j in 0..n_all {
            if j != i && (lam[i] - lam[j]).abs() <= REPEATED_EIGENVALUE_RTOL * lam_max {
                return Err(Error::Numerical(format!(
                    "modes {} and {} have repeated eigenvalues; their derivatives are undefined",
                    i.min(j) + 1,
                    i.max(j) + 1
                )));
            }
        }
    }
    ws.dlam.resize(n_s * m, 0.0);
    ws.dphi.resize(n_s * m * n, 0.0);
    ws.dgam.resize(n_s * m, 0.0);
    let iota = model.ground_influence();
    let m_iota: DVector<f64> = mass * iota;
    let phi_m = modes.phi.columns(0, m);
    for p in 0..n_s {
        // A = Phi^T dK Phi_m, B = Phi^T dM Phi_m (n_all x m); dM iota for Gamma.
        let (a, b, dm_iota) = if p < model.n_alpha() {
            let dk = &model.stiffness_influence()[p];
            (Some(modes.phi.transpose() * (dk * phi_m)), None, None)
        } else {
            let dm = &model.mass_influence()[p - model.n_alpha()];
            (
                None,
                Some(modes.phi.transpose() * (dm * phi_m)),
                Some(dm * iota),
            )
        };
        for i in 0..m {
            let a_ji = |j: usize| a.as_ref().map_or(0.0, |a| a[(j, i)]);
            let b_ji = |j: usize| b.as_ref().map_or(0.0, |b| b[(j, i)]);
            ws.dlam[p * m + i] = a_ji(i) - lam[i] * b_ji(i);
            let dphi = &mut ws.dphi[(p * m + i) * n..(p * m + i + 1) * n];
            dphi.fill(0.0);
            for j in 0..n_all {
                let cj = if j == i {
                    -0.5 * b_ji(i)
                } else {
                    (a_ji(j) - lam[i] * b_ji(j)) / (lam[i] - lam[j])
                };
                for (d, x) in dphi.iter_mut().zip(modes.phi.column(j).iter()) {
                    *d += cj * x;
                }
            }
            let mut dg: f64 = dphi.iter().zip(m_iota.iter()).map(|(a, b)| a * b).sum();
            if let Some(dmi) = &dm_iota {
                dg += modes.phi.column(i).dot(dmi);
            }
            ws.dgam[p * m + i] = dg;
        }
    }
    Ok(())
}

/// FRF magnitudes `|H_k|` (Eq. 17, long-vector order of Eqs. 18-19) and their
/// derivatives with respect to `theta = (alpha, beta, damping variables)`.
///
/// `modes` are all modes at `(alpha, beta)` (from `Modes::solve(.., None)`), of which
/// the first `m` enter the sums; `mass` is `M(beta)`. Column `columns[v]` of `jac`
/// receives `d|H|/d theta_v` (variables mapped to `None` are skipped).
#[allow(clippy::too_many_arguments)]
pub(crate) fn magnitude_jacobian(
    model: &StructuralModel,
    mass: &DMatrix<f64>,
    modes: &Modes,
    m: usize,
    damping: &Damping,
    blocks: &[FrfBlock],
    columns: &[Option<usize>],
    ws: &mut SensitivityWorkspace,
    mag: &mut [f64],
    jac: &mut DMatrix<f64>,
) -> Result<()> {
    let n = modes.phi.nrows();
    let n_s = model.n_alpha() + model.n_beta();
    eigen_derivatives(model, mass, modes, m, ws)?;
    let omega_n = &modes.omega_rad_s[..m];
    ws.c.resize(m, 0.0);
    damping.modal_coefficients(omega_n, &mut ws.c)?;
    // dc_i / d lambda_i through the structure.
    ws.dc_dlam.clear();
    match damping {
        Damping::Rayleigh { a1_s, .. } => ws.dc_dlam.extend(std::iter::repeat_n(*a1_s, m)),
        Damping::Caughey { xi } => ws
            .dc_dlam
            .extend(omega_n.iter().zip(xi).map(|(w, x)| x / w)),
    }
    let n_d = columns.len() - n_s;
    let mut row = 0;
    for block in blocks {
        let nw = block.omega_rad_s.len();
        ws.poles.clear();
        ws.poles2.clear();
        for &w in &block.omega_rad_s {
            for (wn, c) in omega_n.iter().zip(&ws.c) {
                let p = Complex64::new(wn * wn - w * w, c * w).inv();
                ws.poles.push(p);
                ws.poles2.push(p * p);
            }
        }
        for pair in &block.pairs {
            if pair.response >= n || matches!(pair.excitation, Excitation::Dof(e) if e >= n) {
                return Err(Error::Usage(format!(
                    "FRF pair {pair:?} outside a {n}-DOF model"
                )));
            }
            ws.coef.clear();
            ws.dcoef.resize(n_s * m, 0.0);
            let r = pair.response;
            for i in 0..m {
                let phi_r = modes.phi[(r, i)];
                ws.coef.push(match pair.excitation {
                    Excitation::Dof(e) => phi_r * modes.phi[(e, i)],
                    Excitation::Ground => -phi_r * modes.participation[i],
                });
                for p in 0..n_s {
                    let dphi = &ws.dphi[(p * m + i) * n..(p * m + i + 1) * n];
                    ws.dcoef[p * m + i] = match pair.excitation {
                        Excitation::Dof(e) => dphi[r] * modes.phi[(e, i)] + phi_r * dphi[e],
                        Excitation::Ground => {
                            -(dphi[r] * modes.participation[i] + phi_r * ws.dgam[p * m + i])
                        }
                    };
                }
            }
            let power = pair.kind.power();
            for k in 0..nw {
                let w = block.omega_rad_s[k];
                let poles = &ws.poles[k * m..(k + 1) * m];
                let poles2 = &ws.poles2[k * m..(k + 1) * m];
                let mut s = Complex64::new(0.0, 0.0);
                for (p, &a) in poles.iter().zip(&ws.coef) {
                    s += p * a;
                }
                let fac = w.powi(power);
                let s_abs = s.norm();
                mag[row] = fac * s_abs;
                // d|H| = Re(g dS) with g = omega^p conj(S) / |S|.
                let g = if s_abs > 0.0 {
                    s.conj() * (fac / s_abs)
                } else {
                    Complex64::new(0.0, 0.0)
                };
                // B_i = a_i / D_i^2 (1 + j omega dc_i/dlambda_i).
                ws.b.clear();
                for ((q, a), dc) in poles2.iter().zip(&ws.coef).zip(&ws.dc_dlam) {
                    ws.b.push(q * a * Complex64::new(1.0, w * dc));
                }
                for (p, col) in columns[..n_s].iter().enumerate() {
                    let Some(col) = *col else { continue };
                    let (dcoef, dlam) =
                        (&ws.dcoef[p * m..(p + 1) * m], &ws.dlam[p * m..(p + 1) * m]);
                    let mut ds = Complex64::new(0.0, 0.0);
                    for (((pole, b), da), dl) in poles.iter().zip(&ws.b).zip(dcoef).zip(dlam) {
                        ds += pole * da - b * dl;
                    }
                    jac[(row, col)] = (g * ds).re;
                }
                // Damping variables: dS = -sum_i a_i / D_i^2 j omega dc_i/dd.
                for (d, col) in columns[n_s..].iter().enumerate().take(n_d) {
                    let Some(col) = *col else { continue };
                    let ds = match damping {
                        Damping::Rayleigh { .. } => {
                            let mut acc = Complex64::new(0.0, 0.0);
                            for ((q, a), wn) in poles2.iter().zip(&ws.coef).zip(omega_n) {
                                let dc = if d == 0 { 1.0 } else { wn * wn };
                                acc += q * (a * dc);
                            }
                            acc
                        }
                        Damping::Caughey { .. } => poles2[d] * (ws.coef[d] * 2.0 * omega_n[d]),
                    };
                    // -j omega ds
                    let ds = Complex64::new(0.0, -w) * ds;
                    jac[(row, col)] = (g * ds).re;
                }
                row += 1;
            }
        }
    }
    Ok(())
}
