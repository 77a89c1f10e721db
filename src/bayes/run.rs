//! A whole sampling run (`frfbayes sample`): campaign -> FRF estimates -> posterior ->
//! maximum-likelihood start -> ensemble sampling with checkpoints -> outputs.
//!
//! Output folder:
//! - `settings.toml`: everything that defines the run (`--resume` reads it back; TOML
//!   round-trips every float exactly);
//! - `start.json`: the multistart optimum the walkers started around;
//! - `checkpoint.mcmc` while running (atomic; removed once the run has converged, kept
//!   otherwise so that `--resume --max-steps <more>` extends it);
//! - `posterior.json` ([`PosteriorSummary`]), `draws.csv` and `draws.npy` (physical units,
//!   `(chain, draw, parameter)`, parameter order as in `posterior.json`),
//!   `ln_posterior.npy` `(chain, draw)`, `log_likelihood.npy` `(chain, draw, point)`
//!   (every k-th draw above [`MAX_POINTWISE_VALUES`], k in `log_likelihood_thin.json`);
//! - `inference_data.nc`: all of it as ArviZ's InferenceData, `az.from_netcdf(path)`
//!   ([`super::inference_data`]);
//! - figures `corner`, `traces`, `predictive`, `cv` (PNG and SVG), `run.json`.
//!
//! Every file is written atomically. Chains are walkers (chain = ensemble x walkers +
//! walker), as ArviZ reads emcee output.

use super::data::FrfData;
use super::figures::write_figures;
use super::inference_data::{write_inference_data, INFERENCE_DATA_FILE};
pub use super::moves::{de_stretch_moves, default_moves};
use super::posterior::FrfPosterior;
use super::reselect::{reselect_on_model, BandSelection};
pub use super::settings::{SampleSettings, TestSelection};
use super::start::{ball_positions, find_start, plug_in_start, StartPoint};
use super::summary::{
    output_params, physical_draws, stuck_walkers, summarize, OutputParam, PosteriorSummary,
};
use crate::error::{Error, Result};
use crate::io::{read_campaign, resolve_data, write_atomic, Campaign, RunInfo};
use crate::mcmc::{
    Burn, CheckpointConfig, Draws, LogDensity, Moves, ProgressFn, RunSummary, Sampler,
    SamplerConfig, Start, StopReason,
};
use crate::signal::measured::read_measured;
use crate::signal::{estimate_campaign, TestFrf};
use crate::update::MultistartOptions;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The campaign's FRF estimates, the posterior of a run and its start.
pub struct Prepared {
    pub frfs: Vec<TestFrf>,
    pub posterior: FrfPosterior,
    /// The maximum-likelihood start, at which the shared noise's loadings were scaled
    /// ([`plug_in_start`]).
    pub start: StartPoint,
}

/// Reads the campaign, estimates its FRFs, builds the posterior and finds its start
/// ([`plug_in_start`], with `settings.loading_magnitude`); or, with `settings.frfs`,
/// reads the measured FRFs and their model ([`prepare_measured`]). Deterministic for
/// the settings, so that `--resume` rebuilds the same posterior.
pub fn prepare(settings: &SampleSettings) -> Result<Prepared> {
    if let Some(manifest) = &settings.frfs {
        return prepare_measured(Path::new(manifest), settings);
    }
    let root = resolve_data(&settings.campaign)?;
    let campaign = read_campaign(&root)?;
    prepare_campaign(&campaign, settings)
}

/// The posterior of measured FRFs: the manifest at `manifest` names the files, the DOFs
/// and the model; bands are selected as `settings.estimate` says (band factor, highest
/// frequency). What the likelihood assumes without a campaign's recordings:
/// [`crate::signal::measured`] ("Noise").
pub fn prepare_measured(manifest: &Path, settings: &SampleSettings) -> Result<Prepared> {
    let measured = read_measured(manifest, &settings.estimate.options())?;
    let model = measured.nominal.structural_model()?;
    let where_ = format!("the measured FRFs of {}", manifest.display());
    let n_peaks = n_peaks(settings, measured.nominal.n_floors());
    posterior_of(model, measured.tests, settings, n_peaks, &where_)
}

/// [`prepare`] for a campaign already in memory (e.g. simulated): estimates its FRFs
/// with the settings' estimator and builds the posterior (`settings.campaign` unused).
pub fn prepare_campaign(campaign: &Campaign, settings: &SampleSettings) -> Result<Prepared> {
    let model = campaign.nominal.structural_model()?;
    let frfs = estimate_campaign(campaign, &settings.estimate.options())?;
    let where_ = format!("the campaign at {}", campaign.root.display());
    let n_peaks = n_peaks(settings, campaign.nominal.n_floors());
    posterior_of(model, frfs, settings, n_peaks, &where_)
}

