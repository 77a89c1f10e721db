//! FRFs at the observed channels, by modal superposition over the lowest modes of any
//! [`ModeSolver`] (dense, sparse partial, reduced basis).
//!
//! `H_re(omega) = (j omega)^p sum_i coef_i / (omega_i^2 - omega^2 + j c_i omega)` (paper
//! Eqs. 7, 10-12 for a force at DOF `e`, `coef_i = phi_r,i phi_e,i`; Eqs. 15-16 for
//! ground excitation, `coef_i = -phi_r,i Gamma_i`, `Gamma_i = phi_i^T M(beta) iota`),
//! with mass-normalised shapes and modal damping `c_i`:
//! - Rayleigh (Eq. 8), `C = a0 M + a1 K`: `c_i = a0 + a1 omega_i^2`; coordinates
//!   `ln_a0` (a0 in 1/s) and `ln_a1` (a1 in s);
//! - modal (Caughey, Eq. 9): `c_i = 2 xi_i omega_i`; coordinates `ln_xi1..`, one per mode
//!   kept.
//!
//! Only the lowest `n_modes` modes enter the sum: with every mode kept it is the direct
//! solve of Eq. (1) (tested); with fewer, the residual flexibility of the dropped modes is
//! left out, which the study chooses (keep the modes up to well above the band).
//!
//! An exponential window of time constant `tau` on force and response turns the measured
//! FRF into `H(omega - j/tau)` (see [`crate::signal::windows`]): with `eps = 1/tau` the same
//! sum with `omega_i'^2 = omega_i^2 + eps^2 + c_i eps`, `c_i' = c_i + 2 eps`, times
//! `(j omega + eps)^p` instead of `(j omega)^p`. Each block has its own window (or none).
//!
//! Coordinates: the structural ones of the [`Parametrisation`], then the damping ones.
//! Outputs, block by block, pair-major then frequency: `|H|`, `ln |H|`, or `(Re H, Im H)`
//! interleaved ([`FrfOutput`]).
//!
//! Magnitudes (the likelihood's inner loop) go through the fused kernel of
//! [`ModalFrf::magnitudes`] on the modes at the observed DOFs, the window applied to the
//! modal parameters and its gain `|(j omega + eps)^p| / omega^p` per value afterwards; with
//! a solver that gives [`Modes`] directly ([`ModeSolver::modes`]: the dense solver, with
//! the shear frame's tridiagonal fast path) the natural frequencies are taken as solved
//! and an evaluation of a model of up to six DOFs allocates nothing.

use std::sync::Arc;

use num_complex::Complex64;

use super::modal::ModeSolver;
use super::{Parametrisation, Predict};
use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock, FrfKind, FrfPair, ModalFrf};
use crate::modal::Modes;
use crate::model::StructuralModel;

/// The damping model of an [`FrfPredictor`] and its coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrfDamping {
    /// `ln a0`, `ln a1` of `C = a0 M + a1 K`.
    Rayleigh,
    /// `ln xi_i` of every mode kept.
    Modal,
}

/// What an [`FrfPredictor`] writes per FRF value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrfOutput {
    Magnitude,
    LogMagnitude,
    /// Real and imaginary parts, interleaved.
    Complex,
}

impl FrfOutput {
    fn width(self) -> usize {
        match self {
            FrfOutput::Complex => 2,
            _ => 1,
        }
    }
}

/// How an [`FrfPredictor`] sums and reports: damping model, output form, and the number
/// of lowest modes in the sums.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrfOptions {
    pub damping: FrfDamping,
    pub output: FrfOutput,
    pub n_modes: usize,
}

/// One block as the predictor evaluates it: pairs on local shape rows.
#[derive(Debug, Clone)]
struct LocalBlock {
    omega_rad_s: Vec<f64>,
    /// `(response row, excitation row or None for ground, power p)`.
    pairs: Vec<(usize, Option<usize>, i32)>,
    eps_per_s: f64,
}

