//! The FRF posterior's model on the inference layer: the [`FrfPredictor`] of a model's
//! updating variables, whose coordinates are the posterior's sampled ones before `ln s`
//! (free multipliers as they are, damping as logarithms).

use std::sync::Arc;

use crate::error::{Error, Result};
use crate::frf::FrfBlock;
use crate::model::StructuralModel;
use crate::predict::{
    Coordinate, DenseModes, FrfDamping, FrfOptions, FrfOutput, FrfPredictor, Parametrisation,
    Scale, Variable,
};
use crate::update::{self, DampingModel, VariableKind, Variables};

/// The magnitudes `|H^A|` of `model` over `blocks` (block `b` through an exponential
/// window of `window_tau_s[b]` s) as a function of the free variables of `vars` in their
/// internal coordinates, the `n_modes` lowest modes in the sums.
///
/// Multipliers must be on a linear scale and free damping on a log scale (as
/// [`super::FrfPosterior`] sets them); fixed damping keeps its value, a fixed multiplier
/// its value 0 (the model's nominal; other fixed multipliers are refused).
pub fn frf_predictor(
    model: &StructuralModel,
    vars: &Variables,
    n_modes: usize,
    blocks: &[FrfBlock],
    window_tau_s: &[Option<f64>],
) -> Result<FrfPredictor<DenseModes>> {
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
    let model = Arc::new(model.clone());
    let params = Parametrisation::new(&model, coordinates)?;
    let options = FrfOptions {
        damping: match vars.damping_model() {
            DampingModel::Rayleigh => FrfDamping::Rayleigh,
            DampingModel::Caughey => FrfDamping::Modal,
        },
        output: FrfOutput::Magnitude,
        n_modes,
    };
    let solver = DenseModes::new(model.clone());
    FrfPredictor::new(solver, model, params, options, blocks, window_tau_s)?
        .with_fixed_damping(fixed_damping)
}
