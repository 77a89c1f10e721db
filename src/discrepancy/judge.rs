//! Judging a round's finalists ([`super::round`]): which are decisive against the round's
//! model, the time-domain refit of amplitude-dependent ones, and the held-out check,
//! each only where it can change the decision.

use super::diagnose::{DiagnoseStage, ModelResult};
use super::heldout::held_out;
use super::hypothesis::Hypothesis;
use super::model_evidence::{completion, laplace_u};
use super::refine::refit_in_time_domain;
use super::round_state::{tag, BaseModel, RoundContext, Stopwatch, Timings};
use super::verdict::{held_out_passes, is_decisive};
use crate::error::Result;
use crate::infer::screened::Estimator;
use std::sync::Arc;

/// Ranks `finalists` by log evidence, the largest first.
pub(super) fn rank_by_evidence(finalists: &mut [ModelResult]) {
    finalists.sort_by(|a, b| {
        b.ln_z()
            .unwrap_or(f64::NEG_INFINITY)
            .total_cmp(&a.ln_z().unwrap_or(f64::NEG_INFINITY))
    });
}

/// Rule 1 of [`super::verdict`] against the base model.
fn decisive(base: &BaseModel, f: &ModelResult) -> bool {
    let base_ln_z = base.result.ln_z().unwrap_or(f64::NEG_INFINITY);
    let base_sd = base.result.evidence.as_ref().map_or(0.0, |e| e.ln_z_sd);
    let ev = f.evidence.as_ref();
    let delta = ev.map_or(f64::NEG_INFINITY, |e| e.ln_z - base_ln_z);
    let se = ev.map_or(0.0, |e| e.ln_z_sd.hypot(base_sd));
    let bound = ev.and_then(|e| e.gain_bound_nats).unwrap_or(f64::INFINITY);
    is_decisive(delta, se, bound)
}

fn is_amplitude_dependent(hypotheses: &[Arc<dyn Hypothesis>], name: &str) -> bool {
    hypotheses
        .iter()
        .any(|h| h.name() == name && h.amplitude_dependent())
}

/// What the time-domain replay can add to a linearised fit's log-likelihood at its
/// error floor: at most its whole misfit term, `chi2 x N` (the replay would have to
/// fit every point exactly), nats.
fn replay_gain_limit(f: &ModelResult) -> f64 {
    f.map.chi2_per_dof * f.map.n_points as f64
}

fn is_outranked(f: &ModelResult) -> bool {
    f.evidence
        .as_ref()
        .is_some_and(|e| e.estimator == Estimator::Outranked)
}

