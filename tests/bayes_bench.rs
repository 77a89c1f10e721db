//! Speed of the FRF posterior and of `frfbayes sample`'s sampler on the bundled
//! four-story campaign (hammer tests, Caughey damping, receptance), the Rust half of
//! `benches/emcee_vs_rust.py` (ignored; prints figures, asserts only correctness):
//!
//! ```sh
//! FRFBAYES_BENCH_OUT=/tmp/bench cargo test --release --test bayes_bench -- --ignored --nocapture
//! ```
//!
//! 1. samples the posterior to the convergence criterion in a rayon pool of 1 thread and
//!    of 2 threads (wall and CPU time; the two runs must give bit-identical draws);
//! 2. times single-thread log-posterior evaluations at posterior draws (per-core
//!    throughput, no sampler);
//! 3. writes into `$FRFBAYES_BENCH_OUT` (default: a folder in the system temp dir)
//!    `problem.json` (everything a reimplementation needs: model matrices, variable
//!    layout, FRF blocks, windows, data, sigmas, prior box, the initial walkers of the
//!    first ensemble, and the Rust log posterior at check points), `rust.json` (the
//!    figures) and `rust_draws.npy` (kept draws in sampled coordinates, `(chain, draw,
//!    parameter)`, chains ensemble-major).

use frfbayes::bayes::run::{prepare, sample_posterior, SampleSettings, TestSelection};
use frfbayes::bayes::{ball_positions, FrfPosterior};
use frfbayes::frf::{Excitation, FrfKind};
use frfbayes::mcmc::LogDensity;
use frfbayes::update::{DampingModel, ResidualForm, Scale};
use nalgebra::DMatrix;
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// CPU time (user + system) of this process in seconds, from /proc (Linux; 100 Hz
/// ticks); NaN elsewhere. The machine is shared, so CPU time, not wall time, measures
/// the work done.
fn cpu_seconds() -> f64 {
    proc_cpu_seconds("/proc/self/stat")
}

/// CPU time of the calling thread, s.
fn thread_cpu_seconds() -> f64 {
    proc_cpu_seconds("/proc/thread-self/stat")
}