/// Resonances per test, as the estimate found them: the settings' or the model's modes.
fn n_peaks(settings: &SampleSettings, n_floors: usize) -> usize {
    settings
        .estimate
        .options()
        .bands
        .n_peaks
        .unwrap_or(n_floors)
}

/// The posterior of the `settings.tests` among `frfs` and its start (`where_` names them
/// in errors); with [`BandSelection::Model`] the bins are then selected again on the
/// start's model ([`reselect_on_model`], `n_peaks` per test) and the start found again.
/// What `sample` does after estimating the FRFs, and what `repro`'s `[bayes]` does with
/// each variant's.
pub fn posterior_of(
    model: crate::model::StructuralModel,
    mut frfs: Vec<TestFrf>,
    settings: &SampleSettings,
    n_peaks: usize,
    where_: &str,
) -> Result<Prepared> {
    let (posterior, start) = match settings.band_selection {
        BandSelection::Measured => start_of(model, &frfs, settings, where_)?,
        BandSelection::Model => {
            let (first, start) = start_of(model.clone(), &frfs, settings, where_)?;
            let bands = settings.estimate.options().bands;
            let chosen = |f: &TestFrf| settings.tests.includes(f);
            reselect_on_model(&first, &start.z, &mut frfs, chosen, &bands, n_peaks)?;
            start_of(model, &frfs, settings, where_)?
        }
    };
    Ok(Prepared {
        frfs,
        posterior,
        start,
    })
}

/// The posterior of the `settings.tests` among `frfs` at their selected bins, and its
/// start ([`plug_in_start`]).
fn start_of(
    model: crate::model::StructuralModel,
    frfs: &[TestFrf],
    settings: &SampleSettings,
    where_: &str,
) -> Result<(FrfPosterior, StartPoint)> {
    let chosen: Vec<&TestFrf> = frfs.iter().filter(|f| settings.tests.includes(f)).collect();
    if chosen.is_empty() {
        return Err(Error::Usage(format!(
            "{where_} has no {:?} tests (hammer: force-excited; shake_table: ground-excited)",
            settings.tests
        )));
    }
    let data = FrfData::with_noise_model(
        &chosen,
        settings.frf,
        settings.residual,
        settings.rel_sigma_floor,
        settings.input_noise,
        settings.bin_correlation,
        settings.noise_pool_bins,
    )?;
    let posterior = FrfPosterior::new(
        model,
        data,
        settings.damping,
        &settings.variables,
        settings.posterior,
    )?;
    plug_in_start(
        posterior,
        settings.loading_magnitude,
        &multistart_options(settings),
    )
}

/// What a run produced.
#[derive(Debug)]
pub struct SampleOutcome {
    pub out: PathBuf,
    pub summary: PosteriorSummary,
    pub start: Option<StartPoint>,
    pub info: RunInfo,
}

const CHECKPOINT: &str = "checkpoint.mcmc";
const SETTINGS: &str = "settings.toml";

/// Path of the settings file of a run folder.
pub fn settings_path(out: &Path) -> PathBuf {
    out.join(SETTINGS)
}

/// Path of the checkpoint of a run folder.
pub fn checkpoint_path(out: &Path) -> PathBuf {
    out.join(CHECKPOINT)
}

/// Stage messages of a run (`"sampling"`, ...).
pub type StageFn<'a> = &'a dyn Fn(&str);

fn json<T: Serialize>(v: &T) -> Result<Vec<u8>> {
    serde_json::to_vec_pretty(v).map_err(|e| Error::Numerical(format!("JSON: {e}")))
}

