//! The evidence of every model of a diagnosis, by the screen of
//! [`crate::infer::screened`]: the nominal model by a run (importance sampling from the
//! generalised stepping-stone's reference where its weights allow, the stepping-stone
//! otherwise), each hypothesis (which nests it) by the cheapest estimator that is right
//! for the decision: its gain bound when it cannot reach `ln 150`, Laplace in logit
//! coordinates when it is clearly below or clearly above, a run otherwise (issue 14,
//! item 3). The rounds ([`super::round`]) give a run to a winner decided by Laplace and
//! to passing hypotheses within reach of each other. The posterior draws that size the
//! effect come from the run, or, without one, from Laplace's Gaussian in logit
//! coordinates.

use super::diagnose::{DiagnoseOptions, DiagnoseStage, ModelResult};
use super::effect_summary::effect_summaries;
use super::fit::MapFit;
use super::location::Location;
use super::posterior::ModelPosterior;
use super::verdict::{decisive_ln_bayes_factor, EffectSummary};
use crate::error::Result;
use crate::infer::evidence::{EvidenceOptions, EvidenceProgress};
use crate::infer::nested::gain_bound;
use crate::infer::screened::IMPORTANCE_DRAWS;
use crate::infer::screened::{
    choose_for_extension, laplace_of, screened_evidence, BaseEvidence, Estimator, Extension,
    LaplaceInU, ScreenOptions, ScreenedEvidence, GSS_REPLICATES,
};
use crate::infer::unconstrained::LogitMap;
use crate::io::stages::{staged, Stages};
use nalgebra::DVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Stated sd of Laplace's `Delta ln Z` in logit coordinates, nats: Laplace decides
/// (as "not decisive") only below `ln 150 - 2 x` this. Its errors on the validation
/// problems of [`crate::infer::validation`] (12-15 base coordinates, 1-4 effects at a
/// wall, on a plateau or inside) are at most 0.45 nats (the log-uniform plateau;
/// `tests/evidence_validation.rs` asserts they stay below this allowance); 5 allows for
/// the diagnosis' less Gaussian posteriors.
pub const LAPLACE_ALLOWANCE_NATS: f64 = 5.0;

/// Draws from Laplace's Gaussian in logit coordinates that size an effect without a
/// tempered run.
const LAPLACE_DRAWS: usize = 400;

/// Final steps per replicate of a generalised stepping-stone (4 replicates: as many
/// draws as the 100 of each of the 2 replicates of the stepping-stone from the prior).
const GSS_FINAL_STEPS: usize = 50;

/// The screen's settings for a model with `dim` parameters (the seed per model).
pub fn screen_options(opts: &DiagnoseOptions, dim: usize, model_index: u64) -> ScreenOptions {
    let given = opts.evidence.is_some();
    let mut e = opts.evidence.clone().unwrap_or_else(|| {
        let mut e = EvidenceOptions::new(dim, 0);
        e.final_steps = GSS_FINAL_STEPS;
        e
    });
    if e.n_walkers < 2 * dim + 2 {
        e.n_walkers = EvidenceOptions::new(dim, 0).n_walkers;
    }
    e.seed = opts.seed.wrapping_mul(1_000_003).wrapping_add(model_index);
    ScreenOptions {
        threshold_nats: decisive_ln_bayes_factor(),
        laplace_allowance_nats: LAPLACE_ALLOWANCE_NATS,
        // Explicit evidence options (tests, `--quick`) keep their replicates.
        gss_replicates: if given {
            e.n_replicates
        } else {
            GSS_REPLICATES
        },
        importance_draws: IMPORTANCE_DRAWS,
        evidence: e,
    }
}

/// The prior box of `post` as `(lower, upper)` pairs.
pub fn box_bounds(post: &ModelPosterior) -> Vec<(f64, f64)> {
    let (lo, hi) = post.bounds();
    lo.iter().copied().zip(hi.iter().copied()).collect()
}

/// Laplace at the mode in logit coordinates, or why there is none (Newton found no mode,
/// or the curvature there is not positive definite).
pub type LaplaceOutcome = std::result::Result<LaplaceInU, String>;

/// Why a model whose gain bound rules it out has no [`LaplaceOutcome`]: its evidence is
/// the bound ([`Estimator::GainBound`]), which needs none.
pub const NOT_NEEDED: &str = "not computed: the gain bound rules the model out";

/// Laplace at the mode in logit coordinates from the MAP `z`.
pub fn laplace_u(post: &ModelPosterior, z: &[f64]) -> LaplaceOutcome {
    laplace_of(post, &box_bounds(post), z).map_err(|e| e.to_string())
}

