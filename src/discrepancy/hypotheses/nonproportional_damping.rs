//! `nonproportional_damping`: a discrete viscous damper across one story on top of the
//! frame's proportional (modal) damping; the modes become complex and the phases tell.
//! The simulator's [`Dashpot`] across story `s`.
//!
//! Prior: `c` log-uniform on 1e-4..1 x the story's critical coefficient
//! `2 sqrt(k_s m_s)` (nominal story stiffness and floor mass); the nominal model is the
//! limit `c -> 0`.

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{
    shear_frame_locations, shear_frame_only, EffectParam, Hypothesis,
};
use crate::discrepancy::location::Location;
use crate::error::{Error, Result};
use crate::simulate::{Dashpot, LinearSystem, SystemEffect};

#[derive(Debug, Clone, Copy, Default)]
pub struct NonproportionalDamping;

fn story_of(loc: &Location, n_floors: usize) -> Result<usize> {
    match loc {
        Location::Story(s) if (1..=n_floors).contains(s) => Ok(*s),
        other => Err(Error::Usage(format!(
            "nonproportional_damping acts on a story 1..={n_floors}, not on {other}"
        ))),
    }
}

impl Hypothesis for NonproportionalDamping {
    fn name(&self) -> &'static str {
        "nonproportional_damping"
    }

    fn physics(&self) -> &'static str {
        "a discrete viscous damper across one story adds non-proportional damping"
    }

    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        shear_frame_locations(data, (1..=data.n_floors()).map(Location::Story).collect())
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        shear_frame_only(self.name(), data)?;
        let s = story_of(loc, data.n_floors())?;
        let c_crit = 2.0
            * (data.nominal.story_stiffness_n_per_m[s - 1] * data.nominal.floor_mass_kg[s - 1])
                .sqrt();
        Ok(vec![EffectParam::log_uniform(
            "damper_coefficient",
            "N s/m",
            1e-4 * c_crit,
            c_crit,
            Some(0.0),
        )])
    }

    fn modify_system(&self, loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        let s = story_of(loc, sys.n_floors())?;
        Dashpot::story(s, effect[0]).apply(sys)
    }
}
