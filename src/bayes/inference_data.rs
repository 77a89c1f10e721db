//! The ArviZ `InferenceData` of a `frfbayes sample` run ([`INFERENCE_DATA_FILE`] beside
//! `posterior.json`), written by [`crate::mcmc::InferenceData`]:
//! - `posterior`: the reported parameters of `posterior.json`, in its names and units;
//! - `sample_stats`: `lp` (log posterior in the sampled coordinates) and the walkers'
//!   `acceptance_rate`;
//! - `log_likelihood`: `frf_magnitude` `(chain, draw, point)`, the pointwise terms of
//!   `log_likelihood.npy` (every k-th draw of each walker when that file is thinned);
//! - `observed_data`: `frf_magnitude` `(point)`, the measured `|H|` in the likelihood's
//!   long-vector order, with `freq_hz`, `test`, `response_dof` and `sigma` (standard
//!   deviation at noise scale 1, in the residual's units) along `point`.

use std::f64::consts::TAU;
use std::path::Path;

use super::data::FrfData;
use super::posterior::FrfPosterior;
use super::summary::OutputParam;
use crate::error::Result;
pub use crate::mcmc::INFERENCE_DATA_FILE;
use crate::mcmc::{Draws, InferenceData, Observed};

/// Name of the observed variable and of its pointwise log-likelihood.
pub const OBSERVED_NAME: &str = "frf_magnitude";

/// Dimension of the data points.
pub const POINT_DIM: &str = "point";

/// Writes the `InferenceData` of a run: `phys` the kept draws in physical units
/// (`params` order), `pointwise` draws holding the pointwise log-likelihood (`phys`
/// itself or a thinned copy), `acceptance` the acceptance fraction of every walker
/// chain (ensemble-major).
pub fn write_inference_data(
    path: &Path,
    post: &FrfPosterior,
    params: &[OutputParam],
    phys: &Draws,
    pointwise: &Draws,
    acceptance: Vec<f64>,
) -> Result<()> {
    let names: Vec<String> = params.iter().map(|p| p.name.clone()).collect();
    let units: Vec<String> = params.iter().map(|p| p.unit.clone()).collect();
    InferenceData::new(phys, &names, &units)?
        .with_acceptance(acceptance)?
        .with_observed(observed(post.data()))?
        .with_log_likelihood(OBSERVED_NAME, POINT_DIM, pointwise)?
        .with_attr("frfbayes_command", "sample")
        .write(path)
}

/// The measured magnitudes with their frequency, test, response DOF and sigma.
fn observed(data: &FrfData) -> Observed {
    let n = data.len();
    let (mut freq_hz, mut test, mut dof) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    // Long-vector order: block by block, pair by pair, frequency by frequency.
    for (b, block) in data.blocks.iter().enumerate() {
        for pair in &block.pairs {
            for &w in &block.omega_rad_s {
                freq_hz.push(w / TAU);
                test.push(b as f64);
                dof.push(pair.response as f64);
            }
        }
    }
    Observed {
        name: OBSERVED_NAME.into(),
        dim: POINT_DIM.into(),
        values: data.magnitude.clone(),
        unit: "SI: m/N, (m/s)/N or (m/s^2)/N per unit force; per m/s^2 of ground \
               acceleration for ground-excited tests"
            .into(),
        coords: vec![
            ("freq_hz".into(), freq_hz),
            ("test".into(), test),
            ("response_dof".into(), dof),
            ("sigma".into(), data.sigma.clone()),
        ],
        attrs: vec![
            ("tests".into(), data.tests.join(", ")),
            ("residual".into(), format!("{:?}", data.residual)),
        ],
    }
}
