//! Modal predictions: natural frequencies and mode shapes at the measured DOFs.
//!
//! [`ModalPredictor`] pairs model modes with measured modes by index (model mode
//! `modes[i]` for measured mode `i`) and predicts, in this order, the paired modes'
//! natural frequencies (Hz) and then each paired mode's shape at the measured DOFs
//! (mass-normalised, sign as the solver gives it: likelihoods of shapes must be
//! invariant to the sign). The eigen-solution comes from a [`ModeSolver`]: the dense
//! solver of [`crate::modal::Modes`] here ([`DenseModes`], with its shear-frame fast
//! path), or the sparse shift-invert partial solver of [`crate::modal::PartialSolver`]
//! for large models ([`PartialModes`]).

use std::ops::Range;
use std::sync::Arc;

use super::{Parametrisation, Predict};
use crate::error::{Error, Result};
use crate::modal::{Modes, PartialOptions, PartialSolver, PartialWorkspace};
use crate::model::sparse::SparsePencil;
use crate::model::StructuralModel;
use nalgebra::DMatrix;

/// The lowest modes of `K(alpha) phi = omega^2 M(beta) phi` (Eqs. 20-22).
pub trait ModeSolver: Sync {
    /// Scratch memory of one thread.
    type Workspace: Send;
    /// DOFs of the model.
    fn n_dof(&self) -> usize;
    /// A fresh workspace.
    fn workspace(&self) -> Self::Workspace;
    /// The lowest `eigenvalues.len()` eigenvalues `omega^2` (rad^2/s^2, ascending) and
    /// their mass-normalised shapes at `dofs`, column-major into `shapes`
    /// (`dofs.len()` rows, one column per mode). [`Error::Model`] when `(alpha, beta)`
    /// is not an admissible model.
    fn lowest_modes(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut Self::Workspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
    ) -> Result<()>;

    /// [`Self::lowest_modes`] plus their derivatives with respect to the model's
    /// variables `v = [alpha, beta]` (`n_var = n_alpha + n_beta`):
    /// `d_eigenvalues[i * n_var + j] = d lambda_i / d v_j` and
    /// `d_shapes[(i * dofs.len() + k) * n_var + j] = d phi_i[dofs[k]] / d v_j` (the
    /// mass-normalised shapes, with the signs `lowest_modes` gives). Returns `Ok(false)`
    /// (the default) when the solver has no analytic derivatives; callers then
    /// difference [`Self::lowest_modes`].
    #[allow(clippy::too_many_arguments)]
    fn lowest_modes_with_derivatives(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut Self::Workspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
        d_eigenvalues: &mut [f64],
        d_shapes: &mut [f64],
    ) -> Result<bool> {
        let _ = (
            alpha,
            beta,
            dofs,
            ws,
            eigenvalues,
            shapes,
            d_eigenvalues,
            d_shapes,
        );
        Ok(false)
    }

    /// The lowest `n_modes` modes as [`Modes`] at every DOF (natural frequencies,
    /// mass-normalised shapes and ground participation factors as [`Modes::solve`] gives
    /// them), for solvers that compute them in that form ([`DenseModes`]); `Ok(None)`, the
    /// default, for the others, whose callers use [`Self::lowest_modes`].
    fn modes<'w>(
        &self,
        alpha: &[f64],
        beta: &[f64],
        n_modes: usize,
        ws: &'w mut Self::Workspace,
    ) -> Result<Option<&'w mut Modes>> {
        let _ = (alpha, beta, n_modes, ws);
        Ok(None)
    }
}

/// Every mode by the dense solver of [`Modes`] (a tridiagonal solver for shear frames).
///
/// `K(alpha)` and `M(beta)` are assembled into the workspace from the non-zero entries of
/// the influence matrices (the same sums as [`StructuralModel::stiffness`] and
/// [`StructuralModel::mass`], which add `alpha_r 0` elsewhere), and for models of up to
/// six DOFs [`Modes::solve_into`] allocates nothing: an evaluation allocates nothing.
#[derive(Debug, Clone)]
pub struct DenseModes {
    model: Arc<StructuralModel>,
    k0: DMatrix<f64>,
    m0: DMatrix<f64>,
    /// Non-zero entries `(column-major index, value)` of each stiffness influence matrix.
    k_terms: Vec<Vec<(usize, f64)>>,
    /// The same for the mass influence matrices.
    m_terms: Vec<Vec<(usize, f64)>>,
}

