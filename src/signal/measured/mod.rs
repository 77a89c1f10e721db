//! Measured FRFs in: FRFs exported by an analyser (UFF dataset 58/58b, MATLAB `.mat`, or
//! the CSV table of `frfbayes frf`), mapped to model DOFs by a small TOML manifest, as
//! the same [`TestFrf`]s the estimator makes from time histories, so that `sample`,
//! `fit` and the rest use them unchanged.
//!
//! # The manifest
//! ```toml
//! title = "four-story frame, hammer FRFs from the analyser"
//! model = "../campaign"        # a campaign folder whose [nominal] is the model, or
//!                              # bundled:four-story; relative to this file
//! n_averages = 10              # averages behind the analyser's coherence (Bendat & Piersol n)
//!
//! [[test]]
//! name = "hammer-floor1"
//! file = "hammer1.uff"         # .uff/.unv (58 or 58b), .mat or .csv, relative to this file
//! excitation = "force"         # or "ground" (shake table; FRFs per ground acceleration)
//! excited_dof = 1              # force: the model DOF (1-based) the force drives
//! reference = "1+X"            # UFF: the reference node and the direction of the model's
//!                              # DOF (optional when the file has one reference node:
//!                              # then its axis, positive)
//! exp_window_tau_s = 20.0      # optional: the analyser's exponential window, s
//!
//! [[test.channel]]
//! dof = 2                      # model DOF, 1-based
//! node = "2+X"                 # UFF: node and the direction that is the DOF's positive one
//! ```
//! Per channel also: `name` (the CSV column prefix; in UFF the response entity name of
//! record 6, which chooses between FRFs at one node and direction), `column` (`.mat`:
//! 1-based column or row of the FRF matrix), `quantity` (`acceleration` or
//! `displacement`; CSV and `.mat` values are then taken as SI), `unit` (the FRF's unit,
//! e.g. `g/N`, `mm/N`, overriding the file's labels). Per test or for all: `n_averages`,
//! `rel_sigma`, `exp_window_tau_s`; `.mat` variable names under `[test.mat]` (`freq`,
//! `frf`, `coherence`; defaults `freq_hz`, `frf`, `coherence`); ground tests take
//! `ground_response = "relative"` (default: responses relative to the table, as the
//! model's ground FRFs are) or `"absolute"` (absolute accelerations; `H - 1` is used).
//!
//! # Signs and directions
//! A UFF direction opposite to the one the manifest names (`2-X` where the manifest says
//! `2+X`) flips the FRF's sign, for the response and for the reference alike; a
//! different axis (`2+Y`) is not that DOF.
//!
//! # Noise: what the FRF-only path assumes
//! A campaign gives the likelihood each point's Bendat & Piersol error from the
//! coherence and number of averages of its own estimate, and the shared error of the
//! hammer's force noise (`signal::InputNoise`). Measured FRFs carry at most a coherence:
//! - with coherence (UFF function type 6 for the same response and reference, a CSV
//!   `_coherence` column, a `.mat` variable), the Bendat & Piersol error is used as for
//!   a campaign, with the manifest's `n_averages` (required then);
//! - without, every point gets the same relative error `rel_sigma` (default 1 %; stored
//!   as the equivalent coherence `1 / (1 + 2 n rel_sigma^2)`), and the sampled noise
//!   scale `s` sets its size;
//! - no force-noise term: the points of a test are independent given `s`. Analyser FRFs
//!   averaged over many impacts have little of it; single-impact FRFs with a noisy force
//!   channel will give intervals too narrow (see the README's "Honest posteriors").

pub mod export;
mod sources;
#[cfg(test)]
mod tests;

use super::bands::select_bands;
use super::estimate::{EstimateOptions, InputKind, ResponseFrf, TestFrf};
use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::{read_nominal, resolve_data, Channel, NominalModel, Quantity};
use crate::uff::units::Dimension;
use num_complex::Complex64;
use serde::Deserialize;
use sources::{read_columns, Column};
use std::path::{Path, PathBuf};

