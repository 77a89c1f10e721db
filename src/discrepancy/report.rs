//! `diagnosis.json` and `diagnosis.md` of a [`Diagnosis`].

use super::diagnose::{Diagnosis, ModelResult};
use super::hypotheses::hypothesis_by_name;
use super::verdict::{
    decisive_ln_bayes_factor, DiagnosisRecord, EffectRecord, HypothesisEvidence, NotFitted,
};
use crate::infer::screened::Estimator;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// Log evidence of every hypothesis: the screened value (with its estimator, sd and
/// gain bound) for those whose evidence was computed, otherwise the Laplace
/// approximation at its best location's mode in logit coordinates, otherwise `-inf`
/// when neither could be computed (a hypothesis whose every fit failed).
pub fn hypothesis_evidence(d: &Diagnosis) -> Vec<HypothesisEvidence> {
    let nominal = d.nominal.ln_z().unwrap_or(f64::NAN);
    let nominal_sd = d.nominal.evidence.as_ref().map_or(0.0, |e| e.ln_z_sd);
    let mut rows: Vec<HypothesisEvidence> = d
        .searches
        .iter()
        .map(|s| {
            let found = d
                .finalists
                .iter()
                .find(|f| f.name == s.name)
                .and_then(|f| f.evidence.as_ref());
            let lap = d
                .laplace
                .iter()
                .find(|(n, _)| n == s.name)
                .and_then(|(_, v)| *v);
            let ln_z = found.map(|e| e.ln_z).or(lap).unwrap_or(f64::MIN);
            HypothesisEvidence {
                name: s.name.to_string(),
                log_evidence: ln_z,
                delta_log_evidence: ln_z - nominal,
                delta_log_evidence_sd: found.map(|e| e.ln_z_sd.hypot(nominal_sd)),
                estimator: found.map_or(
                    if lap.is_some() { "laplace" } else { "" }.to_string(),
                    |e| e.estimator.label().to_string(),
                ),
                gain_bound: found.and_then(|e| e.gain_bound_nats),
                not_fitted: s
                    .failed
                    .iter()
                    .map(|(loc, reason)| NotFitted {
                        location: serde_json::to_value(d.data.shown(loc)).unwrap_or_default(),
                        reason: reason.clone(),
                    })
                    .collect(),
            }
        })
        .collect();
    rows.sort_by(|a, b| b.log_evidence.total_cmp(&a.log_evidence));
    rows
}

fn plain_location(loc: &super::location::Location, data: &super::data::DiagnosisData) -> String {
    use super::location::Location::*;
    match data.shown(loc) {
        Whole => "the whole structure".into(),
        Story(s) => format!("story {s}"),
        Floor(f) => format!("floor {f}"),
        Dofs([a, b]) => format!("the connection of DOFs {a} and {b}"),
        Channels(c) => format!("channel(s) {}", c.join(", ")),
        Quantity(q) => format!("every {} channel", format!("{q:?}").to_lowercase()),
    }
}