/// FRFs of a model at observed pairs and frequencies (see the module docs).
#[derive(Debug, Clone)]
pub struct FrfPredictor<S: ModeSolver> {
    solver: S,
    model: Arc<StructuralModel>,
    params: Parametrisation,
    damping: FrfDamping,
    /// Per damping variable (`a0`, `a1` or `xi_i`): its value when held fixed (no
    /// coordinate), `None` when sampled.
    fixed_damping: Vec<Option<f64>>,
    output: FrfOutput,
    n_modes: usize,
    /// Model DOFs whose shape entries are solved for (all of them under ground excitation).
    dofs: Vec<usize>,
    /// `dofs` is every model DOF in order (shapes copied whole).
    all_dofs: bool,
    blocks: Vec<LocalBlock>,
    /// The blocks on the local shape rows, for [`ModalFrf`].
    frf_blocks: Vec<FrfBlock>,
    /// Per value: `|(j omega + eps)^p| / omega^p`, the window's change of the kind factor.
    window_gain: Vec<f64>,
    /// Per block: every gain is exactly 1 (receptance, or no window).
    unit_gain: Vec<bool>,
    /// Per block: index of its first value.
    offsets: Vec<usize>,
    n_values: usize,
}

/// Scratch memory of an [`FrfPredictor`].
pub struct FrfWorkspace<W> {
    solver: W,
    alpha: Vec<f64>,
    beta: Vec<f64>,
    eigenvalues: Vec<f64>,
    shapes: Vec<f64>,
    participation: Vec<f64>,
    modal_c: Vec<f64>,
    /// Damping variables in their units (`a0`, `a1` or `xi_i`).
    damping: Vec<f64>,
    /// The modes at the observed DOFs (shape rows in the order of `dofs`).
    modes: Modes,
    /// Unwindowed natural frequencies while `modes` holds windowed ones.
    omega: Vec<f64>,
    c_window: Vec<f64>,
    frfs: Vec<ModalFrf>,
}

impl<S: ModeSolver> FrfPredictor<S> {
    /// `blocks[b]` observed through an exponential window of `window_tau_s[b]` seconds
    /// (`None`: no window).
    pub fn new(
        solver: S,
        model: Arc<StructuralModel>,
        params: Parametrisation,
        options: FrfOptions,
        blocks: &[FrfBlock],
        window_tau_s: &[Option<f64>],
    ) -> Result<Self> {
        let FrfOptions {
            damping,
            output,
            n_modes,
        } = options;
        let n_dof = model.n_dof();
        if solver.n_dof() != n_dof {
            return Err(Error::Usage(format!(
                "mode solver of {} DOFs for a model of {n_dof}",
                solver.n_dof()
            )));
        }
        if n_modes == 0 || n_modes > n_dof {
            return Err(Error::Usage(format!(
                "n_modes must be between 1 and {n_dof} (the model's DOFs), got {n_modes}"
            )));
        }
        if window_tau_s.len() != blocks.len() {
            return Err(Error::Usage(format!(
                "{} window time constants for {} FRF blocks",
                window_tau_s.len(),
                blocks.len()
            )));
        }
        let dofs = needed_dofs(blocks, n_dof)?;
        let mut local = Vec::with_capacity(blocks.len());
        for (b, tau) in blocks.iter().zip(window_tau_s) {
            local.push(local_block(b, *tau, &dofs)?);
        }
        let frf_blocks: Vec<FrfBlock> = local.iter().map(LocalBlock::frf_block).collect();
        let (mut window_gain, mut offsets, mut unit_gain) = (Vec::new(), Vec::new(), Vec::new());
        for b in &local {
            offsets.push(window_gain.len());
            let gains = b.window_gains();
            unit_gain.push(gains.iter().all(|&g| g == 1.0));
            window_gain.extend(gains);
        }
        let n_vars = match damping {
            FrfDamping::Rayleigh => 2,
            FrfDamping::Modal => n_modes,
        };
        Ok(FrfPredictor {
            solver,
            model,
            params,
            damping,
            fixed_damping: vec![None; n_vars],
            output,
            n_modes,
            all_dofs: dofs.iter().copied().eq(0..n_dof),
            dofs,
            blocks: local,
            frf_blocks,
            n_values: window_gain.len(),
            window_gain,
            unit_gain,
            offsets,
        })
    }