/// The manifest of a set of measured FRFs (see the module docs).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrfManifest {
    #[serde(default)]
    pub title: Option<String>,
    /// Campaign folder (its `[nominal]`) or `bundled:four-story`, relative to the manifest.
    pub model: String,
    #[serde(default)]
    pub n_averages: Option<usize>,
    #[serde(default)]
    pub rel_sigma: Option<f64>,
    #[serde(default)]
    pub exp_window_tau_s: Option<f64>,
    #[serde(rename = "test")]
    pub tests: Vec<TestSpec>,
}

/// What drives a test of measured FRFs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Excitation {
    Force,
    Ground,
}

/// Responses of a ground test as the file holds them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GroundResponse {
    #[default]
    Relative,
    Absolute,
}

/// `.mat` variable names.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MatNames {
    pub freq: String,
    pub frf: String,
    pub coherence: String,
}

impl Default for MatNames {
    fn default() -> Self {
        MatNames {
            freq: "freq_hz".into(),
            frf: "frf".into(),
            coherence: "coherence".into(),
        }
    }
}

/// One test: one file, one excitation.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TestSpec {
    pub name: String,
    pub file: String,
    pub excitation: Excitation,
    #[serde(default)]
    pub excited_dof: Option<usize>,
    #[serde(default)]
    pub reference: Option<String>,
    #[serde(default)]
    pub n_averages: Option<usize>,
    #[serde(default)]
    pub rel_sigma: Option<f64>,
    #[serde(default)]
    pub exp_window_tau_s: Option<f64>,
    #[serde(default)]
    pub ground_response: GroundResponse,
    #[serde(default)]
    pub mat: MatNames,
    #[serde(rename = "channel")]
    pub channels: Vec<ChannelSpec>,
}

/// One response of a test mapped to a model DOF.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelSpec {
    pub dof: usize,
    #[serde(default)]
    pub node: Option<String>,
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub column: Option<usize>,
    #[serde(default)]
    pub quantity: Option<Quantity>,
    #[serde(default)]
    pub unit: Option<String>,
}

/// Measured FRFs read and mapped.
#[derive(Debug, Clone)]
pub struct MeasuredFrfs {
    pub manifest: PathBuf,
    pub title: String,
    pub nominal: NominalModel,
    pub tests: Vec<TestFrf>,
    /// What was read but not used (FRFs of unmapped responses, other references).
    pub warnings: Vec<String>,
}

/// Default relative standard deviation of a magnitude without coherence (1 %).
pub const DEFAULT_REL_SIGMA: f64 = 0.01;

/// Reads the manifest at `path` and every file it names; band selection as `opts`
/// says (`n_peaks` defaults to the model's DOFs), bins above `opts.freq_max_hz` dropped.
pub fn read_measured(path: &Path, opts: &EstimateOptions) -> Result<MeasuredFrfs> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let manifest: FrfManifest =
        toml::from_str(&text).map_err(|e| Error::invalid(path, e.to_string()))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let model_root = if manifest.model.starts_with("bundled:") {
        resolve_data(&manifest.model)?
    } else {
        dir.join(&manifest.model)
    };
    let nominal = read_nominal(&model_root)
        .map_err(|e| Error::invalid(path, format!("model = {:?}: {e}", manifest.model)))?;
    if manifest.tests.is_empty() {
        return Err(Error::invalid(path, "no [[test]]: add one per excitation"));
    }
    let mut opts = *opts;
    opts.bands.n_peaks = opts.bands.n_peaks.or(Some(nominal.n_floors()));
    let mut warnings = Vec::new();
    let mut tests = Vec::new();
    for spec in &manifest.tests {
        let test = build_test(
            &manifest,
            spec,
            dir,
            nominal.n_floors(),
            &opts,
            &mut warnings,
        )
        .map_err(|e| match e {
            Error::Usage(what) => Error::invalid(path, format!("[[test]] {:?}: {what}", spec.name)),
            other => other,
        })?;
        tests.push(test);
    }
    Ok(MeasuredFrfs {
        manifest: path.to_path_buf(),
        title: manifest.title.clone().unwrap_or_default(),
        nominal,
        tests,
        warnings,
    })
}

