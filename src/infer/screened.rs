//! The evidence of nested models where a decision is taken at a threshold on
//! `Delta ln Z = ln Z_ext - ln Z_base` (issue 14, item 3): each extension gets the
//! cheapest estimator that is right where it is used.
//!
//! 1. **Gain bound** ([`super::nested::gain_bound`]): `Delta ln Z <= max ln L_ext - max
//!    ln L_base`. An extension whose gain is below the threshold cannot reach it: no run
//!    ([`Estimator::GainBound`]; its `ln Z` is reported as the base's plus the smaller of
//!    the bound and Laplace's `Delta`, and its sd as 0: a bound, not an estimate).
//! 2. **Laplace in logit coordinates** ([`super::nested::laplace_in_u`]), where its
//!    `Delta` is below the threshold by more than two allowances
//!    ([`ScreenOptions::laplace_allowance_nats`]): [`Estimator::Laplace`], with the
//!    allowance as its sd. The allowance is not a computed error but a stated one, set from
//!    Laplace's measured errors on the validation problems ([`super::validation`]).
//!    Laplace never names an extension: one above the threshold needs posterior draws
//!    for its effect's interval anyway, and gets step 3.
//! 3. **Generalised stepping-stone** ([`super::reference::referenced_evidence_at_mode`]):
//!    every other model, with replicates ([`GSS_REPLICATES`]) for its standard error
//!    ([`Estimator::GeneralisedSteppingStone`]).
//! 4. Where no mode in logit coordinates was found (Newton failed, covariance not
//!    positive definite), the stepping-stone from the prior ([`Estimator::SteppingStone`],
//!    2 replicates), as before.

use serde::{Deserialize, Serialize};

use super::evidence::{stepping_stone, Evidence, EvidenceOptions, EvidenceProgress};
use super::laplace::LaplaceEvidence;
use super::nested::{laplace_in_u, InUnconstrained};
use super::reference::referenced_evidence_at_mode;
use super::TemperedTarget;
use crate::error::Result;

/// Replicates of the generalised stepping-stone: three degrees of freedom for its
/// standard error (the stepping-stone from the prior had one, with 2).
pub const GSS_REPLICATES: usize = 4;

/// Which estimator gave a model's `ln Z` (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Estimator {
    /// No run: the gain bound keeps the extension below the threshold.
    GainBound,
    /// Laplace's approximation at the mode in logit coordinates.
    Laplace,
    /// Generalised stepping-stone from a reference at the posterior.
    GeneralisedSteppingStone,
    /// Stepping-stone from the prior.
    SteppingStone,
}

impl Estimator {
    /// Name for reports (the `diagnosis.json` spelling).
    pub fn label(self) -> &'static str {
        match self {
            Estimator::GainBound => "gain_bound",
            Estimator::Laplace => "laplace",
            Estimator::GeneralisedSteppingStone => "generalised_stepping_stone",
            Estimator::SteppingStone => "stepping_stone",
        }
    }
}

/// Settings of the screen.
#[derive(Debug, Clone, PartialEq)]
pub struct ScreenOptions {
    /// The decision threshold on `Delta ln Z`, nats.
    pub threshold_nats: f64,
    /// Stated sd of Laplace's `Delta ln Z`, nats (module docs).
    pub laplace_allowance_nats: f64,
    /// The tempered runs (walkers, steps, final draws; the seed per model).
    pub evidence: EvidenceOptions,
    /// Replicates of the generalised stepping-stone (at least 2; [`GSS_REPLICATES`] by
    /// default). The stepping-stone from the prior keeps `evidence.n_replicates`.
    pub gss_replicates: usize,
}

/// The estimator for an extension whose gain bound is `gain_bound_nats` and whose
/// Laplace `Delta ln Z` (in logit coordinates, against the base's) is
/// `delta_laplace_nats` (`None`: no mode found); module docs.
pub fn choose_estimator(
    gain_bound_nats: f64,
    delta_laplace_nats: Option<f64>,
    opts: &ScreenOptions,
) -> Estimator {
    if gain_bound_nats < opts.threshold_nats {
        return Estimator::GainBound;
    }
    match delta_laplace_nats {
        None => Estimator::SteppingStone,
        Some(d) if d + 2.0 * opts.laplace_allowance_nats < opts.threshold_nats => {
            Estimator::Laplace
        }
        Some(_) => Estimator::GeneralisedSteppingStone,
    }
}

/// Laplace's approximation at the mode in logit coordinates (the reference of the
/// generalised stepping-stone).
#[derive(Debug, Clone)]
pub struct LaplaceInU {
    pub u_mode: Vec<f64>,
    pub laplace: LaplaceEvidence,
    /// Likelihood evaluations that found the mode.
    pub n_likelihood_evaluations: u64,
}

/// [`laplace_in_u`] of `target` (box `bounds`) from `start` (e.g. the MAP).
pub fn laplace_of<T: TemperedTarget>(
    target: &T,
    bounds: &[(f64, f64)],
    start: &[f64],
) -> Result<LaplaceInU> {
    let inner = InUnconstrained::new(target, bounds)?;
    let (u_mode, laplace, n) = laplace_in_u(&inner, start)?;
    Ok(LaplaceInU {
        u_mode,
        laplace,
        n_likelihood_evaluations: n,
    })
}