/// Scratch memory of [`DenseModes`]: the assembled matrices and the modes.
#[derive(Debug, Clone)]
pub struct DenseWorkspace {
    k: DMatrix<f64>,
    m: DMatrix<f64>,
    modes: Modes,
}

impl DenseModes {
    pub fn new(model: Arc<StructuralModel>) -> Self {
        let terms = |matrices: &[DMatrix<f64>]| -> Vec<Vec<(usize, f64)>> {
            let nonzero = |a: &DMatrix<f64>| {
                let entries = a.as_slice().iter().enumerate();
                entries
                    .filter(|(_, y)| **y != 0.0)
                    .map(|(i, &y)| (i, y))
                    .collect()
            };
            matrices.iter().map(nonzero).collect()
        };
        DenseModes {
            k0: model.stiffness(&model.alpha_zero()),
            m0: model.mass(&model.beta_zero()),
            k_terms: terms(model.stiffness_influence()),
            m_terms: terms(model.mass_influence()),
            model,
        }
    }
    pub fn model(&self) -> &StructuralModel {
        &self.model
    }

    /// `K(alpha)` and `M(beta)` into `ws`, then its lowest `n_modes` modes.
    fn solve(
        &self,
        alpha: &[f64],
        beta: &[f64],
        n_modes: usize,
        ws: &mut DenseWorkspace,
    ) -> Result<()> {
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
        ws.modes
            .solve_into(&ws.k, &ws.m, self.model.ground_influence(), Some(n_modes))
            .map_err(|e| Error::Model(format!("no modes at alpha {alpha:?}, beta {beta:?}: {e}")))
    }
}

impl ModeSolver for DenseModes {
    type Workspace = DenseWorkspace;

    fn n_dof(&self) -> usize {
        self.model.n_dof()
    }

    fn workspace(&self) -> DenseWorkspace {
        let n = self.model.n_dof();
        DenseWorkspace {
            k: DMatrix::zeros(n, n),
            m: DMatrix::zeros(n, n),
            modes: Modes {
                omega_rad_s: Vec::with_capacity(n),
                phi: DMatrix::zeros(0, 0),
                participation: Vec::with_capacity(n),
            },
        }
    }

    fn lowest_modes(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut DenseWorkspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
    ) -> Result<()> {
        let n = eigenvalues.len();
        self.solve(alpha, beta, n, ws)?;
        let modes = &ws.modes;
        for i in 0..n {
            eigenvalues[i] = modes.omega_rad_s[i] * modes.omega_rad_s[i];
            for (s, &d) in shapes[i * dofs.len()..(i + 1) * dofs.len()]
                .iter_mut()
                .zip(dofs)
            {
                *s = modes.phi[(d, i)];
            }
        }
        Ok(())
    }

    fn modes<'w>(
        &self,
        alpha: &[f64],
        beta: &[f64],
        n_modes: usize,
        ws: &'w mut DenseWorkspace,
    ) -> Result<Option<&'w mut Modes>> {
        self.solve(alpha, beta, n_modes, ws)?;
        Ok(Some(&mut ws.modes))
    }
}

/// The lowest modes by the sparse shift-invert solver of [`PartialSolver`], for large
/// models (hundreds to thousands of DOFs, possibly with massless DOFs): the symbolic
/// factorisation of the pencil's pattern is shared by all threads, the numeric one is
/// per workspace.
#[derive(Debug, Clone)]
pub struct PartialModes {
    model: Arc<StructuralModel>,
    solver: PartialSolver,
}

impl PartialModes {
    /// Builds the sparse pencil of `model` and analyses its pattern.
    pub fn new(model: Arc<StructuralModel>, options: PartialOptions) -> Result<Self> {
        let pencil = Arc::new(SparsePencil::from_model(&model));
        let solver = PartialSolver::new(pencil, options)?;
        Ok(PartialModes { model, solver })
    }
    pub fn model(&self) -> &StructuralModel {
        &self.model
    }
    pub fn solver(&self) -> &PartialSolver {
        &self.solver
    }
}

impl ModeSolver for PartialModes {
    type Workspace = PartialWorkspace;

    fn n_dof(&self) -> usize {
        self.model.n_dof()
    }

    fn workspace(&self) -> PartialWorkspace {
        self.solver.workspace()
    }

    fn lowest_modes(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut PartialWorkspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
    ) -> Result<()> {
        let n = eigenvalues.len();
        let modes = self.solver.solve(alpha, beta, n, ws).map_err(|e| {
            Error::Model(format!("no modes at alpha {alpha:?}, beta {beta:?}: {e}"))
        })?;
        eigenvalues.copy_from_slice(&modes.eigenvalues_rad2_s2);
        for i in 0..n {
            for (s, &d) in shapes[i * dofs.len()..(i + 1) * dofs.len()]
                .iter_mut()
                .zip(dofs)
            {
                *s = modes.phi[(d, i)];
            }
        }
        Ok(())
    }
}

