//! Adequacy on synthetic data: noise as stated passes; a misfit on one channel, or in one
//! test, fails there with its signature; a misfit below the cell tests' floor passes
//! unless a consistency check points at it.

use super::*;
use crate::discrepancy::consistency::{CheckDetails, Compared, NullDistribution, Verdict};
use crate::discrepancy::data::DiagnosisData;
use crate::discrepancy::tests::{base, synthetic};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::sync::Arc;

/// The synthetic layout with the model at `base()` as data, relative error `rel_err`
/// everywhere, times `1 + noise` (complex, `noise_sd` per component) and times
/// `factor(segment, channel, freq_hz)`.
fn data_with(
    rel_err: f64,
    noise_sd: f64,
    factor: impl Fn(&str, &str, f64) -> f64,
) -> (ModelPosterior, Vec<Complex64>) {
    let clean = synthetic();
    let post0 = ModelPosterior::new(clean.clone(), None).unwrap();
    let z = post0.z_of(&base(), 1e-3, &[]);
    let truth = post0.predict(&z).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let normal = Normal::new(0.0, noise_sd.max(1e-300)).unwrap();
    let mut data: DiagnosisData = (*clean).clone();
    let mut it = truth.iter();
    for seg in &mut data.segments {
        for ch in &mut seg.channels {
            for (j, h) in ch.h.iter_mut().enumerate() {
                let t = it.next().unwrap();
                let e = Complex64::new(normal.sample(&mut rng), normal.sample(&mut rng));
                let f = seg.freq_hz[ch.freq_index[j]];
                *h = t * (1.0 + e) * factor(&seg.name, &ch.channel.name, f);
            }
            ch.rel_err.iter_mut().for_each(|e| *e = rel_err);
        }
    }
    let post = ModelPosterior::new(Arc::new(data), None).unwrap();
    let pred = post.predict(&z).unwrap();
    (post, pred)
}

fn bands() -> Vec<(f64, f64)> {
    vec![(1.5, 2.0), (4.0, 5.0), (6.0, 7.5), (9.0, 11.0)]
}

#[test]
fn noise_as_stated_is_adequate() {
    // Noise 1 % per component, stated 1 %: chi2 per point 1 / (1 + 0.81) at the 0.9 %
    // floor, well inside every test.
    let (post, pred) = data_with(0.01, 0.01, |_, _, _| 1.0);
    let a = assess(&post, &pred, &bands(), Err("not run".into())).unwrap();
    assert!(a.adequate, "{a:?}");
    let expect = 1.0 / (1.0 + 0.81);
    assert!(
        (a.global.chi2_per_point - expect).abs() < 0.05,
        "{}",
        a.global.chi2_per_point
    );
    assert!(a.failed_cells.is_empty() && a.unexplained.is_none());
    assert_eq!(a.checks_unavailable.as_deref(), Some("not run"));
}

#[test]
fn one_channel_off_by_ten_percent_is_unexplained_there() {
    let (post, pred) = data_with(0.01, 0.01, |_, c, _| if c == "acc2" { 1.1 } else { 1.0 });
    let a = assess(&post, &pred, &bands(), Err("not run".into())).unwrap();
    assert!(!a.adequate);
    let u = a.unexplained.unwrap();
    assert_eq!(u.place.channels, vec!["acc2".to_string()]);
    assert_eq!(u.place.floor, Some(2));
    assert_eq!(u.place.quantity, Some(crate::io::Quantity::Acceleration));
    assert_eq!(u.place.tests.len(), 5, "{:?}", u.place.tests);
    assert!(
        u.signature[0].contains("+10.0 % in magnitude"),
        "{:?}",
        u.signature
    );
    assert!(
        u.signature
            .iter()
            .any(|s| s.starts_with("one channel against its neighbours")),
        "{:?}",
        u.signature
    );
}

