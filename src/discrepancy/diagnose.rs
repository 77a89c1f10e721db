//! `frfbayes diagnose`: the whole pipeline on one campaign, with no hints.
//!
//! 1. **Data**: FRF estimates of every test (every impact of a hammer test on its own),
//!    complex, with Bendat-Piersol errors ([`super::data`]).
//! 2. **Nominal model**: multistart MAP, Laplace at the mode in logit coordinates, then
//!    its marginal likelihood by the generalised stepping-stone from there
//!    ([`super::model_evidence`]) with posterior draws; residual map.
//! 3. **Hypotheses**: each one is fitted at every candidate location
//!    ([`super::search`]); its best location gets Laplace in logit coordinates and the
//!    estimator the screen of [`crate::infer::screened`] picks (none where the gain
//!    bound rules it out, Laplace clearly below the threshold, the generalised
//!    stepping-stone elsewhere).
//! 4. **Decision** ([`super::verdict`]): decisive Bayes factor, plausible effect,
//!    better prediction of held-out segments ([`super::heldout`]). Steps 3-4 are one
//!    round ([`super::round`]).
//! 5. **Stepwise** ([`super::stepwise`]): the winner joins the model and the next round
//!    asks what else is missing, until nothing passes, two explanations tie (ambiguous)
//!    or three effects are in.
//! 6. **Adequacy** ([`super::adequacy`]): the final model against the estimator's own
//!    error, globally, per cell, and where the consistency checks point; what fails is
//!    reported as unexplained, with where and what the residual shows.

use super::adequacy::{assess, Adequacy};
use super::consistency::{check_campaign, ConsistencyOptions};
use super::data::{DataOptions, DiagnosisData};
pub use super::effect_summary::effect_columns;
use super::estimator_bias::{replay_bias, REPLAY_OVERSAMPLING};
use super::fit::{fit_map, frame_starts, refit_at_map, MapFit, MapOptions};
use super::forward::frame_system;
use super::heldout::HeldOut;
use super::hypotheses::all_hypotheses;
use super::hypothesis::Hypothesis;
use super::locate::LocateReport;
use super::location::Location;
use super::model_evidence::{completion, laplace_u, model_result, LaplaceOutcome};
use super::posterior::ModelPosterior;
use super::refine::TimeDomainRefit;
use super::residual_map::{ResidualMap, ResidualRow};
use super::round::{run_round, BaseModel, Round, RoundContext, Stopwatch, Timings};
use super::search::HypothesisSearch;
use super::stepwise::{accepted_effects, continue_rounds, AcceptedEffect, Ambiguity};
use super::time_domain::{hold_rel_err, HOLD_REL_ERR};
use super::verdict::{Decision, EffectSummary, FitQuality};
use crate::error::Result;
use crate::infer::evidence::{EvidenceOptions, EvidenceProgress};
use crate::infer::screened::ScreenedEvidence;
use crate::io::stages::{staged, Stages};
use crate::io::Campaign;
use crate::update::fdac;
use num_complex::Complex64;
use std::sync::Arc;
use std::time::Instant;

/// Settings of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseOptions {
    pub seed: u64,
    pub data: DataOptions,
    pub map: MapOptions,
    /// Frame starts of the nominal MAP fit.
    pub n_frame_starts: usize,
    /// Effect starts per candidate location.
    pub n_effect_starts: usize,
    /// Hypotheses (best location each) whose evidence is computed, the most likely first
    /// by maximum log-likelihood; the others are reported with their search results.
    pub max_evidence_runs: usize,
    /// Walkers, replicates, ... of every evidence run (its `seed` is derived per model).
    pub evidence: Option<EvidenceOptions>,
    /// Only these hypotheses (all when empty).
    pub only: Vec<String>,
    /// Add the hammer estimator's own systematic error, measured by replaying the tests
    /// at the nominal MAP, to every frequency-domain prediction
    /// ([`super::estimator_bias`]), and refit the nominal model with it; measure it
    /// again at each accepted model's MAP ([`super::stepwise`]). On by default.
    pub estimator_bias: bool,
}