/// The plain-language explanation of the verdict.
pub fn explanation(d: &Diagnosis) -> String {
    let n0 = d.nominal.ln_z().unwrap_or(f64::NAN);
    let before = d.fit_before;
    let mut s = String::new();
    match d.winner {
        Some(w) => {
            let f = &d.finalists[w];
            let physics = hypothesis_by_name(&f.name)
                .map(|h| h.physics().to_string())
                .unwrap_or_default();
            let ev = f.evidence.as_ref();
            let delta = f.ln_z().unwrap_or(f64::NAN) - n0;
            let se = ev.map_or(0.0, |e| e.ln_z_sd);
            let _ = write!(
                s,
                "The nominal model leaves out {name} at {loc}: {physics}. Adding it raises the log \
                 evidence by {delta:.1} +- {se:.1} (Bayes factor e^{delta:.0}; decisive is above \
                 ln 150 = {thr:.1}) ",
                name = f.name.replace('_', " "),
                loc = plain_location(&f.location, &d.data),
                thr = decisive_ln_bayes_factor(),
            );
            if let Some(h) = &f.held_out {
                let _ = write!(
                    s,
                    "and predicts recordings held out of the fit better by {:.0} nats in total \
                     (better in {} of {} held-out segments; signed-rank p = {:.3}). ",
                    h.gain,
                    h.hypothesis
                        .iter()
                        .zip(&h.nominal)
                        .filter(|(a, b)| a > b)
                        .count(),
                    h.segments.len(),
                    h.p_value
                );
            } else {
                s.push_str(". ");
            }
            // The size in the final model (the estimator's bias measured again at its
            // fit, and any later effects beside it), as in `diagnosis.json`'s `effects`;
            // the first round's own posterior when nothing was accepted.
            let sized = match d.effects.first() {
                Some(a) if a.hypothesis == f.name => &a.effect_parameters,
                _ => &f.effect,
            };
            let effects: Vec<String> = sized
                .iter()
                .map(|(n, e)| {
                    format!(
                        "{n} = {} {} (95 % interval {} to {})",
                        sig4(e.mean),
                        e.unit,
                        sig4(e.q2_5),
                        sig4(e.q97_5)
                    )
                })
                .collect();
            if !effects.is_empty() {
                let _ = write!(s, "Its size: {}. ", effects.join("; "));
            }
            if let Some(t) = &f.time_domain {
                let _ = write!(
                    s,
                    "The size and the fit come from replaying the recorded tests with the \
                     nonlinear model in the time domain (chi2 per point {:.2}; the \
                     equivalent-linear model, which ranked it, reaches {:.2}). ",
                    t.chi2_time_domain, t.chi2_linearised
                );
            }
            let _ = write!(
                s,
                "The fit improves from chi2 per point {:.2} to {:.2} and mean FDAC {:.4} to {:.4}.",
                before.chi2_per_point,
                d.fit_after.chi2_per_point,
                before.fdac_mean,
                d.fit_after.fdac_mean
            );
            if let Some(r) = d.finalists.iter().enumerate().find(|(i, _)| *i != w) {
                // Without a run (a bound), the most its ln Z can be: the nominal
                // model's plus its gain bound.
                let bound = r.1.evidence.as_ref().and_then(|e| {
                    matches!(e.estimator, Estimator::GainBound | Estimator::Outranked)
                        .then_some(e.gain_bound_nats?)
                });
                let bounded = bound.is_some();
                let top = match bound {
                    Some(b) => d.nominal.ln_z().unwrap_or(f64::NAN) + b,
                    None => r.1.ln_z().unwrap_or(f64::NAN),
                };
                let dr = top - f.ln_z().unwrap_or(f64::NAN);
                let _ = write!(
                    s,
                    " The next best explanation, {} at {}, is {}{:.1} nats less likely.",
                    r.1.name.replace('_', " "),
                    plain_location(&r.1.location, &d.data),
                    if bounded { "at least " } else { "" },
                    -dr
                );
            }
        }
        None => {
            let best = hypothesis_evidence(d).into_iter().next();
            let blocked: Vec<String> = d
                .finalists
                .iter()
                .zip(&d.decision.reasons)
                .filter(|(_, r)| r.starts_with("decisive"))
                .map(|(f, r)| format!("{} was {}", f.name.replace('_', " "), r))
                .collect();
            let opening = if !d.adequacy.adequate {
                "No named effect: no hypothesis passes against the nominal model (the campaign's \
                 model, proportional damping, ideal sensors), yet that model does not explain the \
                 recordings (below)"
            } else if blocked.is_empty() {
                "Nothing missing: no hypothesis is decisively better than the nominal model \
                 (the campaign's model, proportional damping, ideal sensors)"
            } else {
                "No hypothesis named: some are decisively better than the nominal model \
                 (the campaign's model, proportional damping, ideal sensors), but none also has \
                 physically plausible parameters and predicts held-out recordings better"
            };
            s.push_str(opening);
            if let Some(b) = best {
                let se = |m: &ModelResult| m.evidence.as_ref().map(|e| e.ln_z_sd);
                let delta_se = d
                    .finalists
                    .iter()
                    .find(|f| f.name == b.name)
                    .and_then(se)
                    .zip(se(&d.nominal))
                    .map(|(a, n)| a.hypot(n));
                let _ = write!(
                    s,
                    "; the best, {}, changes the log evidence by {:.1}",
                    b.name.replace('_', " "),
                    b.delta_log_evidence,
                );
                let _ = match delta_se {
                    Some(se) => write!(
                        s,
                        " +- {se:.1} (decisive needs {:.1} or more after two standard deviations)",
                        decisive_ln_bayes_factor()
                    ),
                    None => write!(s, " (decisive needs {:.1})", decisive_ln_bayes_factor()),
                };
            }
            let _ = write!(
                s,
                ". The nominal fit has chi2 per point {:.2} and mean FDAC {:.4}.",
                before.chi2_per_point, before.fdac_mean
            );
            if !blocked.is_empty() {
                let _ = write!(s, " Decisive but not named: {}.", blocked.join("; "));
                s.push_str(if d.adequacy.adequate {
                    " The nominal model nonetheless explains the recordings within their \
                     error (below): without a plausible size and a better prediction of \
                     held-out recordings, a gain in evidence is not taken for missing physics."
                } else {
                    " The misfit is real but unexplained: check the located channels and \
                     bands for physics outside the six hypotheses, or a hypothesis whose model \
                     is too crude (its parameter then runs to the end of its physical range)."
                });
            }
        }
    }
    s
}