    /// The same predictor with damping variables held fixed: `values[j]` is variable
    /// `j`'s value (`a0` in 1/s, `a1` in s, or `xi_j`) or `None` to keep it sampled.
    pub fn with_fixed_damping(mut self, values: Vec<Option<f64>>) -> Result<Self> {
        let bad = values
            .iter()
            .flatten()
            .any(|x| !(x.is_finite() && *x > 0.0));
        if values.len() != self.fixed_damping.len() || bad {
            return Err(Error::Usage(format!(
                "{} fixed damping values (positive, or none) for {} damping variables",
                values.len(),
                self.fixed_damping.len()
            )));
        }
        self.fixed_damping = values;
        Ok(self)
    }

    /// Number of damping coordinates (after the structural ones).
    pub fn n_damping(&self) -> usize {
        self.fixed_damping.iter().filter(|v| v.is_none()).count()
    }

    /// The damping variables in their units from the damping coordinates (logarithms)
    /// and the fixed values.
    fn damping_values(&self, theta_damping: &[f64], out: &mut Vec<f64>) {
        let mut free = theta_damping.iter();
        out.clear();
        for v in &self.fixed_damping {
            out.push(match v {
                Some(x) => *x,
                None => free.next().map_or(f64::NAN, |t| t.exp()),
            });
        }
    }

    pub fn parametrisation(&self) -> &Parametrisation {
        &self.params
    }

    /// Modal damping coefficients `c_i` (1/s) from the damping variables `d` (units).
    fn modal_damping(&self, d: &[f64], eigenvalues: &[f64], c: &mut [f64]) {
        match self.damping {
            FrfDamping::Rayleigh => {
                let (a0, a1) = (d[0], d[1]);
                for (ci, &l) in c.iter_mut().zip(eigenvalues) {
                    *ci = a0 + a1 * l;
                }
            }
            FrfDamping::Modal => {
                for ((ci, &l), &xi) in c.iter_mut().zip(eigenvalues).zip(d) {
                    *ci = 2.0 * xi * l.sqrt();
                }
            }
        }
    }

    /// Modal damping coefficients `c_i` (1/s) from the damping variables `d` (units) and
    /// the natural frequencies `omega_i` (rad/s): `a0 + a1 omega_i^2` or `2 xi_i omega_i`.
    fn modal_damping_of_omega(&self, d: &[f64], omega: &[f64], c: &mut [f64]) {
        match self.damping {
            FrfDamping::Rayleigh => {
                let (a0, a1) = (d[0], d[1]);
                for (ci, &w) in c.iter_mut().zip(omega) {
                    *ci = a0 + a1 * w * w;
                }
            }
            FrfDamping::Modal => {
                for ((ci, &w), &xi) in c.iter_mut().zip(omega).zip(d) {
                    *ci = 2.0 * xi * w;
                }
            }
        }
    }

