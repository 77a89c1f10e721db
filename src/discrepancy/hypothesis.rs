//! A hypothesis of missing physics: a model extension with physical parameters and
//! priors. The forward model ([`super::forward`]) builds the nominal frame (shear frame
//! with modal damping of its own modes) as a [`LinearSystem`] and asks the hypothesis to
//! change it ([`Hypothesis::modify_system`], once; [`Hypothesis::modify_for_segment`],
//! per segment, for amplitude-dependent physics) and to filter channels
//! ([`Hypothesis::sensor_factor`]). Adding a hypothesis is one file in
//! [`super::hypotheses`] and one line of [`super::hypotheses::all_hypotheses`].
//!
//! Every hypothesis contains the nominal model at one end of its prior (the effect's
//! size goes to 0 or to infinity), so the comparison is between nested models.
//!
//! Effect parameters are sampled in their own coordinates (the prior is uniform on
//! `[lower, upper]` in that coordinate, e.g. `ln m_b`); [`Hypothesis::physical`] maps
//! them to physical values (the units of [`EffectParam::unit`]), and the system and
//! sensor methods receive those physical values.

use super::data::{DiagnosisData, SegmentData};
use super::location::Location;
use crate::error::Result;
use crate::io::Channel;
use crate::simulate::{CubicSpring, LinearSystem};
use num_complex::Complex64;

/// How a sampled coordinate maps to the reported value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Coordinate {
    /// Physical value = `exp(z)`.
    Log,
    /// Physical value = `factor * z`.
    Linear { factor: f64 },
}

/// One effect parameter: its reported name and unit, and the uniform prior of its
/// sampled coordinate.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectParam {
    /// Name of the physical value reported (e.g. `base_mass`).
    pub name: String,
    /// Unit of the physical value (e.g. `kg`).
    pub unit: &'static str,
    /// Name of the sampled coordinate (e.g. `ln_base_mass`).
    pub coordinate_name: String,
    /// Prior of the sampled coordinate: uniform on `[lower, upper]`.
    pub lower: f64,
    pub upper: f64,
    pub coordinate: Coordinate,
    /// The physical value at which the effect vanishes (`0`, or infinite: e.g. a rigid
    /// base), for the decision rule; `None` when this parameter alone does not decide it
    /// (e.g. a damping ratio).
    pub no_effect: Option<f64>,
}

impl EffectParam {
    /// A parameter sampled as `ln value` uniform on `[ln lo, ln hi]` (physical units).
    pub fn log_uniform(
        name: &str,
        unit: &'static str,
        lo: f64,
        hi: f64,
        no_effect: Option<f64>,
    ) -> Self {
        EffectParam {
            name: name.into(),
            unit,
            coordinate_name: format!("ln_{name}"),
            lower: lo.ln(),
            upper: hi.ln(),
            coordinate: Coordinate::Log,
            no_effect,
        }
    }

    /// The physical value of sampled coordinate `z`.
    pub fn physical(&self, z: f64) -> f64 {
        match self.coordinate {
            Coordinate::Log => z.exp(),
            Coordinate::Linear { factor } => factor * z,
        }
    }

    /// The sampled coordinate of a physical value (inverse of [`Self::physical`]).
    pub fn coordinate_of(&self, value: f64) -> f64 {
        match self.coordinate {
            Coordinate::Log => value.ln(),
            Coordinate::Linear { factor } => value / factor,
        }
    }
}

/// A hypothesis of missing physics (see the module docs).
pub trait Hypothesis: Send + Sync + std::fmt::Debug {
    /// Name used in `diagnosis.json` (`"base_flexibility"`, ...).
    fn name(&self) -> &'static str;

    /// One sentence for reports.
    fn physics(&self) -> &'static str;

    /// Candidate locations in this campaign.
    fn locations(&self, data: &DiagnosisData) -> Vec<Location>;

    /// Effect parameters at `loc` with their priors, scaled by the nominal model (never
    /// by a benchmark). Errors when `loc` is not a location of this hypothesis.
    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>>;

    /// Physical values of the sampled effect coordinates `effect` (default: each
    /// parameter's own [`EffectParam::physical`]).
    fn physical(&self, data: &DiagnosisData, loc: &Location, effect: &[f64]) -> Result<Vec<f64>> {
        Ok(self
            .parameters(data, loc)?
            .iter()
            .zip(effect)
            .map(|(p, &z)| p.physical(z))
            .collect())
    }

