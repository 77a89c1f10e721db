//! The FRF posterior's model on the inference layer: the [`FrfPredictor`] of a model's
//! updating variables, whose coordinates are the posterior's sampled ones before `ln s`
//! (free multipliers as they are, damping as logarithms), on the mode solver the model's
//! size calls for ([`mode_solver`]: dense for small models, a reduced basis over the
//! prior box, anchored at the maximum-likelihood point, for large ones).

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::frf::FrfBlock;
use crate::model::StructuralModel;
use crate::predict::choice::{reduced_basis, Anchor, BasisDesign};
use crate::predict::reduced::CondensedModes;
use crate::predict::{
    Coordinate, DenseModes, FrfDamping, FrfOptions, FrfOutput, FrfPredictor, ModeSolverChoice,
    ModelModes, Parametrisation, Scale, Variable,
};
use crate::update::{self, DampingModel, VariableKind, Variables};

/// The magnitudes `|H^A|` of `model` over `blocks` (block `b` through an exponential
/// window of `window_tau_s[b]` s) as a function of the free variables of `vars` in their
/// internal coordinates, the `n_modes` lowest modes of `solver` in the sums.
///
/// Multipliers must be on a linear scale and free damping on a log scale (as
/// [`super::FrfPosterior`] sets them); fixed damping keeps its value, a fixed multiplier
/// its value 0 (the model's nominal; other fixed multipliers are refused).
pub fn frf_predictor(
    model: &Arc<StructuralModel>,
    vars: &Variables,
    n_modes: usize,
    blocks: &[FrfBlock],
    window_tau_s: &[Option<f64>],
    solver: ModelModes,
) -> Result<FrfPredictor<ModelModes>> {
    let (mut coordinates, mut fixed_damping) = (Vec::new(), Vec::new());
    for v in vars.variables() {
        let variable = match v.kind {
            VariableKind::Alpha(r) => Variable::Alpha(r),
            VariableKind::Beta(r) => Variable::Beta(r),
            _ => {
                if v.fixed.is_none() && v.scale != update::Scale::Log {
                    return Err(Error::Usage(format!(
                        "damping variable `{}` must be on a log scale here",
                        v.name
                    )));
                }
                fixed_damping.push(v.fixed);
                continue;
            }
        };
        match (v.fixed, v.scale) {
            (Some(x), _) if x != 0.0 => {
                return Err(Error::Usage(format!(
                    "`{}` is fixed at {x}; only fixed multipliers of 0 are supported",
                    v.name
                )))
            }
            (Some(_), _) => {}
            (None, update::Scale::Linear) => coordinates.push(Coordinate {
                name: v.name.clone(),
                variable,
                scale: Scale::Linear,
            }),
            (None, update::Scale::Log) => {
                return Err(Error::Usage(format!(
                    "multiplier `{}` must be on a linear scale",
                    v.name
                )))
            }
        }
    }
    let params = Parametrisation::new(model, coordinates)?;
    let options = FrfOptions {
        damping: match vars.damping_model() {
            DampingModel::Rayleigh => FrfDamping::Rayleigh,
            DampingModel::Caughey => FrfDamping::Modal,
        },
        output: FrfOutput::Magnitude,
        n_modes,
    };
    FrfPredictor::new(solver, model.clone(), params, options, blocks, window_tau_s)?
        .with_fixed_damping(fixed_damping)
}

/// The box of the model's variables `v = [alpha, beta]` in `vars` (a fixed multiplier:
/// its value at both ends) and its center (the free variables' initial values).
fn variable_box(model: &StructuralModel, vars: &Variables) -> (Vec<f64>, Vec<(f64, f64)>) {
    let n_alpha = model.n_alpha();
    let n = n_alpha + model.n_beta();
    let (mut center, mut bounds) = (vec![0.0; n], vec![(0.0, 0.0); n]);
    for v in vars.variables() {
        let j = match v.kind {
            VariableKind::Alpha(r) => r,
            VariableKind::Beta(r) => n_alpha + r,
            _ => continue,
        };
        match v.fixed {
            Some(x) => (center[j], bounds[j]) = (x, (x, x)),
            None => (center[j], bounds[j]) = (v.initial, (v.lower, v.upper)),
        }
    }
    (center, bounds)
}

/// The mode solver of `model` for a posterior over `vars` with the `n_modes` lowest
/// modes in its sums: `choice` resolved by the model's size ([`ModeSolverChoice::resolve`]);
/// a reduced basis is built over the variables' box ([`reduced_basis`]) or, with
/// `anchor` (the model's `v = [alpha, beta]` and the posterior's spread), made exact
/// there and around it.
pub fn mode_solver(
    model: &Arc<StructuralModel>,
    vars: &Variables,
    n_modes: usize,
    choice: ModeSolverChoice,
    anchor: Option<Anchor>,
) -> Result<ModelModes> {
    Ok(match choice.resolve(model) {
        ModeSolverChoice::Dense | ModeSolverChoice::Auto => {
            ModelModes::Dense(DenseModes::new(model.clone()))
        }
        ModeSolverChoice::Exact => ModelModes::Exact(CondensedModes::new(model.clone())),
        ModeSolverChoice::Reduced => {
            let (center, bounds) = variable_box(model, vars);
            let design = BasisDesign::default();
            ModelModes::Reduced(reduced_basis(
                model, n_modes, &center, &bounds, anchor, &design,
            )?)
        }
    })
}