/// Natural frequencies and shapes at measured DOFs of paired modes (see the module docs).
#[derive(Debug, Clone)]
pub struct ModalPredictor<S: ModeSolver> {
    solver: S,
    params: Parametrisation,
    dofs: Vec<usize>,
    modes: Vec<usize>,
    n_solve: usize,
}

/// Scratch memory of a [`ModalPredictor`].
pub struct ModalWorkspace<W> {
    solver: W,
    alpha: Vec<f64>,
    beta: Vec<f64>,
    eigenvalues: Vec<f64>,
    shapes: Vec<f64>,
    d_eigenvalues: Vec<f64>,
    d_shapes: Vec<f64>,
}

impl<S: ModeSolver> ModalPredictor<S> {
    /// `dofs`: 0-based model DOFs of the measured shape entries; `modes`: 0-based model
    /// mode paired with each measured mode.
    pub fn new(
        solver: S,
        params: Parametrisation,
        dofs: Vec<usize>,
        modes: Vec<usize>,
    ) -> Result<Self> {
        let n = solver.n_dof();
        if let Some(&d) = dofs.iter().find(|&&d| d >= n) {
            return Err(Error::Usage(format!(
                "measured DOF {d} (0-based) is out of range: the model has {n} DOFs"
            )));
        }
        if modes.is_empty() {
            return Err(Error::Usage(
                "a modal prediction needs at least one mode".into(),
            ));
        }
        let n_solve = modes.iter().max().map_or(0, |m| m + 1);
        if n_solve > n {
            return Err(Error::Usage(format!(
                "model mode {} requested, but the model has {n} DOFs",
                n_solve
            )));
        }
        Ok(ModalPredictor {
            solver,
            params,
            dofs,
            modes,
            n_solve,
        })
    }

    pub fn n_modes(&self) -> usize {
        self.modes.len()
    }
    pub fn n_dofs(&self) -> usize {
        self.dofs.len()
    }
    pub fn solver(&self) -> &S {
        &self.solver
    }
    pub fn parametrisation(&self) -> &Parametrisation {
        &self.params
    }
    /// Where the frequencies (Hz) are in the prediction vector.
    pub fn freq_range(&self) -> Range<usize> {
        0..self.modes.len()
    }
    /// Where the shape of paired mode `i` is in the prediction vector.
    pub fn shape_range(&self, i: usize) -> Range<usize> {
        let start = self.modes.len() + i * self.dofs.len();
        start..start + self.dofs.len()
    }

    /// The paired modes' frequencies (Hz) and shapes from the solved modes in `ws`.
    fn write_outputs<W>(&self, ws: &ModalWorkspace<W>, out: &mut [f64]) -> Result<()> {
        let nd = self.dofs.len();
        for (i, &m) in self.modes.iter().enumerate() {
            let lambda = ws.eigenvalues[m];
            if lambda.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return Err(Error::Model(format!(
                    "model mode {} has eigenvalue {lambda} (not positive)",
                    m + 1
                )));
            }
            out[i] = lambda.sqrt() / (2.0 * std::f64::consts::PI);
            out[self.shape_range(i)].copy_from_slice(&ws.shapes[m * nd..(m + 1) * nd]);
        }
        Ok(())
    }
}

impl<S: ModeSolver> Predict for ModalPredictor<S> {
    type Workspace = ModalWorkspace<S::Workspace>;

    fn n_params(&self) -> usize {
        self.params.len()
    }

    fn n_outputs(&self) -> usize {
        self.modes.len() * (1 + self.dofs.len())
    }

    fn param_names(&self) -> Vec<String> {
        self.params.names()
    }

    fn workspace(&self) -> Self::Workspace {
        ModalWorkspace {
            solver: self.solver.workspace(),
            alpha: Vec::new(),
            beta: Vec::new(),
            eigenvalues: vec![0.0; self.n_solve],
            shapes: vec![0.0; self.n_solve * self.dofs.len()],
            d_eigenvalues: Vec::new(),
            d_shapes: Vec::new(),
        }
    }

