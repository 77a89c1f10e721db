//! The decision: which missing physics, if any, the data support, and the record
//! `diagnosis.json` that states it.
//!
//! Rule (fixed in advance, from the statistics alone; no threshold is fitted to our own
//! benchmark):
//! 1. a hypothesis is *decisive* when its log evidence exceeds the nominal model's by at
//!    least `ln 150` (Kass & Raftery 1995: a Bayes factor above 150 is "very strong"
//!    evidence), counting two standard deviations of the difference against it, and its
//!    gain in maximum log-likelihood over the nominal model, which bounds the
//!    difference ([`crate::infer::nested::gain_bound`]), reaches `ln 150` too. Whatever
//!    estimator gave the evidence ([`crate::infer::screened`]: none for a hypothesis the
//!    bound rules out, Laplace in logit coordinates far from the threshold and from any
//!    rival, importance sampling or the generalised stepping-stone elsewhere), it comes
//!    with its sd;
//! 2. it must be *physically plausible*: the 95 % interval of every effect parameter lies
//!    inside its prior range without piling up at a bound, and excludes the no-effect
//!    value (checked by the hypothesis, reported in [`Candidate::plausible`]);
//! 3. it must *predict held-out data better* than the nominal model: leaving one
//!    segment out at a time, the total held-out log predictive density must rise and the
//!    per-segment gains must be positive beyond chance, by the exact one-sided Wilcoxon
//!    signed-rank test at the conventional 5 % level. The gains' scales differ by
//!    segment (a shake-table record holds several impacts' worth of data), so a test on
//!    ranks is used rather than a normal approximation of the total, whose standard error
//!    one large segment can inflate. With fewer than five non-zero gains no signed-rank
//!    result can reach 5 % (its smallest p-value is 2^-n), and the total must instead
//!    exceed two standard errors;
//! 4. among the hypotheses that pass, the one with the largest log evidence wins.
//!
//! Otherwise the verdict is `none`.

use crate::infer::screened::Estimator;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A Bayes factor of 150 (Kass & Raftery's "very strong") in log units.
pub fn decisive_ln_bayes_factor() -> f64 {
    150f64.ln()
}

/// Rule 1: a log Bayes factor `delta` +- `se` over the base model, whose gain bound
/// is `gain_bound`, is decisive (NaN is not).
pub fn is_decisive(delta: f64, se: f64, gain_bound: f64) -> bool {
    let threshold = decisive_ln_bayes_factor();
    gain_bound >= threshold && delta - 2.0 * se >= threshold
}

/// Summary of one effect parameter's posterior, as in `diagnosis.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectSummary {
    pub mean: f64,
    #[serde(rename = "q2.5")]
    pub q2_5: f64,
    #[serde(rename = "q97.5")]
    pub q97_5: f64,
    pub unit: String,
    /// How much the posterior's spread was widened for the correlation of neighbouring
    /// bins, and to at least the sandwich sd ([`super::bin_correlation`]; 1: not
    /// widened, as in files written before it).
    #[serde(default = "one")]
    pub sd_inflation: f64,
}

fn one() -> f64 {
    1.0
}

/// Goodness of fit of one model to all the data.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    /// Mean FDAC over every segment and channel (magnitudes; 1 = identical shapes).
    pub fdac_mean: f64,
    /// Sum of squared standardised residuals per real datum (real and imaginary parts
    /// count separately), with the estimates' own noise (Bendat-Piersol and the nominal
    /// model's error floor): about 1 when model and data agree within noise.
    pub chi2_per_point: f64,
}

