//! `base_flexibility`: the base is not rigid. A base mass `m_b` joined to the ground (or
//! the shake table) by a spring `k_b` and a dashpot `c_b` carries story 1 (the
//! simulator's [`BaseFlexibility`]: displacement channels stay relative to the ground,
//! base motion included; in hammer tests the ground is fixed and the base moves).
//!
//! Parameters: `m_b`, the base's own natural frequency `f_b = sqrt(k_b / m_b) / (2 pi)`
//! (the base on its spring with the frame removed) and damping ratio
//! `zeta_b = c_b / (2 sqrt(k_b m_b))`, so that `k_b = m_b (2 pi f_b)^2` and
//! `c_b = 2 zeta_b sqrt(k_b m_b)`. The nominal model is the limit `f_b -> inf` at any
//! mass (a stiffness bound alone would not do: a heavy base on a stiff spring still
//! resonates in band). Priors (log-uniform), scaled by the nominal model: `m_b`
//! 0.02..2 x the frame's total mass; `f_b` 0.3 x the lowest .. 100 x the highest nominal
//! natural frequency; `zeta_b` 1e-3..1.

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{shear_frame_only, EffectParam, Hypothesis};
use crate::discrepancy::location::Location;
use crate::error::{Error, Result};
use crate::simulate::{BaseFlexibility, LinearSystem, SystemEffect};

#[derive(Debug, Clone, Copy, Default)]
pub struct BaseFlexibilityHypothesis;

impl BaseFlexibilityHypothesis {
    /// The simulator's effect of physical values `[m_b kg, f_b Hz, zeta_b]`.
    pub fn effect(effect: &[f64]) -> BaseFlexibility {
        let (m, f, zeta) = (effect[0], effect[1], effect[2]);
        let k = m * (2.0 * std::f64::consts::PI * f).powi(2);
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
        shear_frame_only(self.name(), data)?;
        if *loc != Location::Whole {
            return Err(Error::Usage(format!(
                "base_flexibility acts on the whole structure, not on {loc}"
            )));
        }
        let total: f64 = data.nominal.floor_mass_kg.iter().sum();
        let fr = &data.nominal_freq_hz;
        Ok(vec![
            EffectParam::log_uniform("base_mass", "kg", 0.02 * total, 2.0 * total, None),
            EffectParam::log_uniform(
                "base_frequency",
                "Hz",
                0.3 * fr[0],
                100.0 * fr[fr.len() - 1],
                Some(f64::INFINITY),
            ),
            EffectParam::log_uniform("base_damping_ratio", "1", 1e-3, 1.0, None),
        ])
    }

    fn modify_system(&self, _loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        Self::effect(effect).apply(sys)
    }
}
