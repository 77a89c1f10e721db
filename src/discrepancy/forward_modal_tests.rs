//! Oracle of the modal fast path ([`super::forward_modal`]): on a 20-story frame, every
//! hypothesis at every location predicts what the dense solve predicts.

use super::data::{nominal_frequencies, DataOptions, DiagnosisData, SegmentData};
use super::forward::{BaseParams, ExtendedModel};
use super::hypotheses::all_hypotheses;
use super::hypothesis::Hypothesis;
use super::tests::segment_on;
use crate::io::NominalModel;
use crate::signal::InputKind;
use num_complex::Complex64;
use std::sync::Arc;

const N: usize = 20;
/// Pointwise relative difference allowed: both are double-precision solves, and the
/// worst point sits where a response nearly vanishes (2.8e-9 for the nominal model and
/// at most 3.1e-9 over every hypothesis and location, measured).
const TOL: f64 = 1e-8;
const FLOORS: [usize; 5] = [1, 5, 10, 17, 20];

fn segment(name: &str, input: InputKind, tau: Option<f64>, freq_hz: &[f64]) -> SegmentData {
    let drift = (0..N).map(|s| Some(1e-6 * (1.0 + s as f64))).collect();
    segment_on(name, input, tau, freq_hz, &FLOORS, drift)
}

/// A 20-story frame with hammer tests at floors 5 and 17, a shake-table test and a
/// stronger second impact at floor 17 (the amplitude-dependent variants).
fn frame20() -> (Arc<DiagnosisData>, BaseParams) {
    let mass: Vec<f64> = (0..N).map(|i| 5.0 + 0.05 * i as f64).collect();
    let stiff: Vec<f64> = (0..N).map(|i| 3000.0 - 40.0 * i as f64).collect();
    let nominal = NominalModel::shear_frame(mass.clone(), stiff.clone());
    let freq: Vec<f64> = (1..=80).map(|i| 0.25 * i as f64).collect();
    let force = |f: usize| InputKind::Force {
        floor: f,
        channel: "force".into(),
    };
    let ground = InputKind::Ground {
        channel: "ground_acc".into(),
    };
    let mut strong = segment("h17b", force(17), Some(19.4), &freq);
    strong.story_drift_lin_sq_m2.iter_mut().for_each(|d| {
        *d = d.map(|v| 4.0 * v);
    });
    let segments = vec![
        segment("h5", force(5), Some(19.4), &freq),
        segment("h17", force(17), None, &freq),
        segment("shake", ground, None, &freq),
        strong,
    ];
    let model = Arc::new(nominal.structural_model().unwrap());
    let xi: Vec<f64> = (0..N).map(|i| 0.01 + 0.001 * i as f64).collect();
    let base = BaseParams::from_physical(
        &model,
        &stiff.iter().map(|k| 1.03 * k).collect::<Vec<_>>(),
        &mass.iter().map(|m| 0.98 * m).collect::<Vec<_>>(),
        xi,
    )
    .unwrap();
    let data = DiagnosisData {
        title: "twenty".into(),
        nominal_freq_hz: nominal_frequencies(&nominal).unwrap(),
        model,
        nominal,
        segments,
        options: DataOptions::default(),
        reduction: None,
    };
    (Arc::new(data), base)
}

fn max_rel_diff(a: &[Complex64], b: &[Complex64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm() / y.norm())
        .fold(0.0, f64::max)
}

#[test]
fn modal_path_matches_the_dense_solve_for_every_hypothesis() {
    let (data, base) = frame20();
    let nominal = ExtendedModel::new(data.clone(), None).unwrap();
    assert!(nominal.is_modal_at(&base, &[]).unwrap());
    let fast = nominal.predict(&base, &[]).unwrap();
    let dense = nominal.clone().dense().predict(&base, &[]).unwrap();
    let err = max_rel_diff(&fast, &dense);
    assert!(err < TOL, "nominal: {err:e}");
    let mut n_modal = 0;
    for h in all_hypotheses() {
        let h: Arc<dyn Hypothesis> = Arc::from(h);
        for loc in h.locations(&data) {
            let params = h.parameters(&data, &loc).unwrap();
            let z: Vec<f64> = params
                .iter()
                .map(|p| 0.3 * p.lower + 0.7 * p.upper)
                .collect();
            let effect = h.physical(&data, &loc, &z).unwrap();
            let model = ExtendedModel::new(data.clone(), Some((h.clone(), loc.clone()))).unwrap();
            let fast = model.predict(&base, &effect).unwrap();
            let dense = model.clone().dense().predict(&base, &effect).unwrap();
            let err = max_rel_diff(&fast, &dense);
            assert!(err < TOL, "{} at {loc:?}: {err:e}", h.name());
            // ... and the effect is there to be matched.
            assert!(max_rel_diff(&fast, &nominal.predict(&base, &[]).unwrap()) > 1e-4);
            n_modal += usize::from(model.is_modal_at(&base, &effect).unwrap());
        }
    }
    // Every location but the flexible base (a DOF inserted under the frame) takes the
    // fast path: 20 oscillators, 20 dampers, 20 cubic springs and 2 x 14 sensors (the
    // force, the ground and 10 response channels, and the two groups of all of them).
    assert_eq!(n_modal, 3 * N + 2 * 14);
}
