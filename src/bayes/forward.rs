//! The forward model of the posterior: analytical FRF magnitudes `|H^A(theta)|` (Eq. 17)
//! on the long vector (Eqs. 18-19), with each block's exponential window applied to the
//! *model* exactly, so that the sampled damping is the structure's own.
//!
//! An exponential window `exp(-t / tau)` on force and response turns the measured FRF
//! into `H(omega - j/tau)` ([`crate::signal::windows`]). With `eps = 1/tau` that is the
//! ordinary modal sum with `omega_i' = sqrt(omega_i^2 + eps^2 + c_i eps)` and
//! `c_i' = c_i + 2 eps` (same mode-shape coefficients), times `|(j omega + eps)^p|`
//! instead of `omega^p` for mobility (`p = 1`) and accelerance (`p = 2`)
//! ([`exp_window_modal_parameters`](crate::signal::exp_window_modal_parameters)).
//! The paper instead fits an unwindowed model to windowed data and subtracts `1/tau`
//! from the decay rates afterwards, a first-order correction.

use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock, ModalFrf};
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::update::{DampingModel, Variables};
use nalgebra::DMatrix;

/// `|H^A(theta)|` over a set of blocks, each with its own exponential window (or none).
#[derive(Debug, Clone)]
pub struct ForwardModel {
    model: StructuralModel,
    variables: Variables,
    n_modes: usize,
    k0: DMatrix<f64>,
    m0: DMatrix<f64>,
    /// Non-zero entries `(column-major index, value)` of each stiffness influence matrix.
    k_terms: Vec<Vec<(usize, f64)>>,
    /// The same for the mass influence matrices.
    m_terms: Vec<Vec<(usize, f64)>>,
    blocks: Vec<FrfBlock>,
    /// Per block: `1 / tau` in 1/s (0 without a window).
    window_eps: Vec<f64>,
    /// Per point: `|(j omega + eps)^p| / omega^p`, the window's change of the kind factor.
    window_gain: Vec<f64>,
    /// Per block: every gain is exactly 1 (receptance, or no window).
    unit_gain: Vec<bool>,
    /// Per block: offset into the long vector.
    offsets: Vec<usize>,
    len: usize,
}

/// Scratch memory of one evaluation thread of a [`ForwardModel`]. For models of up to
/// six DOFs an evaluation allocates nothing ([`Modes::solve_into`]).
#[derive(Debug, Clone)]
pub struct ForwardWorkspace {
    pub(crate) theta: Vec<f64>,
    k: DMatrix<f64>,
    m: DMatrix<f64>,
    c: Vec<f64>,
    c_window: Vec<f64>,
    omega: Vec<f64>,
    modes: Modes,
    frfs: Vec<ModalFrf>,
    pub(crate) magnitude: Vec<f64>,
}

