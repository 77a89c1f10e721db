//! The hammer estimator's own systematic error, measured by replaying the tests.
//!
//! The frequency-domain model ([`super::forward`]) predicts what an ideal H1 estimate of
//! each segment would be: the windowed FRF `H(j omega + 1/tau)`. A per-impact hammer
//! segment is not ideal. Its record starts while the previous impact's response still
//! rings (a mode of damping `xi` at `omega` keeps `exp(-xi omega Delta)` of its amplitude
//! after `Delta` s: 3 % for 1.1 % at 0.86 Hz over 60 s), that ringing is in the quiet
//! part that sets the sensor offsets, and the record is cut before the next impact. None
//! of this is noise: it is the same in every replicate, and the Bendat-Piersol error
//! does not contain it. On the false-alarm study's null campaigns with a lightly damped
//! first mode (`experiments/models/discrepancy/nulls`, null-03 and null-04) it was
//! 0.04-0.5 % (median over the in-band points of an impact-2 segment, noise-free), five
//! to ten times that of impact 1 and of the better-damped nulls, enough for hypotheses to
//! absorb it and for the nominal model to fail its adequacy test.
//!
//! The time-domain model ([`super::time_domain`]) replays each test from its recorded
//! input and estimates every segment exactly as the data were, so it carries these
//! effects. The bias is the replay minus the frequency-domain prediction at the nominal
//! model's MAP, on hammer segments (the shake-table estimate is already the ideal one
//! within the replay's own accuracy: there the replay is the worse of the two). It is
//! then added to every frequency-domain prediction ([`DiagnosisData::with_estimator_bias`]),
//! of the nominal model and of every hypothesis, before a sensor hypothesis' filters
//! (which shape the carried-over ringing as they shape the rest of the response): first order in the change of the frame
//! between the MAP and the point evaluated. The carried-over ringing's phase turns by
//! `omega Delta` times a mode frequency's relative change (0.03 rad for 1e-4 at 0.86 Hz
//! and 60 s), so the correction holds where the data pin the modes (the posteriors'
//! frequencies are within about 1e-4 of the nominal MAP's), not across the prior box
//! (`tests/discrepancy_estimator_bias.rs`).
//!
//! **On by default** (`diagnose --no-estimator-bias` turns it off). Measured once, at the
//! nominal MAP, it turned the final model of the recorded four-story campaign (sensor
//! dynamics at the accelerometers) from adequate to not adequate (at the acc3/disp3
//! place of hammer-floor4 chi2 per point 1.00 -> 1.57): there the nominal MAP is a frame
//! distorted by the filter the model leaves out, and a ringing whose phase turns by
//! `omega Delta` times the frequencies' error is measured wrong. So it is measured again
//! at each accepted model's MAP ([`super::stepwise`]; both sides the structure's
//! response alone, the effects' sensor factors applying to the bias as to the rest), the
//! model refitted and its evidence recomputed on those data, which the next round uses.
//! With that the four-story final model is adequate (chi2 per point 0.55, 3 of 360
//! cells) in 56 s (2026-11-27, idle 2-core machine).
//!
//! The replay is stepped [`REPLAY_OVERSAMPLING`] times per sample interval on the
//! input's band-limited interpolation, and its ratios are corrected for its hold
//! ([`super::time_domain`]), so that what is left is the estimator's error, not the
//! replay's.

use super::data::DiagnosisData;
use super::posterior::ModelPosterior;
use super::time_domain::TimeDomainModel;
use crate::error::{Error, Result};
use crate::io::Campaign;
use num_complex::Complex64;
use std::ops::Range;

/// The replay's prediction minus the frequency-domain one at `z` of `post`, on hammer
/// segments (zero on shake-table segments); flat layout. `post` is the nominal model or
/// the nominal model with effects ([`super::extension::WithEffects`]) whose structure
/// does not depend on the amplitude: both sides are the structure's response alone,
/// without the bias `post`'s data may already carry and without sensor factors, which
/// the prediction applies to the bias as to the rest.
pub fn replay_bias(
    campaign: &Campaign,
    post: &ModelPosterior,
    z: &[f64],
) -> Result<Vec<Complex64>> {
    let hypothesis = post.model().hypothesis();
    if hypothesis.is_some_and(|(h, _)| h.amplitude_dependent()) {
        return Err(Error::Usage(
            "the estimator's bias is measured on a model whose structure does not depend \
             on the amplitude (a replay of it would contain the linearisation's error too)"
                .into(),
        ));
    }
    let (base, effect) = (post.base_params(z), post.effect_physical(z)?);
    let frequency_domain = post.model().predict_structure(&base, &effect)?;
    let td = TimeDomainModel::new(campaign, post.data().clone())?.oversampled(REPLAY_OVERSAMPLING);
    let replay = td.predict(&base, hypothesis.map(|(h, l)| (h.as_ref(), l)), &effect)?;
    let mut bias = vec![Complex64::new(0.0, 0.0); replay.len()];
    for (seg, ranges) in post.data().segments.iter().zip(post.model().layout()) {
        if seg.is_ground() {
            continue;
        }
        for r in ranges {
            for i in r.clone() {
                bias[i] = replay[i] - frequency_domain[i];
            }
        }
    }
    Ok(bias)
}

/// Steps of the estimator-bias replay per sample interval: its hold error at the
/// four-story campaign's band top (23.2 Hz at 500 Hz) is then 6e-8, at the bridge's
/// (15.5 Hz at 400 Hz) 3e-8, far below the estimator's bias it measures.
pub const REPLAY_OVERSAMPLING: usize = 6;

impl DiagnosisData {
    /// The same data with `bias` (flat layout `layout`, as [`replay_bias`] gives it)
    /// as every channel's [`super::data::ChannelData::estimator_bias`].
    pub fn with_estimator_bias(
        &self,
        layout: &[Vec<Range<usize>>],
        bias: &[Complex64],
    ) -> Result<DiagnosisData> {
        let mut out = self.clone();
        if layout.len() != out.segments.len() {
            return Err(Error::Usage("bias layout of other data".into()));
        }
        for (seg, ranges) in out.segments.iter_mut().zip(layout) {
            for (ch, r) in seg.channels.iter_mut().zip(ranges) {
                if r.len() != ch.len() || r.end > bias.len() {
                    return Err(Error::Usage("bias layout of other data".into()));
                }
                ch.estimator_bias = bias[r.clone()].to_vec();
            }
        }
        Ok(out)
    }

    /// True when some channel carries an estimator bias.
    pub fn has_estimator_bias(&self) -> bool {
        self.segments
            .iter()
            .flat_map(|s| &s.channels)
            .any(|c| !c.estimator_bias.is_empty())
    }
}
