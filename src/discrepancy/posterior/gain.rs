//! The input-gain error's part of [`ModelPosterior`]'s likelihood: the Woodbury terms of
//! the gain segments (factors of `G` kept per thread, [`GainCache`]) and the carrier the
//! gain error multiplies ([`GainCarrier`]). The kept factors are keyed by `eta` and the
//! carrier itself (a new plug-in is a new key), so nothing needs resetting.

use super::super::gain_solve::{gain_apply, gain_factor, GainFactor};
use super::ModelPosterior;
use crate::discrepancy::data::GainCarrier;
use crate::error::Result;
use num_complex::Complex64;
use std::sync::Arc;

/// The ratios the input-gain error multiplies, and what keys the factors of `G` kept
/// for them (a plug-in by its `Arc`; the prediction is never kept).
#[derive(Clone, Copy)]
enum CarrierKey<'a> {
    Prediction,
    Measured,
    PlugIn(&'a Arc<Vec<Complex64>>),
}

impl ModelPosterior {
    /// The correlated gain errors' part of [`Self::quadratic_and_ln_det`]: what they take
    /// from the quadratic form and add to the log-determinant (Woodbury, summed over
    /// the gain segments); `inv_d(i)` is point `i`'s `1 / (2 sigma_i^2)` at `eta`;
    /// `gains` receives each segment's `g`. The whitened residuals
    /// need only the `g`, not the diagonal part's quotient and logarithm per point
    /// (skipping them cut the four-story diagnosis from 185 s to 170 s of CPU).
    pub(super) fn gain_terms(
        &self,
        pred: &[Complex64],
        eta: f64,
        inv_d: impl Fn(usize) -> f64,
        mut gains: Option<&mut Vec<Vec<Complex64>>>,
    ) -> (f64, f64) {
        let key = self.carrier_key();
        let carrier = self.carrier_of(key, pred);
        // `w` and `bk` take the same `V` (`diag(carrier) U`), which keeps
        // `q <= e^* D^-1 e`.
        let build = || {
            self.gains
                .iter()
                .map(|gs| {
                    let mut w = vec![0.0; gs.n_freq];
                    for (j, &k) in gs.freq_of.iter().enumerate() {
                        let i = gs.start + j;
                        w[k as usize] += carrier[i].norm_sqr() * inv_d(i);
                    }
                    gain_factor(gs, &w)
                })
                .collect::<Vec<_>>()
        };
        let mut apply = |factors: &[GainFactor]| {
            let (mut quad, mut ln_det) = (0.0, 0.0);
            for (gs, f) in self.gains.iter().zip(factors) {
                let mut bk = vec![Complex64::new(0.0, 0.0); gs.n_freq];
                for (j, &k) in gs.freq_of.iter().enumerate() {
                    let i = gs.start + j;
                    bk[k as usize] += carrier[i].conj() * (self.h[i] - pred[i]) * inv_d(i);
                }
                let (g, q) = gain_apply(gs, f, &bk);
                quad += q;
                ln_det += f.ln_det;
                if let Some(out) = gains.as_deref_mut() {
                    out.push(g);
                }
            }
            (quad, ln_det)
        };
        // The factors depend on the carrier: kept unless it is the prediction itself.
        match key {
            CarrierKey::Prediction => apply(&build()),
            CarrierKey::Measured => self.gain_cache.with(eta, None, build, apply),
            CarrierKey::PlugIn(at_map) => self.gain_cache.with(eta, Some(at_map), build, apply),
        }
    }

    /// Factor sets of the gain segments' `G` built so far (for tests of the cache).
    #[cfg(test)]
    pub(in crate::discrepancy) fn gain_factor_builds(&self) -> usize {
        self.gain_cache.builds()
    }

    /// The ratios the input-gain error multiplies (flat layout,
    /// [`super::data::DataOptions::gain_carrier`]): the measured `h`, the prediction, or
    /// the prediction at the MAP once [`Self::at_map`] has set it.
    pub(super) fn gain_carrier<'a>(&'a self, pred: &'a [Complex64]) -> &'a [Complex64] {
        self.carrier_of(self.carrier_key(), pred)
    }

    /// Which ratios carry the gain error ([`Self::gain_carrier`]).
    fn carrier_key(&self) -> CarrierKey<'_> {
        match (self.data().options.gain_carrier, &self.gain_plug_in) {
            (GainCarrier::Model, _) => CarrierKey::Prediction,
            (GainCarrier::ModelAtMap, Some(at_map)) => CarrierKey::PlugIn(at_map),
            _ => CarrierKey::Measured,
        }
    }

    fn carrier_of<'a>(&'a self, key: CarrierKey<'a>, pred: &'a [Complex64]) -> &'a [Complex64] {
        match key {
            CarrierKey::Prediction => pred,
            CarrierKey::PlugIn(at_map) => at_map,
            CarrierKey::Measured => &self.h,
        }
    }

    /// With [`GainCarrier::ModelAtMap`], the same posterior with the model at `z` (its
    /// MAP) as the gain carrier from now on; otherwise unchanged.
    pub fn at_map(mut self, z: &[f64]) -> Result<Self> {
        match self.data().options.gain_carrier {
            GainCarrier::ModelAtMap => {
                let carrier = match self.replay_carrier(z)? {
                    Some(c) => c,
                    None => self.predict(z)?,
                };
                self.gain_plug_in = Some(Arc::new(carrier));
                Ok(self)
            }
            _ => Ok(self),
        }
    }

    /// [`Self::at_map`] with the prediction at `z` given (flat layout). The carrier is
    /// that prediction, except for a replay with a cubic spring, whose ratios depend on
    /// the drive's level: there it is [`TimeDomainModel::gain_carrier`].
    pub fn at_map_predicted(mut self, z: &[f64], pred: Vec<Complex64>) -> Result<Self> {
        if self.data().options.gain_carrier != GainCarrier::ModelAtMap {
            return Ok(self);
        }
        let carrier = self.replay_carrier(z)?.unwrap_or(pred);
        self.gain_plug_in = Some(Arc::new(carrier));
        Ok(self)
    }

    /// [`TimeDomainModel::gain_carrier`] at `z` for a replay (`None`: the carrier is the
    /// prediction).
    fn replay_carrier(&self, z: &[f64]) -> Result<Option<Vec<Complex64>>> {
        let Some(td) = &self.time_domain else {
            return Ok(None);
        };
        let (base, effect) = (self.base_params(z), self.effect_physical(z)?);
        let hyp = self.model.hypothesis();
        td.gain_carrier(&base, hyp.map(|(h, l)| (h.as_ref(), l)), &effect)
    }
}
