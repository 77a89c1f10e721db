//! The fast subset of the missing-physics benchmark (issue 5): campaigns simulated from
//! `experiments/models/discrepancy/`, diagnosed blind with the default settings, verdict
//! and location asserted. One case with nothing missing and one with an effect at a
//! place no single-channel candidate names (two of eight channels), so both the `none`
//! decision and the location search are exercised. The whole benchmark is
//! `frfbayes diagnose-benchmark` (results/discrepancy_benchmark.md).

use frfbayes::discrepancy::benchmark::{locations_match, read_cases};
use frfbayes::discrepancy::diagnose::{diagnose, DiagnoseOptions};
use frfbayes::discrepancy::report::record;
use frfbayes::simulate::{SimModel, Simulator};
use std::collections::BTreeMap;
use std::path::Path;

fn check_case(id: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (_, cases) = read_cases(&root.join("experiments/models/discrepancy/cases.toml")).unwrap();
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
}

#[test]
fn nothing_missing_gives_none() {
    check_case("none-1");
}

#[test]
fn two_late_accelerometers_are_found() {
    check_case("sensor_timing-3");
}
