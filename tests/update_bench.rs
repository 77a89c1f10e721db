//! Timing of the paper's eight updating variants ({Rayleigh, Caughey} x {receptance,
//! accelerance} x {hammer, shake table}) with 64 starts each on synthetic four-story
//! data. Run with
//! `cargo test --release --test update_bench -- --ignored --nocapture`.

mod update_common;

use frfbayes::frf::FrfKind;
use frfbayes::update::lsq::{LeastSquaresProblem, MultistartOptions};
use frfbayes::update::{update, DampingModel, ObjectiveOptions, VariablesConfig};
use nalgebra::DMatrix;
use std::time::Instant;
use update_common::*;

/// 4 bands x 100 points = 400 points per FRF (the top of the 100-400 range).
const POINTS_PER_BAND: usize = 100;
const N_STARTS: usize = 64;

#[test]
#[ignore = "timing run (about a minute on 2 cores); prints a table"]
fn eight_variants_timing() {
    let t_all = Instant::now();
    let mut total_eval = 0;
    let mut total_jac = 0;
    println!(
        "{:<8} {:<12} {:<9} {:>6} {:>8} {:>6} {:>6} {:>9} {:>10}",
        "test", "kind", "damping", "points", "time_s", "evals", "jacs", "at_best", "cost"
    );
    for test in [Test::Hammer, Test::Ground] {
        for kind in [FrfKind::Receptance, FrfKind::Accelerance] {
            for damping in [DampingModel::Rayleigh, DampingModel::Caughey] {
                let grid = half_power_grid(damping, POINTS_PER_BAND);
                let blocks = blocks(test, kind, &grid);
                let magnitude = true_magnitudes(damping, &blocks);
                // All variables free, as in the paper (ground data then have a ridge).
                let p = problem(
                    damping,
                    blocks,
                    magnitude,
                    None,
                    &VariablesConfig::default(),
                    ObjectiveOptions::default(),
                );
                let opts = MultistartOptions {
                    n_starts: N_STARTS,
                    seed: 1,
                    ..Default::default()
                };
                let t = Instant::now();
                let r = update(&p, &opts).unwrap();
                let dt = t.elapsed().as_secs_f64();
                let (ev, jc): (usize, usize) = r
                    .starts
                    .iter()
                    .filter_map(|s| s.fit.as_ref().ok())
                    .fold((0, 0), |(a, b), f| (a + f.n_evaluations, b + f.n_jacobians));
                total_eval += ev;
                total_jac += jc;
                println!(
                    "{:<8} {:<12} {:<9} {:>6} {:>8.3} {:>6} {:>6} {:>6}/{N_STARTS} {:>10.3e}",
                    format!("{test:?}"),
                    format!("{kind:?}"),
                    format!("{damping:?}"),
                    p.n_residuals(),
                    dt,
                    ev,
                    jc,
                    r.n_at_best,
                    r.best.cost
                );
            }
        }
    }
    let total = t_all.elapsed().as_secs_f64();
    println!("total {total:.2} s for 8 x {N_STARTS} starts: {total_eval} residual and {total_jac} Jacobian evaluations");

    // Single-thread throughput on the largest problem (hammer, 6400 points, Caughey).
    let damping = DampingModel::Caughey;
    let grid = half_power_grid(damping, POINTS_PER_BAND);
    let blocks = blocks(Test::Hammer, FrfKind::Receptance, &grid);
    let magnitude = true_magnitudes(damping, &blocks);
    let p = problem(
        damping,
        blocks,
        magnitude,
        None,
        &VariablesConfig::default(),
        ObjectiveOptions::default(),
    );
    let z = p.to_internal(&p.variables().initial());
    let mut ws = p.workspace();
    let mut r = vec![0.0; p.n_residuals()];
    let mut j = DMatrix::zeros(p.n_residuals(), p.n_params());
    let reps = 300;
    let t = Instant::now();
    for _ in 0..reps {
        p.residuals(&z, &mut ws, &mut r).unwrap();
    }
    let per_r = t.elapsed().as_secs_f64() / reps as f64;
    let t = Instant::now();
    for _ in 0..reps {
        p.jacobian(&z, &mut ws, &mut j).unwrap();
    }
    let per_j = t.elapsed().as_secs_f64() / reps as f64;
    println!(
        "one thread, {} points x {} variables: residuals {:.1} us ({:.0}/s), Jacobian {:.1} us ({:.0}/s)",
        p.n_residuals(),
        p.n_params(),
        per_r * 1e6,
        1.0 / per_r,
        per_j * 1e6,
        1.0 / per_j
    );
    assert!(
        total < 60.0,
        "eight variants took {total:.1} s (target < 60 s)"
    );
}