    fn predict(&self, theta: &[f64], ws: &mut Self::Workspace, out: &mut [f64]) -> Result<()> {
        self.params.apply(theta, &mut ws.alpha, &mut ws.beta);
        self.solver.lowest_modes(
            &ws.alpha,
            &ws.beta,
            &self.dofs,
            &mut ws.solver,
            &mut ws.eigenvalues,
            &mut ws.shapes,
        )?;
        self.write_outputs(ws, out)
    }

    /// `d out / d theta` from the solver's eigen-derivatives when it has them:
    /// `f_i = sqrt(lambda_i) / (2 pi)` gives `df_i = dlambda_i / (8 pi^2 f_i)`, and the
    /// parametrisation's chain factor `d v / d theta` ([`Parametrisation::chain`]).
    fn jacobian(
        &self,
        theta: &[f64],
        ws: &mut Self::Workspace,
        out: &mut [f64],
        jac: &mut DMatrix<f64>,
    ) -> Result<bool> {
        self.params.apply(theta, &mut ws.alpha, &mut ws.beta);
        let n_var = ws.alpha.len() + ws.beta.len();
        let nd = self.dofs.len();
        ws.d_eigenvalues.resize(self.n_solve * n_var, 0.0);
        ws.d_shapes.resize(self.n_solve * nd * n_var, 0.0);
        if !self.solver.lowest_modes_with_derivatives(
            &ws.alpha,
            &ws.beta,
            &self.dofs,
            &mut ws.solver,
            &mut ws.eigenvalues,
            &mut ws.shapes,
            &mut ws.d_eigenvalues,
            &mut ws.d_shapes,
        )? {
            return Ok(false);
        }
        self.write_outputs(ws, out)?;
        let chain = self.params.chain(theta);
        jac.fill(0.0);
        for (i, &m) in self.modes.iter().enumerate() {
            let df = 1.0 / (8.0 * std::f64::consts::PI.powi(2) * out[i]);
            let rows = self.shape_range(i);
            for (t, &(v, factor)) in chain.iter().enumerate() {
                jac[(i, t)] = df * factor * ws.d_eigenvalues[m * n_var + v];
                for k in 0..nd {
                    jac[(rows.start + k, t)] = factor * ws.d_shapes[(m * nd + k) * n_var + v];
                }
            }
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predict::{Coordinate, Scale, Variable};

    /// Oracle: a uniform fixed-free chain of n equal masses m and springs k has
    /// omega_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2n + 1))); its shapes are
    /// sin(j' x) profiles. Coordinates on a log scale move k as expected.
    #[test]
    fn predicts_the_closed_form_chain() {
        let model = Arc::new(StructuralModel::shear_frame(&[2.0; 4], &[800.0; 4]).unwrap());
        let coords = (0..4)
            .map(|r| Coordinate {
                name: format!("k{}", r + 1),
                variable: Variable::Alpha(r),
                scale: Scale::Log { ln_offset: 0.0 },
            })
            .collect();
        let params = Parametrisation::new(&model, coords).unwrap();
        let p =
            ModalPredictor::new(DenseModes::new(model), params, vec![3, 1], vec![0, 2]).unwrap();
        let mut ws = p.workspace();
        let mut out = vec![0.0; p.n_outputs()];
        // 1 + alpha = exp(ln 2): every spring doubled, frequencies up by sqrt 2.
        p.predict(&[2f64.ln(); 4], &mut ws, &mut out).unwrap();
        for (i, j) in [0usize, 2].iter().enumerate() {
            let w =
                2.0 * (800.0f64).sqrt() * ((2 * j + 1) as f64 * std::f64::consts::PI / 18.0).sin();
            assert!((out[i] * 2.0 * std::f64::consts::PI / w - 1.0).abs() < 1e-12);
        }
        // Shape of mode 1 at floors 4 and 2: sin(4 x) / sin(2 x), x = pi / 9.
        let s = &out[p.shape_range(0)];
        let x = std::f64::consts::PI / 9.0;
        assert!((s[0] / s[1] - (4.0 * x).sin() / (2.0 * x).sin()).abs() < 1e-10);
    }

    #[test]
    fn rejects_out_of_range_dofs_and_modes() {
        let model = Arc::new(StructuralModel::shear_frame(&[1.0; 3], &[10.0; 3]).unwrap());
        let params = Parametrisation::all_alphas(&model).unwrap();
        let solver = DenseModes::new(model);
        let e = ModalPredictor::new(solver.clone(), params.clone(), vec![3], vec![0]);
        assert!(e.unwrap_err().to_string().contains("DOF 3"));
        let e = ModalPredictor::new(solver, params, vec![0], vec![3]);
        assert!(e.unwrap_err().to_string().contains("mode 4"));
    }
}