/// Refits and held-out checks, in order of evidence, only where they can change the
/// decision: an outranked finalist ([`Estimator::Outranked`]: its run deferred) is
/// passed over when a finalist that passed is above its gain bound (plus the replay's
/// largest gain, [`replay_gain_limit`], if amplitude-dependent) by the threshold, and
/// otherwise gets its run ([`run_evidence`]) and is judged like the others; a
/// finalist must be decisive; an amplitude-dependent one is refitted by
/// replaying the tests in the time domain and judged on that fit, unless even the
/// replay's largest gain ([`replay_gain_limit`]) left it a decisive factor below a
/// finalist that already passed (it could then neither win nor tie, and neither its
/// refit, about a minute, nor its held-out replay is run); a plausible one is checked
/// on held-out segments. Returns, per finalist (ranked again by evidence, as a refit
/// moves it), whether it was passed over for that reason.
pub(super) fn judge_finalists(
    ctx: &RoundContext<'_>,
    base: &BaseModel,
    hypotheses: &[Arc<dyn Hypothesis>],
    finalists: &mut Vec<ModelResult>,
    step: usize,
    (watch, timings): (&mut Stopwatch, &mut Timings),
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<Vec<bool>> {
    let threshold = super::verdict::decisive_ln_bayes_factor();
    let mut best_passing = f64::NEG_INFINITY;
    let mut judged: Vec<(ModelResult, bool)> = Vec::with_capacity(finalists.len());
    for mut f in finalists.drain(..) {
        if is_outranked(&f) {
            // The highest ln Z it can have: the base's plus its gain bound, plus what a
            // time-domain replay could add to an amplitude-dependent one's.
            let bound = f.evidence.as_ref().and_then(|e| e.gain_bound_nats);
            let replay = if is_amplitude_dependent(hypotheses, &f.name) {
                replay_gain_limit(&f)
            } else {
                0.0
            };
            let top = base.result.ln_z().unwrap_or(f64::NEG_INFINITY)
                + bound.unwrap_or(f64::INFINITY)
                + replay;
            if best_passing - top >= threshold {
                judged.push((f, true));
                continue;
            }
            run_evidence(ctx, &mut f, step, (watch, timings), progress)?;
        }
        if !decisive(base, &f) {
            judged.push((f, false));
            continue;
        }
        if is_amplitude_dependent(hypotheses, &f.name) {
            let sd = f.evidence.as_ref().map_or(0.0, |e| e.ln_z_sd);
            let reach = f.ln_z().unwrap_or(f64::NEG_INFINITY) + 2.0 * sd + replay_gain_limit(&f);
            if best_passing - reach >= threshold {
                judged.push((f, true));
                continue;
            }
            refit(ctx, &mut f, (watch, timings), progress);
        }
        if f.plausible {
            check_held_out(ctx, base, hypotheses, &mut f, (watch, timings), progress)?;
            if f.held_out.as_ref().is_some_and(held_out_passes) {
                let sd = f.evidence.as_ref().map_or(0.0, |e| e.ln_z_sd);
                let lo = f.ln_z().unwrap_or(f64::NEG_INFINITY) - 2.0 * sd;
                best_passing = best_passing.max(lo);
            }
        }
        judged.push((f, false));
    }
    Ok(rank_with_flags(finalists, judged))
}

/// Ranks `judged` (finalists with a flag each) by log evidence into `finalists`;
/// returns the flags in the new order.
pub(super) fn rank_with_flags(
    finalists: &mut Vec<ModelResult>,
    mut judged: Vec<(ModelResult, bool)>,
) -> Vec<bool> {
    judged.sort_by(|a, b| {
        let z = |m: &ModelResult| m.ln_z().unwrap_or(f64::NEG_INFINITY);
        z(&b.0).total_cmp(&z(&a.0))
    });
    let (sorted, flags): (Vec<ModelResult>, Vec<bool>) = judged.into_iter().unzip();
    *finalists = sorted;
    flags
}

/// The time-domain refit of an amplitude-dependent finalist (a replay that fails, a
/// softening spring losing its stiffness, say, leaves only the linearisation, which
/// cannot size this effect: not plausible).
fn refit(
    ctx: &RoundContext<'_>,
    f: &mut ModelResult,
    (watch, timings): (&mut Stopwatch, &mut Timings),
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) {
    progress(DiagnoseStage::TimeDomain {
        hypothesis: &f.name,
    });
    match refit_in_time_domain(ctx.campaign, f, ctx.opts) {
        Ok(r) => f.time_domain = Some(r),
        Err(e) => {
            f.plausible = false;
            f.implausible_because = format!("its time-domain refit failed ({e})");
        }
    }
    watch.mark(&format!("time-domain refit {}", f.name), timings);
}

/// The held-out check of a finalist against the base model (replaying the tests when
/// it was refitted in the time domain).
fn check_held_out(
    ctx: &RoundContext<'_>,
    base: &BaseModel,
    hypotheses: &[Arc<dyn Hypothesis>],
    f: &mut ModelResult,
    (watch, timings): (&mut Stopwatch, &mut Timings),
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<()> {
    if ctx.data.segments.len() < 2 {
        // Nothing to hold out: the check cannot pass, and the hypothesis is not named.
        f.held_out = None;
        return Ok(());
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
    let replay = f.time_domain.is_some().then_some(ctx.campaign);
    let checked = held_out(
        ctx.data,
        &base.extension,
        &base.result.map.z,
        h,
        &f.location,
        &f.map.z,
        &ctx.opts.map,
        replay,
        &mut cb,
    );
    match checked {
        Ok(ho) => f.held_out = Some(ho),
        Err(e) if replay.is_some() => {
            f.plausible = false;
            f.implausible_because = format!("its time-domain held-out check failed ({e})");
        }
        Err(e) => return Err(e),
    }
    watch.mark(&format!("held-out {name}"), timings);
    Ok(())
}

/// Replaces `f`'s evidence (Laplace's, or none yet: [`Estimator::Outranked`]) by a run's
/// (importance sampling, the generalised stepping-stone, or the stepping-stone from the
/// prior where there is no Laplace), keeping its gain bound, and its effect summaries
/// by the run's draws. Round `step`'s stage `<name>-run`.
pub(super) fn run_evidence(
    ctx: &RoundContext<'_>,
    f: &mut ModelResult,
    step: usize,
    (watch, timings): (&mut Stopwatch, &mut Timings),
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<()> {
    let name = format!("{}{}-run", tag(step), f.name);
    let k = ctx.hypotheses.iter().position(|h| h.name() == f.name);
    let index = (64 * step + 32 + k.unwrap_or(31)) as u64;
    let lap = laplace_u(&f.posterior, &f.map.z);
    let done = completion(
        &name,
        &f.posterior,
        &f.map,
        &lap,
        None,
        ctx.opts,
        index,
        ctx.stages,
        progress,
    )?;
    let bound = f.evidence.as_ref().and_then(|e| e.gain_bound_nats);
    let mut evidence = done.evidence;
    evidence.gain_bound_nats = bound;
    f.evidence = Some(evidence);
    f.effect = done.effect;
    f.plausible = done.plausible;
    f.implausible_because = done.why;
    watch.mark(&format!("evidence {name}"), timings);
    Ok(())
}
