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
//!    ([`ScreenOptions::laplace_allowance_nats`]), or above it by as much (a caller
//!    ranking extensions then settles contests among those within reach of each
//!    other, [`is_contested`], by runs): [`Estimator::Laplace`], with the
//!    allowance as its sd. The allowance is not a computed error but a stated one, set from
//!    Laplace's measured errors on the validation problems ([`super::validation`]: at
//!    most 0.45 nats) and on the four-story campaign's seven models (at most 0.3 nats
//!    from the generalised stepping-stone). Far from the threshold and from any rival
//!    the decision does not depend on the estimator, and a run would only refine a
//!    number nobody uses (its posterior draws are then Laplace's).
//! 3. **Importance sampling from the reference** ([`super::importance`]): every other
//!    model first takes the generalised stepping-stone's first rung alone, `Z = E_g[q/g]`
//!    from [`ScreenOptions::importance_draws`] draws of its reference `g`, and keeps it
//!    when it is [`ImportanceEvidence::reliable`] (the weights' Pareto tail shape below
//!    1/2, their effective sample size at least a fifth of the draws, its standard error
//!    below a quarter nat; else once more from a reference adapted to the first pass) ([`Estimator::ImportanceSampling`]): one
//!    likelihood evaluation per draw instead of a tempered run's tens of thousands.
//! 4. **Generalised stepping-stone** ([`super::reference::referenced_evidence_at_mode`]):
//!    where importance sampling is not trusted, with replicates ([`GSS_REPLICATES`]) for
//!    its standard error ([`Estimator::GeneralisedSteppingStone`]).
//! 5. Where no mode in logit coordinates was found (Newton failed, covariance not
//!    positive definite), the stepping-stone from the prior ([`Estimator::SteppingStone`],
//!    2 replicates), as before.
//!
//! A run (3-5) is deferred ([`Estimator::Outranked`]) where a rival extension of the same
//! base is, by its Laplace reach ([`laplace_reach`]), above this one's gain bound by the
//! threshold or more ([`Extension::rival_floor_nats`]): while that rival passes the
//! caller's other tests, this extension can neither outrank it nor tie with it, whatever
//! its run would say. The caller runs it if the rival fails them. On the ten-story
//! frame's oscillator case base flexibility, whose Hessian at the mode was not positive
//! definite, took a 1,294-s stepping-stone from the prior for a gain bound of 33 nats,
//! against the oscillator's 45,586.

use serde::{Deserialize, Serialize};

use super::evidence::{stepping_stone, Evidence, EvidenceOptions, EvidenceProgress};
use super::importance::{importance_evidence, ImportanceEvidence};
use super::laplace::LaplaceEvidence;
use super::nested::{laplace_in_u, InUnconstrained};
use super::reference::referenced_evidence_at_mode;
use super::TemperedTarget;
use crate::error::Result;

/// Replicates of the generalised stepping-stone: three degrees of freedom for its
/// standard error (the stepping-stone from the prior had one, with 2).
pub const GSS_REPLICATES: usize = 4;

/// Draws of the importance-sampling rung (default of [`ScreenOptions::importance_draws`]).
pub const IMPORTANCE_DRAWS: usize = 2000;

/// Posterior draws kept from an importance-sampling estimate (resampled).
pub const IMPORTANCE_KEPT_DRAWS: usize = 400;

/// Which estimator gave a model's `ln Z` (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Estimator {
    /// No run: the gain bound keeps the extension below the threshold.
    GainBound,
    /// Laplace's approximation at the mode in logit coordinates.
    Laplace,
    /// Importance sampling from the generalised stepping-stone's reference.
    ImportanceSampling,
    /// Generalised stepping-stone from a reference at the posterior.
    GeneralisedSteppingStone,
    /// Stepping-stone from the prior.
    SteppingStone,
    /// No run (yet): a rival's reach is above the gain bound by the threshold (module
    /// docs); `ln Z` as for [`Estimator::GainBound`], an upper bound.
    Outranked,
}

