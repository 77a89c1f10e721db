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

/// Relative gap below which two eigenvalues count as repeated (derivatives of the
/// modes are then undefined).
pub const REPEATED_EIGENVALUE_RTOL: f64 = 1e-10;

/// Scratch memory of [`magnitude_jacobian`].
#[derive(Debug, Clone, Default)]
pub(crate) struct SensitivityWorkspace {
    dlam: Vec<f64>,
    dphi: Vec<f64>,
    dgam: Vec<f64>,
    /// `1 / D_i` and `1 / D_i^2` per block, mode-major (`i * nw + k`).
    pole_re: Vec<f64>,
    pole_im: Vec<f64>,
    pole2_re: Vec<f64>,
    pole2_im: Vec<f64>,
    coef: Vec<f64>,
    dcoef: Vec<f64>,
    c: Vec<f64>,
    dc_dlam: Vec<f64>,
    /// Per pair and frequency: `g = omega^p conj(S) / |S|`.
    g_re: Vec<f64>,
    g_im: Vec<f64>,
    /// Per pair, mode-major: `u = Re(g / D)`, `x = Re(g / D^2) - dc/dlambda y`,
    /// `y = omega Im(g / D^2)`.
    u: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
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
///
/// With `g = omega^p conj(S) / |S|`, `d|H| = Re(g dS)` splits into real per-mode
/// frequency arrays, so every column is a short sum of contiguous `axpy`s:
/// - structural `p`: `sum_i da_pi Re(g/D_i) - dlambda_pi a_i [Re(g/D_i^2) -
///   dc_i/dlambda_i omega Im(g/D_i^2)]`;
/// - damping `d`: `sum_i a_i dc_i/dd omega Im(g/D_i^2)` (from `dS = -j omega sum_i a_i
///   dc_i / D_i^2`, and `Re(-j z) = Im(z)`).
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
    let n_rows = jac.nrows();
    let n_d = columns.len() - n_s;
    let mut row = 0;
    for block in blocks {
        let omega = &block.omega_rad_s[..];
        let nw = omega.len();
        for v in [
            &mut ws.pole_re,
            &mut ws.pole_im,
            &mut ws.pole2_re,
            &mut ws.pole2_im,
            &mut ws.u,
            &mut ws.x,
            &mut ws.y,
        ] {
            v.resize(m * nw, 0.0);
        }
        ws.g_re.resize(nw, 0.0);
        ws.g_im.resize(nw, 0.0);
        for (i, (&wn, &c)) in omega_n.iter().zip(&ws.c).enumerate() {
            let range = i * nw..(i + 1) * nw;
            let (pr, pi) = (&mut ws.pole_re[range.clone()], &mut ws.pole_im[range.clone()]);
            let (qr, qi) = (&mut ws.pole2_re[range.clone()], &mut ws.pole2_im[range]);
            for k in 0..nw {
                let w = omega[k];
                let (re, im) = (wn * wn - w * w, c * w);
                let inv = 1.0 / (re * re + im * im);
                let (a, b) = (re * inv, -im * inv);
                pr[k] = a;
                pi[k] = b;
                qr[k] = a * a - b * b;
                qi[k] = 2.0 * a * b;
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
            // S = sum_i a_i / D_i, |H| = omega^p |S|, g = omega^p conj(S) / |S|.
            let (g_re, g_im) = (&mut ws.g_re[..nw], &mut ws.g_im[..nw]);
            g_re.fill(0.0);
            g_im.fill(0.0);
            for (i, &a) in ws.coef.iter().enumerate() {
                let (pr, pi) = (&ws.pole_re[i * nw..(i + 1) * nw], &ws.pole_im[i * nw..(i + 1) * nw]);
                for k in 0..nw {
                    g_re[k] += a * pr[k];
                    g_im[k] += a * pi[k];
                }
            }
            let power = pair.kind.power();
            let out = &mut mag[row..row + nw];
            for k in 0..nw {
                let fac = match power {
                    0 => 1.0,
                    1 => omega[k],
                    _ => omega[k] * omega[k],
                };
                let s_abs = (g_re[k] * g_re[k] + g_im[k] * g_im[k]).sqrt();
                out[k] = fac * s_abs;
                let h = if s_abs > 0.0 { fac / s_abs } else { 0.0 };
                g_re[k] *= h;
                g_im[k] *= -h;
            }
            for i in 0..m {
                let range = i * nw..(i + 1) * nw;
                let (pr, pi) = (&ws.pole_re[range.clone()], &ws.pole_im[range.clone()]);
                let (qr, qi) = (&ws.pole2_re[range.clone()], &ws.pole2_im[range.clone()]);
                let dc = ws.dc_dlam[i];
                let (u, x, y) = (
                    &mut ws.u[range.clone()],
                    &mut ws.x[range.clone()],
                    &mut ws.y[range],
                );
                for k in 0..nw {
                    let (gr, gi) = (g_re[k], g_im[k]);
                    u[k] = gr * pr[k] - gi * pi[k];
                    let yk = omega[k] * (gr * qi[k] + gi * qr[k]);
                    x[k] = gr * qr[k] - gi * qi[k] - dc * yk;
                    y[k] = yk;
                }
            }
            for (p, col) in columns[..n_s].iter().enumerate() {
                let Some(col) = *col else { continue };
                let dst = &mut jac.as_mut_slice()[col * n_rows + row..col * n_rows + row + nw];
                dst.fill(0.0);
                for i in 0..m {
                    let cu = ws.dcoef[p * m + i];
                    let cx = -ws.dlam[p * m + i] * ws.coef[i];
                    let (u, x) = (&ws.u[i * nw..(i + 1) * nw], &ws.x[i * nw..(i + 1) * nw]);
                    for k in 0..nw {
                        dst[k] += cu * u[k] + cx * x[k];
                    }
                }
            }
            for (d, col) in columns[n_s..].iter().enumerate().take(n_d) {
                let Some(col) = *col else { continue };
                let dst = &mut jac.as_mut_slice()[col * n_rows + row..col * n_rows + row + nw];
                dst.fill(0.0);
                // dc_i / d(damping variable d).
                let modes_d = match damping {
                    Damping::Rayleigh { .. } => 0..m,
                    Damping::Caughey { .. } => d..d + 1,
                };
                for i in modes_d {
                    let dc = match damping {
                        Damping::Rayleigh { .. } if d == 0 => 1.0,
                        Damping::Rayleigh { .. } => omega_n[i] * omega_n[i],
                        Damping::Caughey { .. } => 2.0 * omega_n[i],
                    };
                    let cy = ws.coef[i] * dc;
                    let y = &ws.y[i * nw..(i + 1) * nw];
                    for k in 0..nw {
                        dst[k] += cy * y[k];
                    }
                }
            }
            row += nw;
        }
    }
    Ok(())
}
