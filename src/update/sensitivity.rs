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
use crate::frf::{Excitation, FrfBlock, FrfPair};
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
    /// Per pair and frequency: `dr_k / d|H_k|`.
    rf: Vec<f64>,
    /// Per pair, mode-major: `u = Re(g / D)`, `x = Re(g / D^2) - dc/dlambda y`,
    /// `y = omega Im(g / D^2)`.
    u: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    /// Per column: mode weights of `x` (structural) or `y` (Rayleigh damping).
    cx: Vec<f64>,
    cy: Vec<f64>,
    zeros: Vec<f64>,
}

/// How residuals follow from magnitudes: `r_k = w_k (|H_k| - |H^E_k|)`, or
/// `r_k = w_k (ln |H_k| - ln |H^E_k|)` when `log`; the Jacobian rows are scaled by
/// `dr_k / d|H_k|` (`w_k`, or `w_k / |H_k|`; zero where that is not finite).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RowScale<'a> {
    pub weights: &'a [f64],
    pub log: bool,
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
/// receives `dr/d theta_v = dr/d|H| d|H|/d theta_v` (see [`RowScale`]; variables
/// mapped to `None` are skipped).
///
/// With `g = omega^p conj(S) / |S|`, `d|H| = Re(g dS)` splits into real per-mode
/// frequency arrays, so every column is a short sum of contiguous `axpy`s:
/// - structural `p`: `sum_i da_pi Re(g/D_i) - dlambda_pi a_i [Re(g/D_i^2) -
///   dc_i/dlambda_i omega Im(g/D_i^2)]`;
/// - damping `d`: `sum_i a_i dc_i/dd omega Im(g/D_i^2)` (from `dS = -j omega sum_i a_i
///   dc_i / D_i^2`, and `Re(-j z) = Im(z)`).
///
/// On x86-64 CPUs with AVX2 the same code is compiled a second time with 256-bit
/// vectors and chosen at run time; without FMA contraction both give bit-identical
/// results.
#[allow(clippy::too_many_arguments)]
pub(crate) fn magnitude_jacobian(
    model: &StructuralModel,
    mass: &DMatrix<f64>,
    modes: &Modes,
    m: usize,
    damping: &Damping,
    blocks: &[FrfBlock],
    rows: RowScale,
    columns: &[Option<usize>],
    ws: &mut SensitivityWorkspace,
    mag: &mut [f64],
    jac: &mut DMatrix<f64>,
) -> Result<()> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        return unsafe {
            magnitude_jacobian_avx2(
                model, mass, modes, m, damping, blocks, rows, columns, ws, mag, jac,
            )
        };
    }
    magnitude_jacobian_body(
        model, mass, modes, m, damping, blocks, rows, columns, ws, mag, jac,
    )
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn magnitude_jacobian_avx2(
    model: &StructuralModel,
    mass: &DMatrix<f64>,
    modes: &Modes,
    m: usize,
    damping: &Damping,
    blocks: &[FrfBlock],
    rows: RowScale,
    columns: &[Option<usize>],
    ws: &mut SensitivityWorkspace,
    mag: &mut [f64],
    jac: &mut DMatrix<f64>,
) -> Result<()> {
    magnitude_jacobian_body(
        model, mass, modes, m, damping, blocks, rows, columns, ws, mag, jac,
    )
}