/// Re-anchorings of a reduced basis at the nominal MAP (and at each accepted model's,
/// [`super::stepwise`]), at most.
pub(super) const MAX_REANCHOR: usize = 3;

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            seed: 1,
            data: DataOptions::default(),
            map: MapOptions::default(),
            n_frame_starts: 8,
            n_effect_starts: 6,
            max_evidence_runs: usize::MAX,
            evidence: None,
            only: Vec::new(),
            estimator_bias: true,
        }
    }
}

/// Where the pipeline is, for progress bars.
#[derive(Debug, Clone)]
pub enum DiagnoseStage<'a> {
    Data,
    NominalFit,
    Search {
        hypothesis: &'a str,
        location: &'a Location,
    },
    Evidence {
        model: &'a str,
        progress: EvidenceProgress,
    },
    HeldOut {
        hypothesis: &'a str,
        done: usize,
        of: usize,
    },
    /// Refitting an amplitude-dependent hypothesis by replaying the tests.
    TimeDomain {
        hypothesis: &'a str,
    },
}

/// One model's complete result.
#[derive(Debug, Clone)]
pub struct ModelResult {
    /// `"nominal"` or the hypothesis name.
    pub name: String,
    pub location: Location,
    pub posterior: ModelPosterior,
    pub map: MapFit,
    /// Its log evidence, the estimator that gave it, and its sd
    /// ([`super::model_evidence`]).
    pub evidence: Option<ScreenedEvidence>,
    /// Effect parameters' posterior summaries (physical units), from the evidence run's
    /// draws (or Laplace's Gaussian in logit coordinates without a run).
    pub effect: Vec<(String, EffectSummary)>,
    pub plausible: bool,
    pub implausible_because: String,
    pub held_out: Option<HeldOut>,
    /// The refit with the time-domain replay of the tests (amplitude-dependent
    /// hypotheses that are decisive when linearised; see [`super::refine`]).
    pub time_domain: Option<TimeDomainRefit>,
}

impl ModelResult {
    /// A model's result after its MAP fit alone: no evidence, effect summaries, held-out
    /// check or time-domain refit yet, and plausible until judged.
    pub fn fitted(name: &str, location: Location, posterior: ModelPosterior, map: MapFit) -> Self {
        ModelResult {
            name: name.to_string(),
            location,
            posterior,
            map,
            evidence: None,
            effect: Vec::new(),
            plausible: true,
            implausible_because: String::new(),
            held_out: None,
            time_domain: None,
        }
    }

    /// Log evidence, when computed.
    pub fn ln_z(&self) -> Option<f64> {
        self.evidence.as_ref().map(|e| e.ln_z)
    }
}

/// Everything [`diagnose`] found.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    pub data: Arc<DiagnosisData>,
    pub nominal: ModelResult,
    /// Hypotheses whose evidence was computed (ranked by log evidence).
    pub finalists: Vec<ModelResult>,
    /// Every hypothesis' location search.
    pub searches: Vec<HypothesisSearch>,
    /// Laplace approximation of the log evidence, at the mode in logit coordinates, of
    /// the nominal model (`"nominal"`) and of every hypothesis at its best location
    /// (`None` where no mode was found or the curvature there is not positive definite).
    pub laplace: Vec<(String, Option<f64>)>,
    pub decision: Decision,
    /// Index into `finalists` of the first round's winner.
    pub winner: Option<usize>,
    /// The rounds after the first, each on the model with the effects accepted before
    /// it ([`super::stepwise`]).
    pub later: Vec<Round>,
    /// The accepted effects in the order they were added, with their parameters in the
    /// final model.
    pub effects: Vec<AcceptedEffect>,
    /// The final model, every accepted effect in it (`None` without accepted effects):
    /// the model `effects` summarises.
    pub final_model: Option<ModelResult>,
    /// Two passing explanations within a decisive Bayes factor: the diagnosis stopped
    /// there.
    pub ambiguity: Option<Ambiguity>,
    /// Whether the final model (every accepted effect) explains the recordings.
    pub adequacy: Adequacy,
    pub fit_before: FitQuality,
    /// The final model's fit.
    pub fit_after: FitQuality,
    pub elapsed_s: f64,
    /// Wall time of each stage, s.
    pub timings: Vec<(String, f64)>,
    /// Consistency checks and findings, with the nominal model's residual map (`Err`:
    /// why the checks could not run).
    pub locate: std::result::Result<LocateReport, String>,
    /// Residual map of the final model (`None` without accepted effects).
    pub residual_after: Option<ResidualMap>,
}