/// A fresh run into `out`. Refuses a folder holding a checkpoint (an unfinished run:
/// resume it with [`resume_sample`] or delete it).
pub fn run_sample(
    settings: &SampleSettings,
    out: &Path,
    stage: StageFn,
    progress: Option<&mut ProgressFn<'_>>,
) -> Result<SampleOutcome> {
    if checkpoint_path(out).exists() {
        return Err(Error::Usage(format!(
            "{} holds an unfinished run ({CHECKPOINT}); resume it with --resume or delete it",
            out.display()
        )));
    }
    let mut info = RunInfo::start(
        settings.seed,
        toml_value(settings)?,
        settings
            .frfs
            .clone()
            .unwrap_or_else(|| settings.campaign.clone()),
    );
    write_atomic(&settings_path(out), settings.to_toml()?.as_bytes())?;
    stage("estimating FRFs, finding the maximum-likelihood start");
    let prep = info.time("estimate_frfs_and_start", || prepare(settings))?;
    let post = &prep.posterior;
    let start = prep.start.clone();
    write_atomic(&out.join("start.json"), &json(&start_record(post, &start))?)?;
    let mut config = sampler_config(settings, post.dim())?;
    config.checkpoint = Some(CheckpointConfig {
        path: checkpoint_path(out),
        every_steps: settings.checkpoint_every,
    });
    let mut sampler = new_sampler(post, &start, config, settings)?;
    stage("sampling");
    finish(
        settings,
        out,
        &prep,
        &mut sampler,
        Some(start),
        info,
        stage,
        progress,
    )
}

/// Continues the run in `out` from its checkpoint with its stored settings; ends
/// bit-identical to an uninterrupted run. `max_steps` replaces the step cap (and is
/// written to `settings.toml`), e.g. to extend a run that stopped unconverged.
pub fn resume_sample(
    out: &Path,
    max_steps: Option<u64>,
    stage: StageFn,
    progress: Option<&mut ProgressFn<'_>>,
) -> Result<SampleOutcome> {
    let mut settings = SampleSettings::load(&settings_path(out))?;
    let cp = checkpoint_path(out);
    if !cp.exists() {
        return Err(Error::Usage(format!(
            "{} has no checkpoint to resume (the run converged, or was stopped before its \
             first checkpoint at step {}); start it again without --resume",
            out.display(),
            settings.checkpoint_every
        )));
    }
    if let Some(m) = max_steps {
        settings.max_steps = m;
        write_atomic(&settings_path(out), settings.to_toml()?.as_bytes())?;
    }
    let mut info = RunInfo::start(
        settings.seed,
        toml_value(&settings)?,
        settings
            .frfs
            .clone()
            .unwrap_or_else(|| settings.campaign.clone()),
    );
    stage("estimating FRFs, finding the maximum-likelihood start");
    let prep = info.time("estimate_frfs_and_start", || prepare(&settings))?;
    let moves = Moves::from_specs(&settings.moves)?;
    let mut sampler = Sampler::resume(&prep.posterior, moves, &cp)?;
    sampler.set_checkpoint(Some(CheckpointConfig {
        path: cp,
        every_steps: settings.checkpoint_every,
    }))?;
    sampler.set_max_steps(settings.max_steps);
    stage("sampling");
    finish(
        &settings,
        out,
        &prep,
        &mut sampler,
        None,
        info,
        stage,
        progress,
    )
}

fn toml_value(settings: &SampleSettings) -> Result<serde_json::Value> {
    serde_json::to_value(settings).map_err(|e| Error::Numerical(format!("settings: {e}")))
}

pub(crate) fn multistart_options(settings: &SampleSettings) -> MultistartOptions {
    MultistartOptions {
        n_starts: settings.n_starts,
        seed: settings.seed,
        ..Default::default()
    }
}

/// The sampler configuration of `settings` (no checkpoints).
fn sampler_config(settings: &SampleSettings, dim: usize) -> Result<SamplerConfig> {
    if settings.walkers_per_dim < 2 {
        return Err(Error::Usage(format!(
            "walkers_per_dim must be at least 2, got {}",
            settings.walkers_per_dim
        )));
    }
    if settings.checkpoint_every == 0 {
        return Err(Error::Usage("checkpoint_every must be at least 1".into()));
    }
    let mut c = SamplerConfig::new(settings.walkers_per_dim * dim, settings.seed);
    c.n_ensembles = settings.n_ensembles;
    c.max_steps = settings.max_steps;
    c.check_every = settings.check_every;
    c.thin_by = settings.thin_by;
    Ok(c)
}

/// A sampler whose walkers start in the Gauss-Newton ball around `start`.
fn new_sampler<'d>(
    post: &'d FrfPosterior,
    start: &StartPoint,
    config: SamplerConfig,
    settings: &SampleSettings,
) -> Result<Sampler<'d, FrfPosterior>> {
    let n = config.n_walkers * config.n_ensembles;
    let positions = ball_positions(post, start, n, settings.ball_factor, settings.seed)?;
    let moves = Moves::from_specs(&settings.moves)?;
    Sampler::new(post, moves, config, Start::Positions(positions))
}

