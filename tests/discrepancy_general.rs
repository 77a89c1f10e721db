//! The diagnosis on a general model (issue 14, item 1): the six-DOF spring network of
//! `experiments/models/six-dof-hammer.toml` (Matrix Market groups, braces between
//! non-neighbouring DOFs, a mass matrix that is not diagonal), simulated noise-free.
//!
//! Diagnosed blind with the default settings: the network as simulated says `none`, and
//! with `experiments/models/discrepancy/general/six-dof-oscillator.toml`'s concealed
//! oscillator (6 kg at 5.5 Hz, 2 %, on DOF 2) it says `secondary_oscillator` on DOF 2
//! (`{"floor": 2}`: the campaign format's floor of a general model is its DOF), the
//! frequency and damping intervals covering the truth (about 75 s for both); an ignored
//! test finds `six-dof-dashpot.toml`'s damper on its connection, `{"dofs": [3, 5]}`.
//!
//! Oracle: at the simulator's truth (its `alpha`, `beta` as scales `1 + alpha`, and the
//! modal damping ratios of its Rayleigh matrix) the diagnosis' forward model meets the
//! estimated FRFs to the estimator's own accuracy; the nominal posterior is laid out by
//! the model's groups; hypotheses that speak of stories are reported as not testable.
//!
//!     cargo test --release --test discrepancy_general -- --nocapture

use frfbayes::discrepancy::diagnose::{diagnose, DiagnoseOptions};
use frfbayes::discrepancy::report::record;
use frfbayes::discrepancy::{
    all_hypotheses, BaseParams, DataOptions, DiagnosisData, Location, ModelPosterior,
};
use frfbayes::io::Campaign;
use frfbayes::simulate::{SimModel, Simulator, StructureSpec};
use num_complex::Complex64;
use std::path::Path;
use std::sync::Arc;

fn campaign_and_truth() -> (Campaign, BaseParams) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/six-dof-hammer.toml");
    let mut model = SimModel::from_path(&path).unwrap();
    model.noise = Default::default();
    let StructureSpec::General { alpha, beta, .. } = model.structure.clone() else {
        panic!("general model expected")
    };
    let sim = Simulator::new(model).unwrap();
    let xi = sim.system().modal_damping_ratios().unwrap();
    let campaign = sim.run(2, &|_| {}).unwrap();
    let scale = |v: Vec<f64>| v.into_iter().map(|a| 1.0 + a).collect();
    let base = BaseParams {
        stiffness_scale: scale(alpha),
        mass_scale: scale(beta),
        xi,
    };
    (campaign, base)
}

/// Quantiles (median, 90 %) of `|pred / h - 1|` over the in-band points.
fn in_band_errors(post: &ModelPosterior, pred: &[Complex64]) -> (f64, f64) {
    let mut rel: Vec<f64> = Vec::new();
    for (seg, ranges) in post.data().segments.iter().zip(post.model().layout()) {
        for (ch, r) in seg.channels.iter().zip(ranges) {
            for i in (0..ch.len()).filter(|&i| ch.band[i].is_some()) {
                rel.push(((pred[r.start + i] - ch.h[i]) / ch.h[i]).norm());
            }
        }
    }
    rel.sort_by(f64::total_cmp);
    (rel[rel.len() / 2], rel[rel.len() * 9 / 10])
}

#[test]
fn the_model_meets_a_general_campaign_at_its_truth() {
    let (campaign, truth) = campaign_and_truth();
    let data = Arc::new(DiagnosisData::from_campaign(&campaign, &DataOptions::default()).unwrap());
    assert!(!data.is_shear_frame());
    let post = ModelPosterior::new(data.clone(), None).unwrap();
    // Layout: 4 stiffness groups, 3 mass groups, 6 modes, eta.
    let layout = post.frame_layout();
    assert_eq!((layout.n_stiffness, layout.n_mass, layout.n_xi), (4, 3, 6));
    assert_eq!(post.eta_index(), 13);
    let z = post.z_of(&truth, 1e-3, &[]);
    let (median, p90) = in_band_errors(&post, &post.predict(&z).unwrap());
    println!("at the truth: median {median:.2e}, 90 % {p90:.2e}");
    // What is left is the campaign's own systematic error: the simulator's input hold at
    // its 1 kHz internal rate alone, (omega h)^2 / 12, is 1.3e-3 at the 19.3 Hz top mode
    // (3.35e-4 and 1.33e-3 measured).
    assert!(
        median < 1e-3 && p90 < 3e-3,
        "median {median:e}, 90 % {p90:e}"
    );
    // Moving one stiffness group by 1 % is seen well above that.
    let mut moved = truth.clone();
    moved.stiffness_scale[0] *= 1.01;
    let (median_moved, _) =
        in_band_errors(&post, &post.predict(&post.z_of(&moved, 1e-3, &[])).unwrap());
    assert!(
        median_moved > 3.0 * median,
        "{median_moved:e} against {median:e}"
    );
}

