//! Round 2 of the bridge's delay case (`experiments/models/discrepancy/bridge/bridge-delay.toml`:
//! acc870 recorded 4 ms late): with the true effect in the model, a second oscillator
//! must not gain a decisive amount. It did (a 1e-4 oscillator at DOF 894, 5.93 Hz, +40.4
//! nats in max ln L) while the reduced basis stayed anchored at the nominal MAP, which
//! the missing delay had pulled 0.48 away in some stiffness variables; re-anchored at
//! the accepted model's MAP ([`with_data_renewed`]) the gain is 6.1 nats, below what
//! could make it decisive after the Occam factor.
//!
//! Needs the simulated campaign (about 4 minutes), then about 70 s:
//!
//! ```sh
//! frfbayes simulate --model experiments/models/discrepancy/bridge/bridge-delay.toml --out <DIR>
//! FRFBAYES_BRIDGE_DELAY_CAMPAIGN=<DIR> cargo test --release --test bridge_round_two -- --ignored --nocapture
//! ```
//!
//! Skips (prints `SKIPPED: ...`) without `FRFBAYES_BRIDGE_DELAY_CAMPAIGN`.

use frfbayes::discrepancy::diagnose::{DiagnoseOptions, ModelResult};
use frfbayes::discrepancy::estimator_bias::replay_bias;
use frfbayes::discrepancy::extension::{Effect, WithEffects};
use frfbayes::discrepancy::fit::refit_at_map;
use frfbayes::discrepancy::model_evidence::laplace_u;
use frfbayes::discrepancy::round::{BaseModel, RoundContext};
use frfbayes::discrepancy::search::{fit_location, SearchOptions};
use frfbayes::discrepancy::stepwise::with_data_renewed;
use frfbayes::discrepancy::{
    fit_map, frame_starts, hypothesis_by_name, DataOptions, DiagnosisData, EvidenceOptions,
    Hypothesis, Location, MapFit, ModelPosterior,
};
use frfbayes::io::read_campaign;
use std::sync::Arc;

/// `ln 150`: a gain in max ln L below it cannot be decisive.
const DECISIVE: f64 = 5.0106;

fn alpha_of(post: &ModelPosterior, z: &[f64]) -> Vec<f64> {
    post.base_params(z).alpha_beta().0
}