impl ForwardModel {
    /// The model's magnitudes over `blocks`; `window_tau_s[b]` is block `b`'s exponential
    /// window time constant (s), `None` for none. `variables` fixes the layout of `theta`
    /// and the number of modes kept (`n_modes`, all when `None`).
    pub fn new(
        model: StructuralModel,
        variables: Variables,
        n_modes: usize,
        blocks: Vec<FrfBlock>,
        window_tau_s: &[Option<f64>],
    ) -> Result<Self> {
        let n_dof = model.n_dof();
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
        let mut window_eps = Vec::with_capacity(blocks.len());
        let mut window_gain = Vec::new();
        let mut offsets = Vec::with_capacity(blocks.len());
        let mut len = 0;
        for (b, tau) in blocks.iter().zip(window_tau_s) {
            let eps = match tau {
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
            for p in &b.pairs {
                let e_ok = match p.excitation {
                    Excitation::Dof(e) => e < n_dof,
                    Excitation::Ground => true,
                };
                if p.response >= n_dof || !e_ok {
                    return Err(Error::Usage(format!(
                        "FRF pair {p:?} refers to a DOF outside the {n_dof}-DOF model"
                    )));
                }
                let half_power = 0.5 * f64::from(p.kind.power());
                window_gain.extend(
                    b.omega_rad_s
                        .iter()
                        .map(|w| (1.0 + (eps / w).powi(2)).powf(half_power)),
                );
            }
            window_eps.push(eps);
            offsets.push(len);
            len += b.omega_rad_s.len() * b.pairs.len();
        }
        let unit_gain = offsets
            .iter()
            .zip(&blocks)
            .map(|(&o, b)| {
                let n = b.omega_rad_s.len() * b.pairs.len();
                window_gain[o..o + n].iter().all(|&g| g == 1.0)
            })
            .collect();
        let terms = |matrices: &[DMatrix<f64>]| -> Vec<Vec<(usize, f64)>> {
            matrices
                .iter()
                .map(|a| {
                    let nonzero = a.as_slice().iter().enumerate().filter(|(_, y)| **y != 0.0);
                    nonzero.map(|(i, &y)| (i, y)).collect()
                })
                .collect()
        };
        Ok(ForwardModel {
            k0: model.stiffness(&model.alpha_zero()),
            m0: model.mass(&model.beta_zero()),
            k_terms: terms(model.stiffness_influence()),
            m_terms: terms(model.mass_influence()),
            unit_gain,
            model,
            variables,
            n_modes,
            blocks,
            window_eps,
            window_gain,
            offsets,
            len,
        })
    }

    /// The same model and variables over other blocks (e.g. a dense grid for plots).
    pub fn with_blocks(&self, blocks: Vec<FrfBlock>, window_tau_s: &[Option<f64>]) -> Result<Self> {
        ForwardModel::new(
            self.model.clone(),
            self.variables.clone(),
            self.n_modes,
            blocks,
            window_tau_s,
        )
    }

    /// The structural model.
    pub fn model(&self) -> &StructuralModel {
        &self.model
    }
    /// Layout and bounds of `theta`.
    pub fn variables(&self) -> &Variables {
        &self.variables
    }
    /// Modes kept in the modal sums.
    pub fn n_modes(&self) -> usize {
        self.n_modes
    }
    /// The FRF blocks (long-vector layout).
    pub fn blocks(&self) -> &[FrfBlock] {
        &self.blocks
    }
    /// Per block: the window time constant, s.
    pub fn window_tau_s(&self) -> Vec<Option<f64>> {
        self.window_eps
            .iter()
            .map(|&e| (e > 0.0).then(|| 1.0 / e))
            .collect()
    }
    /// Length of the long vector.
    pub fn len(&self) -> usize {
        self.len
    }
    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Fresh scratch memory.
    pub fn workspace(&self) -> ForwardWorkspace {
        let n = self.model.n_dof();
        ForwardWorkspace {
            theta: self.variables.initial(),
            k: DMatrix::zeros(n, n),
            m: DMatrix::zeros(n, n),
            c: vec![0.0; self.n_modes],
            c_window: vec![0.0; self.n_modes],
            omega: vec![0.0; self.n_modes],
            modes: Modes {
                omega_rad_s: Vec::with_capacity(self.n_modes),
                phi: DMatrix::zeros(n, self.n_modes),
                participation: Vec::with_capacity(self.n_modes),
            },
            frfs: self
                .blocks
                .iter()
                .map(|b| ModalFrf::new(vec![b.clone()]))
                .collect(),
            magnitude: vec![0.0; self.len],
        }
    }

    /// `|H^A(theta)|` (`theta` in the full layout of [`Self::variables`]) into `out`
    /// (length [`Self::len`]), windows applied.
    pub fn magnitudes(
        &self,
        theta: &[f64],
        ws: &mut ForwardWorkspace,
        out: &mut [f64],
    ) -> Result<()> {
        if theta.len() != self.variables.len() || out.len() != self.len {
            return Err(Error::Usage(format!(
                "forward model: theta has {} entries (need {}), output {} (need {})",
                theta.len(),
                self.variables.len(),
                out.len(),
                self.len
            )));
        }
        let n_alpha = self.variables.n_alpha();
        let (alpha, rest) = theta.split_at(n_alpha);
        let (beta, damping) = rest.split_at(self.variables.n_beta());
        // K(alpha) = K0 + sum alpha_r K0_r, M(beta) likewise (Eqs. 20-21), over the
        // influence matrices' non-zero entries (adding `a * 0` changes nothing).
        let assemble = |out: &mut DMatrix<f64>,
                        base: &DMatrix<f64>,
                        x: &[f64],
                        terms: &[Vec<(usize, f64)>]| {
            let out = out.as_mut_slice();
            out.copy_from_slice(base.as_slice());
            for (a, terms) in x.iter().zip(terms) {
                for &(i, y) in terms {
                    out[i] += a * y;
                }
            }
        };
        assemble(&mut ws.k, &self.k0, alpha, &self.k_terms);
        assemble(&mut ws.m, &self.m0, beta, &self.m_terms);
        let modes = &mut ws.modes;
        modes.solve_into(
            &ws.k,
            &ws.m,
            self.model.ground_influence(),
            Some(self.n_modes),
        )?;
        // Modal damping coefficients as `Damping::modal_coefficients` computes them
        // (same expressions), without building a `Damping`.
        match self.variables.damping_model() {
            DampingModel::Rayleigh => {
                let (a0_per_s, a1_s) = (damping[0], damping[1]);
                for (c, w) in ws.c.iter_mut().zip(&modes.omega_rad_s) {
                    *c = a0_per_s + a1_s * w * w;
                }
            }
            DampingModel::Caughey => {
                if damping.len() < self.n_modes {
                    return Err(Error::Usage(format!(
                        "Caughey damping has {} ratios for {} modes",
                        damping.len(),
                        self.n_modes
                    )));
                }
                for ((c, w), x) in ws.c.iter_mut().zip(&modes.omega_rad_s).zip(damping) {
                    *c = 2.0 * x * w;
                }
            }
        }
        ws.omega.copy_from_slice(&modes.omega_rad_s);
        // The window of the modal parameters currently in `modes` / `c_window`.
        let mut current_eps = 0.0;
        for (b, frf) in ws.frfs.iter_mut().enumerate() {
            let eps = self.window_eps[b];
            let range = self.offsets[b]..self.offsets[b] + frf.len();
            if eps == 0.0 {
                if current_eps != 0.0 {
                    modes.omega_rad_s.copy_from_slice(&ws.omega);
                    current_eps = 0.0;
                }
                frf.magnitudes(modes, &ws.c, &mut out[range])?;
                continue;
            }
            if eps != current_eps {
                for i in 0..self.n_modes {
                    let (w, c) = (ws.omega[i], ws.c[i]);
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::{FrfKind, FrfPair};
    use crate::signal::windowed_modal_frf;
    use crate::update::{DampingModel, VariablesConfig};

    fn frame() -> StructuralModel {
        StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0]).unwrap()
    }

    fn blocks() -> Vec<FrfBlock> {
        let grid = |lo: f64, n: usize| (0..n).map(|i| lo + 0.37 * i as f64).collect();
        let pairs = |e: Excitation| {
            [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance]
                .iter()
                .enumerate()
                .map(|(r, &kind)| FrfPair {
                    response: r + 1,
                    excitation: e,
                    kind,
                })
                .collect()
        };
        vec![
            FrfBlock {
                omega_rad_s: grid(3.0, 90),
                pairs: pairs(Excitation::Dof(0)),
            },
            FrfBlock {
                omega_rad_s: grid(4.1, 70),
                pairs: pairs(Excitation::Ground),
            },
        ]
    }

    /// Oracle: the windowed modal sum evaluated at the complex frequency `omega - j/tau`
    /// (`windowed_modal_frf`), point by point, for Rayleigh and Caughey damping.
    #[test]
    fn windowed_magnitudes_match_the_complex_frequency_oracle() {
        let model = frame();
        // A window then none, the same window twice (its modal parameters reused), none
        // then a window.
        let windows = [[Some(7.5), None], [Some(7.5), Some(7.5)], [None, Some(3.0)]];
        for (taus, damping) in windows
            .into_iter()
            .flat_map(|t| [(t, DampingModel::Rayleigh), (t, DampingModel::Caughey)])
        {
            let vars = Variables::new(&model, damping, 4, &VariablesConfig::default()).unwrap();
            let fm = ForwardModel::new(model.clone(), vars.clone(), 4, blocks(), &taus).unwrap();
            let mut theta = vec![0.05, -0.1, 0.2, 0.02, 0.03, -0.05, 0.1, 0.0];
            match damping {
                DampingModel::Rayleigh => theta.extend([0.04, 2e-4]),
                DampingModel::Caughey => theta.extend([0.012, 0.004, 0.02, 0.007]),
            }
            let mut ws = fm.workspace();
            let mut out = vec![0.0; fm.len()];
            fm.magnitudes(&theta, &mut ws, &mut out).unwrap();
            let (alpha, beta, d) = vars.split(&theta);
            let modes = Modes::solve(
                &model.stiffness(alpha),
                &model.mass(beta),
                model.ground_influence(),
                None,
            )
            .unwrap();
            let mut c = vec![0.0; 4];
            d.modal_coefficients(&modes.omega_rad_s, &mut c).unwrap();
            let mut k = 0;
            for (b, tau) in blocks().iter().zip(taus) {
                for pair in &b.pairs {
                    for &w in &b.omega_rad_s {
                        let h =
                            windowed_modal_frf(&modes, &c, pair, w, tau.unwrap_or(f64::INFINITY));
                        assert!(
                            (out[k] - h.norm()).abs() <= 1e-11 * h.norm(),
                            "{damping:?} point {k}: {} vs {}",
                            out[k],
                            h.norm()
                        );
                        k += 1;
                    }
                }
            }
            assert_eq!(k, fm.len());
            // A second evaluation with the same workspace gives the same bits.
            let mut again = vec![0.0; fm.len()];
            fm.magnitudes(&theta, &mut ws, &mut again).unwrap();
            assert_eq!(out, again);
        }
    }

    #[test]
    fn rejects_bad_layouts() {
        let model = frame();
        let vars = Variables::new(
            &model,
            DampingModel::Rayleigh,
            4,
            &VariablesConfig::default(),
        )
        .unwrap();
        assert!(ForwardModel::new(model.clone(), vars.clone(), 4, blocks(), &[None]).is_err());
        assert!(ForwardModel::new(
            model.clone(),
            vars.clone(),
            4,
            blocks(),
            &[Some(-1.0), None]
        )
        .is_err());
        assert!(
            ForwardModel::new(model.clone(), vars.clone(), 5, blocks(), &[None, None]).is_err()
        );
        let mut bad = blocks();
        bad[0].pairs[0].response = 4;
        assert!(ForwardModel::new(model, vars, 4, bad, &[None, None]).is_err());
    }
}