/// One test's [`TestFrf`] from its file.
fn build_test(
    manifest: &FrfManifest,
    spec: &TestSpec,
    dir: &Path,
    n_dof: usize,
    opts: &EstimateOptions,
    warnings: &mut Vec<String>,
) -> Result<TestFrf> {
    if spec.channels.is_empty() {
        return Err(Error::Usage(
            "no [[test.channel]]: map at least one response to a DOF".into(),
        ));
    }
    for c in &spec.channels {
        if c.dof == 0 || c.dof > n_dof {
            return Err(Error::Usage(format!(
                "channel dof = {}: the model's DOFs are 1..={n_dof}",
                c.dof
            )));
        }
    }
    let input = match (spec.excitation, spec.excited_dof) {
        (Excitation::Force, Some(d)) if (1..=n_dof).contains(&d) => InputKind::Force {
            floor: d,
            channel: spec.reference.clone().unwrap_or_else(|| "force".into()),
        },
        (Excitation::Force, d) => {
            return Err(Error::Usage(format!(
                "excitation = \"force\" needs excited_dof = <1..={n_dof}> (got {d:?})"
            )))
        }
        (Excitation::Ground, None) => InputKind::Ground {
            channel: spec.reference.clone().unwrap_or_else(|| "ground".into()),
        },
        (Excitation::Ground, Some(_)) => {
            return Err(Error::Usage(
                "a ground test has no excited_dof: remove it".into(),
            ))
        }
    };
    let columns = read_columns(spec, &dir.join(&spec.file), warnings)?;
    let n_averages = spec.n_averages.or(manifest.n_averages);
    let rel_sigma = spec
        .rel_sigma
        .or(manifest.rel_sigma)
        .unwrap_or(DEFAULT_REL_SIGMA);
    if !(rel_sigma.is_finite() && rel_sigma > 0.0) {
        return Err(Error::Usage(format!(
            "rel_sigma = {rel_sigma}: it must be positive"
        )));
    }
    if columns.iter().any(|c| c.coherence.is_some()) && n_averages.is_none() {
        return Err(Error::Usage(
            "the file has coherences: add n_averages = <number of averages of the analyser> \
             (to the test or the manifest) so that their error can be computed"
                .into(),
        ));
    }
    let n = n_averages.unwrap_or(1).max(1);
    let freq_hz = common_grid(&columns, opts.freq_max_hz)?;
    let nk = freq_hz.len();
    let mut responses = Vec::new();
    for (c, col) in spec.channels.iter().zip(&columns) {
        responses.push(response(c, col, spec, nk, &freq_hz, n, rel_sigma)?);
    }
    let tau = spec.exp_window_tau_s.or(manifest.exp_window_tau_s);
    finish_test(spec, freq_hz, input, responses, n, tau, opts)
}

/// The frequency grid every column shares, cut at `freq_max_hz`.
fn common_grid(columns: &[Column], freq_max_hz: Option<f64>) -> Result<Vec<f64>> {
    let first = &columns[0].freq_hz;
    for c in columns {
        let same = c.freq_hz.len() == first.len()
            && c.freq_hz
                .iter()
                .zip(first)
                .all(|(a, b)| (a - b).abs() <= 1e-9 * b.abs().max(1.0));
        if !same {
            return Err(Error::Usage(format!(
                "{} and {} are on different frequency grids; one test needs one grid",
                columns[0].label, c.label
            )));
        }
    }
    if first.windows(2).any(|w| w[1] <= w[0]) || first.first().is_some_and(|f| *f < 0.0) {
        return Err(Error::Usage(format!(
            "{}: frequencies must be non-negative and increasing",
            columns[0].label
        )));
    }
    let n = match freq_max_hz {
        Some(fmax) => first.iter().take_while(|&&f| f <= fmax).count(),
        None => first.len(),
    };
    if n < 3 {
        return Err(Error::Usage(format!(
            "{}: {n} frequencies up to {freq_max_hz:?} Hz; too few for band selection",
            columns[0].label
        )));
    }
    Ok(first[..n].to_vec())
}

