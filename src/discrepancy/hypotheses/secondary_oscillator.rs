//! `secondary_oscillator`: a mass on a spring and dashpot attached to one floor (an
//! appendage, equipment, a local mode): one extra DOF the floor sensors do not see. The
//! simulator's [`Oscillator`].
//!
//! Locations: every floor of a shear frame; on a general model every DOF with mass that
//! carries a response channel (a floor is a DOF: the campaign format's convention).
//!
//! Priors (log-uniform), scaled by the nominal model: mass 1e-3..0.3 x the floor's
//! nominal mass (the DOF's diagonal entry of the nominal `M`; a shear frame's floor
//! mass) (the nominal model is the limit of zero mass); natural frequency on a
//! fixed floor 0.5 x the lowest .. 1.5 x the highest nominal natural frequency; damping
//! ratio 1e-3..0.3.

use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::hypothesis::{EffectParam, Hypothesis};
use crate::discrepancy::location::Location;
use crate::error::{Error, Result};
use crate::simulate::{LinearSystem, Oscillator, SystemEffect};

#[derive(Debug, Clone, Copy, Default)]
pub struct SecondaryOscillator;

fn floor_of(loc: &Location, n_floors: usize) -> Result<usize> {
    match loc {
        Location::Floor(f) if (1..=n_floors).contains(f) => Ok(*f),
        other => Err(Error::Usage(format!(
            "secondary_oscillator sits on a floor 1..={n_floors}, not on {other}"
        ))),
    }
}

/// The nominal mass of floor (DOF) `f`, 1-based: the diagonal entry of the nominal `M`
/// (a shear frame's floor mass). Read in place: [`Hypothesis::physical`] asks for the
/// parameters at every posterior evaluation.
fn dof_mass(data: &DiagnosisData, f: usize) -> f64 {
    let m = data.model.nominal_mass();
    f.checked_sub(1)
        .filter(|&d| d < m.nrows())
        .map_or(0.0, |d| m[(d, d)])
}

impl SecondaryOscillator {
    /// The oscillator of physical values `[mass_kg, freq_hz, damping_ratio]`.
    fn effect(floor: usize, effect: &[f64]) -> Oscillator {
        let (m, f, zeta) = (effect[0], effect[1], effect[2]);
        let w = 2.0 * std::f64::consts::PI * f;
        Oscillator {
            floor,
            mass_kg: m,
            stiffness_n_per_m: m * w * w,
            damping_ratio: zeta,
        }
    }
}

impl Hypothesis for SecondaryOscillator {
    fn name(&self) -> &'static str {
        "secondary_oscillator"
    }

    fn physics(&self) -> &'static str {
        "a secondary mass-spring-damper (appendage, equipment, local mode) is attached to one floor"
    }

    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        if data.is_shear_frame() {
            return (1..=data.n_floors()).map(Location::Floor).collect();
        }
        let mut dofs: Vec<usize> = data
            .segments
            .iter()
            .flat_map(|s| s.channels.iter().map(|c| c.channel.floor))
            .filter(|&f| dof_mass(data, f) > 0.0)
            .collect();
        dofs.sort_unstable();
        dofs.dedup();
        dofs.into_iter().map(Location::Floor).collect()
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        let f = floor_of(loc, data.n_floors())?;
        let m = dof_mass(data, f);
        if m.is_nan() || m <= 0.0 {
            return Err(Error::Usage(format!(
                "secondary_oscillator: DOF {f} has no mass of its own in the nominal model"
            )));
        }
        let fr = &data.nominal_freq_hz;
        Ok(vec![
            EffectParam::log_uniform("oscillator_mass", "kg", 1e-3 * m, 0.3 * m, Some(0.0)),
            EffectParam::log_uniform(
                "oscillator_frequency",
                "Hz",
                0.5 * fr[0],
                1.5 * fr[fr.len() - 1],
                None,
            ),
            EffectParam::log_uniform("oscillator_damping_ratio", "1", 1e-3, 0.3, None),
        ])
    }

    fn modify_system(&self, loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        let f = floor_of(loc, sys.n_floors())?;
        Self::effect(f, effect).apply(sys)
    }
}
