//! The stepwise, open-world decision (issue 14, item 2): add the winner of a round to the
//! model and diagnose again, until no hypothesis passes ([`super::verdict::decide`] against
//! the model of the round), two pass within a decisive Bayes factor of each other
//! (ambiguous), or [`MAX_EFFECTS`] effects are in; then judge the final model's adequacy
//! ([`super::adequacy`]).

use super::diagnose::{DiagnoseStage, ModelResult, MAX_REANCHOR};
use super::estimator_bias::replay_bias;
use super::fit::{fit_map, refit_at_map};
use super::location::Location;
use super::model_evidence::{completion, laplace_u, model_result};
use super::posterior::ModelPosterior;
use super::round::{run_round, BaseModel, Round, RoundContext, Stopwatch, Timings};
use super::verdict::{decisive_ln_bayes_factor, EffectSummary};
use crate::error::Result;
use crate::io::stages::staged;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The most effects a diagnosis adds (each costs a round of searches and evidence).
pub const MAX_EFFECTS: usize = 3;

/// An accepted effect with its parameters' posterior in the final model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AcceptedEffect {
    pub hypothesis: String,
    pub location: Location,
    pub effect_parameters: Vec<(String, EffectSummary)>,
}

/// Two explanations that both pass, within a decisive Bayes factor of each other.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ambiguity {
    /// The round (0: against the nominal model) and the two, the more likely first.
    pub round: usize,
    pub hypotheses: [String; 2],
    pub locations: [Location; 2],
    /// Their difference in log evidence, nats (below `ln 150`).
    pub delta_ln_z: f64,
    /// Where their fitted models differ most, relative to the noise there: what a test
    /// would have to measure to separate them.
    pub separating_test: String,
}

/// The rounds after `first`, the final model, and an ambiguity if one stopped them.
pub struct Stepwise {
    pub later: Vec<Round>,
    pub last: BaseModel,
    pub ambiguity: Option<Ambiguity>,
}