/// One row of the hypothesis ranking.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HypothesisEvidence {
    pub name: String,
    pub log_evidence: f64,
    /// `log_evidence` minus the nominal model's.
    pub delta_log_evidence: f64,
    /// Standard deviation of `delta_log_evidence` (hypothesis and nominal model), nats:
    /// replicates of a stepping-stone, the stated allowance of Laplace, or 0 for a
    /// `gain_bound` or `outranked` (then `delta_log_evidence` is Laplace's value capped
    /// at the bound, or the bound: an upper bound).
    #[serde(default)]
    pub delta_log_evidence_sd: Option<f64>,
    /// `gain_bound`, `outranked`, `laplace`, `importance_sampling`,
    /// `generalised_stepping_stone` or `stepping_stone`
    /// ([`crate::infer::screened::Estimator`]).
    #[serde(default)]
    pub estimator: String,
    /// Upper bound on `delta_log_evidence`: the gain in maximum log-likelihood, nats.
    #[serde(default)]
    pub gain_bound: Option<f64>,
    /// Candidate locations the hypothesis could not be fitted at, with the reason (e.g.
    /// a story whose drift no sensor measures): what the diagnosis could not test.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_fitted: Vec<NotFitted>,
}

/// A candidate location left out of a hypothesis' search, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NotFitted {
    pub location: serde_json::Value,
    pub reason: String,
}

/// One accepted effect in `diagnosis.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectRecord {
    pub hypothesis: String,
    pub location: serde_json::Value,
    /// Its parameters' posterior in the final model (every accepted effect in it).
    pub effect_parameters: BTreeMap<String, EffectSummary>,
}

/// `diagnosis.json`: the schema of issue 5 plus the open-world fields of issue 14.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiagnosisRecord {
    /// The first effect's name, `"none"`, `"ambiguous"` or `"unexplained"`.
    pub verdict: String,
    /// The first effect's location: `{}`, `{"story": s}`, `{"floor": f}`,
    /// `{"channels": [...]}` or `{"quantity": q}`; for `unexplained` its `where`.
    pub location: serde_json::Value,
    /// The first effect's parameters.
    pub effect_parameters: BTreeMap<String, EffectSummary>,
    /// Every accepted effect, in the order it was added.
    #[serde(default)]
    pub effects: Vec<EffectRecord>,
    /// Whether the final model explains the recordings within the estimator's error
    /// ([`super::adequacy`]).
    #[serde(default = "yes")]
    pub adequate: bool,
    /// Where and how the final model fails, when it does.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unexplained: Option<super::adequacy::Unexplained>,
    /// Two explanations that tie, when they stopped the diagnosis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambiguous: Option<super::stepwise::Ambiguity>,
    pub fit_before: FitQuality,
    pub fit_after: FitQuality,
    pub hypotheses: Vec<HypothesisEvidence>,
    pub explanation: String,
}

/// What the decision needs to know about one fitted hypothesis (at its best location).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    pub name: String,
    pub log_evidence: f64,
    /// Standard deviation of `log_evidence`, nats (0 for a bound).
    pub log_evidence_se: f64,
    /// Upper bound on `log_evidence` minus the nominal model's (the gain in maximum
    /// log-likelihood; infinite when unknown).
    #[serde(default = "infinite")]
    pub gain_bound: f64,
    /// The estimator of `log_evidence` ([`crate::infer::screened::Estimator::label`]).
    #[serde(default)]
    pub estimator: String,
    /// Every effect parameter's 95 % interval is inside its prior and excludes no effect.
    pub plausible: bool,
    /// Why not plausible (empty when plausible).
    pub implausible_because: String,
    /// Held-out log predictive density minus the nominal model's, and its standard error.
    pub heldout_gain: f64,
    pub heldout_gain_se: f64,
    /// One-sided Wilcoxon signed-rank p-value of the per-segment gains, and how many
    /// non-zero gains it ranked.
    pub heldout_p_value: f64,
    pub heldout_n_ranked: usize,
    /// The time-domain refit and held-out check were skipped: they replay the tests
    /// (minutes) and a candidate decisively more likely had already passed every test,
    /// beyond what the replay could add, so this one can neither win nor tie. For an
    /// `outranked` estimator: its evidence run and held-out check were skipped, as a
    /// candidate that passed is above its gain bound by the threshold.
    pub heldout_skipped: bool,
}

fn yes() -> bool {
    true
}

fn infinite() -> f64 {
    f64::INFINITY
}

/// Level of the held-out signed-rank test.
pub const HELDOUT_TEST_LEVEL: f64 = 0.05;

