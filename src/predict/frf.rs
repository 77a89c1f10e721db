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

use std::sync::Arc;

use num_complex::Complex64;

use super::modal::ModeSolver;
use super::{Parametrisation, Predict};
use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock};
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
    output: FrfOutput,
    n_modes: usize,
    /// Model DOFs whose shape entries are solved for (all of them under ground excitation).
    dofs: Vec<usize>,
    blocks: Vec<LocalBlock>,
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
        let row = |d: usize| dofs.binary_search(&d).unwrap_or(0);
        let mut local = Vec::with_capacity(blocks.len());
        let mut n_values = 0;
        for (b, tau) in blocks.iter().zip(window_tau_s) {
            let eps_per_s = match tau {
                None => 0.0,
                Some(t) if t.is_finite() && *t > 0.0 => 1.0 / t,
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
                .collect::<Vec<_>>();
            n_values += pairs.len() * b.omega_rad_s.len();
            local.push(LocalBlock {
                omega_rad_s: b.omega_rad_s.clone(),
                pairs,
                eps_per_s,
            });
        }
        Ok(FrfPredictor {
            solver,
            model,
            params,
            damping,
            output,
            n_modes,
            dofs,
            blocks: local,
            n_values,
        })
    }

    /// Number of damping coordinates (after the structural ones).
    pub fn n_damping(&self) -> usize {
        match self.damping {
            FrfDamping::Rayleigh => 2,
            FrfDamping::Modal => self.n_modes,
        }
    }

    pub fn parametrisation(&self) -> &Parametrisation {
        &self.params
    }

    /// Modal damping coefficients `c_i` (1/s) from the damping coordinates.
    fn modal_damping(&self, theta_damping: &[f64], eigenvalues: &[f64], c: &mut [f64]) {
        match self.damping {
            FrfDamping::Rayleigh => {
                let (a0, a1) = (theta_damping[0].exp(), theta_damping[1].exp());
                for (ci, &l) in c.iter_mut().zip(eigenvalues) {
                    *ci = a0 + a1 * l;
                }
            }
            FrfDamping::Modal => {
                for ((ci, &l), &ln_xi) in c.iter_mut().zip(eigenvalues).zip(theta_damping) {
                    *ci = 2.0 * ln_xi.exp() * l.sqrt();
                }
            }
        }
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
        match self.damping {
            FrfDamping::Rayleigh => names.extend(["ln_a0".to_string(), "ln_a1".to_string()]),
            FrfDamping::Modal => names.extend((1..=self.n_modes).map(|i| format!("ln_xi{i}"))),
        }
        names
    }

    fn workspace(&self) -> Self::Workspace {
        FrfWorkspace {
            solver: self.solver.workspace(),
            alpha: Vec::new(),
            beta: Vec::new(),
            eigenvalues: vec![0.0; self.n_modes],
            shapes: vec![0.0; self.n_modes * self.dofs.len()],
            participation: vec![0.0; self.n_modes],
            modal_c: vec![0.0; self.n_modes],
        }
    }

    fn predict(&self, theta: &[f64], ws: &mut Self::Workspace, out: &mut [f64]) -> Result<()> {
        let n_struct = self.params.len();
        self.params
            .apply(&theta[..n_struct], &mut ws.alpha, &mut ws.beta);
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
        self.modal_damping(&theta[n_struct..], &ws.eigenvalues, &mut c);
        ws.modal_c = c;
        let mut start = 0;
        for b in &self.blocks {
            let len = b.pairs.len() * b.omega_rad_s.len() * self.output.width();
            self.write_block(b, ws, &mut out[start..start + len]);
            start += len;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
