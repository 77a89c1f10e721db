//! Seeded tests of the diagnostics against processes with known answers: the
//! integrated autocorrelation time of AR(1) chains, ESS of AR(1) and i.i.d. draws, and
//! R-hat on independent, shifted and over-dispersed chains.

use frfbayes::mcmc::{
    diagnostics, ensemble_diagnostics, ess_bulk, ess_mean, ess_tail, integrated_time, rhat,
    Diagnostics,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Stationary Gaussian AR(1): `x_t = rho x_{t-1} + sqrt(1 - rho^2) e_t`, `x_0 ~ N(0,1)`;
/// unit variance, autocorrelation `rho^k`, `tau = (1 + rho) / (1 - rho)`.
fn ar1(rho: f64, n: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut x: f64 = rng.sample(StandardNormal);
    let s = (1.0 - rho * rho).sqrt();
    (0..n)
        .map(|_| {
            let v = x;
            let e: f64 = rng.sample(StandardNormal);
            x = rho * x + s * e;
            v
        })
        .collect()
}

fn iid(mean: f64, sd: f64, n: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    (0..n)
        .map(|_| mean + sd * rng.sample::<f64, _>(StandardNormal))
        .collect()
}

#[test]
fn tau_of_ar1_chains_matches_theory() {
    // Sokal: for one series of length N with window M, var(tau_hat)/tau^2 ~ 2(2M+1)/N.
    // emcee averages the autocorrelation of W independent series, which divides that
    // variance by W. Tolerance: 4 standard deviations. The biases (truncation at M ~ 5
    // tau: 2 rho^(M+1)/(1-rho) < 1e-3; mean subtraction and the 1/N normalisation:
    // O(M tau / N) ~ 1%) are well inside it.
    let (w, n) = (32, 20_000);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for rho in [0.5, 0.9] {
        let series: Vec<Vec<f64>> = (0..w).map(|_| ar1(rho, n, &mut rng)).collect();
        let refs: Vec<&[f64]> = series.iter().map(|s| s.as_slice()).collect();
        let est = integrated_time(&refs, 5.0);
        let tau = (1.0 + rho) / (1.0 - rho);
        let m = est.window as f64;
        let sd = tau * (2.0 * (2.0 * m + 1.0) / (n * w) as f64).sqrt();
        println!(
            "rho {rho}: tau {tau} estimate {:.3} (window {m}, sd {sd:.3})",
            est.tau
        );
        assert!(est.window_found && est.is_reliable(n, 50.0));
        assert!(
            (est.tau - tau).abs() < 4.0 * sd,
            "rho {rho}: {} vs {tau}",
            est.tau
        );
    }
}

#[test]
fn tau_flags_a_too_short_chain() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let x = ar1(0.99, 200, &mut rng); // tau = 199 > N
    let est = integrated_time(&[&x[..]], 5.0);
    assert!(!est.is_reliable(200, 50.0));
}

#[test]
fn ess_of_ar1_matches_theory() {
    // M = 4 chains of N = 50 000, rho = 0.5: ESS = M N / tau with tau = 3. Geyer's
    // truncated estimator behaves like a windowed one with window max_t; for rho = 0.5
    // the autocorrelation drops below the noise level 1/sqrt(M N) ~ 2e-3 by lag 9 and the
    // positive-pair truncation stops within a few tens of lags, so with max_t <= 50,
    // sd(tau_hat)/tau <= sqrt(2 (2 * 50 + 1) / (M N)) = 3.2%; tolerance 4 sd = 12.7%.
    // Rank normalisation is monotone and maps a Gaussian AR(1) to (nearly) itself, so
    // bulk-ESS obeys the same bound.
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let chains: Vec<Vec<f64>> = (0..4).map(|_| ar1(0.5, 50_000, &mut rng)).collect();
    let expect = 200_000.0 / 3.0;
    for (name, ess) in [("mean", ess_mean(&chains)), ("bulk", ess_bulk(&chains))] {
        println!("ESS {name}: {ess:.0} vs {expect:.0}");
        assert!(
            (ess / expect - 1.0).abs() < 0.127,
            "{name}: {ess} vs {expect}"
        );
    }
}