/// A model's `ln Z` with its uncertainty and the estimator that gave it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ScreenedEvidence {
    pub estimator: Estimator,
    /// `ln Z`, nats.
    pub ln_z: f64,
    /// Its sd, nats: the replicates' standard error (stepping-stones), the stated
    /// allowance (Laplace), 0 (gain bound: a bound).
    pub ln_z_sd: f64,
    /// Laplace's `ln Z` at the mode in logit coordinates, when found.
    pub ln_z_laplace: Option<f64>,
    /// Bound on `ln Z - ln Z_base` (extensions only), nats.
    pub gain_bound_nats: Option<f64>,
    /// The tempered run (stepping-stones; posterior draws in box coordinates).
    pub run: Option<Evidence>,
    /// Likelihood evaluations of the run and of Laplace's mode.
    pub n_likelihood_evaluations: u64,
    /// Why Laplace in logit coordinates failed, when it did (set by the caller, which
    /// found the mode).
    #[serde(default)]
    pub laplace_failure: Option<String>,
}

impl ScreenedEvidence {
    /// The thermodynamic-integration cross-check of a stepping-stone from the prior.
    /// `None` for the generalised stepping-stone: its path starts at a heavy-tailed
    /// reference, where `Var_g[ln q/g]` is huge, and the derivative-corrected trapezoid
    /// on a ladder made for the stepping-stone is then meaningless (measured: 40 nats
    /// to 8e10 nats off on the four-story campaign).
    pub fn ln_z_ti(&self) -> Option<f64> {
        match self.estimator {
            Estimator::SteppingStone => self.run.as_ref().map(|r| r.ln_z_ti),
            _ => None,
        }
    }
}

/// What an extension's screen knows about its base model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseEvidence {
    pub ln_z: f64,
    /// Laplace's `ln Z` of the base in logit coordinates, when found.
    pub ln_z_laplace: Option<f64>,
    /// `max ln L` of the base.
    pub max_ln_likelihood: f64,
}

/// An extension's base model and its gain bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extension {
    pub base: BaseEvidence,
    /// [`super::nested::gain_bound`] of the extension over the base, nats.
    pub gain_bound_nats: f64,
}

impl Extension {
    /// Laplace's `Delta ln Z` of an extension whose Laplace `ln Z` is `ln_z_laplace`.
    pub fn delta_laplace(&self, ln_z_laplace: Option<f64>) -> Option<f64> {
        Some(ln_z_laplace? - self.base.ln_z_laplace?)
    }
}

/// One model's evidence by `estimator` (module docs). `laplace` is its
/// [`laplace_of`] (needed by every estimator but the stepping-stone), `effect` the
/// coordinates the base model fixes, `extension` the base model's evidence and the
/// gain bound (`None` for the base model itself, which takes a stepping-stone).
#[allow(clippy::too_many_arguments)]
pub fn screened_evidence<T: TemperedTarget>(
    target: &T,
    bounds: &[(f64, f64)],
    laplace: Option<&LaplaceInU>,
    effect: &[usize],
    estimator: Estimator,
    extension: Option<&Extension>,
    opts: &ScreenOptions,
    progress: Option<&mut dyn FnMut(EvidenceProgress)>,
) -> Result<ScreenedEvidence> {
    let ln_z_laplace = laplace.map(|l| l.laplace.ln_z);
    let n_newton = laplace.map_or(0, |l| l.n_likelihood_evaluations);
    let gain_bound_nats = extension.map(|x| x.gain_bound_nats);
    let delta_laplace = extension.and_then(|x| x.delta_laplace(ln_z_laplace));
    let done = |estimator, ln_z, ln_z_sd, run: Option<Evidence>| {
        let n_run = run.as_ref().map_or(0, |r| r.n_likelihood_evaluations);
        ScreenedEvidence {
            estimator,
            ln_z,
            ln_z_sd,
            ln_z_laplace,
            gain_bound_nats,
            run,
            n_likelihood_evaluations: n_run + n_newton,
            laplace_failure: None,
        }
    };
    match (estimator, laplace) {
        (Estimator::GainBound, _) => {
            let x = extension.ok_or_else(|| no_base(estimator))?;
            let bound = x.gain_bound_nats;
            let delta = delta_laplace.map_or(bound, |d| d.min(bound));
            Ok(done(estimator, x.base.ln_z + delta, 0.0, None))
        }
        (Estimator::Laplace, Some(_)) => {
            let x = extension.ok_or_else(|| no_base(estimator))?;
            let delta = delta_laplace.ok_or_else(|| no_base(estimator))?;
            let sd = opts.laplace_allowance_nats;
            Ok(done(estimator, x.base.ln_z + delta, sd, None))
        }
        (Estimator::GeneralisedSteppingStone, Some(l)) => {
            let mut o = opts.evidence.clone();
            o.n_replicates = opts.gss_replicates;
            let ev = referenced_evidence_at_mode(
                target, bounds, &l.u_mode, &l.laplace, effect, &o, progress,
            )?;
            Ok(done(estimator, ev.ln_z, ev.ln_z_se, Some(ev)))
        }
        _ => {
            let ev = stepping_stone(target, &opts.evidence, progress)?;
            Ok(done(
                Estimator::SteppingStone,
                ev.ln_z,
                ev.ln_z_se,
                Some(ev),
            ))
        }
    }
}

fn no_base(e: Estimator) -> crate::Error {
    crate::Error::Usage(format!(
        "evidence by {}: needs the base model's evidence and Laplace",
        e.label()
    ))
}
