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
//!    better prediction of held-out segments ([`super::heldout`]).

use super::consistency::{check_campaign, ConsistencyOptions};
use super::data::{DataOptions, DiagnosisData};
pub use super::effect_summary::effect_columns;
use super::fit::{fit_map, frame_starts, MapFit, MapOptions};
use super::forward::frame_system;
use super::heldout::{held_out, HeldOut};
use super::hypotheses::all_hypotheses;
use super::hypothesis::Hypothesis;
use super::locate::LocateReport;
use super::location::Location;
use super::model_evidence::{
    completion, evidence_key, extension_of, laplace_u, model_result, LaplaceOutcome,
};
use super::posterior::ModelPosterior;
use super::refine::{refit_in_time_domain, TimeDomainRefit};
use super::residual_map::{ResidualMap, ResidualRow};
use super::search::{search, HypothesisSearch, SearchOptions};
use super::verdict::{decide, held_out_passes, Candidate, Decision, EffectSummary, FitQuality};
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
}

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
    /// Index into `finalists` of the verdict.
    pub winner: Option<usize>,
    pub fit_before: FitQuality,
    pub fit_after: FitQuality,
    pub elapsed_s: f64,
    /// Wall time of each stage, s.
    pub timings: Vec<(String, f64)>,
    /// Consistency checks and findings, with the nominal model's residual map (`Err`:
    /// why the checks could not run).
    pub locate: std::result::Result<LocateReport, String>,
    /// Residual map of the verdict's model (`None` for verdict `none`).
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
    let modes = frame_system(&post.base_params(z))?.modes()?;
    let bands: Vec<(f64, f64)> = modes
        .omega_rad_s
        .iter()
        .map(|w| {
            let f = w / (2.0 * std::f64::consts::PI);
            (0.9 * f, 1.1 * f)
        })
        .collect();
    ResidualMap::new(&rows, &bands)
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

    let mut timings: Vec<(String, f64)> = Vec::new();
    let mut lap_t = t0;
    let mut mark = |what: &str, timings: &mut Vec<(String, f64)>| {
        timings.push((what.to_string(), lap_t.elapsed().as_secs_f64()));
        lap_t = Instant::now();
    };
    mark("data", &mut timings);
    progress(DiagnoseStage::NominalFit);
    let post0 = ModelPosterior::new(data.clone(), None)?;
    let map0 = staged(stages, "nominal-map", || {
        let starts = frame_starts(&post0, opts.n_frame_starts, 0.3, opts.seed)?;
        fit_map(&post0, &starts, &opts.map)
    })?;
    mark("nominal MAP", &mut timings);
    let lap0 = laplace_u(&post0, &map0.z);
    let done = completion(
        "nominal", &post0, &map0, &lap0, None, opts, 0, stages, progress,
    )?;
    let nominal = model_result("nominal", Location::Whole, post0, map0.clone(), done);
    mark("nominal evidence", &mut timings);

    let hypotheses: Vec<Arc<dyn Hypothesis>> = all_hypotheses()
        .into_iter()
        .filter(|h| opts.only.is_empty() || opts.only.iter().any(|o| o == h.name()))
        .map(Arc::from)
        .collect();
    let sopts = SearchOptions {
        n_effect_starts: opts.n_effect_starts,
        map: opts.map.clone(),
        seed: opts.seed,
    };
    // The hypotheses' searches, one farmed task each (over the ranks of an MPI run).
    let key = |h: &Arc<dyn Hypothesis>| format!("search-{}", h.name());
    let found = crate::dist::farm(
        hypotheses.len(),
        |i| {
            let h = &hypotheses[i];
            let mut cb = |name: &str, loc: &Location| {
                progress(DiagnoseStage::Search {
                    hypothesis: name,
                    location: loc,
                })
            };
            staged(stages, &key(h), || {
                search(&data, h, &map0.z, &sopts, &mut cb).map(|s| (s.tried, s.failed))
            })
        },
        |i, found| {
            mark(&format!("search {}", hypotheses[i].name()), &mut timings);
            stages.map_or(Ok(()), |s| s.save_if_absent(&key(&hypotheses[i]), found))
        },
    )?;
    let searches: Vec<_> = hypotheses
        .iter()
        .zip(found)
        .map(|(h, (tried, failed))| {
            let found = HypothesisSearch {
                name: h.name(),
                tried,
                failed,
            };
            (h.clone(), found)
        })
        .collect();

    // Laplace at the mode in logit coordinates of every hypothesis' best location: the
    // screen of the evidence and the reference of its generalised stepping-stone.
    let mut posts: Vec<Option<(ModelPosterior, LaplaceOutcome)>> = Vec::new();
    for (h, s) in &searches {
        posts.push(match s.best() {
            Some(b) => {
                let post =
                    ModelPosterior::new(data.clone(), Some((h.clone(), b.location.clone())))?;
                let lap = laplace_u(&post, &b.map.z);
                Some((post, lap))
            }
            None => None,
        });
    }
    let mut laplace_z = vec![(
        "nominal".to_string(),
        lap0.as_ref().ok().map(|l| l.laplace.ln_z),
    )];
    for ((h, _), p) in searches.iter().zip(&posts) {
        let v = p
            .as_ref()
            .and_then(|(_, l)| l.as_ref().ok().map(|l| l.laplace.ln_z));
        laplace_z.push((h.name().to_string(), v));
    }
    mark("Laplace", &mut timings);

    // Evidence for every hypothesis (best location each), the best fits first, up to
    // `max_evidence_runs`.
    let mut order: Vec<usize> = (0..searches.len())
        .filter(|&i| searches[i].1.best().is_some())
        .collect();
    order.sort_by(|&a, &b| {
        let la = searches[a]
            .1
            .best()
            .map_or(f64::NEG_INFINITY, |f| f.map.ln_likelihood);
        let lb = searches[b]
            .1
            .best()
            .map_or(f64::NEG_INFINITY, |f| f.map.ln_likelihood);
        lb.total_cmp(&la)
    });
    order.truncate(opts.max_evidence_runs);
    // Their evidence runs, one farmed task each.
    let picked: Vec<_> = order
        .iter()
        .filter_map(|&i| {
            let b = searches[i].1.best()?;
            let (post, lap) = posts[i].take()?;
            Some((&searches[i].0, b, post, lap))
        })
        .collect();
    let done = crate::dist::farm(
        picked.len(),
        |k| {
            let (h, best, post, lap) = &picked[k];
            let x = extension_of(&nominal, lap0.as_ref().ok(), &best.map);
            completion(
                h.name(),
                post,
                &best.map,
                lap,
                Some(&x),
                opts,
                k as u64 + 1,
                stages,
                progress,
            )
        },
        |k, done| {
            let name = picked[k].0.name();
            mark(&format!("evidence {name}"), &mut timings);
            stages.map_or(Ok(()), |s| s.save_if_absent(&evidence_key(name), done))
        },
    )?;
    let mut finalists: Vec<ModelResult> = picked
        .into_iter()
        .zip(done)
        .map(|((h, best, post, _), done)| {
            model_result(
                h.name(),
                best.location.clone(),
                post,
                best.map.clone(),
                done,
            )
        })
        .collect();
    finalists.sort_by(|a, b| {
        b.ln_z()
            .unwrap_or(f64::NEG_INFINITY)
            .total_cmp(&a.ln_z().unwrap_or(f64::NEG_INFINITY))
    });

    let nominal_ln_z = nominal.ln_z().unwrap_or(f64::NEG_INFINITY);
    let nominal_se = nominal.evidence.as_ref().map_or(0.0, |e| e.ln_z_sd);
    let decisive = |f: &ModelResult| {
        let ev = f.evidence.as_ref();
        let delta = ev.map_or(f64::NEG_INFINITY, |e| e.ln_z - nominal_ln_z);
        let se = ev.map_or(0.0, |e| e.ln_z_sd.hypot(nominal_se));
        let bound = ev.and_then(|e| e.gain_bound_nats).unwrap_or(f64::INFINITY);
        let thr = super::verdict::decisive_ln_bayes_factor();
        delta - 2.0 * se >= thr && bound >= thr
    };
    // Amplitude-dependent hypotheses that are decisive when linearised: refit by
    // replaying the tests in the time domain, and judge the effect on that fit.
    for f in &mut finalists {
        let amplitude = hypotheses
            .iter()
            .any(|h| h.name() == f.name && h.amplitude_dependent());
        if amplitude && decisive(f) {
            progress(DiagnoseStage::TimeDomain {
                hypothesis: &f.name,
            });
            // A replay that fails (a softening spring losing its stiffness, say) leaves
            // only the linearisation, which cannot size this effect: not plausible.
            match refit_in_time_domain(campaign, f, opts) {
                Ok(r) => f.time_domain = Some(r),
                Err(e) => {
                    f.plausible = false;
                    f.implausible_because = format!("its time-domain refit failed ({e})");
                }
            }
            mark(&format!("time-domain refit {}", f.name), &mut timings);
        }
    }
    finalists.sort_by(|a, b| {
        b.ln_z()
            .unwrap_or(f64::NEG_INFINITY)
            .total_cmp(&a.ln_z().unwrap_or(f64::NEG_INFINITY))
    });

    // Held-out check only where it can change the verdict: decisive and plausible, and,
    // for a check that replays the tests, not below a hypothesis that already passed.
    let mut passed = false;
    let mut skipped = vec![false; finalists.len()];
    for (k, f) in finalists.iter_mut().enumerate() {
        if f.plausible && decisive(f) {
            if passed && f.time_domain.is_some() {
                skipped[k] = true;
                continue;
            }
            let h = hypotheses
                .iter()
                .find(|h| h.name() == f.name)
                .expect("finalists come from the hypotheses");
            let name = f.name.clone();
            let mut cb = |done: usize, of: usize| {
                progress(DiagnoseStage::HeldOut {
                    hypothesis: &name,
                    done,
                    of,
                })
            };
            let replay = f.time_domain.is_some().then_some(campaign);
            match held_out(
                &data,
                h,
                &f.location,
                &nominal.map.z,
                &f.map.z,
                &opts.map,
                replay,
                &mut cb,
            ) {
                Ok(ho) => f.held_out = Some(ho),
                Err(e) if replay.is_some() => {
                    f.plausible = false;
                    f.implausible_because = format!("its time-domain held-out check failed ({e})");
                }
                Err(e) => return Err(e),
            }
            mark(&format!("held-out {name}"), &mut timings);
            passed |= f.held_out.as_ref().is_some_and(held_out_passes);
        }
    }

    let candidates: Vec<Candidate> = finalists
        .iter()
        .zip(&skipped)
        .map(|(f, &heldout_skipped)| Candidate {
            heldout_skipped,
            name: f.name.clone(),
            log_evidence: f.ln_z().unwrap_or(f64::NEG_INFINITY),
            log_evidence_se: f.evidence.as_ref().map_or(0.0, |e| e.ln_z_sd),
            gain_bound: f
                .evidence
                .as_ref()
                .and_then(|e| e.gain_bound_nats)
                .unwrap_or(f64::INFINITY),
            estimator: f
                .evidence
                .as_ref()
                .map_or(String::new(), |e| e.estimator.label().to_string()),
            plausible: f.plausible,
            implausible_because: f.implausible_because.clone(),
            heldout_gain: f.held_out.as_ref().map_or(f64::NEG_INFINITY, |h| h.gain),
            heldout_gain_se: f.held_out.as_ref().map_or(0.0, |h| h.gain_se),
            heldout_p_value: f.held_out.as_ref().map_or(1.0, |h| h.p_value),
            heldout_n_ranked: f.held_out.as_ref().map_or(0, |h| h.n_ranked),
        })
        .collect();
    let decision = decide(nominal_ln_z, nominal_se, &candidates);

    let eta0 = nominal.map.eta;
    let pred0 = nominal.posterior.predict(&nominal.map.z)?;
    let fit_before = fit_quality(&nominal.posterior, &pred0, eta0);
    let locate = check_campaign(campaign, &ConsistencyOptions::default())
        .map_err(|e| e.to_string())
        .and_then(|c| {
            let map = residual_map(&nominal.posterior, &nominal.map.z, eta0)
                .map_err(|e| e.to_string())?;
            Ok(LocateReport::new(c, Some(map)))
        });
    mark("consistency checks", &mut timings);
    let residual_after = match decision.winner {
        Some(w) => {
            let f = &finalists[w];
            Some(residual_map(&f.posterior, &f.map.z, eta0)?)
        }
        None => None,
    };
    let fit_after = match decision.winner {
        Some(w) => {
            let f = &finalists[w];
            fit_quality(&f.posterior, &f.posterior.predict(&f.map.z)?, eta0)
        }
        None => fit_before,
    };
    Ok(Diagnosis {
        data,
        nominal,
        winner: decision.winner,
        finalists,
        searches: searches.into_iter().map(|(_, s)| s).collect(),
        laplace: laplace_z,
        decision,
        fit_before,
        fit_after,
        elapsed_s: t0.elapsed().as_secs_f64(),
        timings,
        locate,
        residual_after,
    })
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
