//! The input-gain term of `diagnose` on a hammer campaign recorded at a low rate for its
//! pulse (the bridge's 60 Hz case in miniature): the six-DOF spring network of
//! `experiments/models/six-dof-hammer.toml` recorded at 100 Hz with 6 ms pulses (0.6
//! samples) and 2 N of force noise against 500 N peaks (`six-dof-low-rate.toml` of the
//! general benchmark), so the force noise inside each
//! force window is a gain error of about 4 % per impact, shared by every channel.
//!
//! Carried by the *measured* ratios (`V = diag(h) U`), that term's covariance holds the
//! very error it weighs (`h = H (1 + delta)`), and the Woodbury correction pulls the fit
//! by an amount of order `var(delta)` that repeats in every segment. The fitted model is
//! far more precise than that (thousands of points), so a sensor low-pass absorbs it: on
//! these two seeds its gain in maximum log-likelihood over the nominal model is 92 and
//! 83 nats, a false `sensor_dynamics` at every response channel (docs/diagnose.md, "The bridge's
//! size in diagnose"). Carried by each model's own `H` at its MAP
//! (`GainCarrier::ModelAtMap`) it is 0.0 and 0.3 nats, as a null's should be (below
//! `ln 150`, which bounds what the evidence could make of it).
//!
//!     cargo test --release --test discrepancy_low_rate -- --nocapture

use frfbayes::discrepancy::data::GainCarrier;
use frfbayes::discrepancy::fit::refit_at_map;
use frfbayes::discrepancy::search::{fit_location, SearchOptions};
use frfbayes::discrepancy::{
    fit_map, frame_starts, hypothesis_by_name, DataOptions, DiagnosisData, Hypothesis, Location,
    MapOptions, ModelPosterior,
};
use frfbayes::io::{Campaign, Quantity};
use frfbayes::simulate::{SimModel, Simulator};
use std::path::Path;
use std::sync::Arc;

/// The campaign of `experiments/models/discrepancy/general/six-dof-low-rate.toml` (the
/// six-DOF network at 100 Hz, 6 ms pulses, 2 N of force noise), noise seed `seed`.
fn low_rate_campaign(seed: u64) -> Campaign {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("experiments/models/discrepancy/general/six-dof-low-rate.toml");
    let model = SimModel::from_path(&path).unwrap();
    Simulator::new(model).unwrap().run(seed, &|_| {}).unwrap()
}

/// Gain in maximum log-likelihood of a sensor low-pass on every response channel over the
/// nominal model (both fitted as `diagnose` fits them, without the estimator-bias
/// replay), with the input-gain error carried by `carrier`.
fn sensor_filter_gain(campaign: &Campaign, carrier: GainCarrier) -> f64 {
    let options = DataOptions {
        gain_carrier: carrier,
        ..DataOptions::default()
    };
    let data = Arc::new(DiagnosisData::from_campaign(campaign, &options).unwrap());
    let map_options = MapOptions::default();
    let nominal = ModelPosterior::new(data.clone(), None).unwrap();
    let starts = frame_starts(&nominal, 8, 0.3, 1).unwrap();
    let map = fit_map(&nominal, &starts, &map_options).unwrap();
    let (_, map) = refit_at_map(nominal, map, &map_options).unwrap();
    let responses: Vec<String> = data
        .channels()
        .into_iter()
        .filter(|c| c.quantity != Quantity::Force)
        .map(|c| c.name)
        .collect();
    assert_eq!(responses.len(), 7, "{responses:?}");
    let h: Arc<dyn Hypothesis> = hypothesis_by_name("sensor_dynamics").unwrap().into();
    let loc = Location::Channels(responses);
    let fit = fit_location(&data, &h, &loc, &map.z, &SearchOptions::default()).unwrap();
    fit.map.ln_likelihood - map.ln_likelihood
}

#[test]
fn low_rate_force_noise_is_not_a_sensor_filter() {
    let ln_decisive = 150f64.ln();
    for seed in [20261201, 20261202] {
        let campaign = low_rate_campaign(seed);
        let measured = sensor_filter_gain(&campaign, GainCarrier::Measured);
        let at_map = sensor_filter_gain(&campaign, GainCarrier::ModelAtMap);
        println!("seed {seed}: gain {measured:.1} nats (measured h), {at_map:.1} (model at MAP)");
        // The measured carrier's pull is many times the decision threshold; the model's
        // carrier leaves a null's few nats (two filter parameters: about 1 on average).
        assert!(measured > 8.0 * ln_decisive, "{measured}");
        assert!(at_map < ln_decisive, "{at_map}");
    }
}