/// Largest difference of the stiffness variables at `z` from the basis's anchor.
fn from_anchor(post: &ModelPosterior, z: &[f64]) -> f64 {
    let anchor = &post.data().reduction.as_ref().unwrap().anchor_alpha;
    alpha_of(post, z)
        .iter()
        .zip(anchor)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// Max ln L gain of a second oscillator at `floor` over `base` (the first effect in it).
fn oscillator_gain(
    data: &Arc<DiagnosisData>,
    first: &Effect,
    base: &MapFit,
    floor: usize,
    sopts: &SearchOptions,
) -> (f64, Vec<f64>) {
    let osc: Arc<dyn Hypothesis> = Arc::new(
        WithEffects::new(
            data,
            vec![first.clone()],
            Arc::from(hypothesis_by_name("secondary_oscillator").unwrap()),
        )
        .unwrap(),
    );
    let loc = Location::Floor(floor);
    let fit = fit_location(data, &osc, &loc, &base.z, sopts).unwrap();
    let post = ModelPosterior::new(data.clone(), Some((osc, loc))).unwrap();
    (
        fit.map.ln_likelihood - base.ln_likelihood,
        post.effect_physical(&fit.map.z).unwrap(),
    )
}

#[test]
#[ignore = "about 70 s; needs the simulated bridge-delay campaign"]
fn delay_case_round_two_adds_no_oscillator_once_the_basis_follows_the_accepted_model() {
    let Some(dir) = std::env::var_os("FRFBAYES_BRIDGE_DELAY_CAMPAIGN") else {
        println!("SKIPPED: FRFBAYES_BRIDGE_DELAY_CAMPAIGN not set");
        return;
    };
    let raw = read_campaign(std::path::Path::new(&dir)).unwrap();
    let opts = DiagnoseOptions {
        data: DataOptions {
            freq_max_hz: Some(15.5),
            ..DataOptions::default()
        },
        // The base's evidence is not under test: a short run.
        evidence: Some(EvidenceOptions {
            n_replicates: 2,
            min_steps_per_temperature: 1,
            max_steps_per_temperature: 3,
            final_steps: 10,
            ..EvidenceOptions::new(1, 0)
        }),
        ..DiagnoseOptions::default()
    };
    let sopts = SearchOptions {
        n_effect_starts: opts.n_effect_starts,
        map: opts.map.clone(),
        seed: opts.seed,
    };
    // The nominal model as `diagnose` fits it: re-anchored at its MAP, debiased.
    let mut data = Arc::new(DiagnosisData::from_campaign(&raw, &opts.data).unwrap());
    let campaign = data.reduction.as_ref().unwrap().renumber(&raw);
    let mut post0 = ModelPosterior::new(data.clone(), None).unwrap();
    let starts = frame_starts(&post0, opts.n_frame_starts, 0.3, opts.seed).unwrap();
    let mut map0 = fit_map(&post0, &starts, &opts.map).unwrap();
    for _ in 0..3 {
        let Some((moved, _)) = data.reanchored(&post0.base_params(&map0.z)).unwrap() else {
            break;
        };
        data = Arc::new(moved);
        post0 = ModelPosterior::new(data.clone(), None).unwrap();
        map0 = fit_map(&post0, std::slice::from_ref(&map0.z), &opts.map).unwrap();
    }
    let bias = replay_bias(&campaign, &post0, &map0.z).unwrap();
    data = Arc::new(
        data.with_estimator_bias(post0.model().layout(), &bias)
            .unwrap(),
    );
    post0 = ModelPosterior::new(data.clone(), None).unwrap();
    map0 = fit_map(&post0, std::slice::from_ref(&map0.z), &opts.map).unwrap();
    let (_, map0) = refit_at_map(post0, map0, &opts.map).unwrap();

    // Round 1's winner, the truth: acc870 late.
    let first = Effect {
        hypothesis: Arc::from(hypothesis_by_name("sensor_timing").unwrap()),
        location: Location::Channels(vec!["acc870".into()]),
    };
    let ext = Some((first.hypothesis.clone(), first.location.clone()));
    let f1 = fit_location(&data, &first.hypothesis, &first.location, &map0.z, &sopts).unwrap();
    let post1 = ModelPosterior::new(data.clone(), ext.clone())
        .unwrap()
        .at_map(&f1.map.z)
        .unwrap();
    let delay = post1.effect_physical(&f1.map.z).unwrap()[0];
    assert!((delay - 4e-3).abs() < 2e-5, "delay {delay}");
    let stale = from_anchor(&post1, &f1.map.z);
    let (stale_gain, stale_osc) = oscillator_gain(&data, &first, &f1.map, 8, &sopts);
    println!(
        "basis at the nominal MAP: the accepted model's MAP {stale:.3} from the anchor; \
         max ln L {:.1}; + oscillator at DOF 894 gains {stale_gain:.1} ({stale_osc:?})",
        f1.map.ln_likelihood
    );

    // Round 2's base as `continue_rounds` makes it.
    let result = ModelResult::fitted(
        "sensor_timing",
        first.location.clone(),
        post1.clone(),
        f1.map.clone(),
    );
    let base = BaseModel {
        laplace: laplace_u(&post1, &f1.map.z),
        result,
        extension: ext,
        effects: vec![first.clone()],
    };
    let hypotheses: Vec<Arc<dyn Hypothesis>> = Vec::new();
    let ctx = RoundContext {
        campaign: &campaign,
        data: &data,
        opts: &opts,
        stages: None,
        hypotheses: &hypotheses,
    };
    let renewed = with_data_renewed(&ctx, &base, 1, &mut |_| {})
        .unwrap()
        .expect("the data are renewed at the accepted model's MAP");
    let post2 = &renewed.result.posterior;
    let map2 = &renewed.result.map;
    let gap = from_anchor(post2, &map2.z);
    let (gain, osc) = oscillator_gain(post2.data(), &first, map2, 8, &sopts);
    println!(
        "basis renewed: MAP {gap:.3} from the anchor; max ln L {:.1}; + oscillator at DOF 894 \
         gains {gain:.1} ({osc:?})",
        map2.ln_likelihood
    );
    // The campaign shows the fault the test guards against...
    assert!(stale > 0.1, "the nominal anchor is {stale} from the MAP");
    assert!(stale_gain > 4.0 * DECISIVE, "stale-basis gain {stale_gain}");
    // ...and the renewed basis removes it: the base sits at its anchor, fits better,
    // and a second oscillator gains about what noise gives (6.1 nats measured; the
    // Occam factor of its three parameters is about 10).
    assert!(gap < 0.05, "renewed MAP {gap} from its anchor");
    assert!(map2.ln_likelihood > f1.map.ln_likelihood + 50.0);
    assert!(gain < 2.0 * DECISIVE, "gain {gain} with the renewed basis");
}
