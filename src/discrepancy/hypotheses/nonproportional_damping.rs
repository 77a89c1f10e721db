//! `nonproportional_damping`: a discrete viscous damper across one story (on a general
//! model: across one connection between two DOFs) on top of the model's proportional
//! (modal) damping; the modes become complex and the phases tell. The simulator's
//! [`Dashpot`].
//!
//! Locations: every story of a shear frame; on a general model every pair of DOFs that a
//! stiffness term of the nominal `K` joins (`K_ab != 0`), at least one of them
//! instrumented.
//!
//! Prior: `c` log-uniform on 1e-4..1 x the connection's critical coefficient
//! `2 sqrt(k m)`: a story's nominal stiffness and its upper floor's mass; a connection's
//! `|K_ab|` and the lighter end's diagonal mass. The nominal model is the limit `c -> 0`.

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{EffectParam, Hypothesis};
use crate::discrepancy::location::Location;
use crate::error::{Error, Result};
use crate::simulate::{Dashpot, LinearSystem, SystemEffect};

#[derive(Debug, Clone, Copy, Default)]
pub struct NonproportionalDamping;

/// The two levels (0 = the ground; floors and DOFs 1-based) the damper at `loc` joins.
fn levels_of(loc: &Location, data_is_frame: bool, n: usize) -> Result<[usize; 2]> {
    match loc {
        Location::Story(s) if data_is_frame && (1..=n).contains(s) => Ok([s - 1, *s]),
        Location::Dofs([a, b]) if !data_is_frame && a < b && *b <= n => Ok([*a, *b]),
        other => Err(Error::Usage(format!(
            "nonproportional_damping acts on a story of a shear frame or on the connection \
             of two DOFs of a general model (1..={n}), not on {other}"
        ))),
    }
}

/// Diagonal entry `d` (1-based) of `m`, 0 for the ground.
fn diagonal(m: &nalgebra::DMatrix<f64>, d: usize) -> f64 {
    d.checked_sub(1).map_or(0.0, |i| m[(i, i)])
}

impl Hypothesis for NonproportionalDamping {
    fn name(&self) -> &'static str {
        "nonproportional_damping"
    }

    fn physics(&self) -> &'static str {
        "a discrete viscous damper across one story (or connection) adds non-proportional damping"
    }

    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        let n = data.n_floors();
        if data.is_shear_frame() {
            return (1..=n).map(Location::Story).collect();
        }
        let model = &data.model;
        let k = model.stiffness(&model.alpha_zero());
        let instrumented: Vec<usize> = data
            .segments
            .iter()
            .flat_map(|s| s.channels.iter().map(|c| c.channel.floor))
            .collect();
        let mut out = Vec::new();
        for b in 1..=n {
            for a in 1..b {
                let joined = k[(a - 1, b - 1)] != 0.0;
                if joined && (instrumented.contains(&a) || instrumented.contains(&b)) {
                    out.push(Location::Dofs([a, b]));
                }
            }
        }
        out
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        let [a, b] = levels_of(loc, data.is_shear_frame(), data.n_floors())?;
        let model = &data.model;
        let c_crit = if data.is_shear_frame() {
            2.0 * (data.nominal.story_stiffness_n_per_m[b - 1] * data.nominal.floor_mass_kg[b - 1])
                .sqrt()
        } else {
            let (k, m) = (
                model.stiffness(&model.alpha_zero()),
                model.mass(&model.beta_zero()),
            );
            let (ma, mb) = (diagonal(&m, a), diagonal(&m, b));
            let lighter = if a == 0 { mb } else { ma.min(mb) };
            2.0 * (k[(a.max(1) - 1, b - 1)].abs() * lighter).sqrt()
        };
        if !(c_crit.is_finite() && c_crit > 0.0) {
            return Err(Error::Usage(format!(
                "nonproportional_damping: no stiffness or mass at {loc} to scale its prior"
            )));
        }
        Ok(vec![EffectParam::log_uniform(
            "damper_coefficient",
            "N s/m",
            1e-4 * c_crit,
            c_crit,
            Some(0.0),
        )])
    }

    fn modify_system(&self, loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        let levels = match loc {
            Location::Story(s) if *s >= 1 => [s - 1, *s],
            Location::Dofs(d) => *d,
            other => {
                return Err(Error::Usage(format!(
                    "nonproportional_damping cannot act on {other}"
                )))
            }
        };
        Dashpot::between(levels, effect[0]).apply(sys)
    }
}
