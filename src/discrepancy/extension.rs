//! Several effects in one model: the effects a stepwise diagnosis has already accepted,
//! plus one more hypothesis under test ([`WithEffects`]). It is itself a [`Hypothesis`],
//! so the posterior, the location search, the evidence, the held-out check and the
//! time-domain refit take it unchanged: a diagnosis with two effects is the same
//! machinery as one with one.
//!
//! Its effect coordinates are those of the accepted effects, in the order they were
//! added, then those of the added hypothesis; all of them stay free (an effect accepted
//! first is refitted with the one added after it). The system is changed by each effect
//! in that order (each acts on the structure left by the ones before it: the
//! simulator's effects keep floors and stories on their DOFs whatever DOFs were added),
//! and a channel's sensor factor is the product of the effects' factors.

use super::data::{DiagnosisData, SegmentData};
use super::hypothesis::{EffectParam, Hypothesis};
use super::location::Location;
use crate::error::{Error, Result};
use crate::io::Channel;
use crate::simulate::{CubicSpring, LinearSystem};
use num_complex::Complex64;
use std::sync::Arc;

/// An accepted effect: a hypothesis at its location.
#[derive(Debug, Clone)]
pub struct Effect {
    pub hypothesis: Arc<dyn Hypothesis>,
    pub location: Location,
}

impl Effect {
    /// Its effect parameters, renamed `name_k` where an earlier effect already uses the
    /// name (the same hypothesis twice: two oscillators), `k` its 1-based position.
    fn parameters(
        &self,
        data: &DiagnosisData,
        position: usize,
        taken: &[EffectParam],
    ) -> Result<Vec<EffectParam>> {
        let mut ps = self.hypothesis.parameters(data, &self.location)?;
        for p in &mut ps {
            if taken.iter().any(|t| t.name == p.name) {
                p.name = format!("{}_{}", p.name, position + 1);
                p.coordinate_name = format!("{}_{}", p.coordinate_name, position + 1);
            }
        }
        Ok(ps)
    }
}

/// One part of a [`WithEffects`]: a hypothesis, its location and its effect values.
type Part<'a> = (&'a dyn Hypothesis, &'a Location, &'a [f64]);

/// Accepted effects plus the hypothesis under test (see the module docs).
#[derive(Debug, Clone)]
pub struct WithEffects {
    accepted: Vec<Effect>,
    /// Effect coordinates of each accepted effect, in order.
    counts: Vec<usize>,
    added: Arc<dyn Hypothesis>,
}

impl WithEffects {
    /// `added` on top of `accepted` (which may be empty: then it behaves as `added`).
    /// Errors when an accepted effect cannot act on `data` at its location.
    pub fn new(
        data: &DiagnosisData,
        accepted: Vec<Effect>,
        added: Arc<dyn Hypothesis>,
    ) -> Result<Self> {
        let counts = accepted
            .iter()
            .map(|e| e.hypothesis.parameters(data, &e.location).map(|p| p.len()))
            .collect::<Result<Vec<_>>>()?;
        Ok(WithEffects {
            accepted,
            counts,
            added,
        })
    }

    /// Every part with its location and its slice of `effect` (`added` at `loc`, last,
    /// takes what the accepted effects leave).
    fn parts<'a>(&'a self, loc: &'a Location, effect: &'a [f64]) -> Result<Vec<Part<'a>>> {
        let mut out = Vec::with_capacity(self.accepted.len() + 1);
        let mut at = 0;
        for (e, &n) in self.accepted.iter().zip(&self.counts) {
            let part = effect.get(at..at + n).ok_or_else(|| {
                Error::Usage(format!(
                    "{} effect values; the accepted effects alone have {}",
                    effect.len(),
                    self.counts.iter().sum::<usize>()
                ))
            })?;
            out.push((e.hypothesis.as_ref(), &e.location, part));
            at += n;
        }
        out.push((self.added.as_ref(), loc, &effect[at..]));
        Ok(out)
    }
}

impl Hypothesis for WithEffects {
    fn name(&self) -> &'static str {
        self.added.name()
    }

    fn physics(&self) -> &'static str {
        self.added.physics()
    }

    /// The added hypothesis' locations, less those where it is already accepted.
    fn locations(&self, data: &DiagnosisData) -> Vec<Location> {
        self.added
            .locations(data)
            .into_iter()
            .filter(|l| {
                !self
                    .accepted
                    .iter()
                    .any(|e| e.hypothesis.name() == self.added.name() && e.location == *l)
            })
            .collect()
    }

    fn parameters(&self, data: &DiagnosisData, loc: &Location) -> Result<Vec<EffectParam>> {
        let mut all: Vec<EffectParam> = Vec::new();
        for (k, e) in self.accepted.iter().enumerate() {
            let ps = e.parameters(data, k, &all)?;
            all.extend(ps);
        }
        let added = Effect {
            hypothesis: self.added.clone(),
            location: loc.clone(),
        };
        let ps = added.parameters(data, self.accepted.len(), &all)?;
        all.extend(ps);
        Ok(all)
    }

    fn physical(&self, data: &DiagnosisData, loc: &Location, effect: &[f64]) -> Result<Vec<f64>> {
        let mut out = Vec::with_capacity(effect.len());
        for (h, l, z) in self.parts(loc, effect)? {
            out.extend(h.physical(data, l, z)?);
        }
        Ok(out)
    }

    fn modify_system(&self, loc: &Location, effect: &[f64], sys: &mut LinearSystem) -> Result<()> {
        for (h, l, v) in self.parts(loc, effect)? {
            h.modify_system(l, v, sys)?;
        }
        Ok(())
    }

    fn amplitude_dependent(&self) -> bool {
        self.accepted
            .iter()
            .any(|e| e.hypothesis.amplitude_dependent())
            || self.added.amplitude_dependent()
    }

    fn modify_for_segment(
        &self,
        loc: &Location,
        effect: &[f64],
        seg: &SegmentData,
        sys: &mut LinearSystem,
    ) -> Result<()> {
        for (h, l, v) in self.parts(loc, effect)? {
            h.modify_for_segment(l, v, seg, sys)?;
        }
        Ok(())
    }

    fn cubic_springs(
        &self,
        loc: &Location,
        effect: &[f64],
        sys: &LinearSystem,
    ) -> Result<Vec<CubicSpring>> {
        let mut out = Vec::new();
        for (h, l, v) in self.parts(loc, effect)? {
            out.extend(h.cubic_springs(l, v, sys)?);
        }
        Ok(out)
    }

    fn affects_channel(&self, loc: &Location, channel: &Channel) -> bool {
        self.accepted
            .iter()
            .any(|e| e.hypothesis.affects_channel(&e.location, channel))
            || self.added.affects_channel(loc, channel)
    }

    fn sensor_factor(
        &self,
        loc: &Location,
        effect: &[f64],
        channel: &Channel,
        s: Complex64,
    ) -> Complex64 {
        let Ok(parts) = self.parts(loc, effect) else {
            return Complex64::new(f64::NAN, f64::NAN);
        };
        parts
            .into_iter()
            .filter(|(h, l, _)| h.affects_channel(l, channel))
            .map(|(h, l, v)| h.sensor_factor(l, v, channel, s))
            .product()
    }
}
