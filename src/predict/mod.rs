//! What a model predicts at the observed channels.
//!
//! [`Predict`] is the one interface between a structural model and the inference layer
//! ([`crate::infer`]): a vector of sampled coordinates `theta` in, a vector of predicted
//! observables out (natural frequencies and mode shapes at the measured DOFs, FRF values
//! at the observed bins, ...). The likelihood decides how predictions meet data; the
//! predictor knows nothing of noise. Fast paths (the shear frame's tridiagonal
//! eigensolver, a reduced basis for large models) live behind the same trait.
//!
//! [`Parametrisation`] maps `theta` onto the model's updating variables `alpha`
//! (stiffness, paper Eq. 20) and `beta` (mass, Eq. 21), on a linear or a log scale.

pub mod choice;
pub mod frf;
pub mod kept;
pub mod modal;
pub mod poles;
pub mod reduced;

pub use choice::{ModeSolverChoice, ModelModes};
pub use frf::{FrfDamping, FrfOptions, FrfOutput, FrfPredictor, FrfWorkspace};
pub use modal::{DenseModes, ModalPredictor, ModeSolver, PartialModes};
pub use poles::PoleResidue;

use crate::error::{Error, Result};
use crate::model::StructuralModel;
use nalgebra::DMatrix;

/// A model's predictions at the observed channels as a function of the sampled
/// coordinates.
///
/// Contract: `predict` writes `n_outputs()` finite values, or returns
/// [`Error::Model`] when `theta` gives an inadmissible model (a mass matrix that is not
/// positive definite, say), which the posterior treats as zero density; any other error
/// is a numerical failure that stops the caller.
pub trait Predict: Sync {
    /// Scratch memory of one thread of evaluations.
    type Workspace: Send;
    /// Number of coordinates `theta`.
    fn n_params(&self) -> usize;
    /// Number of predicted values.
    fn n_outputs(&self) -> usize;
    /// Names of the coordinates, for reports.
    fn param_names(&self) -> Vec<String>;
    /// A fresh workspace.
    fn workspace(&self) -> Self::Workspace;
    /// Predictions at `theta` into `out` (length `n_outputs()`).
    fn predict(&self, theta: &[f64], ws: &mut Self::Workspace, out: &mut [f64]) -> Result<()>;
    /// The predictions at `theta` into `out` and the analytic Jacobian
    /// `d out_i / d theta_j` into `jac` (`n_outputs x n_params`), from one solve,
    /// returning `Ok(true)`; `Ok(false)` (the default) when the predictor has none and
    /// callers should difference [`Predict::predict`].
    fn jacobian(
        &self,
        theta: &[f64],
        ws: &mut Self::Workspace,
        out: &mut [f64],
        jac: &mut DMatrix<f64>,
    ) -> Result<bool> {
        let _ = (theta, ws, out, jac);
        Ok(false)
    }
}

/// Which updating variable a coordinate moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variable {
    /// `alpha_r` of `K(alpha) = K0 + sum_r alpha_r K_r` (Eq. 20).
    Alpha(usize),
    /// `beta_r` of `M(beta) = M0 + sum_r beta_r M_r` (Eq. 21).
    Beta(usize),
}

/// How a coordinate maps onto its variable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scale {
    /// `alpha_r = theta` (SMU's and the paper's multipliers).
    Linear,
    /// `1 + alpha_r = exp(theta - ln_offset)`: `theta` is the log of the physical value
    /// when `ln_offset` is the log of its nominal value (`ln k_r` with
    /// `ln_offset = ln k_r0`), and the log of the factor when `ln_offset = 0`.
    Log { ln_offset: f64 },
}

/// One sampled coordinate of a structural model.
#[derive(Debug, Clone, PartialEq)]
pub struct Coordinate {
    pub name: String,
    pub variable: Variable,
    pub scale: Scale,
}

/// Maps `theta` to the model's `alpha` and `beta`; variables without a coordinate stay 0.
#[derive(Debug, Clone, PartialEq)]
pub struct Parametrisation {
    coordinates: Vec<Coordinate>,
    n_alpha: usize,
    n_beta: usize,
    /// The coordinates are `[alpha, beta]` themselves, in order, all linear: `apply`
    /// copies them (the 4-DOF fast path).
    direct: bool,
}

impl Parametrisation {
    /// Checks every coordinate names an existing variable, at most once.
    pub fn new(model: &StructuralModel, coordinates: Vec<Coordinate>) -> Result<Self> {
        let (n_alpha, n_beta) = (model.n_alpha(), model.n_beta());
        let mut seen = Vec::new();
        for c in &coordinates {
            let ok = match c.variable {
                Variable::Alpha(r) => r < n_alpha,
                Variable::Beta(r) => r < n_beta,
            };
            if !ok {
                return Err(Error::Usage(format!(
                    "coordinate `{}` moves {:?}, but the model has {n_alpha} alphas and {n_beta} betas",
                    c.name, c.variable
                )));
            }
            if seen.contains(&c.variable) {
                return Err(Error::Usage(format!(
                    "coordinate `{}`: {:?} already has a coordinate",
                    c.name, c.variable
                )));
            }
            seen.push(c.variable);
        }
        let in_order = (0..n_alpha)
            .map(Variable::Alpha)
            .chain((0..n_beta).map(Variable::Beta));
        let direct = coordinates.len() == n_alpha + n_beta
            && coordinates.iter().map(|c| c.variable).eq(in_order)
            && coordinates.iter().all(|c| c.scale == Scale::Linear);
        Ok(Parametrisation {
            coordinates,
            n_alpha,
            n_beta,
            direct,
        })
    }

