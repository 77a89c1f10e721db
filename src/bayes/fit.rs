//! A maximum-likelihood update (`frfbayes fit`): the same posterior as `frfbayes sample`
//! (campaign -> FRF estimates -> [`FrfPosterior`]), but only its multistart
//! maximum-likelihood point ([`super::plug_in_start`]) with Gauss-Newton standard deviations, for
//! any model a campaign names (shear frame or general). Writes `settings.toml` and
//! `fit.json` ([`FitReport`]).
//!
//! The Gauss-Newton standard deviations come from the per-point errors alone (the start's
//! residuals do not carry a hammer test's shared force-noise term), so they are a lower
//! bound on the posterior's; `sample` gives the full posterior.

use super::posterior::FrfPosterior;
use super::run::{prepare, SampleSettings};
use super::start::StartPoint;
use super::summary::{output_params, physical_values};
use crate::error::{Error, Result};
use crate::io::write_atomic;
use serde::Serialize;
use std::path::Path;

/// One reported parameter of a fit, in the units of `posterior.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitRow {
    pub name: String,
    pub unit: String,
    /// Value at the maximum-likelihood point.
    pub value: f64,
    /// First-order (Gauss-Newton) standard deviation, mapped through the coordinate's
    /// derivative; infinite along an exact ridge.
    pub sd: f64,
}

/// `fit.json`.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// Campaign the fit used.
    pub campaign: String,
    /// Number of measured points.
    pub n_points: usize,
    /// Selected bins dropped for zero coherence ([`super::FrfData::n_dropped_bins`]).
    pub n_dropped_bins: usize,
    pub parameters: Vec<FitRow>,
    /// The optimum in sampled coordinates, with the multistart record.
    pub start: StartPoint,
}

/// The reported parameters at `start` with first-order standard deviations
/// (`|d value / d z_c| sd_c`, central difference of step 1e-6 of the prior range).
pub fn fit_rows(post: &FrfPosterior, start: &StartPoint) -> Vec<FitRow> {
    let params = output_params(post);
    let value = physical_values(post, &params, &start.z);
    let (lo, hi) = (post.prior().lower(), post.prior().upper());
    params
        .iter()
        .zip(value)
        .map(|(p, v)| {
            let c = p.coord;
            let h = 1e-6 * (hi[c] - lo[c]);
            let at = |d: f64| {
                let mut z = start.z.clone();
                z[c] += d;
                physical_values(post, std::slice::from_ref(p), &z)[0]
            };
            let slope = (at(h) - at(-h)) / (2.0 * h);
            FitRow {
                name: p.name.clone(),
                unit: p.unit.clone(),
                value: v,
                sd: slope.abs() * start.sd[c],
            }
        })
        .collect()
}

/// Fits the campaign of `settings` and writes `settings.toml` and `fit.json` into `out`.
pub fn run_fit(settings: &SampleSettings, out: &Path) -> Result<FitReport> {
    write_atomic(&out.join("settings.toml"), settings.to_toml()?.as_bytes())?;
    let prep = prepare(settings)?;
    let post = &prep.posterior;
    let start = prep.start.clone();
    let report = FitReport {
        campaign: settings.campaign.clone(),
        n_points: post.data().len(),
        n_dropped_bins: post.data().n_dropped_bins,
        parameters: fit_rows(post, &start),
        start,
    };
    let text = serde_json::to_vec_pretty(&report)
        .map_err(|e| Error::Numerical(format!("fit.json: {e}")))?;
    write_atomic(&out.join("fit.json"), &text)?;
    Ok(report)
}