/// Standardised residual map of `post` at `z` (error floor `eta`), with one column per
/// resonance of the fitted frame (+-10 % of its natural frequency) plus off-band.
pub fn residual_map(post: &ModelPosterior, z: &[f64], eta: f64) -> Result<ResidualMap> {
    let pred = post.predict(z)?;
    let h = post.measured();
    let data = post.data();
    let mut rows = Vec::new();
    for (si, seg) in post.model().layout().iter().enumerate() {
        let sd = &data.segments[si];
        for (ci, r) in seg.iter().enumerate() {
            let ch = &sd.channels[ci];
            rows.push(ResidualRow {
                segment: sd.name.clone(),
                channel: ch.channel.name.clone(),
                freq_hz: ch.freq_index.iter().map(|&i| sd.freq_hz[i]).collect(),
                measured: h[r.clone()].to_vec(),
                predicted: pred[r.clone()].to_vec(),
                sigma: ch
                    .rel_err
                    .iter()
                    .zip(&h[r.clone()])
                    .map(|(e, v)| (e * e + eta * eta).sqrt() * v.norm())
                    .collect(),
            });
        }
    }
    ResidualMap::new(&rows, &mode_bands(post, z)?)
}

/// The resonance bands of the frame of `post` at `z`: +-10 % of each natural frequency.
pub fn mode_bands(post: &ModelPosterior, z: &[f64]) -> Result<Vec<(f64, f64)>> {
    let modes = frame_system(&post.data().model, &post.base_params(z))?.modes()?;
    Ok(modes
        .omega_rad_s
        .iter()
        .map(|w| {
            let f = w / (2.0 * std::f64::consts::PI);
            (0.9 * f, 1.1 * f)
        })
        .collect())
}

/// Mean FDAC (magnitudes) over every segment and channel, and chi2 per real datum with
/// the Bendat-Piersol errors and the error floor `eta`.
pub fn fit_quality(post: &ModelPosterior, pred: &[Complex64], eta: f64) -> FitQuality {
    let mut sum = 0.0;
    let mut n = 0usize;
    for seg in post.model().layout() {
        for r in seg {
            let a: Vec<f64> = pred[r.clone()].iter().map(|v| v.norm()).collect();
            let e: Vec<f64> = post.measured()[r.clone()]
                .iter()
                .map(|v| v.norm())
                .collect();
            sum += fdac(&a, &e);
            n += 1;
        }
    }
    FitQuality {
        fdac_mean: if n == 0 { f64::NAN } else { sum / n as f64 },
        chi2_per_point: post.chi2_per_dof_of(pred, eta),
    }
}