/// What an extension's screen needs of the nominal model (no rival known: the caller
/// sets [`Extension::rival_floor_nats`]).
pub fn extension_of(nominal: &ModelResult, lap0: Option<&LaplaceInU>, map: &MapFit) -> Extension {
    Extension {
        base: BaseEvidence {
            ln_z: nominal.ln_z().unwrap_or(f64::NAN),
            ln_z_laplace: lap0.map(|l| l.laplace.ln_z),
            max_ln_likelihood: nominal.map.ln_likelihood,
        },
        gain_bound_nats: gain_bound(map.ln_likelihood, nominal.map.ln_likelihood),
        rival_floor_nats: f64::NEG_INFINITY,
    }
}

/// The resumable part of a model's result: its evidence and what follows from its draws.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Completion {
    pub evidence: ScreenedEvidence,
    pub effect: Vec<(String, EffectSummary)>,
    pub plausible: bool,
    pub why: String,
}

/// The stage key of model `name`'s evidence.
pub fn evidence_key(name: &str) -> String {
    format!("screened-evidence-{name}")
}

/// `n` draws (box coordinates) from Laplace's Gaussian in logit coordinates.
fn laplace_draws(post: &ModelPosterior, lap: &LaplaceInU, seed: u64) -> Option<Vec<Vec<f64>>> {
    let map = LogitMap::from_bounds(&box_bounds(post)).ok()?;
    let l = nalgebra::Cholesky::new(lap.laplace.covariance.clone())?.l();
    let mu = DVector::from_column_slice(&lap.u_mode);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let draws = (0..LAPLACE_DRAWS)
        .map(|_| {
            let xi = DVector::from_fn(mu.len(), |_, _| StandardNormal.sample(&mut rng));
            let u = &mu + &l * xi;
            let mut z = vec![0.0; u.len()];
            map.to_box(u.as_slice(), &mut z);
            z
        })
        .collect();
    Some(draws)
}

/// Evidence, draws and effect summaries of one model at its MAP `map` (read back from
/// `stages` when an interrupted run finished it): `laplace` its Laplace in logit
/// coordinates (or why none; recorded in the evidence), `extension` the nominal model's
/// evidence and the gain bound (`None` for the nominal model).
#[allow(clippy::too_many_arguments)]
pub fn completion(
    name: &str,
    post: &ModelPosterior,
    map: &MapFit,
    laplace: &LaplaceOutcome,
    extension: Option<&Extension>,
    opts: &DiagnoseOptions,
    model_index: u64,
    stages: Option<&Stages>,
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<Completion> {
    let lap = laplace.as_ref().ok();
    let run = || -> Result<Completion> {
        let screen = screen_options(opts, post.dim(), model_index);
        let estimator = match extension {
            Some(x) => {
                let delta = x.delta_laplace(lap.map(|l| l.laplace.ln_z));
                choose_for_extension(x, delta, &screen)
            }
            None if lap.is_some() => Estimator::GeneralisedSteppingStone,
            None => Estimator::SteppingStone,
        };
        let effect: Vec<usize> = (post.eta_index() + 1..post.dim()).collect();
        let mut cb = |p: EvidenceProgress| {
            progress(DiagnoseStage::Evidence {
                model: name,
                progress: p,
            })
        };
        let mut evidence = screened_evidence(
            post,
            &box_bounds(post),
            lap,
            &effect,
            estimator,
            extension,
            &screen,
            Some(&mut cb),
        )?;
        // A gain-bound evidence needs no Laplace: its absence there is not a failure.
        if evidence.estimator != Estimator::GainBound {
            evidence.laplace_failure = laplace.as_ref().err().cloned();
        }
        let draws: Vec<Vec<f64>> = match (evidence.posterior_draws(), lap) {
            (Some(d), _) => d,
            (None, Some(l)) => {
                laplace_draws(post, l, screen.evidence.seed).unwrap_or_else(|| vec![map.z.clone()])
            }
            (None, None) => vec![map.z.clone()],
        };
        let (effect, plausible, why) = effect_summaries(post, &draws)?;
        Ok(Completion {
            evidence,
            effect,
            plausible,
            why,
        })
    };
    staged(stages, &evidence_key(name), run)
}

/// One model's result from its evidence.
pub fn model_result(
    name: &str,
    location: Location,
    posterior: ModelPosterior,
    map: MapFit,
    done: Completion,
) -> ModelResult {
    ModelResult {
        evidence: Some(done.evidence),
        effect: done.effect,
        plausible: done.plausible,
        implausible_because: done.why,
        ..ModelResult::fitted(name, location, posterior, map)
    }
}
