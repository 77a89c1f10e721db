//! `base_flexibility`: the base is not rigid. A base mass `m_b` joined to the ground (or
//! the shake table) by a spring `k_b` and a dashpot `c_b` carries story 1 (the
//! simulator's [`BaseFlexibility`]: displacement channels stay relative to the ground,
//! base motion included; in hammer tests the ground is fixed and the base moves).
//!
//! Priors (uniform in the logarithm), scaled by the nominal model: `m_b` in
//! 0.02-2 x the frame's total mass; `k_b` in 0.5-1000 x the nominal story-1 stiffness
//! (the nominal model is the limit `k_b -> inf`); the base's own damping ratio
//! `zeta_b = c_b / (2 sqrt(k_b m_b))` in 1e-3..1. Reported: `m_b` (kg), `k_b` (N/m),
//! `c_b` (N s/m).

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{EffectParam, Hypothesis};
use crate::discrepancy::location::Location;
use crate::error::{Error, Result};
use crate::simulate::{BaseFlexibility, LinearSystem, SystemEffect};

#[derive(Debug, Clone, Copy, Default)]
pub struct BaseFlexibilityHypothesis;

impl BaseFlexibilityHypothesis {
    fn effect(effect: &[f64]) -> BaseFlexibility {
        let (m, k, zeta) = (effect[0].exp(), effect[1].exp(), effect[2].exp());
        BaseFlexibility {
            mass_kg: m,
            stiffness_n_per_m: k,
            damping_n_s_per_m: 2.0 * zeta * (k * m).sqrt(),
        }
    }
}

impl Hypothesis for BaseFlexibilityHypothesis {
    fn name(&self) -> &'static str {
        "base_flexibility"
    }

    fn physics(&self) -> &'static str {
        "the base is not rigid: the frame stands on a base mass held by a spring and a dashpot"
    }

    fn locations(&self, _data: &DiagnosisData) -> Vec<Location> {
        vec![Location::Whole]
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        if *loc != Location::Whole {
            return Err(Error::Usage(format!(
                "base_flexibility acts on the whole structure, not on {loc}"
            )));
        }
        let total: f64 = data.nominal.floor_mass_kg.iter().sum();
        let k1 = data.nominal.story_stiffness_n_per_m[0];
        let mut zeta = EffectParam::log_uniform("base_damping", "N s/m", 1e-3, 1.0, None);
        zeta.coordinate_name = "ln_base_damping_ratio".into();
        Ok(vec![
            EffectParam::log_uniform("base_mass", "kg", 0.02 * total, 2.0 * total, None),
            EffectParam::log_uniform(
                "base_stiffness",
                "N/m",
                0.5 * k1,
                1000.0 * k1,
                Some(f64::INFINITY),
            ),
            zeta,
        ])
    }

    fn physical(&self, _data: &DiagnosisData, _loc: &Location, effect: &[f64]) -> Result<Vec<f64>> {
        let b = Self::effect(effect);
        Ok(vec![b.mass_kg, b.stiffness_n_per_m, b.damping_n_s_per_m])
    }

    fn modify_system(&self, _loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        BaseFlexibility {
            mass_kg: effect[0],
            stiffness_n_per_m: effect[1],
            damping_n_s_per_m: effect[2],
        }
        .apply(sys)
    }
}