/// The fewest non-zero gains with which the signed-rank test can reach
/// [`HELDOUT_TEST_LEVEL`] (`2^-5 = 0.031`).
pub const MIN_RANKED_SEGMENTS: usize = 5;

/// True when a held-out comparison passes the rule of [`decide`].
pub fn held_out_passes(h: &super::heldout::HeldOut) -> bool {
    predicts_better(h.gain, h.gain_se, h.p_value, h.n_ranked).0
}

/// Rule 3 of this module: whether held-out data are predicted better (total gain `gain`
/// +- `gain_se` nats; one-sided signed-rank `p_value` over `n_ranked` non-zero segment
/// gains), and how that was judged.
fn predicts_better(gain: f64, gain_se: f64, p_value: f64, n_ranked: usize) -> (bool, String) {
    if n_ranked >= MIN_RANKED_SEGMENTS {
        let ok = gain > 0.0 && p_value < HELDOUT_TEST_LEVEL;
        let how = format!(
            "held-out gain {gain:.1} nats, signed-rank p = {p_value:.3} over {n_ranked} segments"
        );
        (ok, how)
    } else {
        let ok = gain - 2.0 * gain_se > 0.0;
        let how = format!("held-out gain {gain:.1} +- {gain_se:.1} nats over {n_ranked} segments");
        (ok, how)
    }
}

/// Outcome of [`decide`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decision {
    /// Index into the candidates of the winner, if any.
    pub winner: Option<usize>,
    /// For every candidate, why it was or was not named.
    pub reasons: Vec<String>,
    /// Indices of the candidates that pass every rule (the winner among them).
    #[serde(default)]
    pub passing: Vec<usize>,
}