#[test]
fn story_hypotheses_are_not_testable_on_a_general_model() {
    let (campaign, _) = campaign_and_truth();
    let data = Arc::new(DiagnosisData::from_campaign(&campaign, &DataOptions::default()).unwrap());
    for h in all_hypotheses() {
        let locs = h.locations(&data);
        let fitted: Vec<_> = locs
            .iter()
            .filter(|l| h.parameters(&data, l).is_ok())
            .collect();
        match h.name() {
            "base_flexibility" | "stiffness_nonlinearity" => {
                assert!(fitted.is_empty(), "{}: {fitted:?}", h.name());
                let e = h.parameters(&data, &locs[0]).unwrap_err().to_string();
                assert!(e.contains("not testable") && e.contains("general"), "{e}");
            }
            // Every instrumented DOF (all six carry an accelerometer).
            "secondary_oscillator" => assert_eq!(fitted.len(), 6, "{locs:?}"),
            // The nine pairs of DOFs that K0.mtx joins; not a story, not the ground.
            "nonproportional_damping" => {
                assert!(h.parameters(&data, &Location::Story(2)).is_err());
                assert!(h.parameters(&data, &Location::Dofs([0, 3])).is_err());
                assert_eq!(fitted.len(), 9, "{locs:?}");
                assert!(
                    locs.contains(&Location::Dofs([3, 5]))
                        && !locs.contains(&Location::Dofs([2, 3]))
                );
            }
            _ => assert!(!fitted.is_empty(), "{}", h.name()),
        }
    }
}

/// The record of a blind diagnosis of the campaign simulated from `model` (relative to
/// `experiments/models`) with its own seed.
fn diagnosed(model: &str) -> frfbayes::discrepancy::DiagnosisRecord {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("experiments/models")
        .join(model);
    let model = SimModel::from_path(&path).unwrap();
    let seed = model.seed.unwrap_or(1);
    let campaign = Simulator::new(model).unwrap().run(seed, &|_| {}).unwrap();
    let d = diagnose(&campaign, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    record(&d)
}

#[test]
fn a_general_model_with_nothing_missing_gives_none() {
    let r = diagnosed("six-dof-hammer.toml");
    assert_eq!(r.verdict, "none", "{}", r.explanation);
    assert!(r.effects.is_empty() && r.adequate, "{}", r.explanation);
    // The story and base hypotheses are reported as not testable, not dropped.
    let not_fitted: Vec<&str> = r
        .hypotheses
        .iter()
        .filter(|h| !h.not_fitted.is_empty())
        .map(|h| h.name.as_str())
        .collect();
    assert_eq!(not_fitted, ["base_flexibility", "stiffness_nonlinearity"]);
}

#[test]
fn an_oscillator_on_a_general_model_is_found_on_its_dof() {
    let r = diagnosed("discrepancy/general/six-dof-oscillator.toml");
    assert_eq!(r.verdict, "secondary_oscillator", "{}", r.explanation);
    assert_eq!(r.location, serde_json::json!({ "floor": 2 }));
    assert_eq!(r.effects.len(), 1, "{}", r.explanation);
    let truth_hz = (7165.0f64 / 6.0).sqrt() / (2.0 * std::f64::consts::PI);
    let f = &r.effect_parameters["oscillator_frequency"];
    assert!(
        f.q2_5 <= truth_hz && truth_hz <= f.q97_5,
        "{f:?} vs {truth_hz}"
    );
    let m = &r.effect_parameters["oscillator_mass"];
    assert!((m.mean / 6.0 - 1.0).abs() < 0.05, "{m:?}");
    // The words quote the final model's size, as `effect_parameters` and `effects` do
    // (not the first round's posterior, before the estimator's bias was measured again).
    let words = format!("oscillator_mass = {:.3} kg", m.mean);
    assert!(r.explanation.contains(&words), "{words}: {}", r.explanation);
}

/// A damper across a connection of the general model (about 60 s; ignored to keep the
/// default run short: `cargo test --release --test discrepancy_general -- --ignored`).
#[test]
#[ignore = "a blind diagnosis, about 60 s"]
fn a_damper_between_two_dofs_is_found_on_its_connection() {
    let r = diagnosed("discrepancy/general/six-dof-dashpot.toml");
    assert_eq!(r.verdict, "nonproportional_damping", "{}", r.explanation);
    assert_eq!(r.location, serde_json::json!({ "dofs": [3, 5] }));
    assert_eq!(r.effects.len(), 1, "{}", r.explanation);
    let c = &r.effect_parameters["damper_coefficient"];
    assert!((c.mean / 300.0 - 1.0).abs() < 0.05, "{c:?}");
}