impl Estimator {
    /// Name for reports (the `diagnosis.json` spelling).
    pub fn label(self) -> &'static str {
        match self {
            Estimator::GainBound => "gain_bound",
            Estimator::Laplace => "laplace",
            Estimator::ImportanceSampling => "importance_sampling",
            Estimator::GeneralisedSteppingStone => "generalised_stepping_stone",
            Estimator::SteppingStone => "stepping_stone",
            Estimator::Outranked => "outranked",
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
    /// Draws of the importance-sampling rung tried before a generalised stepping-stone
    /// (0: never tried).
    pub importance_draws: usize,
}

/// The estimator for an extension whose gain bound is `gain_bound_nats` and whose
/// Laplace `Delta ln Z` (in logit coordinates, against the base's) is
/// `delta_laplace_nats` (`None`: no mode found); module docs. Far above the threshold
/// it is Laplace whatever other extensions there are: a caller that ranks extensions
/// settles contests afterwards, among those that pass ([`is_contested`]).
pub fn choose_estimator(
    gain_bound_nats: f64,
    delta_laplace_nats: Option<f64>,
    opts: &ScreenOptions,
) -> Estimator {
    let (thr, a) = (opts.threshold_nats, opts.laplace_allowance_nats);
    if gain_bound_nats < thr {
        return Estimator::GainBound;
    }
    match delta_laplace_nats {
        None => Estimator::SteppingStone,
        Some(d) if d + 2.0 * a < thr => Estimator::Laplace,
        Some(d) if d - 2.0 * a >= thr => Estimator::Laplace,
        Some(_) => Estimator::GeneralisedSteppingStone,
    }
}

/// [`choose_estimator`] for extension `x`, deferring a run ([`Estimator::Outranked`])
/// where a rival's reach is above `x`'s gain bound by the threshold or more.
pub fn choose_for_extension(
    x: &Extension,
    delta_laplace_nats: Option<f64>,
    opts: &ScreenOptions,
) -> Estimator {
    let e = choose_estimator(x.gain_bound_nats, delta_laplace_nats, opts);
    let needs_run = matches!(
        e,
        Estimator::GeneralisedSteppingStone | Estimator::SteppingStone
    );
    if needs_run && x.rival_floor_nats - x.gain_bound_nats >= opts.threshold_nats {
        Estimator::Outranked
    } else {
        e
    }
}

/// Each extension's [`Extension::rival_floor_nats`] from the lower ends of every
/// extension's [`laplace_reach`] (of the same base): the highest among the others.
pub fn rival_floors(reach_low_nats: &[f64]) -> Vec<f64> {
    (0..reach_low_nats.len())
        .map(|i| {
            reach_low_nats
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, &lo)| lo)
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect()
}

/// Where Laplace puts an extension's `Delta ln Z`: within two allowances of its value,
/// and never above the gain bound; without Laplace, anywhere below the bound.
pub fn laplace_reach(
    gain_bound_nats: f64,
    delta_laplace_nats: Option<f64>,
    allowance_nats: f64,
) -> (f64, f64) {
    match delta_laplace_nats {
        Some(d) => (
            (d - 2.0 * allowance_nats).min(gain_bound_nats),
            (d + 2.0 * allowance_nats).min(gain_bound_nats),
        ),
        None => (f64::NEG_INFINITY, gain_bound_nats),
    }
}

/// Whether extension `i` is contested: another extension of the same base, which could
/// itself reach the threshold, has a [`laplace_reach`] within `threshold_nats` of
/// `i`'s, so that which of the two is the more likely, or whether they tie, is not
/// settled by Laplace.
pub fn is_contested(reach: &[(f64, f64)], i: usize, threshold_nats: f64) -> bool {
    let (lo_i, hi_i) = reach[i];
    reach.iter().enumerate().any(|(j, &(lo_j, hi_j))| {
        j != i
            && hi_j >= threshold_nats
            && lo_i - hi_j < threshold_nats
            && lo_j - hi_i < threshold_nats
    })
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
    /// The importance-sampling rung, when tried (kept or not: its diagnostics say why).
    #[serde(default)]
    pub importance: Option<ImportanceEvidence>,
    /// Likelihood evaluations of the run and of Laplace's mode.
    pub n_likelihood_evaluations: u64,
    /// Why Laplace in logit coordinates failed, when it did (set by the caller, which
    /// found the mode).
    #[serde(default)]
    pub laplace_failure: Option<String>,
}

impl ScreenedEvidence {
    /// The posterior draws behind the estimate, in box coordinates: the importance
    /// sample (resampled by weight) when importance sampling gave `ln Z`, else the
    /// tempered run's last rung; `None` when neither was run (Laplace, a bound).
    pub fn posterior_draws(&self) -> Option<Vec<Vec<f64>>> {
        if self.estimator == Estimator::ImportanceSampling {
            if let Some(is) = &self.importance {
                return Some(is.draws.clone());
            }
        }
        let p = self.run.as_ref()?.posterior.as_ref()?;
        Some(
            p.draws
                .values
                .chunks_exact(p.draws.dim)
                .map(<[f64]>::to_vec)
                .collect(),
        )
    }

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
    /// The highest lower end of a rival extension's [`laplace_reach`] (same base), nats
    /// (`-inf`: no rival known); [`rival_floors`].
    pub rival_floor_nats: f64,
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
            importance: None,
            n_likelihood_evaluations: n_run + n_newton,
            laplace_failure: None,
        }
    };
    match (estimator, laplace) {
        (Estimator::GainBound | Estimator::Outranked, _) => {
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
            let tried = try_importance(target, bounds, l, effect, opts)?;
            if let Some(is) = tried.as_ref().filter(|is| is.reliable()) {
                let mut e = done(Estimator::ImportanceSampling, is.ln_z, is.ln_z_se, None);
                e.n_likelihood_evaluations += is.n_likelihood_evaluations;
                e.importance = tried;
                return Ok(e);
            }
            let mut o = opts.evidence.clone();
            o.n_replicates = opts.gss_replicates;
            let ev = referenced_evidence_at_mode(
                target, bounds, &l.u_mode, &l.laplace, effect, &o, progress,
            )?;
            let mut e = done(estimator, ev.ln_z, ev.ln_z_se, Some(ev));
            if let Some(is) = tried {
                e.n_likelihood_evaluations += is.n_likelihood_evaluations;
                e.importance = Some(is);
            }
            Ok(e)
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

/// The importance-sampling rung of `target` at Laplace's mode `l`, when the options ask
/// for one (seeded from the evidence seed).
fn try_importance<T: TemperedTarget>(
    target: &T,
    bounds: &[(f64, f64)],
    l: &LaplaceInU,
    effect: &[usize],
    opts: &ScreenOptions,
) -> Result<Option<ImportanceEvidence>> {
    if opts.importance_draws == 0 {
        return Ok(None);
    }
    let seed = opts.evidence.seed ^ 0x1d9f_5a3c_77e1_0b42;
    // A model evaluation that fails at a draw in the reference's tails leaves the
    // stepping-stone, whose walkers stay where the posterior is.
    let found = importance_evidence(
        target,
        bounds,
        &l.u_mode,
        &l.laplace,
        effect,
        opts.importance_draws,
        IMPORTANCE_KEPT_DRAWS,
        seed,
    );
    Ok(found.ok())
}

fn no_base(e: Estimator) -> crate::Error {
    crate::Error::Usage(format!(
        "evidence by {}: needs the base model's evidence and Laplace",
        e.label()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    const THR: f64 = 5.01;

    fn options() -> ScreenOptions {
        ScreenOptions {
            threshold_nats: THR,
            laplace_allowance_nats: 5.0,
            evidence: EvidenceOptions::new(4, 1),
            gss_replicates: GSS_REPLICATES,
            importance_draws: IMPORTANCE_DRAWS,
        }
    }

    #[test]
    fn posterior_draws_are_those_of_the_estimator_that_gave_ln_z() {
        let draws = vec![vec![0.1, 0.2], vec![0.3, 0.4]];
        let importance = ImportanceEvidence {
            ln_z: -1.0,
            ln_z_se: 0.1,
            pareto_k: 0.3,
            ess: 2.0,
            n_draws: 2,
            adapted: false,
            n_likelihood_evaluations: 2,
            draws: draws.clone(),
        };
        let mut e = ScreenedEvidence {
            estimator: Estimator::ImportanceSampling,
            ln_z: -1.0,
            ln_z_sd: 0.1,
            ln_z_laplace: None,
            gain_bound_nats: None,
            run: None,
            importance: Some(importance),
            n_likelihood_evaluations: 2,
            laplace_failure: None,
        };
        assert_eq!(e.posterior_draws(), Some(draws));
        // An importance rung that was tried and not kept does not stand for the posterior.
        e.estimator = Estimator::Laplace;
        assert_eq!(e.posterior_draws(), None);
    }

    #[test]
    fn laplace_decides_only_far_from_the_threshold() {
        let o = options();
        let pick = |g, d| choose_estimator(g, d, &o);
        assert_eq!(pick(4.9, Some(-20.0)), Estimator::GainBound);
        assert_eq!(pick(50.0, Some(-5.0)), Estimator::Laplace);
        // Within two allowances of the threshold, on either side: a run.
        assert_eq!(pick(50.0, Some(-4.9)), Estimator::GeneralisedSteppingStone);
        assert_eq!(pick(50.0, Some(15.0)), Estimator::GeneralisedSteppingStone);
        assert_eq!(pick(50.0, Some(15.1)), Estimator::Laplace);
        assert_eq!(pick(50.0, None), Estimator::SteppingStone);
    }

    #[test]
    fn a_run_is_deferred_only_below_a_rival_by_the_threshold() {
        let o = options();
        let base = BaseEvidence {
            ln_z: 0.0,
            ln_z_laplace: Some(0.0),
            max_ln_likelihood: 0.0,
        };
        let floors = rival_floors(&[45_576.0, f64::NEG_INFINITY, 30.0]);
        assert_eq!(floors, vec![30.0, 45_576.0, 45_576.0]);
        let x = |g: f64, floor: f64| Extension {
            base,
            gain_bound_nats: g,
            rival_floor_nats: floor,
        };
        let pick = |g, d, floor| choose_for_extension(&x(g, floor), d, &o);
        // No mode, a bound of 33 nats, a rival at 45,576 or more: no run.
        assert_eq!(pick(33.0, None, 45_576.0), Estimator::Outranked);
        // 5.02 apart is enough, 5.0 is not.
        assert_eq!(pick(33.0, None, 38.02), Estimator::Outranked);
        assert_eq!(pick(33.0, None, 38.0), Estimator::SteppingStone);
        assert_eq!(pick(33.0, Some(10.0), 45_576.0), Estimator::Outranked);
        assert_eq!(
            pick(33.0, Some(10.0), 30.0),
            Estimator::GeneralisedSteppingStone
        );
        // A cheap estimate stays what it is.
        assert_eq!(pick(33.0, Some(-20.0), 45_576.0), Estimator::Laplace);
        assert_eq!(pick(4.0, None, 45_576.0), Estimator::GainBound);
    }

    #[test]
    fn an_outranked_extension_reports_its_bound() {
        let x = Extension {
            base: BaseEvidence {
                ln_z: 100.0,
                ln_z_laplace: None,
                max_ln_likelihood: 0.0,
            },
            gain_bound_nats: 33.0,
            rival_floor_nats: 1e4,
        };
        let spec = &crate::infer::validation::ProblemSpec::all()[0];
        let problem = spec.build(1).unwrap();
        let target = problem.extension();
        let o = options();
        let effect: Vec<usize> = (target.n_base()..target.dim()).collect();
        let e = screened_evidence(
            &target,
            target.bounds(),
            None,
            &effect,
            Estimator::Outranked,
            Some(&x),
            &o,
            None,
        )
        .unwrap();
        assert_eq!(e.estimator, Estimator::Outranked);
        assert_eq!((e.ln_z, e.ln_z_sd), (133.0, 0.0));
        assert!(e.run.is_none() && e.posterior_draws().is_none());
    }

    #[test]
    fn a_rival_is_contested_only_within_the_threshold_of_its_reach() {
        let reach = |d: f64| laplace_reach(f64::INFINITY, Some(d), 5.0);
        // 100 and 81: reaches [90, 110] and [71, 91] overlap: contested both ways.
        let r = [reach(100.0), reach(81.0)];
        assert!(is_contested(&r, 0, THR) && is_contested(&r, 1, THR));
        // 100 and 74.9: [90, 110] and [64.9, 84.9] are 5.1 apart, more than ln 150.
        let r = [reach(100.0), reach(74.9)];
        assert!(!is_contested(&r, 0, THR) && !is_contested(&r, 1, THR));
        // A rival that cannot reach the threshold contests nothing.
        let r = [reach(12.0), laplace_reach(4.0, Some(3.0), 5.0)];
        assert!(!is_contested(&r, 0, THR));
        // Without Laplace a rival reaches anywhere below its bound.
        let r = [reach(100.0), laplace_reach(120.0, None, 5.0)];
        assert!(is_contested(&r, 0, THR));
        let r = [reach(100.0), laplace_reach(80.0, None, 5.0)];
        assert!(!is_contested(&r, 0, THR));
        // The bound caps what Laplace says.
        assert_eq!(laplace_reach(20.0, Some(30.0), 5.0), (20.0, 20.0));
    }
}