    /// The lowest modes at `ws.alpha`, `ws.beta` into `ws.modes` (shape rows of `dofs`):
    /// as the solver gives them when it gives [`Modes`], else from its eigenvalues and
    /// shapes. [`Error::Model`] when a natural frequency is not positive.
    fn local_modes<W>(&self, ws: &mut FrfWorkspace<W>) -> Result<()>
    where
        S: ModeSolver<Workspace = W>,
    {
        let (n, nd) = (self.n_modes, self.dofs.len());
        let modes = &mut ws.modes;
        if let Some(full) = self.solver.modes(&ws.alpha, &ws.beta, n, &mut ws.solver)? {
            if self.all_dofs && full.phi.ncols() == n {
                // the solver's modes are these: exchanged, not copied (the solver
                // overwrites what it gets back on its next solve)
                std::mem::swap(modes, full);
            } else {
                modes.omega_rad_s.clear();
                modes.omega_rad_s.extend_from_slice(&full.omega_rad_s);
                modes.participation.clear();
                modes.participation.extend_from_slice(&full.participation);
                for i in 0..n {
                    for (row, &d) in self.dofs.iter().enumerate() {
                        modes.phi[(row, i)] = full.phi[(d, i)];
                    }
                }
            }
        } else {
            self.solver.lowest_modes(
                &ws.alpha,
                &ws.beta,
                &self.dofs,
                &mut ws.solver,
                &mut ws.eigenvalues,
                &mut ws.shapes,
            )?;
            modes.omega_rad_s.clear();
            modes
                .omega_rad_s
                .extend(ws.eigenvalues.iter().map(|l| l.max(0.0).sqrt()));
            modes.phi.as_mut_slice().copy_from_slice(&ws.shapes);
            if nd == self.model.n_dof() {
                self.participation(ws);
            }
            ws.modes.participation.clear();
            ws.modes.participation.extend_from_slice(&ws.participation);
        }
        // branch-free over the modes (NaN fails `w > 0`), the message only on failure
        let omega = &ws.modes.omega_rad_s;
        let admissible = omega
            .iter()
            .fold(true, |ok, &w| ok & (w > 0.0) & (w < f64::INFINITY));
        match admissible {
            true => Ok(()),
            false => {
                let w = omega.iter().find(|w| !(**w > 0.0 && w.is_finite()));
                Err(Error::Model(format!(
                    "a model natural frequency is {} rad/s (not positive)",
                    w.copied().unwrap_or(f64::NAN)
                )))
            }
        }
    }

    /// Magnitudes `|H|` of every block from `ws.modes` and `ws.modal_c`, each block's
    /// window applied to the modal parameters (computed once per run of blocks with the
    /// same window) and its gain to the values.
    fn write_magnitudes<W>(&self, ws: &mut FrfWorkspace<W>, out: &mut [f64]) -> Result<()> {
        let modes = &mut ws.modes;
        ws.omega.copy_from_slice(&modes.omega_rad_s);
        // The window of the modal parameters currently in `modes` / `c_window`.
        let mut current_eps = 0.0;
        for (b, frf) in ws.frfs.iter_mut().enumerate() {
            let eps = self.blocks[b].eps_per_s;
            let range = self.offsets[b]..self.offsets[b] + frf.len();
            if eps == 0.0 {
                if current_eps != 0.0 {
                    modes.omega_rad_s.copy_from_slice(&ws.omega);
                    current_eps = 0.0;
                }
                frf.magnitudes(modes, &ws.modal_c, &mut out[range])?;
                continue;
            }
            if eps != current_eps {
                for i in 0..self.n_modes {
                    let (w, c) = (ws.omega[i], ws.modal_c[i]);
                    modes.omega_rad_s[i] = (w * w + eps * eps + c * eps).sqrt();
                    ws.c_window[i] = c + 2.0 * eps;
                }
                current_eps = eps;
            }
            frf.magnitudes(modes, &ws.c_window, &mut out[range.clone()])?;
            if !self.unit_gain[b] {
                for (o, g) in out[range.clone()].iter_mut().zip(&self.window_gain[range]) {
                    *o *= g;
                }
            }
        }
        if current_eps != 0.0 {
            modes.omega_rad_s.copy_from_slice(&ws.omega);
        }
        Ok(())
    }

    /// Complex values from the solver's eigenvalues and shapes (damping in `ws.damping`).
    fn predict_complex(&self, ws: &mut FrfWorkspace<S::Workspace>, out: &mut [f64]) -> Result<()> {
        self.solver.lowest_modes(
            &ws.alpha,
            &ws.beta,
            &self.dofs,
            &mut ws.solver,
            &mut ws.eigenvalues,
            &mut ws.shapes,
        )?;
        if let Some(l) = ws
            .eigenvalues
            .iter()
            .find(|l| l.partial_cmp(&&0.0) != Some(std::cmp::Ordering::Greater))
        {
            return Err(Error::Model(format!(
                "a model eigenvalue is {l} (not positive)"
            )));
        }
        if self.dofs.len() == self.model.n_dof() {
            self.participation(ws);
        }
        let mut c = std::mem::take(&mut ws.modal_c);
        self.modal_damping(&ws.damping, &ws.eigenvalues, &mut c);
        ws.modal_c = c;
        let mut start = 0;
        for b in &self.blocks {
            let len = b.pairs.len() * b.omega_rad_s.len() * self.output.width();
            self.write_block(b, ws, &mut out[start..start + len]);
            start += len;
        }
        Ok(())
    }

