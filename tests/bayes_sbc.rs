//! Simulation-based calibration (Talts et al. 2018) of the FRF posterior and its sampler
//! on the small 4-DOF problem of `frfbayes::bayes::sbc::small_problem` (k1, k2, k3,
//! Rayleigh a0 and the noise scale free).
//!
//! Each replication draws parameters from the prior, simulates magnitudes from the
//! likelihood, finds the start and samples exactly as `frfbayes sample` does, and ranks
//! the true value among the L = 80 walkers of the last step. Ranks are binned into 9
//! bins of 9 rank values and tested for uniformity with Pearson's chi-square (8 dof).
//! A coordinate fails when p < 0.001: with 5 coordinates the false-failure rate of a
//! calibrated sampler is below 0.5 %, and the seeds are fixed, so each test is
//! deterministic.
//!
//! Measured (seed 7, 1000 replications): with 200 steps per replication the noise
//! scale's ranks gave p = 0.0095 (the walkers had not forgotten the Laplace start in
//! that coordinate); with 600 steps every p was between 0.14 and 0.73. So the fast test
//! runs 400 steps and the thorough one 600.
//!
//! Thorough version (1000 replications x 3 settings, ~10 min on 2 cores):
//! `cargo test --release --test bayes_sbc -- --ignored`

use frfbayes::bayes::run::default_moves;
use frfbayes::bayes::sbc::{run_sbc, small_problem, SbcOptions, SbcResult};
use frfbayes::bayes::PriorKind;
use frfbayes::update::ResidualForm;
use std::time::Instant;

/// Significance level of each coordinate's rank test.
const ALPHA: f64 = 0.001;
/// Rank bins: 81 rank values (L = 80) in 9 bins of 9.
const BINS: usize = 9;

fn options(n_replications: usize, n_steps: u64, seed: u64) -> SbcOptions {
    SbcOptions {
        n_replications,
        n_walkers: 20,
        n_ensembles: 4,
        n_steps,
        n_starts: 8,
        ball_factor: 1.0,
        moves: default_moves(),
        seed,
    }
}

fn report(what: &str, r: &SbcResult) -> Vec<f64> {
    let tests = r.uniformity(BINS).unwrap();
    println!("{what}: acceptance {:.3}", r.mean_acceptance);
    for t in &tests {
        println!(
            "  {:<16} X2 {:6.2} (dof {}) p {:.4} counts {:?}",
            t.name, t.chi_square, t.dof, t.p_value, t.counts
        );
    }
    tests.iter().map(|t| t.p_value).collect()
}

fn check(what: &str, residual: ResidualForm, prior: PriorKind, opts: &SbcOptions) {
    let post = small_problem(residual, prior).unwrap();
    let t0 = Instant::now();
    let r = run_sbc(&post, opts).unwrap();
    println!("{what}: {:.1} s", t0.elapsed().as_secs_f64());
    let p = report(what, &r);
    assert_eq!(r.n_draws, 80);
    for (name, p) in r.names.iter().zip(&p) {
        assert!(
            *p > ALPHA,
            "{what}: ranks of {name} are not uniform (p = {p:.2e})"
        );
    }
}

#[test]
fn sbc_fast() {
    check(
        "magnitude residuals, uniform prior, 100 replications x 400 steps",
        ResidualForm::Magnitude,
        PriorKind::Uniform,
        &options(100, 400, 2024),
    );
}

/// The test has power: walkers left in a ball of 0.3 Laplace standard deviations
/// without sampling (an under-dispersed "posterior") make the ranks pile up at both
/// ends, and the chi-square test rejects by far.
#[test]
fn sbc_detects_an_underdispersed_posterior() {
    let post = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    let mut opts = options(100, 0, 2024);
    opts.ball_factor = 0.3;
    let r = run_sbc(&post, &opts).unwrap();
    let p = report("ball of 0.3 sd, no sampling", &r);
    for (name, p) in r.names.iter().zip(&p).take(4) {
        assert!(*p < 1e-6, "{name}: p = {p:.2e}, the test should reject");
    }
}

#[test]
#[ignore = "thorough SBC, ~10 min on 2 cores"]
fn sbc_thorough() {
    for (what, residual, prior) in [
        (
            "magnitude, uniform",
            ResidualForm::Magnitude,
            PriorKind::Uniform,
        ),
        (
            "log-magnitude, uniform",
            ResidualForm::LogMagnitude,
            PriorKind::Uniform,
        ),
        (
            "magnitude, lognormal (cv 0.1, damping ln-sd 1)",
            ResidualForm::Magnitude,
            PriorKind::LogNormal {
                cv: 0.1,
                damping_ln_sd: 1.0,
            },
        ),
    ] {
        check(what, residual, prior, &options(1000, 600, 7));
    }
}