/// Runs rounds after `first` while a hypothesis is accepted (see the module docs).
pub fn continue_rounds(
    ctx: &RoundContext<'_>,
    nominal: BaseModel,
    first: &Round,
    (watch, timings): (&mut Stopwatch, &mut Timings),
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<Stepwise> {
    let mut later: Vec<Round> = Vec::new();
    let mut base = nominal;
    let mut data = ctx.data.clone();
    loop {
        let step = later.len();
        let round = later.last().unwrap_or(first);
        if let Some(a) = ambiguity(round, step)? {
            return Ok(Stepwise {
                later,
                last: base,
                ambiguity: Some(a),
            });
        }
        let Some(w) = round.decision.winner else {
            break;
        };
        let won = &round.finalists[w];
        let plain = ctx
            .hypotheses
            .iter()
            .find(|h| h.name() == won.name)
            .cloned()
            .expect("finalists come from the hypotheses");
        base = base.accept(won, plain);
        let step = base.effects.len();
        if let Some(renewed) = with_data_renewed(ctx, &base, step, progress)? {
            base = renewed;
            data = base.result.posterior.data().clone();
            watch.mark(&format!("step{step}-basis and estimator bias"), timings);
        }
        if step >= MAX_EFFECTS {
            break;
        }
        let ctx = RoundContext {
            data: &data,
            ..*ctx
        };
        let next = run_round(&ctx, &base, step, (watch, timings), progress)?;
        later.push(next);
    }
    Ok(Stepwise {
        later,
        last: base,
        ambiguity: None,
    })
}

/// Whether the estimator's bias is measured again at `base`'s MAP: the data carry one
/// (`--estimator-bias`, hammer tests) and `base`'s structure does not depend on the
/// amplitude ([`replay_bias`]).
fn remeasures_bias(ctx: &RoundContext<'_>, base: &BaseModel) -> bool {
    let post = &base.result.posterior;
    ctx.opts.estimator_bias
        && post.data().has_estimator_bias()
        && !post
            .model()
            .hypothesis()
            .is_some_and(|(h, _)| h.amplitude_dependent())
}

/// `base` on data renewed at its own MAP, refitted there, with its Laplace and
/// evidence on those data, which the next round uses; `None` when nothing is renewed.
/// Two things in the data depend on the point they were made at, and both were made at
/// the nominal MAP, which the missing physics distorts:
///
/// - **The reduced basis** (a model reduced onto the kept DOFs,
///   [`super::reduction`]) is exact only at its anchor. It is re-anchored at `base`'s
///   MAP and `base` refitted there until the MAP stays put (as the nominal model's,
///   [`MAX_REANCHOR`] times at most;
///   [`super::data::DiagnosisData::reanchored`]). On the bridge's
///   effect cases the accepted model's MAP lay 0.48 (delay) and 1.09 (oscillator) from
///   the nominal anchor in some stiffness variable: the basis error there was what a
///   false second oscillator near 5.9 Hz absorbed (40.4 and 57.6 nats in max ln L;
///   6.1 and 2.8 once re-anchored; docs/diagnose.md, the bridge section).
/// - **The estimator's bias** ([`remeasures_bias`]) is measured again at `base`'s MAP:
///   the carried-over ringing in it turns in phase with the frequencies' error, so
///   each accepted effect moves the point it should be measured at.
pub fn with_data_renewed(
    ctx: &RoundContext<'_>,
    base: &BaseModel,
    step: usize,
    progress: &mut dyn FnMut(DiagnoseStage<'_>),
) -> Result<Option<BaseModel>> {
    let old = &base.result;
    let mut post = old.posterior.clone();
    let mut map = old.map.clone();
    let mut renewed = false;
    for k in 1..=MAX_REANCHOR {
        let Some((moved, _)) = post.data().reanchored(&post.base_params(&map.z))? else {
            break;
        };
        post = ModelPosterior::new(Arc::new(moved), base.extension.clone())?;
        map = staged(
            ctx.stages,
            &format!("step{step}-base-map-reanchored-{k}"),
            || fit_map(&post, std::slice::from_ref(&map.z), &ctx.opts.map),
        )?;
        renewed = true;
    }
    if remeasures_bias(ctx, base) {
        let bias = replay_bias(ctx.campaign, &post, &map.z)?;
        let data = post
            .data()
            .with_estimator_bias(post.model().layout(), &bias)?;
        post = ModelPosterior::new(Arc::new(data), base.extension.clone())?;
        map = staged(
            ctx.stages,
            &format!("step{step}-base-map-renewed-debiased"),
            || fit_map(&post, std::slice::from_ref(&map.z), &ctx.opts.map),
        )?;
        renewed = true;
    }
    if !renewed {
        return Ok(None);
    }
    let (post, map) = refit_at_map(post, map, &ctx.opts.map)?;
    let laplace = laplace_u(&post, &map.z);
    let name = format!("step{step}-base-renewed");
    let index = (64 * step + 63) as u64;
    let done = completion(
        &name, &post, &map, &laplace, None, ctx.opts, index, ctx.stages, progress,
    )?;
    let mut result = model_result(&old.name, old.location.clone(), post, map, done);
    result.held_out = old.held_out.clone();
    result.time_domain = old.time_domain.clone();
    Ok(Some(BaseModel {
        result,
        laplace,
        ..base.clone()
    }))
}

/// The ambiguity of `round`, if its winner has a passing rival of another hypothesis
/// within `ln 150` in log evidence.
fn ambiguity(round: &Round, step: usize) -> Result<Option<Ambiguity>> {
    let Some(w) = round.decision.winner else {
        return Ok(None);
    };
    let a = &round.finalists[w];
    let ln_z = |m: &ModelResult| m.ln_z().unwrap_or(f64::NEG_INFINITY);
    let names: Vec<&str> = round.finalists.iter().map(|f| f.name.as_str()).collect();
    let values: Vec<f64> = round.finalists.iter().map(ln_z).collect();
    let Some(r) = rival(w, &round.decision.passing, &names, &values) else {
        return Ok(None);
    };
    let b = &round.finalists[r];
    Ok(Some(Ambiguity {
        round: step,
        hypotheses: [a.name.clone(), b.name.clone()],
        locations: [a.location.clone(), b.location.clone()],
        delta_ln_z: ln_z(a) - ln_z(b),
        separating_test: separating_test(a, b)?,
    }))
}

/// The passing candidate of another hypothesis than the winner `w` whose log evidence
/// is within `ln 150` of the winner's (the closest), if any.
fn rival(w: usize, passing: &[usize], names: &[&str], ln_z: &[f64]) -> Option<usize> {
    passing
        .iter()
        .copied()
        .filter(|&i| names[i] != names[w] && ln_z[w] - ln_z[i] < decisive_ln_bayes_factor())
        .max_by(|&x, &y| ln_z[x].total_cmp(&ln_z[y]))
}

/// Where the MAP predictions of `a` and `b` differ most in units of the noise of the
/// measurement there (the Bendat-Piersol error and `a`'s fitted floor).
fn separating_test(a: &ModelResult, b: &ModelResult) -> Result<String> {
    let pa = a.posterior.predict(&a.map.z)?;
    let pb = b.posterior.predict(&b.map.z)?;
    let h = a.posterior.measured();
    let data = a.posterior.data();
    let mut best = (0.0, String::new());
    for (si, seg) in a.posterior.model().layout().iter().enumerate() {
        let sd = &data.segments[si];
        for (ci, range) in seg.iter().enumerate() {
            let ch = &sd.channels[ci];
            for (j, i) in range.clone().enumerate() {
                let sigma = ch.rel_err[j].hypot(a.map.eta) * h[i].norm();
                let z = (pa[i] - pb[i]).norm() / sigma;
                if z > best.0 {
                    let f = sd.freq_hz[ch.freq_index[j]];
                    best = (
                        z,
                        format!("{} in {} at {f:.2} Hz", ch.channel.name, sd.test),
                    );
                }
            }
        }
    }
    Ok(format!(
        "the two fitted models differ most on {} ({:.1} noise standard deviations at one \
         frequency): more averages or a longer record there, or an excitation and sensor \
         placed for that frequency, would separate them",
        best.1, best.0
    ))
}

/// The final model's effect summaries split by accepted effect.
pub fn accepted_effects(last: &BaseModel) -> Result<Vec<AcceptedEffect>> {
    let data = last.result.posterior.data();
    let mut out = Vec::with_capacity(last.effects.len());
    let mut at = 0;
    for e in &last.effects {
        let n = e.hypothesis.parameters(data, &e.location)?.len();
        let params = last.result.effect.get(at..at + n).unwrap_or(&[]).to_vec();
        at += n;
        out.push(AcceptedEffect {
            hypothesis: e.hypothesis.name().to_string(),
            location: e.location.clone(),
            effect_parameters: params,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::rival;

    #[test]
    fn a_rival_is_another_passing_hypothesis_within_a_decisive_factor() {
        let names = ["a", "b", "c", "a"];
        // b passes 3 nats below the winner: a tie.
        assert_eq!(rival(0, &[0, 1], &names, &[100.0, 97.0, 0.0, 0.0]), Some(1));
        // 6 nats below (> ln 150 = 5.01): the winner is decisively better.
        assert_eq!(rival(0, &[0, 1], &names, &[100.0, 94.0, 0.0, 0.0]), None);
        // c is close but does not pass.
        assert_eq!(rival(0, &[0, 1], &names, &[100.0, 80.0, 99.0, 0.0]), None);
        // The same hypothesis elsewhere is not a rival explanation.
        assert_eq!(rival(0, &[0, 3], &names, &[100.0, 0.0, 0.0, 99.0]), None);
        // The closest of two rivals.
        assert_eq!(
            rival(0, &[0, 1, 2], &names, &[100.0, 97.0, 98.0, 0.0]),
            Some(2)
        );
    }
}
