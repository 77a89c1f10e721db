//! `nonproportional_damping`: a discrete viscous damper across one story (on a general
//! model: across one connection between two DOFs) on top of the model's proportional
//! (modal) damping; the modes become complex and the phases tell. The simulator's
//! [`Dashpot`].
//!
//! Locations: every story of a shear frame; on a general model every pair of DOFs that a
//! stiffness term of the nominal `K` joins (`K_ab != 0`), at least one of them
//! instrumented (on a model reduced for the diagnosis, both kept).
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
fn levels(loc: &Location) -> Result<[usize; 2]> {
    match loc {
        Location::Story(s) if *s >= 1 => Ok([s - 1, *s]),
        Location::Dofs([a, b]) if a < b => Ok([*a, *b]),
        other => Err(Error::Usage(format!(
            "nonproportional_damping acts on a story or on the connection of two DOFs, not \
             on {other}"
        ))),
    }
}

/// [`levels`], checked against `data`'s model: a story of a shear frame, a connection
/// of two DOFs of a general model, inside its floors or DOFs.
fn levels_in(loc: &Location, data: &DiagnosisData) -> Result<[usize; 2]> {
    let [a, b] = levels(loc)?;
    // A general model's connections join two of its DOFs (the ground is not one).
    let kind_fits = match loc {
        Location::Story(_) => data.is_shear_frame(),
        _ => !data.is_shear_frame() && a >= 1,
    };
    if !kind_fits || b > data.n_floors() {
        return Err(Error::Usage(format!(
            "nonproportional_damping: {loc} is not a {} of this model (1..={})",
            if data.is_shear_frame() {
                "story"
            } else {
                "connection of DOFs"
            },
            data.n_floors()
        )));
    }
    Ok([a, b])
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
        let instrumented: Vec<usize> = data
            .segments
            .iter()
            .flat_map(|s| s.channels.iter().map(|c| c.channel.floor))
            .collect();
        // A reduced model's DOFs are coupled through its generalised coordinates; its
        // connections are the full model's, between kept DOFs.
        let pairs: Vec<[usize; 2]> = match &data.reduction {
            Some(r) => r.connections.clone(),
            None => {
                let k = data.model.nominal_stiffness();
                (1..=n)
                    .flat_map(|b| (1..b).map(move |a| [a, b]))
                    .filter(|&[a, b]| k[(a - 1, b - 1)] != 0.0)
                    .collect()
            }
        };
        pairs
            .into_iter()
            .filter(|[a, b]| instrumented.contains(a) || instrumented.contains(b))
            .map(Location::Dofs)
            .collect()
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        let [a, b] = levels_in(loc, data)?;
        let c_crit = if data.is_shear_frame() {
            2.0 * (data.nominal.story_stiffness_n_per_m[b - 1] * data.nominal.floor_mass_kg[b - 1])
                .sqrt()
        } else {
            let (k, m) = (data.model.nominal_stiffness(), data.model.nominal_mass());
            let lighter = m[(a - 1, a - 1)].min(m[(b - 1, b - 1)]);
            2.0 * (k[(a - 1, b - 1)].abs() * lighter).sqrt()
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
        Dashpot::between(levels(loc)?, effect[0]).apply(sys)
    }
}