/// A posterior sampled in memory (no files, no checkpoints), as `repro` uses it.
#[derive(Debug, Clone)]
pub struct PosteriorSample {
    pub summary: PosteriorSummary,
    /// The reported parameters (order of `summary.parameters` and of `physical`).
    pub params: Vec<OutputParam>,
    /// Kept draws in sampled coordinates ...
    pub draws: Draws,
    /// ... and in physical units (reported parameters).
    pub physical: Draws,
    pub start: StartPoint,
}

/// Samples `post` with the run settings `settings` (the data-related fields, campaign,
/// estimate, tests, are not used: `post` carries the data): maximum-likelihood start,
/// Gauss-Newton ball, sampling to the convergence criterion or the step cap, summary.
/// `post` is sampled as it is (its loadings are not rescaled: [`sample_prepared`] does
/// what `frfbayes sample` does).
pub fn sample_posterior(post: &FrfPosterior, settings: &SampleSettings) -> Result<PosteriorSample> {
    let start = find_start(post, &multistart_options(settings))?;
    sample_from(post, start, settings)
}

/// [`sample_posterior`] of a prepared run: its posterior from its start ([`prepare`]).
pub fn sample_prepared(prep: &Prepared, settings: &SampleSettings) -> Result<PosteriorSample> {
    sample_from(&prep.posterior, prep.start.clone(), settings)
}

/// Samples `post` from `start` (see [`sample_posterior`]).
fn sample_from(
    post: &FrfPosterior,
    start: StartPoint,
    settings: &SampleSettings,
) -> Result<PosteriorSample> {
    let config = sampler_config(settings, post.dim())?;
    let mut sampler = new_sampler(post, &start, config, settings)?;
    let t0 = Instant::now();
    let run = sample_to_criterion(post, &mut sampler, None)?;
    let wall_s = t0.elapsed().as_secs_f64();
    let (summary, draws) = summarize_run(post, &sampler, &run, wall_s, settings)?;
    let params = output_params(post);
    let physical = physical_draws(post, &params, &draws);
    Ok(PosteriorSample {
        summary,
        params,
        draws,
        physical,
        start,
    })
}

#[derive(Serialize)]
struct StartRecord<'a> {
    names: Vec<String>,
    physical: Vec<(String, f64)>,
    #[serde(flatten)]
    start: &'a StartPoint,
}

fn start_record<'a>(post: &FrfPosterior, start: &'a StartPoint) -> StartRecord<'a> {
    let params = output_params(post);
    let phys = super::summary::physical_values(post, &params, &start.z);
    StartRecord {
        names: post.names(),
        physical: params.into_iter().map(|p| p.name).zip(phys).collect(),
        start,
    }
}