#[test]
fn rhat_and_ess_on_independent_draws() {
    // 4 chains of 10 000 i.i.d. N(0,1). ESS ~ S = 40 000; Geyer's window stays at a few
    // lags (max_t <= 4), so sd(ESS)/S ~ sqrt(2 (2*4+1) / S) = 2.1%; tolerance 4 sd = 8.5%.
    // The tail indicators are i.i.d. Bernoulli, same bound.
    // R-hat: 8 split chains of n = 5000; R^2 ~ (n-1)/n + F/n, F ~ chi2_7/7, so
    // R - 1 ~ (F - 1)/(2n) < 3e-4 for F < 4 (its 0.01% quantile); assert R < 1.001.
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let chains: Vec<Vec<f64>> = (0..4).map(|_| iid(0.0, 1.0, 10_000, &mut rng)).collect();
    let d: Diagnostics = diagnostics(&chains);
    println!("{d:?}");
    let s = 40_000.0;
    assert!(
        d.rhat < 1.001 && d.rhat_bulk >= 0.999 && d.rhat_tail >= 0.999,
        "{d:?}"
    );
    for (name, ess) in [
        ("bulk", d.ess_bulk),
        ("tail", d.ess_tail),
        ("mean", ess_mean(&chains)),
    ] {
        assert!((ess / s - 1.0).abs() < 0.085, "{name} ESS {ess}");
    }
    assert_eq!(d.ess_tail, ess_tail(&chains));
}

#[test]
fn bulk_rhat_and_ess_are_invariant_under_monotone_maps() {
    // Rank normalisation: bulk statistics depend on ranks only.
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    let chains: Vec<Vec<f64>> = (0..4).map(|_| ar1(0.7, 1000, &mut rng)).collect();
    let mapped: Vec<Vec<f64>> = chains
        .iter()
        .map(|c| c.iter().map(|v| (2.0 * v).exp() + v * v * v).collect())
        .collect();
    let (a, b) = (diagnostics(&chains), diagnostics(&mapped));
    assert!((a.rhat_bulk - b.rhat_bulk).abs() < 1e-12);
    assert!((a.ess_bulk - b.ess_bulk).abs() < 1e-9 * a.ess_bulk);
}

#[test]
fn rhat_detects_shifted_and_overdispersed_chains() {
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    // One chain shifted by 3 sd. After rank normalisation it holds (almost) the top
    // quartile of normal scores: mean phi(0.674)/0.25 = 1.27, variance ~0.2; the others
    // have mean -0.42, variance ~0.6. Split-chain means (-0.42 x 6, 1.27 x 2) vary by
    // ~0.61 and W ~ 0.5, so R ~ sqrt(1 + 0.61/0.5) ~ 1.49; assert > 1.3.
    let mut chains: Vec<Vec<f64>> = (0..3).map(|_| iid(0.0, 1.0, 1000, &mut rng)).collect();
    chains.push(iid(3.0, 1.0, 1000, &mut rng));
    let r = rhat(&chains);
    println!("shifted: R-hat {r}");
    assert!(r > 1.3, "{r}");
    // One chain 3x wider, same centre: the bulk R-hat barely moves, the folded (tail)
    // R-hat catches it (E|x| is 0.80 vs 2.39).
    let mut chains: Vec<Vec<f64>> = (0..3).map(|_| iid(0.0, 1.0, 1000, &mut rng)).collect();
    chains.push(iid(0.0, 3.0, 1000, &mut rng));
    let d = diagnostics(&chains);
    println!("wide: {d:?}");
    assert!(d.rhat_bulk < 1.01 && d.rhat_tail > 1.1, "{d:?}");
}

#[test]
fn ensemble_rhat_flags_a_displaced_ensemble() {
    // 4 ensembles of 16 walker chains (i.i.d. N(0,1), 400 draws): R-hat with ensembles as
    // chains ~1 (8 split chains of 3200 draws: R - 1 < 1e-3). Shifting one ensemble by
    // 1 sd makes the split-ensemble means (0 x 6, 1 x 2) vary by ~0.21, B/W ~ 3200 * 0.21,
    // R ~ sqrt(1 + 0.21) ~ 1.1.
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let chains: Vec<Vec<f64>> = (0..64).map(|_| iid(0.0, 1.0, 400, &mut rng)).collect();
    let d = ensemble_diagnostics(&chains, 16);
    assert!(d.rhat < 1.001, "{d:?}");
    let shifted: Vec<Vec<f64>> = chains
        .iter()
        .enumerate()
        .map(|(i, c)| {
            c.iter()
                .map(|v| if i >= 48 { v + 1.0 } else { *v })
                .collect()
        })
        .collect();
    let d = ensemble_diagnostics(&shifted, 16);
    println!("displaced ensemble: {d:?}");
    assert!(d.rhat > 1.05, "{d:?}");
}