fn proc_cpu_seconds(path: &str) -> f64 {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|s| {
            let rest = &s[s.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f[11].parse::<f64>().ok()? + f[12].parse::<f64>().ok()?) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

fn matrix(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

/// Everything `benches/emcee_vs_rust.py` needs to rebuild the log posterior.
fn problem_json(
    post: &FrfPosterior,
    walkers: &[Vec<f64>],
    checks: &[Vec<f64>],
) -> serde_json::Value {
    let model = post.model();
    let vars = post.variables();
    let data = post.data();
    let blocks: Vec<serde_json::Value> = data
        .blocks
        .iter()
        .zip(data.window_tau_s.iter().copied())
        .map(|(b, tau)| {
            json!({
                "omega_rad_s": b.omega_rad_s,
                "window_tau_s": tau,
                "pairs": b.pairs.iter().map(|p| json!({
                    "response": p.response,
                    // -1: ground excitation.
                    "excitation": match p.excitation { Excitation::Dof(e) => e as i64, Excitation::Ground => -1 },
                    "power": p.kind.power(),
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    let check_values: Vec<f64> = checks.iter().map(|z| post.ln_density(z).unwrap()).collect();
    json!({
        "format": "frfbayes-posterior/1",
        "names": post.names(),
        "k0": matrix(&model.stiffness(&model.alpha_zero())),
        "m0": matrix(&model.mass(&model.beta_zero())),
        "k_influence": model.stiffness_influence().iter().map(matrix).collect::<Vec<_>>(),
        "m_influence": model.mass_influence().iter().map(matrix).collect::<Vec<_>>(),
        "ground_influence": model.ground_influence().iter().copied().collect::<Vec<_>>(),
        "n_modes": post.n_modes(),
        "damping": match vars.damping_model() { DampingModel::Rayleigh => "rayleigh", DampingModel::Caughey => "caughey" },
        "n_alpha": vars.n_alpha(),
        "n_beta": vars.n_beta(),
        "theta_initial": vars.initial(),
        "free": vars.free(),
        "log_scale": vars.free().iter().map(|&i| vars.variables()[i].scale == Scale::Log).collect::<Vec<_>>(),
        "blocks": blocks,
        "residual": match data.residual { ResidualForm::Magnitude => "magnitude", ResidualForm::LogMagnitude => "log_magnitude" },
        "magnitude": data.magnitude,
        "sigma": data.sigma,
        "prior": "uniform",
        "prior_lower": post.prior().lower(),
        "prior_upper": post.prior().upper(),
        "initial_walkers": walkers,
        "check_points": checks,
        "check_ln_posterior": check_values,
    })
}

#[test]
#[ignore = "speed measurement, ~1 min"]
fn posterior_speed_threads_and_export() {
    let out = std::env::var_os("FRFBAYES_BENCH_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("frfbayes_bench"));
    std::fs::create_dir_all(&out).unwrap();
    let mut settings = SampleSettings::new(
        "bundled:four-story".into(),
        DampingModel::Caughey,
        FrfKind::Receptance,
        TestSelection::Hammer,
        1,
    )
    .unwrap();
    // The noise model `benches/emcee_vs_rust.py` reimplements (and the speed history was
    // measured on): neighbouring bins independent, each bin's own noise estimate, bins
    // selected on the estimates; not `sample`'s defaults since 2026-12-02 (the phase
    // chain, pooled noise, two-stage bands), whose cost is in the README's Speed table.
    settings.bin_correlation = frfbayes::bayes::BinCorrelation::Independent;
    settings.noise_pool_bins = 0;
    settings.band_selection = frfbayes::bayes::BandSelection::Measured;
    // Experiments: another move mixture (TOML `[[moves]]` tables) or walker count.
    if let Ok(text) = std::env::var("FRFBAYES_BENCH_MOVES") {
        #[derive(serde::Deserialize)]
        struct File {
            moves: Vec<frfbayes::mcmc::WeightedMove>,
        }
        settings.moves = toml::from_str::<File>(&text).unwrap().moves;
    }
    if let Ok(w) = std::env::var("FRFBAYES_BENCH_WALKERS_PER_DIM") {
        settings.walkers_per_dim = w.parse().unwrap();
    }
    let moves = frfbayes::mcmc::Moves::from_specs(&settings.moves)
        .unwrap()
        .describe();
    println!(
        "moves: {moves}; {} walkers per dimension",
        settings.walkers_per_dim
    );
    let prep = prepare(&settings).unwrap();
    let post = &prep.posterior;

    // 1. Sampling on 1 and 2 threads.
    let mut runs = Vec::new();
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let (t, c) = (Instant::now(), cpu_seconds());
        let s = pool.install(|| sample_posterior(post, &settings)).unwrap();
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        let sm = &s.summary;
        println!(
            "{threads} thread(s): {} steps, {} evaluations, sampling {:.2} s ({:.0} evaluations/s), \
             whole call {wall:.2} s wall / {cpu:.2} s CPU, max R-hat {:.4}, min bulk ESS {:.0} ({:.0}/s), converged {}",
            sm.n_steps,
            sm.n_likelihood_evals,
            sm.wall_s,
            sm.n_likelihood_evals as f64 / sm.wall_s,
            sm.rhat_max,
            sm.ess_bulk_min,
            sm.ess_bulk_min / sm.wall_s,
            sm.converged
        );
        runs.push((threads, s, wall, cpu));
    }
    // The moves emcee also has (0.9 DE + 0.1 stretch, 4 x dim walkers), one thread: the
    // like-for-like comparison of `benches/emcee_vs_rust.py`.
    let mut same = settings.clone();
    same.moves = frfbayes::bayes::run::de_stretch_moves();
    same.walkers_per_dim = 4;
    let (t, c) = (Instant::now(), cpu_seconds());
    let same_run = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| sample_posterior(post, &same))
        .unwrap();
    let (same_wall, same_cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
    println!(
        "same moves as emcee (0.9 DE + 0.1 stretch, 4 x dim walkers), 1 thread: {} steps, \
         {same_cpu:.2} s CPU, min bulk ESS {:.0}",
        same_run.summary.n_steps, same_run.summary.ess_bulk_min
    );
    let (one, two) = (&runs[0].1, &runs[1].1);
    assert!(
        one.draws == two.draws && one.summary.parameters == two.summary.parameters,
        "1-thread and 2-thread runs differ"
    );
    let speedup = one.summary.wall_s / two.summary.wall_s;
    let cpu_ratio = runs[1].3 / runs[0].3;
    println!(
        "1 -> 2 threads: sampling wall-time speed-up {speedup:.2}x, CPU time x{cpu_ratio:.3} \
         (parallel overhead); draws bit-identical"
    );

    // 2. Per-core throughput at posterior draws, no sampler.
    let draws = &two.draws;
    let n_total = draws.n_chains * draws.n_draws;
    let stride = (n_total / 2000).max(1);
    let points: Vec<&[f64]> = (0..n_total)
        .step_by(stride)
        .map(|s| &draws.values[s * draws.dim..(s + 1) * draws.dim])
        .collect();
    // On this thread, serially (no rayon), for at least 3 s of CPU time.
    let (t, c) = (Instant::now(), thread_cpu_seconds());
    let mut n_evals = 0usize;
    let mut acc = 0.0;
    while thread_cpu_seconds() - c < 3.0 {
        for z in &points {
            acc += post.ln_density(z).unwrap();
        }
        n_evals += points.len();
    }
    assert!(acc.is_finite());
    let (wall, cpu) = (t.elapsed().as_secs_f64(), thread_cpu_seconds() - c);
    let per_core = n_evals as f64 / cpu;
    println!(
        "log posterior alone, 1 thread: {per_core:.0} evaluations per CPU second ({:.2} us each; \
         {:.0} per wall second), {} points",
        1e6 / per_core,
        n_evals as f64 / wall,
        post.data().len()
    );

    // 3. Export.
    // emcee starts from the first ensemble of the same-moves run.
    let start = &same_run.start;
    let walkers = ball_positions(
        post,
        start,
        same_run.summary.n_walkers,
        same.ball_factor,
        same.seed,
    )
    .unwrap();
    let mut checks = vec![start.z.clone(), walkers[0].clone()];
    checks.extend(points.iter().step_by(points.len() / 4).map(|z| z.to_vec()));
    let problem = problem_json(post, &walkers, &checks);
    std::fs::write(
        out.join("problem.json"),
        serde_json::to_vec(&problem).unwrap(),
    )
    .unwrap();
    two.draws.write_npy(&out.join("rust_draws.npy")).unwrap();
    same_run
        .draws
        .write_npy(&out.join("rust_draws_same_moves.npy"))
        .unwrap();
    let run_json =
        |(threads, s, wall, cpu): &(usize, frfbayes::bayes::run::PosteriorSample, f64, f64)| {
            let sm = &s.summary;
            json!({
                "threads": threads,
                "n_steps": sm.n_steps,
                "n_evaluations": sm.n_likelihood_evals,
                "sampling_wall_s": sm.wall_s,
                "call_wall_s": wall,
                "call_cpu_s": cpu,
                "evaluations_per_s": sm.n_likelihood_evals as f64 / sm.wall_s,
            // Whole call (start search included): a lower bound on the sampler's rate.
            "evaluations_per_cpu_s": sm.n_likelihood_evals as f64 / cpu,
                "rhat_max": sm.rhat_max,
                "ess_bulk_min": sm.ess_bulk_min,
                "converged": sm.converged,
                "acceptance": sm.acceptance,
                "tau_steps": sm.parameters.iter().map(|p| p.tau).collect::<Vec<_>>(),
            })
        };
    let rust = json!({
        "problem": "four-story hammer tests, Caughey damping, receptance",
        "dim": post.dim(),
        "n_points": post.data().len(),
        "n_walkers": two.summary.n_walkers,
        "n_ensembles": two.summary.n_ensembles,
        "moves": moves,
        "thin_by": settings.thin_by,
        "discarded_steps": two.draws.discarded_steps,
        "thin_steps": two.draws.thin_steps,
        "runs": runs.iter().map(run_json).collect::<Vec<_>>(),
        "speedup_1_to_2_threads": speedup,
        "cpu_time_ratio_2_to_1_threads": cpu_ratio,
        "draws_identical_1_and_2_threads": true,
        "ln_posterior_evals_per_cpu_s": per_core,
        "same_moves_run": {
            "moves": frfbayes::mcmc::Moves::from_specs(&same.moves).unwrap().describe(),
            "n_walkers": same_run.summary.n_walkers,
            "n_ensembles": same_run.summary.n_ensembles,
            "n_steps": same_run.summary.n_steps,
            "n_evaluations": same_run.summary.n_likelihood_evals,
            "discarded_steps": same_run.draws.discarded_steps,
            "call_wall_s": same_wall,
            "call_cpu_s": same_cpu,
            "ess_bulk_min": same_run.summary.ess_bulk_min,
            "tau_steps": same_run.summary.parameters.iter().map(|p| p.tau).collect::<Vec<_>>(),
        },
        "ln_posterior_evals_per_wall_s": n_evals as f64 / wall,
    });
    std::fs::write(
        out.join("rust.json"),
        serde_json::to_vec_pretty(&rust).unwrap(),
    )
    .unwrap();
    println!("wrote {}", out.display());
}