/// One response in SI, in the model's direction, with its coherence.
fn response(
    c: &ChannelSpec,
    col: &Column,
    spec: &TestSpec,
    nk: usize,
    freq_hz: &[f64],
    n: usize,
    rel_sigma: f64,
) -> Result<ResponseFrf> {
    let (num, den) = col.units;
    let (quantity, kind) = match num.dimension {
        Dimension::Acceleration => (Quantity::Acceleration, FrfKind::Accelerance),
        Dimension::Displacement => (Quantity::Displacement, FrfKind::Receptance),
        d => {
            return Err(Error::Usage(format!(
                "{}: a {d:?} response; the model's channels are accelerations and \
                 displacements (give unit = ... if the file's label is wrong)",
                col.label
            )))
        }
    };
    if c.quantity.is_some_and(|q| q != quantity) {
        return Err(Error::Usage(format!(
            "{}: the file's unit says {quantity:?}, the manifest says {:?}",
            col.label, c.quantity
        )));
    }
    let want = match spec.excitation {
        Excitation::Force => Dimension::Force,
        Excitation::Ground => Dimension::Acceleration,
    };
    if den.dimension != want {
        return Err(Error::Usage(format!(
            "{}: FRF per {:?}, but the test's excitation is {:?} (per {want:?})",
            col.label, den.dimension, spec.excitation
        )));
    }
    let scale = col.sign * num.to_si / den.to_si;
    let absolute =
        spec.excitation == Excitation::Ground && spec.ground_response == GroundResponse::Absolute;
    if absolute && kind == FrfKind::Receptance {
        return Err(Error::Usage(format!(
            "{}: absolute displacements of a ground test are not supported; give them \
             relative to the table",
            col.label
        )));
    }
    let h1: Vec<Complex64> = col.h[..nk]
        .iter()
        .map(|&h| {
            h * scale
                - if absolute {
                    Complex64::new(1.0, 0.0)
                } else {
                    Complex64::new(0.0, 0.0)
                }
        })
        .collect();
    let coherence: Vec<f64> = match &col.coherence {
        Some(g) => g[..nk].to_vec(),
        None => vec![1.0 / (1.0 + 2.0 * n as f64 * rel_sigma * rel_sigma); nk],
    };
    if let Some(k) = coherence
        .iter()
        .position(|g| !(0.0..=1.0 + 1e-9).contains(g))
    {
        return Err(Error::Usage(format!(
            "{}: coherence {} at {} Hz; it must be within 0..1",
            col.label, coherence[k], freq_hz[k]
        )));
    }
    let name = c.name.clone().unwrap_or_else(|| col.name.clone());
    Ok(ResponseFrf {
        channel: Channel {
            name,
            quantity,
            floor: c.dof,
            unit: quantity.unit().into(),
        },
        kind,
        h2: h1.clone(),
        h1,
        output_coherence: coherence.clone(),
        coherence,
    })
}

/// Bands and the [`TestFrf`].
fn finish_test(
    spec: &TestSpec,
    freq_hz: Vec<f64>,
    input: InputKind,
    responses: Vec<ResponseFrf>,
    n_averages: usize,
    tau: Option<f64>,
    opts: &EstimateOptions,
) -> Result<TestFrf> {
    if tau.is_some_and(|t| !(t.is_finite() && t > 0.0)) {
        return Err(Error::Usage(format!(
            "exp_window_tau_s = {tau:?}: it must be positive"
        )));
    }
    let nk = freq_hz.len();
    let h_refs: Vec<&[Complex64]> = responses.iter().map(|r| r.h1.as_slice()).collect();
    let mean_coherence: Vec<f64> = (0..nk)
        .map(|k| responses.iter().map(|r| r.coherence[k]).sum::<f64>() / responses.len() as f64)
        .collect();
    let input_power = vec![1.0; nk];
    let n_peaks = opts.bands.n_peaks.unwrap_or(1);
    let (bands, selected) = select_bands(
        &freq_hz,
        &h_refs,
        &input_power,
        &mean_coherence,
        &opts.bands,
        n_peaks,
    )?;
    let df = freq_hz[1] - freq_hz[0];
    Ok(TestFrf {
        test: spec.name.clone(),
        input,
        responses,
        n_averages,
        coherence_dof: n_averages,
        exp_window_tau_s: tau,
        block_s: 1.0 / df,
        impacts_s: Vec::new(),
        input_power,
        input_spectra: Vec::new(),
        bands,
        selected,
        input_noise: None,
        freq_hz,
    })
}