    /// One linear coordinate per alpha, named after the model's parameters.
    pub fn all_alphas(model: &StructuralModel) -> Result<Self> {
        let coordinates = model
            .alpha_parameters()
            .iter()
            .enumerate()
            .map(|(r, p)| Coordinate {
                name: p.name.clone(),
                variable: Variable::Alpha(r),
                scale: Scale::Linear,
            })
            .collect();
        Self::new(model, coordinates)
    }

    pub fn coordinates(&self) -> &[Coordinate] {
        &self.coordinates
    }
    pub fn len(&self) -> usize {
        self.coordinates.len()
    }
    pub fn is_empty(&self) -> bool {
        self.coordinates.is_empty()
    }
    pub fn names(&self) -> Vec<String> {
        self.coordinates.iter().map(|c| c.name.clone()).collect()
    }

    /// For each coordinate, the index of its variable in `v = [alpha, beta]` and
    /// `d v / d theta` at `theta` (1 on a linear scale, `exp(theta - ln_offset)` on a
    /// log scale).
    pub fn chain(&self, theta: &[f64]) -> Vec<(usize, f64)> {
        self.coordinates
            .iter()
            .zip(theta)
            .map(|(c, &t)| {
                let v = match c.variable {
                    Variable::Alpha(r) => r,
                    Variable::Beta(r) => self.n_alpha + r,
                };
                let d = match c.scale {
                    Scale::Linear => 1.0,
                    Scale::Log { ln_offset } => (t - ln_offset).exp(),
                };
                (v, d)
            })
            .collect()
    }

    /// `alpha` and `beta` at `theta` (resized to the model's counts).
    pub fn apply(&self, theta: &[f64], alpha: &mut Vec<f64>, beta: &mut Vec<f64>) {
        if self.direct && theta.len() == self.n_alpha + self.n_beta {
            let (a, b) = theta.split_at(self.n_alpha);
            alpha.clear();
            alpha.extend_from_slice(a);
            beta.clear();
            beta.extend_from_slice(b);
            return;
        }
        alpha.clear();
        alpha.resize(self.n_alpha, 0.0);
        beta.clear();
        beta.resize(self.n_beta, 0.0);
        for (c, &t) in self.coordinates.iter().zip(theta) {
            let v = match c.scale {
                Scale::Linear => t,
                Scale::Log { ln_offset } => (t - ln_offset).exp() - 1.0,
            };
            match c.variable {
                Variable::Alpha(r) => alpha[r] = v,
                Variable::Beta(r) => beta[r] = v,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_and_linear_coordinates_map_onto_alpha_and_beta() {
        let model = StructuralModel::shear_frame(&[2.0, 3.0], &[100.0, 200.0]).unwrap();
        let p = Parametrisation::new(
            &model,
            vec![
                Coordinate {
                    name: "k1".into(),
                    variable: Variable::Alpha(0),
                    scale: Scale::Log {
                        ln_offset: 100f64.ln(),
                    },
                },
                Coordinate {
                    name: "m2".into(),
                    variable: Variable::Beta(1),
                    scale: Scale::Linear,
                },
            ],
        )
        .unwrap();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        p.apply(&[150f64.ln(), -0.25], &mut a, &mut b);
        assert!((a[0] - 0.5).abs() < 1e-14 && a[1] == 0.0);
        assert_eq!(b, vec![0.0, -0.25]);
        let twice = Parametrisation::new(&model, vec![p.coordinates()[0].clone(); 2]);
        assert!(twice.unwrap_err().to_string().contains("already"));
        let bad = Coordinate {
            name: "k9".into(),
            variable: Variable::Alpha(9),
            scale: Scale::Linear,
        };
        let err = Parametrisation::new(&model, vec![bad])
            .unwrap_err()
            .to_string();
        assert!(err.contains("k9") && err.contains("2 alphas"), "{err}");
    }

    /// The direct path (coordinates `[alpha, beta]` in order, linear) gives what the
    /// general path gives for the same coordinates listed in another order.
    #[test]
    fn direct_coordinates_apply_like_the_general_path() {
        let model = StructuralModel::shear_frame(&[2.0, 3.0], &[100.0, 200.0]).unwrap();
        let coordinate = |name: &str, variable| Coordinate {
            name: name.into(),
            variable,
            scale: Scale::Linear,
        };
        let ordered = vec![
            coordinate("k1", Variable::Alpha(0)),
            coordinate("k2", Variable::Alpha(1)),
            coordinate("m1", Variable::Beta(0)),
            coordinate("m2", Variable::Beta(1)),
        ];
        let direct = Parametrisation::new(&model, ordered.clone()).unwrap();
        assert!(direct.direct);
        let mut shuffled = ordered;
        shuffled.reverse();
        let general = Parametrisation::new(&model, shuffled).unwrap();
        assert!(!general.direct);
        let theta = [0.1, -0.2, 0.3, -0.05];
        let reversed: Vec<f64> = theta.iter().rev().copied().collect();
        let (mut a1, mut b1, mut a2, mut b2) = (vec![9.0; 7], vec![], vec![], vec![1.0]);
        direct.apply(&theta, &mut a1, &mut b1);
        general.apply(&reversed, &mut a2, &mut b2);
        assert_eq!((a1, b1), (a2, b2));
    }
}
