//! Predictive check on data held out of the fit: leave one segment (test or impact) out,
//! fit the nominal model and the hypothesis to the rest (MAP, from their full-data fits),
//! and score the held-out segment by its log-likelihood under each fit (plug-in log
//! predictive density, error floor included).
//!
//! The gain of a hypothesis is the sum over segments of its held-out log density minus
//! the nominal model's. Its standard error is `sqrt(n) sd(per-segment gains)` (the
//! segments are independent recordings). A hypothesis that only bends the nominal model
//! towards noise or estimator artefacts of the fitted segments does not predict a
//! recording it has not seen.

use super::data::DiagnosisData;
use super::fit::{fit_map, MapOptions};
use super::hypothesis::Hypothesis;
use super::location::Location;
use super::posterior::ModelPosterior;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Held-out comparison of one hypothesis against the nominal model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// Held-out segment names.
    pub segments: Vec<String>,
    /// Held-out log density of each segment under the nominal fit and the hypothesis' fit.
    pub nominal: Vec<f64>,
    pub hypothesis: Vec<f64>,
    /// Sum of `hypothesis - nominal`.
    pub gain: f64,
    /// `sqrt(n) sd(per-segment gains)`.
    pub gain_se: f64,
}

fn subset(data: &DiagnosisData, keep: impl Fn(usize) -> bool) -> DiagnosisData {
    let mut d = data.clone();
    d.segments = data
        .segments
        .iter()
        .enumerate()
        .filter(|(i, _)| keep(*i))
        .map(|(_, s)| s.clone())
        .collect();
    d
}

/// A posterior of `data` under `hypothesis`, or of the nominal model when the
/// hypothesis cannot act on this data (e.g. its channels are not in these segments); the
/// second value says which (`true`: the hypothesis).
fn posterior_or_nominal(
    data: DiagnosisData,
    hypothesis: Option<(Arc<dyn Hypothesis>, Location)>,
) -> Result<(ModelPosterior, bool)> {
    let data = Arc::new(data);
    if hypothesis.is_some() {
        if let Ok(p) = ModelPosterior::new(data.clone(), hypothesis) {
            return Ok((p, true));
        }
    }
    Ok((ModelPosterior::new(data, None)?, false))
}

/// `z` restricted to the frame (and error floor) when `full` is false.
fn restrict(z: &[f64], full: bool, post: &ModelPosterior) -> Vec<f64> {
    if full {
        z.to_vec()
    } else {
        z[..=post.eta_index()].to_vec()
    }
}

/// Log density of segment `i` under a fit of all other segments, starting from `z`.
/// Where the hypothesis cannot act on the rest (its channels are only in segment `i`)
/// the rest is fitted by the nominal model; where it cannot act on segment `i` that
/// segment is scored with the frame of the fit.
fn held_out_density(
    data: &DiagnosisData,
    i: usize,
    hypothesis: Option<(Arc<dyn Hypothesis>, Location)>,
    z: &[f64],
    map: &MapOptions,
) -> Result<f64> {
    let (post, full) = posterior_or_nominal(subset(data, |j| j != i), hypothesis.clone())?;
    let start = restrict(z, full, &post);
    let fit = fit_map(&post, &[start], map)?;
    let hyp = if full { hypothesis } else { None };
    let (post_one, full_one) = posterior_or_nominal(subset(data, |j| j == i), hyp)?;
    post_one.ln_likelihood(&restrict(&fit.z, full_one, &post_one))
}

/// Leave-one-segment-out comparison of `hypothesis` at `location` (full-data MAP
/// `hyp_z`) with the nominal model (full-data MAP `nominal_z`). Needs two segments.
pub fn held_out(
    data: &DiagnosisData,
    hypothesis: &Arc<dyn Hypothesis>,
    location: &Location,
    nominal_z: &[f64],
    hyp_z: &[f64],
    map: &MapOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<HeldOut> {
    let n = data.segments.len();
    if n < 2 {
        return Err(Error::Usage(
            "a held-out check needs at least two segments (tests or impacts)".into(),
        ));
    }
    let mut out = HeldOut {
        segments: Vec::with_capacity(n),
        nominal: Vec::with_capacity(n),
        hypothesis: Vec::with_capacity(n),
        gain: 0.0,
        gain_se: 0.0,
    };
    for i in 0..n {
        out.segments.push(data.segments[i].name.clone());
        out.nominal
            .push(held_out_density(data, i, None, nominal_z, map)?);
        out.hypothesis.push(held_out_density(
            data,
            i,
            Some((hypothesis.clone(), location.clone())),
            hyp_z,
            map,
        )?);
        progress(i + 1, n);
    }
    let gains: Vec<f64> = out
        .hypothesis
        .iter()
        .zip(&out.nominal)
        .map(|(h, n)| h - n)
        .collect();
    let mean = gains.iter().sum::<f64>() / n as f64;
    let var = gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    out.gain = mean * n as f64;
    out.gain_se = (var * n as f64).sqrt();
    Ok(out)
}
