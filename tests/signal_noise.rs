//! Calibration of the coherence estimates: with `n = n_averages` and the reported
//! coherence, the Bendat & Piersol relative error `sqrt((1 - g^2) / (2 g^2 n))` must match
//! the actual scatter of `|H1|` over independent noise realisations.

mod signal_common;

use frfbayes::frf::Excitation;
use frfbayes::io::Test;
use frfbayes::signal::{
    bendat_piersol_rel_std, estimate_test, CoherenceMethod, EstimateOptions, HammerEstimator,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use signal_common::*;

const FS: f64 = 500.0;
const XI: [f64; 4] = [0.01, 0.005, 0.005, 0.002];

/// Adds white noise of the given standard deviation to every channel (by quantity).
fn noisy(test: &Test, sd: &dyn Fn(frfbayes::io::Quantity) -> f64, seed: u64) -> Test {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = test.clone();
    for (ch, d) in t.channels.iter().zip(t.data.iter_mut()) {
        let nd = Normal::new(0.0, sd(ch.quantity)).unwrap();
        d.iter_mut().for_each(|v| *v += nd.sample(&mut rng));
    }
    t
}

/// Sensor noise of the order of the shared campaign's (quiet-segment rms).
fn sensor_sd(q: frfbayes::io::Quantity) -> f64 {
    use frfbayes::io::Quantity::*;
    match q {
        Force => 0.02,
        GroundAcceleration | Acceleration => 0.005,
        Displacement => 2e-6,
    }
}

/// Mean of `z^2 = ((|H1| - |H1_clean|) / (|H1| s_pred))^2` per coherence class (lower
/// bound of the class, mean z^2, count), over realisations, responses and bins in 0.5-7 Hz,
/// and the estimates' `coherence_dof`.
/// `s_pred |H1|` is the absolute standard deviation a consumer derives from the measured
/// magnitude (relative to the noise-free `|H|` the ratio is ill-defined at antiresonances).
fn calibration(
    clean: &Test,
    opts: &EstimateOptions,
    n_real: u64,
) -> (Vec<(f64, f64, usize)>, usize) {
    let reference = estimate_test(clean, opts).unwrap();
    let classes = [(0.0, 0.5), (0.5, 0.9), (0.9, 0.99), (0.99, 1.01)];
    let mut acc = vec![(0.0, 0usize); classes.len()];
    for seed in 0..n_real {
        let est = estimate_test(&noisy(clean, &sensor_sd, 100 + seed), opts).unwrap();
        for (r, r0) in est.responses.iter().zip(&reference.responses) {
            for (k, &f) in est.freq_hz.iter().enumerate() {
                if !(0.5..=7.0).contains(&f) {
                    continue;
                }
                let g = r.coherence[k];
                let s = bendat_piersol_rel_std(g, est.n_averages);
                let z = (r.h1[k].norm() - r0.h1[k].norm()) / (r.h1[k].norm() * s);
                if let Some(c) = classes.iter().position(|&(lo, hi)| g >= lo && g < hi) {
                    acc[c].0 += z * z;
                    acc[c].1 += 1;
                }
            }
        }
    }
    let classes = classes
        .iter()
        .zip(acc)
        .map(|(&(lo, _), (s, n))| (lo, s / n.max(1) as f64, n))
        .collect();
    (classes, reference.coherence_dof)
}

/// Statistical and systematic allowances of the calibration tests: with `dof` complex
/// degrees of freedom, `E[sigma^2 / sigma_hat^2] = dof / (dof - 1)` inflates `E[z^2]` by
/// 8 % (K = 2, dof 14) to 25 % (K = 1, dof 5) even when `sigma_hat^2` is unbiased, so the
/// accepted range is `Z2_RANGE` times `dof / (dof - 1)` (the estimate's `coherence_dof`);
/// model errors that are not noise (local-model misfit, with impact blocks the previous
/// impact's ring-down in block 2) raise the estimated noise and lower `E[z^2]`. Measured (4
/// realisations, seeds 100-103): hammer, whole record (dof 5, range 0.62..1.88): 1.51
/// (gamma^2 >= 0.99, 22 361 bins), 1.28 (0.9-0.99), 1.20 (0.5-0.9); hammer, impact blocks:
/// 0.50 (gamma^2 >= 0.99); shake table 0.91 (>= 0.99). Accepted: 0.5..1.5 after the
/// `dof / (dof - 1)` factor, i.e. the predicted standard deviation is right within about
/// -30 %..+20 %; the ordinary two-block coherence gives 7.7 at gamma^2 >= 0.99 (scatter
/// underpredicted 2.8x) and is shown to be far outside.
const Z2_RANGE: (f64, f64) = (0.5, 1.5);

fn check((classes, dof): &(Vec<(f64, f64, usize)>, usize), what: &str) {
    let d = *dof as f64;
    assert!(d > 1.0, "{what}: {dof} degrees of freedom");
    let (lo_z2, hi_z2) = (Z2_RANGE.0 * d / (d - 1.0), Z2_RANGE.1 * d / (d - 1.0));
    println!(
        "{what}: dof {dof}, accepted {lo_z2:.2}..{hi_z2:.2}; (class, mean z^2, count) {classes:?}"
    );
    for &(lo, z2, n) in classes {
        if lo >= 0.5 && n >= 20 {
            assert!(
                z2 >= lo_z2 && z2 <= hi_z2,
                "{what}: coherence class {lo}: mean z^2 {z2} over {n}"
            );
        }
    }
}

#[test]
fn hammer_coherence_predicts_the_scatter_of_h1() {
    let (modes, c) = frame(&XI);
    let mut f = vec![0.0; 60_000];
    add_pulse(&mut f, 1000, 4, 40.0);
    add_pulse(&mut f, 31_000, 4, 40.0);
    let (disp, acc) = simulate(&modes, &c, Excitation::Dof(1), &f, 1.0 / FS);
    let clean = hammer_test("h", 2, FS, f, disp, acc);
    let opts = EstimateOptions::default();
    check(
        &calibration(&clean, &opts, 4),
        "hammer, whole record, local rational",
    );
    let mut blocks = opts;
    blocks.hammer.estimator = HammerEstimator::ImpactBlocks;
    // the ordinary coherence of 2 blocks is biased high: it underpredicts the scatter
    let ordinary = EstimateOptions {
        coherence: CoherenceMethod::Ordinary,
        ..blocks
    };
    let (cls, _) = calibration(&clean, &ordinary, 4);
    println!("hammer, ordinary coherence: {cls:?}");
    let (z2, n) = cls
        .iter()
        .filter(|c| c.0 >= 0.5)
        .fold((0.0, 0), |(s, n), c| (s + c.1 * c.2 as f64, n + c.2));
    assert!(z2 / n as f64 > 3.0 * Z2_RANGE.1, "{}", z2 / n as f64);
}

#[test]
fn shake_table_coherence_predicts_the_scatter_of_h1() {
    let (modes, c) = frame(&XI);
    let ag = chirp(FS, 60.0, 10.0, 130.0, 1.0);
    let (disp, acc) = simulate(&modes, &c, Excitation::Ground, &ag, 1.0 / FS);
    let clean = shake_test("s", FS, ag, disp, acc);
    check(
        &calibration(&clean, &EstimateOptions::default(), 4),
        "shake table",
    );
}