/// Runs the diagnosis of `campaign` (see the module docs).
pub fn diagnose(
    campaign: &Campaign,
    opts: &DiagnoseOptions,
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<Diagnosis> {
    diagnose_resumable(campaign, opts, None, progress)
}

/// [`diagnose`], saving the result of every long stage (nominal MAP, every evidence run,
/// every location search) in `stages` and reading back those an interrupted run
/// finished: the diagnosis is the same as an uninterrupted run's.
pub fn diagnose_resumable(
    campaign: &Campaign,
    opts: &DiagnoseOptions,
    stages: Option<&Stages>,
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<Diagnosis> {
    let t0 = Instant::now();
    progress(DiagnoseStage::Data);
    let data = Arc::new(DiagnosisData::from_campaign(campaign, &opts.data)?);
    // On a reduced model the tests are replayed, and checked, on the kept DOFs.
    let renumbered = data.reduction.as_ref().map(|r| r.renumber(campaign));
    let campaign = renumbered.as_ref().unwrap_or(campaign);
    let mut timings: Timings = Vec::new();
    let mut watch = Stopwatch::new(t0);
    watch.mark("data", &mut timings);
    let (data, nominal, lap0) = nominal_model(
        campaign,
        data,
        opts,
        stages,
        (&mut watch, &mut timings),
        progress,
    )?;
    let nominal_laplace = lap0.as_ref().ok().map(|l| l.laplace.ln_z);

    let hypotheses: Vec<Arc<dyn Hypothesis>> = all_hypotheses()
        .into_iter()
        .filter(|h| opts.only.is_empty() || opts.only.iter().any(|o| o == h.name()))
        .map(Arc::from)
        .collect();
    let ctx = RoundContext {
        campaign,
        data: &data,
        opts,
        stages,
        hypotheses: &hypotheses,
    };
    let base = BaseModel {
        result: nominal.clone(),
        laplace: lap0,
        extension: None,
        effects: Vec::new(),
    };
    let first = run_round(&ctx, &base, 0, (&mut watch, &mut timings), progress)?;
    let steps = continue_rounds(&ctx, base, &first, (&mut watch, &mut timings), progress)?;
    let effects = accepted_effects(&steps.last)?;

    let eta0 = nominal.map.eta;
    let pred0 = nominal.posterior.predict(&nominal.map.z)?;
    let fit_before = fit_quality(&nominal.posterior, &pred0, eta0);
    let (locate, adequacy) = locate_and_assess(campaign, &nominal, &steps.last.result)?;
    watch.mark("consistency checks and adequacy", &mut timings);
    let last = &steps.last.result;
    let residual_after = match effects.is_empty() {
        false => Some(residual_map(&last.posterior, &last.map.z, eta0)?),
        true => None,
    };
    let fit_after = fit_quality(&last.posterior, &last.posterior.predict(&last.map.z)?, eta0);
    Ok(Diagnosis {
        data,
        nominal,
        winner: first.decision.winner,
        finalists: first.finalists,
        searches: first.searches,
        laplace: std::iter::once(("nominal".to_string(), nominal_laplace))
            .chain(first.laplace)
            .collect(),
        decision: first.decision,
        later: steps.later,
        final_model: (!effects.is_empty()).then(|| steps.last.result.clone()),
        effects,
        ambiguity: steps.ambiguity,
        adequacy,
        fit_before,
        fit_after,
        elapsed_s: t0.elapsed().as_secs_f64(),
        timings,
        locate,
        residual_after,
    })
}

/// The nominal model's MAP (multistart), Laplace and evidence; with
/// `opts.estimator_bias`, the data then carry the estimator's bias measured at that MAP
/// and the nominal model is refitted on them (from that MAP). Returns the data every
/// later model uses.
fn nominal_model(
    campaign: &Campaign,
    data: Arc<DiagnosisData>,
    opts: &DiagnoseOptions,
    stages: Option<&Stages>,
    (watch, timings): (&mut Stopwatch, &mut Timings),
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<(Arc<DiagnosisData>, ModelResult, LaplaceOutcome)> {
    progress(DiagnoseStage::NominalFit);
    let mut post0 = ModelPosterior::new(data.clone(), None)?;
    let mut map0 = staged(stages, "nominal-map", || {
        let starts = frame_starts(&post0, opts.n_frame_starts, 0.3, opts.seed)?;
        fit_map(&post0, &starts, &opts.map)
    })?;
    let mut data = data;
    // A reduced basis is exact only at its anchor: move it to the MAP and refit there
    // until the MAP stays put.
    for round in 1..=MAX_REANCHOR {
        let Some((moved_data, moved)) = data.reanchored(&post0.base_params(&map0.z))? else {
            break;
        };
        data = Arc::new(moved_data);
        post0 = ModelPosterior::new(data.clone(), None)?;
        map0 = staged(stages, &format!("nominal-map-reanchored-{round}"), || {
            fit_map(&post0, std::slice::from_ref(&map0.z), &opts.map)
        })?;
        watch.mark(
            &format!(
                "reduced basis re-anchored at the nominal MAP ({moved:.3} from the last anchor)"
            ),
            timings,
        );
    }
    // The replay is only as good as its straight-line hold: too coarse, it would add its
    // own error, not the estimator's (the stage table says so).
    let (hold_err, hold_f_hz) = hold_rel_err(campaign, &data, REPLAY_OVERSAMPLING);
    let replay_ok = hold_err <= HOLD_REL_ERR;
    if opts.estimator_bias && !replay_ok {
        watch.mark(
            &format!(
                "estimator bias not replayed: the replay's hold error {hold_err:.1e} at \
                 {hold_f_hz:.1} Hz exceeds {HOLD_REL_ERR:.0e}"
            ),
            timings,
        );
    }
    if opts.estimator_bias && replay_ok && data.segments.iter().any(|s| !s.is_ground()) {
        let bias = replay_bias(campaign, &post0, &map0.z)?;
        data = Arc::new(data.with_estimator_bias(post0.model().layout(), &bias)?);
        post0 = ModelPosterior::new(data.clone(), None)?;
        map0 = staged(stages, "nominal-map-debiased", || {
            fit_map(&post0, std::slice::from_ref(&map0.z), &opts.map)
        })?;
    }
    let (post0, map0) = refit_at_map(post0, map0, &opts.map)?;
    watch.mark("nominal MAP", timings);
    let lap0 = laplace_u(&post0, &map0.z);
    let done = completion(
        "nominal", &post0, &map0, &lap0, None, opts, 0, stages, progress,
    )?;
    let nominal = model_result("nominal", Location::Whole, post0, map0, done);
    watch.mark("nominal evidence", timings);
    Ok((data, nominal, lap0))
}

/// The consistency checks with the nominal model's residual map (or why they could not
/// run), and the adequacy of the final model `last`, which they feed.
fn locate_and_assess(
    campaign: &Campaign,
    nominal: &ModelResult,
    last: &ModelResult,
) -> Result<(std::result::Result<LocateReport, String>, Adequacy)> {
    // Peaks searched: the modes of the analysed band (every mode of a model that is not
    // reduced, as the checks' default; on a reduced model not its thousand DOFs), below
    // the band's top where it has one.
    let data = nominal.posterior.data();
    let check_opts = ConsistencyOptions::for_band(data.nominal_freq_hz.len(), data.band_cap_hz());
    let locate = check_campaign(campaign, &check_opts)
        .map_err(|e| e.to_string())
        .and_then(|c| {
            let map = residual_map(&nominal.posterior, &nominal.map.z, nominal.map.eta)
                .map_err(|e| e.to_string())?;
            Ok(LocateReport::new(c, Some(map)))
        });
    let pred = last.posterior.predict(&last.map.z)?;
    let adequacy = assess(
        &last.posterior,
        &pred,
        &mode_bands(&last.posterior, &last.map.z)?,
        locate
            .as_ref()
            .map(|l| &l.consistency)
            .map_err(|e| e.clone()),
    )?;
    Ok((locate, adequacy))
}

impl crate::infer::TemperedTarget for ModelPosterior {
    fn dim(&self) -> usize {
        ModelPosterior::dim(self)
    }
    fn ln_prior(&self, z: &[f64]) -> f64 {
        ModelPosterior::ln_prior(self, z)
    }
    fn ln_likelihood(&self, z: &[f64]) -> Result<f64> {
        ModelPosterior::ln_likelihood(self, z)
    }
    fn sample_prior(&self, rng: &mut rand_chacha::ChaCha8Rng) -> Result<Vec<f64>> {
        ModelPosterior::sample_prior(self, rng)
    }
}