    /// `Gamma_i = phi_i^T M(beta) iota` from the full shapes in `ws` (ground excitation).
    fn participation<W>(&self, ws: &mut FrfWorkspace<W>) {
        let m_iota = self.model.mass(&ws.beta) * self.model.ground_influence();
        let n = self.dofs.len();
        for (i, g) in ws.participation.iter_mut().enumerate() {
            let phi = &ws.shapes[i * n..(i + 1) * n];
            *g = phi.iter().zip(m_iota.iter()).map(|(a, b)| a * b).sum();
        }
    }

    /// Writes the block's values from the solved modes.
    fn write_block<W>(&self, b: &LocalBlock, ws: &FrfWorkspace<W>, out: &mut [f64]) {
        let (nd, eps) = (self.dofs.len(), b.eps_per_s);
        let width = self.output.width();
        let mut k = 0;
        for &(r, e, p) in &b.pairs {
            for &w in &b.omega_rad_s {
                let mut h = Complex64::new(0.0, 0.0);
                for i in 0..self.n_modes {
                    let (l, c) = (ws.eigenvalues[i], ws.modal_c[i]);
                    let phi_r = ws.shapes[i * nd + r];
                    let coef = match e {
                        Some(e) => phi_r * ws.shapes[i * nd + e],
                        None => -phi_r * ws.participation[i],
                    };
                    let den = Complex64::new(l + eps * eps + c * eps - w * w, (c + 2.0 * eps) * w);
                    h += coef / den;
                }
                h *= Complex64::new(eps, w).powi(p);
                match self.output {
                    FrfOutput::Magnitude => out[k] = h.norm(),
                    FrfOutput::LogMagnitude => out[k] = h.norm().ln(),
                    FrfOutput::Complex => {
                        out[k] = h.re;
                        out[k + 1] = h.im;
                    }
                }
                k += width;
            }
        }
    }
}

/// Block `b` on the local shape rows of `dofs`, observed through a window of `tau` s.
fn local_block(b: &FrfBlock, tau: Option<f64>, dofs: &[usize]) -> Result<LocalBlock> {
    let row = |d: usize| dofs.binary_search(&d).unwrap_or(0);
    let eps_per_s = match tau {
        None => 0.0,
        Some(t) if t.is_finite() && t > 0.0 => 1.0 / t,
        Some(t) => {
            return Err(Error::Usage(format!(
                "exponential window time constant must be positive, got {t} s"
            )))
        }
    };
    if let Some(w) = b.omega_rad_s.iter().find(|w| !(w.is_finite() && **w > 0.0)) {
        return Err(Error::Usage(format!(
            "frequencies must be finite and positive, got {w} rad/s"
        )));
    }
    let pairs = b
        .pairs
        .iter()
        .map(|p| {
            let e = match p.excitation {
                Excitation::Dof(e) => Some(row(e)),
                Excitation::Ground => None,
            };
            (row(p.response), e, p.kind.power())
        })
        .collect();
    Ok(LocalBlock {
        omega_rad_s: b.omega_rad_s.clone(),
        pairs,
        eps_per_s,
    })
}

impl LocalBlock {
    /// The block as [`ModalFrf`] takes it (local rows).
    fn frf_block(&self) -> FrfBlock {
        let pairs = self
            .pairs
            .iter()
            .map(|&(r, e, p)| FrfPair {
                response: r,
                excitation: e.map_or(Excitation::Ground, Excitation::Dof),
                kind: match p {
                    0 => FrfKind::Receptance,
                    1 => FrfKind::Mobility,
                    _ => FrfKind::Accelerance,
                },
            })
            .collect();
        FrfBlock {
            omega_rad_s: self.omega_rad_s.clone(),
            pairs,
        }
    }