    /// Changes the structure for every segment (extra DOFs allowed); `effect` holds the
    /// physical values of [`Self::physical`].
    fn modify_system(&self, loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        let _ = (loc, effect, sys);
        Ok(())
    }

    /// True when the system depends on the segment ([`Self::modify_for_segment`]).
    fn amplitude_dependent(&self) -> bool {
        false
    }

    /// Changes the structure for one segment (after [`Self::modify_system`]), e.g. an
    /// equivalent linearisation at the segment's amplitude.
    fn modify_for_segment(
        &self,
        loc: &Location,
        effect: &[f64],
        seg: &SegmentData,
        sys: &mut LinearSystem,
    ) -> Result<()> {
        let _ = (loc, effect, seg, sys);
        Ok(())
    }

    /// Nonlinear elements for a time-domain replay of the tests
    /// ([`super::time_domain`]), on `sys` after [`Self::modify_system`]; none by default.
    /// Hypotheses with elements are [`Self::amplitude_dependent`], and the replay of
    /// the tests stands in for [`Self::modify_for_segment`].
    fn cubic_springs(
        &self,
        loc: &Location,
        effect: &[f64],
        sys: &LinearSystem,
    ) -> Result<Vec<CubicSpring>> {
        let _ = (loc, effect, sys);
        Ok(Vec::new())
    }

    /// True when [`Self::sensor_factor`] of `channel` can differ from 1 at `loc`.
    fn affects_channel(&self, loc: &Location, channel: &Channel) -> bool {
        let _ = (loc, channel);
        false
    }

    /// The factor channel `channel` puts on what it measures at Laplace variable `s`
    /// (`s = j omega + 1/tau` under an exponential window: exact for any LTI sensor).
    /// The measured ratio is `H * factor(response) / factor(input)`. Called only for
    /// channels where [`Self::affects_channel`] is true (every other channel's factor
    /// is 1).
    fn sensor_factor(
        &self,
        loc: &Location,
        effect: &[f64],
        channel: &Channel,
        s: Complex64,
    ) -> Complex64 {
        let _ = (loc, effect, channel, s);
        Complex64::new(1.0, 0.0)
    }
}

/// Where a hypothesis that speaks of stories or of the base (a shear frame's) stands on
/// `data`'s model: its own `locations` on a shear frame; on a general model the whole
/// structure, whose [`Hypothesis::parameters`] then fail with [`shear_frame_only`], so
/// that the diagnosis reports it as not fitted, with the reason.
pub fn shear_frame_locations(data: &DiagnosisData, locations: Vec<Location>) -> Vec<Location> {
    match data.is_shear_frame() {
        true => locations,
        false => vec![Location::Whole],
    }
}

/// Errors unless `data`'s model is a shear frame (see [`shear_frame_locations`]).
pub fn shear_frame_only(name: &str, data: &DiagnosisData) -> Result<()> {
    match data.is_shear_frame() {
        true => Ok(()),
        false => Err(crate::Error::Usage(format!(
            "not testable: {name} acts on a shear frame's stories or base, and this \
             campaign's model is general (its groups and DOFs have no stories)"
        ))),
    }
}

/// Candidate channel locations of a sensor hypothesis: every response quantity present,
/// then every channel (inputs included) on its own.
pub fn sensor_locations(data: &DiagnosisData) -> Vec<Location> {
    let mut out: Vec<Location> = data
        .response_quantities()
        .into_iter()
        .map(Location::Quantity)
        .collect();
    out.extend(
        data.channels()
            .into_iter()
            .map(|c| Location::Channels(vec![c.name])),
    );
    out
}

/// Checks that `loc` is a channel location naming known channels.
pub fn check_sensor_location(name: &str, data: &DiagnosisData, loc: &Location) -> Result<()> {
    let known = data.channels();
    match loc {
        Location::Quantity(_) => Ok(()),
        Location::Channels(c) if !c.is_empty() => {
            if let Some(bad) = c.iter().find(|n| !known.iter().any(|k| &k.name == *n)) {
                return Err(crate::Error::Usage(format!(
                    "{name}: no channel called {bad} in this campaign"
                )));
            }
            Ok(())
        }
        other => Err(crate::Error::Usage(format!(
            "{name} acts on channels or a quantity, not on {other}"
        ))),
    }
}