#[test]
fn one_test_off_is_a_change_between_tests() {
    let (post, pred) = data_with(0.01, 0.01, |s, _, _| if s == "h1" { 0.9 } else { 1.0 });
    let a = assess(&post, &pred, &bands(), Err("not run".into())).unwrap();
    assert!(a.global.failed);
    let u = a
        .unexplained
        .expect("a 10 % misfit in a fifth of the data fails");
    assert_eq!(u.place.tests, vec!["h1".to_string()]);
    assert_eq!(u.place.channels.len(), 8);
    assert!(
        u.signature[0].contains("-10.0 % in magnitude"),
        "{:?}",
        u.signature
    );
    assert!(
        u.signature
            .iter()
            .any(|s| s.starts_with("change between tests: 1 of the 5")),
        "{:?}",
        u.signature
    );
}

/// A misfit in one band of one test shows in the cells, but a global test over all the
/// data does not reject for it: cells locate, they do not decide.
#[test]
fn cells_locate_but_do_not_decide() {
    let (post, pred) = data_with(0.01, 0.01, |s, _, f| {
        if s == "h1" && (4.0..=5.0).contains(&f) {
            0.9
        } else {
            1.0
        }
    });
    let a = assess(&post, &pred, &bands(), Err("not run".into())).unwrap();
    assert!(a.adequate);
    assert!(!a.failed_cells.is_empty());
    assert!(a
        .failed_cells
        .iter()
        .all(|c| c.tests == vec!["h1".to_string()] && c.bands_hz == vec![(4.0, 5.0)]));
}

fn check(test: &str, channel: &str, band: (f64, f64)) -> ConsistencyReport {
    ConsistencyReport {
        level: 0.01,
        correction: "holm".into(),
        checks: vec![CheckResult {
            kind: CheckKind::Drift,
            name: format!("drift {test} {channel}"),
            compared: Compared {
                segments: vec![test.into()],
                channels: vec![channel.into()],
                bands_hz: vec![band],
            },
            statistic: 50.0,
            null: NullDistribution::ChiSquared { dof: 2 },
            p_value: 1e-11,
            p_adjusted: 1e-10,
            verdict: Verdict::Inconsistent,
            summary: "the pole moved".into(),
            details: CheckDetails::Modes { modes: Vec::new() },
        }],
        skipped: Vec::new(),
    }
}

#[test]
fn a_small_misfit_fails_only_where_a_check_points() {
    // Noise-free data with a stated 0.2 % error; disp3 of h3 is 0.8 % high in 3-6 Hz
    // (11 points): |0.008|^2 / (0.002^2 + 0.009^2) = 0.75 per point at the global floor
    // (passes); |0.008|^2 / (0.002^2 + 0.003^2) = 4.9 per point at the checks' floor,
    // 54 on 22 dof where a check points (p = 1.5e-4): it fails.
    let (post, pred) = data_with(0.002, 0.0, |s, c, f| {
        if s == "h3" && c == "disp3" && (3.0..=6.0).contains(&f) {
            1.008
        } else {
            1.0
        }
    });
    let a = assess(&post, &pred, &bands(), Err("not run".into())).unwrap();
    assert!(a.adequate, "{:?}", a.failed_cells);
    let here = check("h3", "disp3", (3.0, 6.0));
    let a = assess(&post, &pred, &bands(), Ok(&here)).unwrap();
    assert!(!a.adequate);
    let u = a.unexplained.unwrap();
    assert_eq!(u.place.channels, vec!["disp3".to_string()]);
    assert!(
        u.signature
            .iter()
            .any(|s| s.contains("the structure changes between tests")),
        "{:?}",
        u.signature
    );
    // A check pointing where the model fits is explained by it.
    let elsewhere = check("h2-raw", "acc1", (6.0, 7.5));
    let a = assess(&post, &pred, &bands(), Ok(&elsewhere)).unwrap();
    assert!(a.adequate, "{:?}", a.checks);
    assert_eq!(a.checks.len(), 1);
    assert!(!a.checks[0].failed);
}
