//! Real measurements (issue 6): validation on data that no one in this project made.
//!
//! The data live in `../shared/data/real/<dataset>` (provenance, variables and units in
//! each folder's README); they are read in place and never copied into the repository.
//!
//! - [`mat`]: MATLAB v5 reader (re-exported from [`crate::model::mat`]) with errors naming
//!   the file and variable.
//! - [`posterior`]: sampling to R-hat/ESS targets and the `posterior.json` schema.
//! - [`four_story`], [`four_story_run`], [`four_story_assess`], [`four_story_report`],
//!   [`four_story_figures`]: identified modes of the four-story frame against a
//!   shear-frame modal likelihood (`four-story-modal`).
//! - [`wheel`], [`wheel_run`], [`wheel_scatter`], [`wheel_assess`], [`wheel_report`]:
//!   Bayesian modal parameters from the measured accelerance of a wheel, damping against
//!   frequency uncertainty (`wheel-frf`).
//! - [`bridge`], [`bridge_run`], [`bridge_assess`], [`bridge_report`]: the 946-DOF steel
//!   pedestrian bridge and its 5 identified modes, updated as SMU does and sampled
//!   (`bridge-fe`).
//! - [`tower`], [`tower_model`], [`tower_run`], [`tower_residuals`], [`tower_assess`],
//!   [`tower_report`]: FRFs from a building's mass-damper force, a 5-story shear model
//!   with uncertain channel gains, and where its fit fails, per mode and per floor
//!   ([`tower_residuals::shear_model_residuals`]) (`tower-hmd`).
//!
//! Each study is load (the data), run (models and sampling), assess (the conclusions,
//! as data: `findings.json`) and report (renders the run and the findings, computes no
//! conclusion). It writes `report.md` (and the same as a self-contained `report.html`),
//! `findings.json`, `posterior.json`, `run.json` and figures (PNG + SVG) into its output
//! folder.

pub mod bridge;
pub mod bridge_assess;
pub mod bridge_posterior;
pub mod bridge_report;
pub mod bridge_run;
pub mod four_story;
pub mod four_story_assess;
pub mod four_story_figures;
pub mod four_story_report;
pub mod four_story_run;
/// The `.mat` reader lives in the model layer; re-exported so `crate::real::mat` keeps working.
pub use crate::model::mat;
pub mod posterior;
pub mod report;
pub mod tower;
pub mod tower_assess;
pub mod tower_model;
pub mod tower_report;
pub mod tower_residuals;
pub mod tower_run;
pub mod wheel;
pub mod wheel_assess;
pub mod wheel_report;
pub mod wheel_run;
pub mod wheel_scatter;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::RunInfo;
use crate::io::StagedDir;
use posterior::Sampling;

/// The datasets with a study.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dataset {
    FourStoryModal,
    WheelFrf,
    TowerHmd,
    BridgeFe,
}

impl Dataset {
    /// Folder name under `data/real` and `results/real`.
    pub fn name(self) -> &'static str {
        match self {
            Dataset::FourStoryModal => "four-story-modal",
            Dataset::WheelFrf => "wheel-frf",
            Dataset::TowerHmd => "tower-hmd",
            Dataset::BridgeFe => "bridge-fe",
        }
    }
}

/// The shared folder: `shared` when given, else `$FRFBAYES_SHARED_DIR` when set, else
/// `../shared` beside the current directory.
pub fn shared_dir(shared: Option<&Path>) -> PathBuf {
    shared.map(Path::to_path_buf).unwrap_or_else(|| {
        std::env::var_os("FRFBAYES_SHARED_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("../shared"))
    })
}

/// `<shared>/data/real/<dataset>`.
pub fn data_dir(shared: &Path, dataset: Dataset) -> PathBuf {
    shared.join("data/real").join(dataset.name())
}

/// How a study runs: the full study (the default), or a short one for tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StudyOptions {
    /// Master seed.
    pub seed: u64,
    /// Every stage on a small scale ([`QUICK_STEPS`] sampler steps; the bridge also
    /// [`bridge_run::BridgeSettings::quick`]): the numbers are not the study's.
    pub quick: bool,
    /// Step cap of every sampler of the study (the bridge's replaces its own cap, so it
    /// also lengthens a `quick` run).
    pub max_steps: Option<u64>,
}

impl StudyOptions {
    /// The full study with `seed`.
    pub fn full(seed: u64) -> Self {
        StudyOptions {
            seed,
            quick: false,
            max_steps: None,
        }
    }
}

/// Sampler steps of a `quick` study (the bridge: [`bridge_run::BridgeSettings::quick`]).
pub const QUICK_STEPS: u64 = 200;

