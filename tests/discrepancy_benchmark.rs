//! The fast subset of the missing-physics benchmark (issue 5): campaigns simulated from
//! `experiments/models/discrepancy/`, diagnosed blind with the default settings, verdict
//! and location asserted. One case with nothing missing and one with an effect at a
//! place no single-channel candidate names (two of eight channels), so both the `none`
//! decision and the location search are exercised. The whole benchmark is
//! `frfbayes diagnose-benchmark` (results/discrepancy_benchmark.md).

use frfbayes::discrepancy::benchmark::{locations_match, read_cases};
use frfbayes::discrepancy::diagnose::{diagnose, DiagnoseOptions};
use frfbayes::discrepancy::report::record;
use frfbayes::discrepancy::verdict::{decisive_ln_bayes_factor, DiagnosisRecord};
use frfbayes::simulate::{SimModel, Simulator};
use std::collections::BTreeMap;
use std::path::Path;

fn check_case(id: &str) -> DiagnosisRecord {
    check_case_of("experiments/models/discrepancy/cases.toml", id)
}

/// Diagnoses case `id` of the cases file `cases` (relative to the repository) blind and
/// checks its verdict, location, single effect and adequacy; returns the record.
fn check_case_of(cases: &str, id: &str) -> DiagnosisRecord {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (_, cases) = read_cases(&root.join(cases)).unwrap();
    let case = cases.iter().find(|c| c.id == id).expect("case listed");
    let model = SimModel::from_path(&case.model).unwrap();
    let campaign = Simulator::new(model)
        .unwrap()
        .run(case.seed, &|_| {})
        .unwrap();
    let channel_quantity: BTreeMap<String, String> = campaign
        .tests
        .iter()
        .flat_map(|t| t.channels.iter())
        .map(|c| {
            (
                c.name.clone(),
                serde_json::to_value(c.quantity)
                    .unwrap()
                    .as_str()
                    .unwrap()
                    .to_string(),
            )
        })
        .collect();
    let d = diagnose(&campaign, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    let r = record(&d);
    println!("{id}: {}", serde_json::to_string_pretty(&r).unwrap());
    assert_eq!(r.verdict, case.verdict, "{id}: {}", r.explanation);
    assert!(
        locations_match(&case.location, &r.location, &channel_quantity),
        "{id}: location {} expected {}",
        r.location,
        case.location
    );
    // The schema's numbers are finite and the fit does not get worse.
    assert!(r.fit_before.chi2_per_point.is_finite() && r.fit_after.chi2_per_point.is_finite());
    assert!(r.fit_after.chi2_per_point <= r.fit_before.chi2_per_point + 1e-12);
    assert_eq!(r.hypotheses.len(), 6);
    // Open world (issue 14): data simulated with at most one effect of the library get
    // exactly that effect, nothing more, and the final model explains them.
    let expected_effects = usize::from(case.verdict != "none");
    assert_eq!(r.effects.len(), expected_effects, "{id}: {}", r.explanation);
    assert!(r.adequate, "{id}: {:?}", r.unexplained);
    assert!(r.unexplained.is_none() && r.ambiguous.is_none());
    r
}

#[test]
fn nothing_missing_gives_none() {
    check_case("none-1");
}

#[test]
fn two_late_accelerometers_are_found() {
    check_case("sensor_timing-3");
}

/// The ten-story oscillator case (about 28 minutes on 2 cores): found at its floor, and
/// the evidence runs of hypotheses it outranks deferred and never made. Every
/// `outranked` row's bound lies below the winner's `delta ln Z` (less two sd) by the
/// decisive factor, and on this case there is at least one such row (on 6c4c1dc base
/// flexibility's stepping-stone took 1,294 s for a bound of 33 nats against 45,586).
#[test]
#[ignore = "about 28 minutes: cargo test --release --test discrepancy_benchmark -- --ignored"]
fn ten_story_oscillator_is_found_without_runs_it_outranks() {
    let r = check_case_of(
        "experiments/models/discrepancy/ten-story/cases.toml",
        "ten-story-oscillator-1",
    );
    let winner = r
        .hypotheses
        .iter()
        .find(|h| h.name == r.verdict)
        .expect("the winner's row");
    let floor = winner.delta_log_evidence - 2.0 * winner.delta_log_evidence_sd.unwrap();
    let outranked: Vec<_> = r
        .hypotheses
        .iter()
        .filter(|h| h.estimator == "outranked")
        .collect();
    assert!(!outranked.is_empty(), "{:?}", r.hypotheses);
    for h in outranked {
        let bound = h.gain_bound.unwrap();
        assert!(
            floor - bound >= decisive_ln_bayes_factor(),
            "{}: {bound}",
            h.name
        );
        assert!(h.delta_log_evidence <= bound + 1e-9, "{}", h.name);
    }
}