    /// Per value: `|(j omega + eps)^p| / omega^p = (1 + (eps / omega)^2)^(p / 2)`.
    fn window_gains(&self) -> Vec<f64> {
        let eps = self.eps_per_s;
        let per_pair = |&(_, _, p): &(usize, Option<usize>, i32)| {
            let half_power = 0.5 * f64::from(p);
            self.omega_rad_s
                .iter()
                .map(move |w| (1.0 + (eps / w).powi(2)).powf(half_power))
        };
        self.pairs.iter().flat_map(per_pair).collect()
    }
}

/// Sorted model DOFs the pairs need; every DOF when a pair is ground-excited.
fn needed_dofs(blocks: &[FrfBlock], n_dof: usize) -> Result<Vec<usize>> {
    let mut dofs = Vec::new();
    for p in blocks.iter().flat_map(|b| &b.pairs) {
        let e = match p.excitation {
            Excitation::Dof(e) => Some(e),
            Excitation::Ground => None,
        };
        if p.response >= n_dof || e.is_some_and(|e| e >= n_dof) {
            return Err(Error::Usage(format!(
                "FRF pair {p:?} refers to a DOF outside the {n_dof}-DOF model"
            )));
        }
        if e.is_none() {
            return Ok((0..n_dof).collect());
        }
        dofs.push(p.response);
        dofs.extend(e);
    }
    dofs.sort_unstable();
    dofs.dedup();
    Ok(dofs)
}

impl<S: ModeSolver> Predict for FrfPredictor<S> {
    type Workspace = FrfWorkspace<S::Workspace>;

    fn n_params(&self) -> usize {
        self.params.len() + self.n_damping()
    }

    fn n_outputs(&self) -> usize {
        self.n_values * self.output.width()
    }

    fn param_names(&self) -> Vec<String> {
        let mut names = self.params.names();
        let all: Vec<String> = match self.damping {
            FrfDamping::Rayleigh => vec!["ln_a0".to_string(), "ln_a1".to_string()],
            FrfDamping::Modal => (1..=self.n_modes).map(|i| format!("ln_xi{i}")).collect(),
        };
        let free = all.into_iter().zip(&self.fixed_damping);
        names.extend(free.filter(|(_, f)| f.is_none()).map(|(n, _)| n));
        names
    }

    fn workspace(&self) -> Self::Workspace {
        let (n, nd) = (self.n_modes, self.dofs.len());
        FrfWorkspace {
            solver: self.solver.workspace(),
            alpha: Vec::new(),
            beta: Vec::new(),
            eigenvalues: vec![0.0; n],
            shapes: vec![0.0; n * nd],
            participation: vec![0.0; n],
            modal_c: vec![0.0; n],
            damping: Vec::with_capacity(self.fixed_damping.len()),
            modes: Modes {
                omega_rad_s: vec![0.0; n],
                phi: nalgebra::DMatrix::zeros(nd, n),
                participation: vec![0.0; n],
            },
            omega: vec![0.0; n],
            c_window: vec![0.0; n],
            frfs: self
                .frf_blocks
                .iter()
                .map(|b| ModalFrf::new(vec![b.clone()]))
                .collect(),
        }
    }

    fn predict(&self, theta: &[f64], ws: &mut Self::Workspace, out: &mut [f64]) -> Result<()> {
        let n_struct = self.params.len();
        if theta.len() != self.n_params() || out.len() != self.n_outputs() {
            return Err(Error::Usage(format!(
                "FRF predictor: {} coordinates (need {}), {} outputs (need {})",
                theta.len(),
                self.n_params(),
                out.len(),
                self.n_outputs()
            )));
        }
        self.params
            .apply(&theta[..n_struct], &mut ws.alpha, &mut ws.beta);
        self.damping_values(&theta[n_struct..], &mut ws.damping);
        if self.output == FrfOutput::Complex {
            return self.predict_complex(ws, out);
        }
        self.local_modes(ws)?;
        let mut c = std::mem::take(&mut ws.modal_c);
        self.modal_damping_of_omega(&ws.damping, &ws.modes.omega_rad_s, &mut c);
        ws.modal_c = c;
        self.write_magnitudes(ws, out)?;
        if self.output == FrfOutput::LogMagnitude {
            out.iter_mut().for_each(|v| *v = v.ln());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