/// `dst[k] = scale_k sum_i (cu_i u[i nw + k] + cx_i x[i nw + k])` with `nw =
/// dst.len()`: the output stays in registers across the modes, 8 frequencies at a time.
#[inline(always)]
fn combine(dst: &mut [f64], scale: &[f64], cu: &[f64], u: &[f64], cx: &[f64], x: &[f64]) {
    const W: usize = 8;
    let nw = dst.len();
    let mut k = 0;
    while k + W <= nw {
        let mut acc = [0.0; W];
        for (i, (&a, &b)) in cu.iter().zip(cx).enumerate() {
            let ui = &u[i * nw + k..i * nw + k + W];
            let xi = &x[i * nw + k..i * nw + k + W];
            for t in 0..W {
                acc[t] += a * ui[t] + b * xi[t];
            }
        }
        let sc = &scale[k..k + W];
        for t in 0..W {
            acc[t] *= sc[t];
        }
        dst[k..k + W].copy_from_slice(&acc);
        k += W;
    }
    for (kk, d) in dst.iter_mut().enumerate().skip(k) {
        let mut acc = 0.0;
        for (i, (&a, &b)) in cu.iter().zip(cx).enumerate() {
            acc += a * u[i * nw + kk] + b * x[i * nw + kk];
        }
        *d = acc * scale[kk];
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn magnitude_jacobian_body(
    model: &StructuralModel,
    mass: &DMatrix<f64>,
    modes: &Modes,
    m: usize,
    damping: &Damping,
    blocks: &[FrfBlock],
    rows: RowScale,
    columns: &[Option<usize>],
    ws: &mut SensitivityWorkspace,
    mag: &mut [f64],
    jac: &mut DMatrix<f64>,
) -> Result<()> {
    let n = modes.phi.nrows();
    let n_s = model.n_alpha() + model.n_beta();
    eigen_derivatives(model, mass, modes, m, ws)?;
    let omega_n = &modes.omega_rad_s[..m];
    modal_damping(damping, omega_n, ws)?;
    let n_d = columns.len() - n_s;
    for v in [&mut ws.cx, &mut ws.cy, &mut ws.zeros] {
        v.clear();
        v.resize(m, 0.0);
    }
    let mut row = 0;
    for block in blocks {
        let omega = &block.omega_rad_s[..];
        let nw = omega.len();
        pole_factors(omega, omega_n, ws);
        for pair in &block.pairs {
            if pair.response >= n || matches!(pair.excitation, Excitation::Dof(e) if e >= n) {
                return Err(Error::Usage(format!(
                    "FRF pair {pair:?} outside a {n}-DOF model"
                )));
            }
            pair_coefficients(pair, modes, m, n_s, ws);
            let weights = &rows.weights[row..row + nw];
            magnitudes_and_gain(
                omega,
                pair.kind.power(),
                weights,
                rows.log,
                ws,
                &mut mag[row..row + nw],
            );
            mode_projections(omega, m, ws);
            structural_columns(&columns[..n_s], m, row, nw, ws, jac);
            damping_columns(&columns[n_s..], n_d, damping, omega_n, row, nw, ws, jac);
            row += nw;
        }
    }
    Ok(())
}

/// Modal damping `c_i` (Rayleigh or Caughey) into `ws.c` and its slope through the
/// structure, `dc_i / d lambda_i`, into `ws.dc_dlam`.
#[inline(always)]
fn modal_damping(damping: &Damping, omega_n: &[f64], ws: &mut SensitivityWorkspace) -> Result<()> {
    let m = omega_n.len();
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
    Ok(())
}

/// `1 / D_i` and `1 / D_i^2` with `D_i = lambda_i - omega^2 + j c_i omega`, mode-major
/// over the block's frequencies `omega` (rad/s); sizes the block's per-mode scratch.
#[inline(always)]
fn pole_factors(omega: &[f64], omega_n: &[f64], ws: &mut SensitivityWorkspace) {
    let (m, nw) = (omega_n.len(), omega.len());
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
    ws.rf.resize(nw, 0.0);
    for (i, (&wn, &c)) in omega_n.iter().zip(&ws.c).enumerate() {
        let range = i * nw..(i + 1) * nw;
        let (pr, pi) = (
            &mut ws.pole_re[range.clone()],
            &mut ws.pole_im[range.clone()],
        );
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
}

/// Modal coefficients of one FRF pair, `a_i = phi_ri phi_ei` (Eqs. 7, 10) or
/// `-phi_ri Gamma_i` (Eqs. 15, 16), into `ws.coef`, and their derivatives for every
/// structural variable into `ws.dcoef` (`p*m + i`).
#[inline(always)]
fn pair_coefficients(
    pair: &FrfPair,
    modes: &Modes,
    m: usize,
    n_s: usize,
    ws: &mut SensitivityWorkspace,
) {
    let n = modes.phi.nrows();
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
}

/// Magnitudes `|H_k| = omega^p |S|` of one pair into `out` (Eq. 17), the gain `g =
/// omega^p conj(S) / |S|` into `ws.g_re`/`ws.g_im` and the row factors `dr_k / d|H_k|`
/// (see [`RowScale`]) into `ws.rf`; `weights` are the pair's rows of `w_k`.
#[inline(always)]
fn magnitudes_and_gain(
    omega: &[f64],
    power: i32,
    weights: &[f64],
    log: bool,
    ws: &mut SensitivityWorkspace,
    out: &mut [f64],
) {
    let nw = omega.len();
    // S = sum_i a_i / D_i, |H| = omega^p |S|, g = omega^p conj(S) / |S|.
    let (g_re, g_im) = (&mut ws.g_re[..nw], &mut ws.g_im[..nw]);
    g_re.fill(0.0);
    g_im.fill(0.0);
    for (i, &a) in ws.coef.iter().enumerate() {
        let (pr, pi) = (
            &ws.pole_re[i * nw..(i + 1) * nw],
            &ws.pole_im[i * nw..(i + 1) * nw],
        );
        for k in 0..nw {
            g_re[k] += a * pr[k];
            g_im[k] += a * pi[k];
        }
    }
    let rf = &mut ws.rf[..nw];
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
        let w = weights[k];
        let f = if log { w / out[k] } else { w };
        rf[k] = if f.is_finite() { f } else { 0.0 };
    }
}

/// Per-mode frequency arrays of one pair: `u = Re(g / D)`, `y = omega Im(g / D^2)` and
/// `x = Re(g / D^2) - dc/dlambda y`, into `ws.u`, `ws.y`, `ws.x` (mode-major).
#[inline(always)]
fn mode_projections(omega: &[f64], m: usize, ws: &mut SensitivityWorkspace) {
    let nw = omega.len();
    let (g_re, g_im) = (&ws.g_re[..nw], &ws.g_im[..nw]);
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
}

/// Jacobian rows `row..row + nw` of the structural columns: `sum_i da_pi Re(g/D_i) -
/// dlambda_pi a_i [Re(g/D_i^2) - dc_i/dlambda_i omega Im(g/D_i^2)]`, scaled by `ws.rf`.
#[inline(always)]
fn structural_columns(
    columns: &[Option<usize>],
    m: usize,
    row: usize,
    nw: usize,
    ws: &mut SensitivityWorkspace,
    jac: &mut DMatrix<f64>,
) {
    let n_rows = jac.nrows();
    let (u, x) = (&ws.u[..m * nw], &ws.x[..m * nw]);
    for (p, col) in columns.iter().enumerate() {
        let Some(col) = *col else { continue };
        let dst = &mut jac.as_mut_slice()[col * n_rows + row..col * n_rows + row + nw];
        for ((cx, dl), a) in ws.cx.iter_mut().zip(&ws.dlam[p * m..]).zip(&ws.coef) {
            *cx = -dl * a;
        }
        combine(
            dst,
            &ws.rf[..nw],
            &ws.dcoef[p * m..(p + 1) * m],
            u,
            &ws.cx,
            x,
        );
    }
}

/// Jacobian rows `row..row + nw` of the first `n_d` damping columns: `sum_i a_i
/// dc_i/dd omega Im(g/D_i^2)`, scaled by `ws.rf`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn damping_columns(
    columns: &[Option<usize>],
    n_d: usize,
    damping: &Damping,
    omega_n: &[f64],
    row: usize,
    nw: usize,
    ws: &mut SensitivityWorkspace,
    jac: &mut DMatrix<f64>,
) {
    let (n_rows, m) = (jac.nrows(), omega_n.len());
    let y = &ws.y[..m * nw];
    for (d, col) in columns.iter().enumerate().take(n_d) {
        let Some(col) = *col else { continue };
        let dst = &mut jac.as_mut_slice()[col * n_rows + row..col * n_rows + row + nw];
        match damping {
            // dc_i/da0 = 1, dc_i/da1 = lambda_i.
            Damping::Rayleigh { .. } => {
                for ((cy, a), wn) in ws.cy.iter_mut().zip(&ws.coef).zip(omega_n) {
                    *cy = if d == 0 { *a } else { a * wn * wn };
                }
                combine(dst, &ws.rf[..nw], &ws.cy, y, &ws.zeros, y);
            }
            // dc_i/dxi_d = 2 omega_d for i = d only.
            Damping::Caughey { .. } => {
                let cy = ws.coef[d] * 2.0 * omega_n[d];
                let y = &y[d * nw..(d + 1) * nw];
                for ((o, v), sc) in dst.iter_mut().zip(y).zip(&ws.rf[..nw]) {
                    *o = cy * v * sc;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::FrfKind;

    #[test]
    fn vector_paths_agree_bit_for_bit() {
        let model =
            StructuralModel::shear_frame(&[4.64, 4.7, 4.6], &[1019.0, 1217.0, 1420.0]).unwrap();
        let (k, mass) = (
            model.stiffness(&[0.05, -0.02, 0.1]),
            model.mass(&[0.01, 0.0, -0.03]),
        );
        let modes = Modes::solve(&k, &mass, model.ground_influence(), None).unwrap();
        // 37 frequencies: four 8-wide chunks and a remainder.
        let omega_rad_s = (1..=37).map(|i| 1.3 * i as f64).collect();
        let pairs = [Excitation::Dof(1), Excitation::Ground]
            .into_iter()
            .map(|excitation| FrfPair {
                response: 2,
                excitation,
                kind: FrfKind::Accelerance,
            })
            .collect();
        let blocks = [FrfBlock { omega_rad_s, pairs }];
        for damping in [
            Damping::Rayleigh {
                a0_per_s: 0.1,
                a1_s: 1e-4,
            },
            Damping::Caughey {
                xi: vec![0.01, 0.02, 0.005],
            },
        ] {
            let columns: Vec<Option<usize>> = (0..6 + damping.n_params()).map(Some).collect();
            let run = |dispatched: bool| {
                let mut ws = SensitivityWorkspace::default();
                let mut mag = vec![0.0; 74];
                let mut jac = DMatrix::zeros(74, columns.len());
                let f = if dispatched {
                    magnitude_jacobian
                } else {
                    magnitude_jacobian_body
                };
                let weights: Vec<f64> = (0..74).map(|k| 1.0 + k as f64).collect();
                let rows = RowScale {
                    weights: &weights,
                    log: true,
                };
                f(
                    &model, &mass, &modes, 3, &damping, &blocks, rows, &columns, &mut ws, &mut mag,
                    &mut jac,
                )
                .unwrap();
                (mag, jac)
            };
            let ((m1, j1), (m2, j2)) = (run(true), run(false));
            assert!(m1.iter().zip(&m2).all(|(a, b)| a.to_bits() == b.to_bits()));
            assert!(j1
                .iter()
                .zip(j2.iter())
                .all(|(a, b)| a.to_bits() == b.to_bits()));
            assert!(j1.iter().all(|v| v.is_finite()) && j1.amax() > 0.0);
        }
    }
}
