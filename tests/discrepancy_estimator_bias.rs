//! The hammer estimator's own systematic error (`discrepancy::estimator_bias`) on a
//! noise-free campaign whose first mode is lightly damped (the false-alarm study's
//! null-04: xi1 = 1.09 %, so 2.7 % of impact 1's ringing is left when impact 2 comes).
//!
//! At the truth, the frequency-domain model alone misses the second impacts' estimates by
//! several times what it misses the first impacts' by; with the bias measured by the
//! replay it meets both to the replay's own accuracy, and the bias measured at the truth
//! still serves where the data pin the modes (frequencies 1e-4 away; first order).
//!
//!     cargo test --release --test discrepancy_estimator_bias -- --nocapture

use frfbayes::discrepancy::estimator_bias::replay_bias;
use frfbayes::discrepancy::{BaseParams, DataOptions, DiagnosisData, ModelPosterior};
use frfbayes::io::Campaign;
use frfbayes::simulate::{DampingSpec, SimModel, Simulator, StructureSpec};
use num_complex::Complex64;
use std::path::Path;
use std::sync::Arc;

fn campaign_and_truth() -> (Campaign, BaseParams) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("experiments/models/discrepancy/nulls/null-04.toml");
    let mut model = SimModel::from_path(&path).unwrap();
    model.noise = Default::default();
    let StructureSpec::ShearFrame {
        floor_mass_kg,
        story_stiffness_n_per_m,
    } = model.structure.clone()
    else {
        panic!("shear frame expected")
    };
    let DampingSpec::Modal { xi } = model.damping.clone() else {
        panic!("modal damping expected")
    };
    let campaign = Simulator::new(model).unwrap().run(4, &|_| {}).unwrap();
    let nominal = campaign.nominal.structural_model().unwrap();
    let base =
        BaseParams::from_physical(&nominal, &story_stiffness_n_per_m, &floor_mass_kg, xi).unwrap();
    (campaign, base)
}

/// Median of `|pred / h - 1|` over the in-band points of each hammer segment, as
/// (segment name, median).
fn in_band_errors(post: &ModelPosterior, pred: &[Complex64]) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for (seg, ranges) in post.data().segments.iter().zip(post.model().layout()) {
        if seg.is_ground() {
            continue;
        }
        let mut rel: Vec<f64> = Vec::new();
        for (ch, r) in seg.channels.iter().zip(ranges) {
            for i in (0..ch.len()).filter(|&i| ch.band[i].is_some()) {
                rel.push(((pred[r.start + i] - ch.h[i]) / ch.h[i]).norm());
            }
        }
        rel.sort_by(f64::total_cmp);
        out.push((seg.name.clone(), rel[rel.len() / 2]));
    }
    out
}

#[test]
fn the_replayed_bias_explains_the_lightly_damped_second_impacts() {
    let (campaign, truth) = campaign_and_truth();
    let data = Arc::new(DiagnosisData::from_campaign(&campaign, &DataOptions::default()).unwrap());
    let post = ModelPosterior::new(data.clone(), None).unwrap();
    let z = post.z_of(&truth, 1e-3, &[]);
    let before = in_band_errors(&post, &post.predict(&z).unwrap());
    let bias = replay_bias(&campaign, &post, &z).unwrap();
    let debiased = Arc::new(
        data.with_estimator_bias(post.model().layout(), &bias)
            .unwrap(),
    );
    let post_b = ModelPosterior::new(debiased, None).unwrap();
    let after = in_band_errors(&post_b, &post_b.predict(&z).unwrap());
    let mean = |v: &[(String, f64)], k: &str| {
        let x: Vec<f64> = v
            .iter()
            .filter(|(n, _)| n.ends_with(k))
            .map(|p| p.1)
            .collect();
        x.iter().sum::<f64>() / x.len() as f64
    };
    for ((name, b), (_, a)) in before.iter().zip(&after) {
        println!("{name}: in-band median |pred/h - 1| {b:.2e} -> {a:.2e}");
    }
    let (b1, b2) = (mean(&before, "impact1"), mean(&before, "impact2"));
    let (a1, a2) = (mean(&after, "impact1"), mean(&after, "impact2"));
    println!("impact 1: {b1:.2e} -> {a1:.2e}; impact 2: {b2:.2e} -> {a2:.2e}");
    // What the bias is for: the second impacts are off by several times the first.
    assert!(b2 > 3.0 * b1, "impact 2 {b2:.2e} against impact 1 {b1:.2e}");
    // With it, both meet the estimates at the replay's accuracy.
    assert!(a2 < b2 / 5.0 && a1 < b1, "{a1:.2e} {a2:.2e}");
    // The replay's own error is far below that (measured 4.5e-7 and 5.4e-9 since it
    // steps 6 times finer and divides only the state part by the hold's gain; 2.7e-6
    // and 8.3e-6 before).
    assert!(a1 < 2e-6 && a2 < 1e-6, "{a1:.2e} {a2:.2e}");

    // First order where the data pin the modes: with every frequency 1e-4 higher
    // (stiffnesses x 1.0002) the bias measured at the truth misses the replay's bias
    // there by what the carried-over ringing's phase turn allows, `omega Delta` times
    // 1e-4 (0.21 rad for the highest mode, 5.6 Hz, 60 s after impact 1; bound 0.25),
    // and the miss halves with the change (first order). A 0.5 % stiffer frame (0.25 %
    // in frequency) is printed, not held to it.
    let miss_of = |factor: f64| {
        let mut moved = truth.clone();
        for k in &mut moved.stiffness_scale {
            *k *= factor;
        }
        let z_moved = post.z_of(&moved, 1e-3, &[]);
        let bias_moved = replay_bias(&campaign, &post, &z_moved).unwrap();
        let shifted = post_b.predict(&z_moved).unwrap();
        let frequency_domain = post.predict(&z_moved).unwrap();
        let norm =
            |v: &mut dyn Iterator<Item = Complex64>| v.map(|c| c.norm_sqr()).sum::<f64>().sqrt();
        let miss = norm(
            &mut shifted
                .iter()
                .zip(&frequency_domain)
                .zip(&bias_moved)
                .map(|((s, f), b)| s - f - b),
        );
        let size = norm(&mut bias_moved.iter().copied());
        println!("stiffness x {factor}: bias {size:.3e}, missed by the truth's bias by {miss:.3e}");
        (miss, size)
    };
    let (miss, size) = miss_of(1.0002);
    assert!(miss < 0.25 * size, "{miss:.3e} of {size:.3e}");
    let (half, _) = miss_of(1.0001);
    assert!(
        (0.4..0.6).contains(&(half / miss)),
        "{half:.3e} against {miss:.3e}"
    );
    miss_of(1.005);
}