/// Runs the study of `dataset` on the data in `data_dir` and writes `report.md`,
/// `posterior.json`, `run.json` and the figures into `out_dir`, atomically: the folder
/// is built aside ([`StagedDir`]) and replaces `out_dir` only when complete. `sampling`
/// sees every sampler step. Returns the wall-clock seconds of each stage.
pub fn run(
    dataset: Dataset,
    data_dir: &Path,
    out_dir: &Path,
    options: StudyOptions,
    sampling: &mut Sampling<'_>,
) -> Result<Vec<(String, f64)>> {
    let seed = options.seed;
    if !data_dir.is_dir() {
        return Err(Error::Usage(format!(
            "data folder {} not found: pass --shared <DIR> with <DIR>/data/real/{} (or set \
             FRFBAYES_SHARED_DIR)",
            data_dir.display(),
            dataset.name()
        )));
    }
    let config = serde_json::json!({
        "dataset": dataset.name(),
        "seed": seed,
        "quick": options.quick,
        "max_steps": options.max_steps,
    });
    cap_steps(dataset, options, sampling);
    let mut info = RunInfo::start(seed, config, data_dir.display().to_string());
    // Under MPI every rank runs the study (the samplers spread their walkers over the
    // ranks); only rank 0 writes `out_dir`, the others a scratch folder they delete.
    let scratch = match crate::dist::is_root() {
        true => None,
        false => Some(crate::io::ScratchDir::new("real")?),
    };
    let staged = match &scratch {
        None => StagedDir::new(out_dir)?,
        Some(s) => StagedDir::new(&s.path().join("out"))?,
    };
    let out = staged.path().to_path_buf();
    compute_and_write(dataset, data_dir, &out, options, sampling, &mut info)?;
    info.write(&out)?;
    crate::report::write_html_report(
        &out,
        &crate::report::HtmlReport {
            markdown: &["report.md"],
            lead: crate::report::LEAD,
            tail: crate::report::TAIL,
            title: None,
        },
    )?;
    staged.commit()?;
    Ok(info.timings_s)
}

/// Lowers `sampling`'s step cap to the one of `options` (the bridge caps its sampler
/// itself, [`bridge_settings`]).
fn cap_steps(dataset: Dataset, options: StudyOptions, sampling: &mut Sampling<'_>) {
    if dataset == Dataset::BridgeFe {
        return;
    }
    let cap = match (options.quick, options.max_steps) {
        (_, Some(n)) => Some(n),
        (true, None) => Some(QUICK_STEPS),
        (false, None) => None,
    };
    if let Some(n) = cap {
        sampling.step_cap = Some(sampling.step_cap.map_or(n, |c| c.min(n)));
    }
}

/// The bridge study's settings for `options`.
fn bridge_settings(options: StudyOptions) -> bridge_run::BridgeSettings {
    let mut settings = match options.quick {
        true => bridge_run::BridgeSettings::quick(options.seed),
        false => bridge_run::BridgeSettings {
            seed: options.seed,
            ..Default::default()
        },
    };
    if let Some(n) = options.max_steps {
        settings.max_steps = n;
    }
    settings
}

/// Computes the study of `dataset` and writes its report, posterior and figures into
/// `out`, timing each stage in `info`.
fn compute_and_write(
    dataset: Dataset,
    data_dir: &Path,
    out: &Path,
    options: StudyOptions,
    sampling: &mut Sampling<'_>,
    info: &mut RunInfo,
) -> Result<()> {
    let (seed, t0) = (options.seed, Instant::now());
    match dataset {
        Dataset::FourStoryModal => {
            let study = info.time("sample three variants and check", || {
                four_story_run::run(data_dir, seed, sampling)
            })?;
            let mut timings = info.timings_s.clone();
            timings.push(("total before writing".into(), t0.elapsed().as_secs_f64()));
            info.time("write report and figures", || {
                four_story_report::write(&study, out, &timings)
            })?;
        }
        Dataset::WheelFrf => {
            let data = info.time("read data", || wheel::load(data_dir))?;
            let bands = info.time("fit and sample bands", || {
                wheel_run::run(&data, seed, sampling)
            })?;
            let scatter = info.time("channel-by-channel fits", || {
                bands
                    .iter()
                    .map(wheel_run::channel_scatter)
                    .collect::<Result<Vec<_>>>()
            })?;
            let study = wheel_run::WheelStudy {
                scatter: scatter.into_iter().flatten().collect(),
                bands,
                wall_s: t0.elapsed().as_secs_f64(),
            };
            let timings = info.timings_s.clone();
            info.time("write report and figures", || {
                wheel_report::write(&study, &data, out, &timings)
            })?;
        }
        Dataset::BridgeFe => {
            let data = info.time("read model and modes", || bridge::load(data_dir))?;
            let settings = bridge_settings(options);
            let study = info.time("reduced basis, SMU multistarts, posterior", || {
                bridge_run::run(&data, &settings, sampling)
            })?;
            let timings = info.timings_s.clone();
            info.time("write report and figures", || {
                bridge_report::write(&study, out, &timings)
            })?;
        }
        Dataset::TowerHmd => {
            let study = info.time("estimate FRFs, fit and sample", || {
                tower_run::run(data_dir, seed, sampling)
            })?;
            let timings = info.timings_s.clone();
            info.time("write report and figures", || {
                tower_report::write(&study, out, &timings)
            })?;
        }
    }
    Ok(())
}

/// For tests: `<shared>/data/real/<dataset>` when present (`$FRFBAYES_SHARED_DIR` or
/// `../shared` beside the repository), else `None` after printing why.
#[cfg(test)]
pub(crate) fn shared_dataset(dataset: Dataset) -> Option<PathBuf> {
    let mut roots = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")];
    if let Some(d) = std::env::var_os("FRFBAYES_SHARED_DIR") {
        roots.push(PathBuf::from(d));
    }
    let found = roots
        .into_iter()
        .map(|r| r.join("data/real").join(dataset.name()))
        .find(|p| p.is_dir());
    if found.is_none() {
        println!(
            "skipped: data/real/{} not found (no ../shared beside the repository and no \
             FRFBAYES_SHARED_DIR)",
            dataset.name()
        );
    }
    found
}

#[cfg(test)]
mod smoke_tests;