/// Runs until emcee's tau rule, then on (a convergence check at a time) until every
/// parameter meets R-hat < 1.01 and bulk ESS > 400, or the step cap.
fn sample_to_criterion(
    post: &FrfPosterior,
    sampler: &mut Sampler<'_, FrfPosterior>,
    mut progress: Option<&mut ProgressFn<'_>>,
) -> Result<RunSummary> {
    loop {
        let summary = sampler.run(progress.as_deref_mut())?;
        if summary.stopped_because != StopReason::Converged {
            return Ok(summary);
        }
        let draws = sampler.draws(Burn::Auto)?;
        let tau = summary.tau_steps.clone();
        let params = summarize(post, &output_params(post), &draws, &tau);
        let done = PosteriorSummary::meets_criterion(&params) && stuck_walkers(&draws).is_empty();
        if done || sampler.step_count() >= sampler.config().max_steps {
            return Ok(summary);
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn finish(
    settings: &SampleSettings,
    out: &Path,
    prep: &Prepared,
    sampler: &mut Sampler<'_, FrfPosterior>,
    start: Option<StartPoint>,
    mut info: RunInfo,
    stage: StageFn,
    progress: Option<&mut ProgressFn<'_>>,
) -> Result<SampleOutcome> {
    let post = &prep.posterior;
    let t0 = Instant::now();
    let run = sample_to_criterion(post, sampler, progress)?;
    let wall_s = t0.elapsed().as_secs_f64();
    info.timings_s.push(("sampling".into(), wall_s));
    stage("writing outputs");
    let (summary, mut draws) = summarize_run(post, sampler, &run, wall_s, settings)?;
    let every = pointwise_thin(draws.n_chains * draws.n_draws, post.data().len());
    // Small enough: every draw, as ever; else a thinned copy (see `MAX_POINTWISE_VALUES`).
    let thinned = info.time("pointwise_log_likelihood", || -> Result<Option<Draws>> {
        if every == 1 {
            return draws.compute_pointwise(post).map(|()| None);
        }
        let mut t = draws.thinned(every);
        t.compute_pointwise(post)?;
        Ok(Some(t))
    })?;
    let params = output_params(post);
    let phys = physical_draws(post, &params, &draws);
    let names: Vec<String> = params.iter().map(|p| p.name.clone()).collect();
    info.time("write_draws", || -> Result<()> {
        write_atomic(&out.join("posterior.json"), &json(&summary)?)?;
        phys.write_csv(&out.join("draws.csv"), &names)?;
        phys.write_npy(&out.join("draws.npy"))?;
        phys.write_ln_density_npy(&out.join("ln_posterior.npy"))?;
        match &thinned {
            None => phys.write_pointwise_npy(&out.join("log_likelihood.npy")),
            Some(t) => {
                let note = format!("{{\"every\": {every}}}\n");
                write_atomic(&out.join("log_likelihood_thin.json"), note.as_bytes())?;
                t.write_pointwise_npy(&out.join("log_likelihood.npy"))
            }
        }
    })?;
    info.time("write_inference_data", || {
        let acceptance = sampler.acceptance_fractions().concat();
        let pointwise = thinned.as_ref().unwrap_or(&phys);
        let path = out.join(INFERENCE_DATA_FILE);
        write_inference_data(&path, post, &params, &phys, pointwise, acceptance)
    })?;
    info.time("figures", || {
        write_figures(out, prep, sampler, &params, &draws, settings)
    })?;
    info.write(out)?;
    super::report::write_report(&summary, out)?;
    // A converged run needs its checkpoint no more; an unconverged one keeps it, so that
    // `--resume --max-steps` can extend it.
    let cp = checkpoint_path(out);
    if summary.converged && cp.exists() {
        std::fs::remove_file(&cp).map_err(|e| Error::io(&cp, e))?;
    }
    Ok(SampleOutcome {
        out: out.to_path_buf(),
        summary,
        start,
        info,
    })
}

/// Most values of the pointwise log-likelihood array a run writes (2^27, 1 GiB of
/// f64). Above it (e.g. the ten-story frame: 1104 walkers x ~400 draws x ~1200 points,
/// 4 GiB) `log_likelihood.npy` holds every k-th draw of each chain, k the smallest that
/// fits, written to `log_likelihood_thin.json` beside it.
pub const MAX_POINTWISE_VALUES: usize = 1 << 27;

/// The k of [`MAX_POINTWISE_VALUES`] for `n_rows` draws (all chains) of `n_points`.
fn pointwise_thin(n_rows: usize, n_points: usize) -> usize {
    (n_rows * n_points).div_ceil(MAX_POINTWISE_VALUES).max(1)
}

/// The kept draws (automatic burn-in, or the second half when tau is not yet reliable)
/// and their [`PosteriorSummary`].
fn summarize_run(
    post: &FrfPosterior,
    sampler: &Sampler<'_, FrfPosterior>,
    run: &RunSummary,
    wall_s: f64,
    settings: &SampleSettings,
) -> Result<(PosteriorSummary, Draws)> {
    let draws = sampler.draws(Burn::Auto).or_else(|_| {
        let s = sampler.step_count();
        sampler.draws(Burn::Steps {
            discard: s / 2,
            thin: 1,
        })
    })?;
    let params = output_params(post);
    let tau = sampler
        .tau_estimates()
        .iter()
        .map(|t| t.tau * settings.thin_by as f64)
        .collect::<Vec<_>>();
    let rows = summarize(post, &params, &draws, &tau);
    let n_stuck_walkers = stuck_walkers(&draws).len();
    let summary = PosteriorSummary {
        converged: PosteriorSummary::meets_criterion(&rows) && n_stuck_walkers == 0,
        n_stuck_walkers,
        rhat_max: rows.iter().map(|p| p.rhat).fold(f64::NAN, f64::max),
        ess_bulk_min: rows.iter().map(|p| p.ess_bulk).fold(f64::NAN, f64::min),
        parameters: rows,
        acceptance: run.acceptance,
        n_walkers: sampler.config().n_walkers,
        n_ensembles: sampler.config().n_ensembles,
        n_steps: run.steps,
        n_likelihood_evals: run.n_evaluations,
        n_data_points: post.data().len(),
        n_points_at_sigma_floor: Some(post.data().n_floored),
        wall_s,
        stopped_because: run.stopped_because,
        n_draws_per_walker: draws.n_draws,
        discarded_steps: draws.discarded_steps,
        thin_steps: draws.thin_steps,
    };
    Ok((summary, draws))
}
