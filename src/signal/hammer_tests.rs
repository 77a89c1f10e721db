//! Unit tests of [`super`]: the median, impact detection, impact blocks and the pretrigger.

use super::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn record(n: usize, hits: &[(usize, f64)], noise: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nd = Normal::new(0.0, noise).unwrap();
    let mut f: Vec<f64> = (0..n).map(|_| 0.3 + nd.sample(&mut rng)).collect();
    for &(i, a) in hits {
        f[i - 1] += 0.2 * a;
        f[i] += a;
        f[i + 1] += 0.3 * a;
    }
    f
}

#[test]
fn median_even_and_odd() {
    assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
    assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
    assert_eq!(median(&[]), 0.0);
}

#[test]
fn finds_impacts_ignores_double_hit_and_small_spike() {
    let fs = 500.0;
    // impacts at 1000 and 30000, double hit at 1100 (0.2 s later), small spike at 20000
    let f = record(
        60_000,
        &[(1000, 40.0), (1100, 8.0), (20_000, 2.0), (30_000, -35.0)],
        0.02,
        1,
    );
    let imp = detect_impacts(&f, fs, &HammerOptions::default());
    assert_eq!(imp.len(), 2, "{imp:?}");
    assert_eq!(imp[0].trigger, 999);
    assert_eq!(imp[0].peak, 1000);
    assert!(imp[0].pulse_end >= 1101);
    assert!((imp[0].peak_force_n - 40.0).abs() < 0.1);
    assert_eq!(imp[1].peak, 30_000);
    assert!((imp[1].peak_force_n + 35.0).abs() < 0.1);
    let blocks = impact_blocks(&imp, f.len(), fs, &HammerOptions::default()).unwrap();
    assert_eq!(blocks.starts, vec![999 - 50, 29_999 - 50]);
    assert_eq!(blocks.len, (29_999 - 50) - (999 - 50));
}

#[test]
fn late_short_impact_block_is_dropped_and_no_impact_is_an_error() {
    let fs = 500.0;
    let f = record(
        60_000,
        &[(1000, 40.0), (50_000, 40.0), (58_000, 40.0)],
        0.02,
        2,
    );
    let imp = detect_impacts(&f, fs, &HammerOptions::default());
    assert_eq!(imp.len(), 3);
    let blocks = impact_blocks(&imp, f.len(), fs, &HammerOptions::default()).unwrap();
    assert_eq!(blocks.impacts.len(), 2);
    assert_eq!(blocks.len, 8000);
    let quiet = vec![0.0; 1000];
    assert!(detect_impacts(&quiet, fs, &HammerOptions::default()).is_empty());
    let r: Vec<&[f64]> = vec![];
    assert!(hammer_spectra(&quiet, &r, fs, &HammerOptions::default(), 1).is_err());
}

#[test]
fn pretrigger_is_the_longer_of_its_seconds_and_its_samples() {
    let opts = HammerOptions::default();
    // 0.1 s: 50 samples at 500 Hz (unchanged by the floor), 6 at 60 Hz (floored to 32)
    assert_eq!(opts.pretrigger_samples(500.0), 50);
    assert_eq!(opts.pretrigger_samples(320.0), 32);
    assert_eq!(opts.pretrigger_samples(60.0), MIN_PRETRIGGER_SAMPLES);
    let seconds_only = HammerOptions {
        min_pretrigger_samples: 0,
        ..opts
    };
    assert_eq!(seconds_only.pretrigger_samples(60.0), 6);
}