/// Applies the rule of this module's documentation. `nominal_se` is the standard error
/// of the nominal model's log evidence.
pub fn decide(nominal_log_evidence: f64, nominal_se: f64, candidates: &[Candidate]) -> Decision {
    let threshold = decisive_ln_bayes_factor();
    let mut winner: Option<usize> = None;
    let mut passing = Vec::new();
    let mut reasons = Vec::with_capacity(candidates.len());
    for (i, c) in candidates.iter().enumerate() {
        let delta = c.log_evidence - nominal_log_evidence;
        let se = (c.log_evidence_se.powi(2) + nominal_se.powi(2)).sqrt();
        let reason = if c.gain_bound < threshold {
            format!(
                "cannot be decisive: its gain in max ln L, {:.1} nats, bounds delta ln Z below {threshold:.1}",
                c.gain_bound
            )
        } else if c.heldout_skipped && c.estimator == Estimator::Outranked.label() {
            format!(
                "outranked: its gain in max ln L, {:.1} nats, bounds delta ln Z more than \
                 {threshold:.1} below a hypothesis that passed every test; it can neither \
                 win nor tie, and neither its evidence run nor its held-out check was run",
                c.gain_bound
            )
        } else if !delta.is_finite() {
            "its evidence could not be computed".to_string()
        } else if !is_decisive(delta, se, c.gain_bound) {
            format!(
                "not decisive: delta ln Z = {delta:.1} +- {se:.1} by {} (needs >= {threshold:.1} after two standard deviations)",
                c.estimator.replace('_', " ")
            )
        } else if c.heldout_skipped {
            format!(
                "decisive when linearised (delta ln Z = {delta:.1}); neither its time-domain \
                 refit nor its held-out check was run: a hypothesis decisively more likely \
                 passed every test, and the replay could not close the gap"
            )
        } else if !c.plausible {
            format!(
                "decisive (delta ln Z = {delta:.1}) but implausible: {}",
                c.implausible_because
            )
        } else {
            let (ok, how) = predicts_better(
                c.heldout_gain,
                c.heldout_gain_se,
                c.heldout_p_value,
                c.heldout_n_ranked,
            );
            if !ok {
                format!(
                    "decisive (delta ln Z = {delta:.1}) but does not predict held-out data better ({how})"
                )
            } else {
                if winner.is_none_or(|w| c.log_evidence > candidates[w].log_evidence) {
                    winner = Some(i);
                }
                passing.push(i);
                format!("decisive (delta ln Z = {delta:.1} +- {se:.1}), plausible, {how}")
            }
        };
        reasons.push(reason);
    }
    Decision {
        winner,
        reasons,
        passing,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(name: &str, ln_z: f64) -> Candidate {
        Candidate {
            name: name.into(),
            log_evidence: ln_z,
            log_evidence_se: 0.5,
            gain_bound: f64::INFINITY,
            estimator: "generalised_stepping_stone".into(),
            plausible: true,
            implausible_because: String::new(),
            heldout_gain: 10.0,
            heldout_gain_se: 1.0,
            heldout_p_value: 0.002,
            heldout_n_ranked: 9,
            heldout_skipped: false,
        }
    }

    #[test]
    fn a_candidate_whose_held_out_check_was_skipped_is_not_named() {
        let mut c = vec![cand("a", 30.0), cand("b", 20.0)];
        c[1].heldout_skipped = true;
        let d = decide(0.0, 0.5, &c);
        assert_eq!(d.winner, Some(0));
        assert!(d.reasons[1].contains("was run"), "{}", d.reasons[1]);
    }

    #[test]
    fn an_outranked_candidate_passed_over_is_named_neither_way() {
        let mut c = vec![cand("a", 100.0), cand("b", 40.0)];
        c[1].estimator = "outranked".into();
        c[1].gain_bound = 40.0;
        c[1].log_evidence_se = 0.0;
        c[1].heldout_skipped = true;
        let d = decide(0.0, 0.1, &c);
        assert_eq!((d.winner, d.passing.clone()), (Some(0), vec![0]));
        assert!(d.reasons[1].starts_with("outranked"), "{}", d.reasons[1]);
    }

    #[test]
    fn the_largest_decisive_plausible_candidate_wins() {
        let c = vec![cand("a", 3.0), cand("b", 30.0), cand("c", 20.0)];
        let d = decide(0.0, 0.5, &c);
        assert_eq!(d.winner, Some(1));
        assert_eq!(d.passing, vec![1, 2]);
        assert!(d.reasons[0].starts_with("not decisive"), "{}", d.reasons[0]);
    }

    #[test]
    fn borderline_evidence_needs_two_standard_errors() {
        // delta = 6 > ln 150 = 5.01, but 6 - 2 sqrt(0.5^2 + 0.5^2) = 4.59 < 5.01.
        let d = decide(0.0, 0.5, &[cand("a", 6.0)]);
        assert_eq!(d.winner, None);
        let d = decide(0.0, 0.5, &[cand("a", 6.5)]);
        assert_eq!(d.winner, Some(0));
    }

    #[test]
    fn a_hypothesis_whose_gain_bound_is_below_the_threshold_is_not_decisive() {
        // An estimate above the threshold that contradicts the bound (an estimator's
        // error) does not make it decisive: the bound holds whatever the estimator.
        let mut a = cand("a", 30.0);
        a.gain_bound = 4.9;
        let d = decide(0.0, 0.5, &[a.clone()]);
        assert_eq!(d.winner, None);
        assert!(
            d.reasons[0].starts_with("cannot be decisive"),
            "{}",
            d.reasons[0]
        );
        a.gain_bound = 5.1;
        assert_eq!(decide(0.0, 0.5, &[a]).winner, Some(0));
    }

    #[test]
    fn implausible_or_not_predictive_candidates_are_not_named() {
        let mut a = cand("a", 100.0);
        a.plausible = false;
        a.implausible_because = "k_b at its upper bound".into();
        let mut b = cand("b", 90.0);
        b.heldout_p_value = 0.09;
        let d = decide(0.0, 0.5, &[a.clone(), b.clone()]);
        assert_eq!(d.winner, None);
        assert!(d.reasons[0].contains("implausible"));
        assert!(d.reasons[1].contains("held-out"));
        let d = decide(0.0, 0.5, &[a, b, cand("c", 20.0)]);
        assert_eq!(d.winner, Some(2));
    }

    #[test]
    fn a_gain_in_every_segment_counts_however_unequal_the_segments() {
        // base_flexibility-1: every segment gains, one by 16x the rest, so the total's
        // standard error (75 654) swamps the total (107 963); the ranks do not care.
        let mut a = cand("a", 100.0);
        a.heldout_gain = 107_963.3;
        a.heldout_gain_se = 75_653.3;
        a.heldout_p_value = 1.0 / 512.0;
        assert_eq!(decide(0.0, 0.5, &[a.clone()]).winner, Some(0));
        // A positive total carried by a minority of segments is not enough.
        a.heldout_p_value = 0.25;
        let d = decide(0.0, 0.5, &[a]);
        assert_eq!(d.winner, None);
        assert!(
            d.reasons[0].contains("signed-rank p = 0.250"),
            "{}",
            d.reasons[0]
        );
    }

    #[test]
    fn with_few_segments_the_total_must_exceed_two_standard_errors() {
        let mut a = cand("a", 100.0);
        a.heldout_n_ranked = 4;
        a.heldout_p_value = 1.0 / 16.0;
        a.heldout_gain = 10.0;
        a.heldout_gain_se = 4.0;
        assert_eq!(decide(0.0, 0.5, &[a.clone()]).winner, Some(0));
        a.heldout_gain_se = 6.0;
        assert_eq!(decide(0.0, 0.5, &[a]).winner, None);
    }

    #[test]
    fn record_has_exactly_the_issue_schema() {
        let mut effect = BTreeMap::new();
        effect.insert(
            "time_offset".to_string(),
            EffectSummary {
                mean: 0.018,
                q2_5: 0.017,
                q97_5: 0.019,
                unit: "s".into(),
                sd_inflation: 1.0,
            },
        );
        let r = DiagnosisRecord {
            verdict: "sensor_timing".into(),
            location: serde_json::json!({"quantity": "acceleration"}),
            effect_parameters: effect.clone(),
            fit_before: FitQuality {
                fdac_mean: 0.9,
                chi2_per_point: 10.0,
            },
            fit_after: FitQuality {
                fdac_mean: 0.99,
                chi2_per_point: 1.1,
            },
            hypotheses: vec![HypothesisEvidence {
                name: "sensor_timing".into(),
                log_evidence: -10.0,
                delta_log_evidence: 50.0,
                delta_log_evidence_sd: Some(0.2),
                estimator: "generalised_stepping_stone".into(),
                gain_bound: Some(60.0),
                not_fitted: vec![NotFitted {
                    location: serde_json::json!({"story": 3}),
                    reason: "not testable".into(),
                }],
            }],
            explanation: "x".into(),
            effects: vec![EffectRecord {
                hypothesis: "sensor_timing".into(),
                location: serde_json::json!({"quantity": "acceleration"}),
                effect_parameters: effect.clone(),
            }],
            adequate: true,
            unexplained: None,
            ambiguous: None,
        };
        let v = serde_json::to_value(&r).unwrap();
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        let mut expected = vec![
            "verdict",
            "location",
            "effect_parameters",
            "fit_before",
            "fit_after",
            "hypotheses",
            "explanation",
            "effects",
            "adequate",
        ];
        expected.sort();
        let mut keys_sorted = keys.clone();
        keys_sorted.sort();
        assert_eq!(keys_sorted, expected);
        let e = &v["effect_parameters"]["time_offset"];
        for k in ["mean", "q2.5", "q97.5", "unit"] {
            assert!(e.get(k).is_some(), "missing {k}");
        }
        assert!(v["fit_before"].get("fdac_mean").is_some());
        assert!(v["fit_after"].get("chi2_per_point").is_some());
        assert!(v["hypotheses"][0].get("delta_log_evidence").is_some());
        assert_eq!(v["hypotheses"][0]["not_fitted"][0]["location"]["story"], 3);
        let back: DiagnosisRecord = serde_json::from_value(v).unwrap();
        assert_eq!(back, r);
    }
}
