//! The ten-story frame given as Matrix Market files (`experiments/models/ten-story/`) and
//! its simulated hammer campaign (`experiments/models/ten-story-hammer.toml`).

mod truth_frf;

use frfbayes::io::{read_campaign, write_campaign};
use frfbayes::modal::Modes;
use frfbayes::model::{ModelManifest, StructuralModel};
use frfbayes::signal::{estimate_campaign, EstimateOptions};
use frfbayes::simulate::{NoiseSpec, SimModel, Simulator};
use std::path::{Path, PathBuf};
use truth_frf::{analytic, true_modes};

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models")
}

fn sim_model() -> SimModel {
    SimModel::from_path(&models_dir().join("ten-story-hammer.toml")).unwrap()
}

/// The generated files are the shear frame of the documented masses and stiffnesses, with
/// one alpha per story and one beta per floor.
#[test]
fn manifest_is_the_documented_shear_frame() {
    let model = ModelManifest::load(&models_dir().join("ten-story/model.toml")).unwrap();
    let mass_kg: Vec<f64> = (0..10)
        .map(|i| 4.8e4 + (3.6e4 - 4.8e4) * i as f64 / 9.0)
        .collect();
    let k_n_per_m: Vec<f64> = (0..10)
        .map(|i| 1.6e8 + (0.7e8 - 1.6e8) * i as f64 / 9.0)
        .collect();
    let frame = StructuralModel::shear_frame(&mass_kg, &k_n_per_m).unwrap();
    assert_eq!(
        (model.n_dof(), model.n_alpha(), model.n_beta()),
        (10, 10, 10)
    );
    let alpha: Vec<f64> = (0..10).map(|i| 0.01 * i as f64 - 0.04).collect();
    let beta: Vec<f64> = (0..10).map(|i| 0.03 - 0.005 * i as f64).collect();
    let dk = (model.stiffness(&alpha) - frame.stiffness(&alpha)).amax();
    let dm = (model.mass(&beta) - frame.mass(&beta)).amax();
    assert!(dk <= 1e-15 * 3.1e8 && dm <= 1e-15 * 4.8e4, "{dk:e} {dm:e}");
    let f_hz = Modes::solve(
        &model.stiffness(&[0.0; 10]),
        &model.mass(&[0.0; 10]),
        model.ground_influence(),
        None,
    )
    .unwrap()
    .freq_hz();
    println!("ten-story nominal natural frequencies (Hz): {f_hz:.3?}");
    assert!(f_hz[0] > 0.8 && f_hz[0] < 1.5 && f_hz[9] < 20.0, "{f_hz:?}");
}

/// Noise-free: H1 at every sensor DOF equals the analytic FRF of the truth within 0.5 %
/// where the coherence exceeds 0.99 (0.5-20 Hz), as for the four-story frame
/// (`tests/signal_simulated.rs`).
#[test]
fn noise_free_h1_matches_the_analytic_frf() {
    let mut model = sim_model();
    model.noise = NoiseSpec::default();
    let sim = Simulator::new(model).unwrap();
    assert_eq!(sim.modal_basis().unwrap().n_modes(), 10);
    let (modes, c) = true_modes(&sim);
    let campaign = sim.run(1, &|_| {}).unwrap();
    let opts = EstimateOptions {
        freq_max_hz: Some(25.0),
        ..EstimateOptions::default()
    };
    for e in estimate_campaign(&campaign, &opts).unwrap() {
        for r in &e.responses {
            let pair = r.pair(&e.input).unwrap();
            let (mut worst, mut n) = (0.0f64, 0);
            for (k, &f) in e.freq_hz.iter().enumerate() {
                if (0.5..=20.0).contains(&f) && r.coherence[k] > 0.99 {
                    let h = analytic(&e, &modes, &c, &pair, f);
                    worst = worst.max((r.h1[k] - h).norm() / h.norm());
                    n += 1;
                }
            }
            println!(
                "{} {}: worst {:.3} % over {n} bins",
                e.test,
                r.channel.name,
                100.0 * worst
            );
            assert!(
                n > 500 && worst < 5e-3,
                "{} {}: {worst} over {n}",
                e.test,
                r.channel.name
            );
        }
    }
}

/// Largest relative error for which the first-order (Bendat & Piersol) error of `|H1|` is
/// used: the linearisation behind it holds for small errors (their rule: below about 0.2).
const EPS_MAX: f64 = 0.1;

/// With the configured noise: the campaign written to disk reads back to the simulated
/// one, and at the selected resonance bins `|H1|` departs from the analytic `|H|` by the
/// estimator's stated error: `z = (|H1| - |H|) / (|H| eps)`, `eps` the Bendat & Piersol
/// relative standard deviation the posterior uses (where it is at most [`EPS_MAX`]), has an
/// rms within a factor 2 of 1
/// (the bound allows the 1.2-1.5x under-statement reported in issue 13, item 7), and
/// under 1 % of the points have |z| > 5 (a Gaussian gives 6e-7).
#[test]
fn noisy_campaign_reads_back_and_h1_is_within_the_estimator_error() {
    let sim = Simulator::new(sim_model()).unwrap();
    let (modes, c) = true_modes(&sim);
    let seed = sim.model().seed.unwrap();
    let simulated = sim.run(seed, &|_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("ten-story");
    write_campaign(&simulated, &root).unwrap();
    let campaign = read_campaign(&root).unwrap();
    assert!(campaign.warnings.is_empty(), "{:?}", campaign.warnings);
    assert_eq!(campaign.nominal, simulated.nominal);
    assert_eq!(campaign.nominal.n_floors(), 10);
    for (a, b) in campaign.tests.iter().zip(&simulated.tests) {
        assert_eq!(
            (&a.kind, &a.channels, &a.data),
            (&b.kind, &b.channels, &b.data)
        );
    }
    let opts = EstimateOptions {
        freq_max_hz: Some(25.0),
        ..EstimateOptions::default()
    };
    let (mut sum_z2, mut n, mut n_far, mut n_skipped) = (0.0, 0usize, 0usize, 0usize);
    for e in estimate_campaign(&campaign, &opts).unwrap() {
        let eps = e.selected_rel_std();
        let mut i = 0;
        for r in &e.responses {
            let pair = r.pair(&e.input).unwrap();
            for &k in &e.selected {
                let h = analytic(&e, &modes, &c, &pair, e.freq_hz[k]).norm();
                let z = (r.h1[k].norm() - h) / (h * eps[i]);
                i += 1;
                if eps[i - 1] > EPS_MAX {
                    n_skipped += 1;
                    continue;
                }
                sum_z2 += z * z;
                n += 1;
                n_far += usize::from(z.abs() > 5.0);
            }
        }
    }
    let rms = (sum_z2 / n as f64).sqrt();
    println!(
        "ten-story noisy H1: rms z = {rms:.3} over {n} points with eps <= {EPS_MAX} \
         ({n_skipped} with larger eps skipped), {n_far} with |z| > 5"
    );
    assert!(n >= 200, "{n} selected points");
    assert!((0.5..=2.0).contains(&rms), "rms z = {rms}");
    assert!(n_far * 100 <= n, "{n_far} of {n} points beyond 5 sd");
}