/// `diagnosis.json`.
pub fn record(d: &Diagnosis) -> DiagnosisRecord {
    let effects: Vec<EffectRecord> = d
        .effects
        .iter()
        .map(|e| EffectRecord {
            hypothesis: e.hypothesis.clone(),
            location: json_of(&d.data.shown(&e.location)),
            effect_parameters: e.effect_parameters.iter().cloned().collect(),
        })
        .collect();
    let unexplained = d.adequacy.unexplained.clone();
    let tie_first = d.ambiguity.as_ref().is_some_and(|a| a.round == 0);
    let (verdict, location, effect_parameters) = match (effects.first(), &unexplained) {
        _ if tie_first => (
            "ambiguous".to_string(),
            serde_json::json!({}),
            BTreeMap::new(),
        ),
        (Some(e), _) => (
            e.hypothesis.clone(),
            e.location.clone(),
            e.effect_parameters.clone(),
        ),
        (None, Some(u)) => (
            "unexplained".to_string(),
            json_of(&u.place),
            BTreeMap::new(),
        ),
        (None, None) => ("none".to_string(), serde_json::json!({}), BTreeMap::new()),
    };
    DiagnosisRecord {
        verdict,
        location,
        effect_parameters,
        effects,
        adequate: d.adequacy.adequate,
        unexplained,
        ambiguous: d.ambiguity.clone(),
        fit_before: d.fit_before,
        fit_after: d.fit_after,
        hypotheses: hypothesis_evidence(d),
        // A tie in the first round is stated by the open-world part alone.
        explanation: if tie_first {
            open_world_explanation(d)
        } else {
            format!("{} {}", explanation(d), open_world_explanation(d))
        },
    }
}

fn json_of<T: serde::Serialize>(v: &T) -> serde_json::Value {
    serde_json::to_value(v).unwrap_or_else(|_| serde_json::json!({}))
}

/// The later rounds, a tie, and the adequacy of the final model, in words.
pub fn open_world_explanation(d: &Diagnosis) -> String {
    let mut s = String::new();
    for (k, r) in d.later.iter().enumerate() {
        let with = r.extends.join(" and ").replace('_', " ");
        match r.decision.winner {
            Some(w) if d.effects.len() > k + 1 => {
                let f = &r.finalists[w];
                let _ = write!(
                    s,
                    "With {with} in the model, {} at {} is also missing (delta ln Z = {:.1} over that model). ",
                    f.name.replace('_', " "),
                    plain_location(&f.location, &d.data),
                    f.ln_z().unwrap_or(f64::NAN) - r.base_ln_z
                );
            }
            _ => {
                let _ = write!(
                    s,
                    "With {with} in the model, no further hypothesis passes. "
                );
            }
        }
    }
    if let Some(a) = &d.ambiguity {
        let _ = write!(
            s,
            "Ambiguous: {} at {} and {} at {} both pass every test and are {:.1} nats apart (decisive needs {:.1}); {}. ",
            a.hypotheses[0].replace('_', " "),
            plain_location(&a.locations[0], &d.data),
            a.hypotheses[1].replace('_', " "),
            plain_location(&a.locations[1], &d.data),
            a.delta_ln_z,
            decisive_ln_bayes_factor(),
            a.separating_test
        );
    }
    let q = &d.adequacy;
    let named = if d.effects.is_empty() {
        "The nominal model".to_string()
    } else {
        "The final model".to_string()
    };
    match &q.unexplained {
        None => {
            let _ = write!(
                s,
                "{named} explains the recordings within the estimator's own error: chi2 per point {:.2} at a {:.1} % floor, {} of {} cells fail (they locate, they do not decide), and it fits the places of all {} inconsistent consistency checks.",
                q.global.chi2_per_point,
                100.0 * super::adequacy::ADEQUACY_FLOOR,
                q.failed_cells.len(),
                q.n_cells,
                q.checks.len()
            );
        }
        Some(u) => {
            let p = &u.place;
            let bands: Vec<String> = p
                .bands_hz
                .iter()
                .map(|(a, b)| format!("{a:.2}-{b:.2} Hz"))
                .collect();
            let _ = write!(
                s,
                "Unexplained: {named} still fails against the estimator's own error (all points: chi2 per point {:.2}, p = {:.1e}; {} of {} cells; {} of {} inconsistent-check places) at tests {}; channels {}; bands {}. What the residual shows: {}.",
                q.global.chi2_per_point,
                q.global.p_value,
                q.failed_cells.len(),
                q.n_cells,
                q.checks.iter().filter(|c| c.failed).count(),
                q.checks.len(),
                p.tests.join(", "),
                p.channels.join(", "),
                if bands.is_empty() { "off the resonances".to_string() } else { bands.join(", ") },
                u.signature.join("; ")
            );
        }
    }
    s
}

/// `v` to four significant digits (scientific notation outside 1e-3..1e5).
fn sig4(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let decimals = if a == 0.0 {
            3
        } else {
            (3 - a.log10().floor() as i32).max(0) as usize
        };
        format!("{v:.decimals$}")
    }
}

#[cfg(test)]
mod tests {
    use super::sig4;

    #[test]
    fn four_significant_digits() {
        assert_eq!(sig4(1.4998e8), "1.500e8");
        assert_eq!(sig4(3.01234), "3.012");
        assert_eq!(sig4(0.0123456), "0.01235");
        assert_eq!(sig4(-4.5e-5), "-4.500e-5");
        assert_eq!(sig4(12345.6), "12346");
        assert_eq!(sig4(0.0), "0.000");
    }
}
