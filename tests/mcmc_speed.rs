//! Speed measurements (ignored; they print figures, they do not assert timings):
//! `cargo test --release --test mcmc_speed -- --ignored --nocapture --test-threads 1`.

mod mcmc_support;

use std::hint::black_box;
use std::time::Instant;

use frfbayes::mcmc::{Ball, Burn, LogDensity, Moves, Sampler, SamplerConfig, Start};
use mcmc_support::Gaussian;

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

fn start(d: usize) -> Start {
    Start::Ball(Ball {
        center: vec![0.0; d],
        scale: vec![0.1; d],
    })
}

/// Standard normal: ~20 flops, so the time is the sampler's own overhead.
struct Trivial(usize);

impl LogDensity for Trivial {
    fn dim(&self) -> usize {
        self.0
    }
    fn ln_density(&self, x: &[f64]) -> frfbayes::Result<f64> {
        Ok(-0.5 * x.iter().map(|v| v * v).sum::<f64>())
    }
}

/// Standard normal plus ~`work` iterations of artificial cost per evaluation.
struct Expensive {
    d: usize,
    work: usize,
}

impl LogDensity for Expensive {
    fn dim(&self) -> usize {
        self.d
    }
    fn ln_density(&self, x: &[f64]) -> frfbayes::Result<f64> {
        let mut acc = 0.0f64;
        for i in 0..self.work {
            acc += black_box((i as f64 * 1e-3 + x[0]).sin());
        }
        Ok(-0.5 * x.iter().map(|v| v * v).sum::<f64>() + 1e-300 * acc)
    }
}

/// CPU time (user + system) of this process in seconds, from /proc (Linux; 100 Hz
/// ticks); NaN elsewhere.
fn cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = &s[s.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f[11].parse::<f64>().ok()? + f[12].parse::<f64>().ok()?) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

/// Evaluations per wall-clock second and per CPU second (the machine is shared, so the
/// second tells the parallel overhead apart from the cores actually obtained).
fn evals_per_second<D: LogDensity>(density: &D, threads: usize, steps: u64) -> (f64, f64) {
    pool(threads).install(|| {
        let mut config = SamplerConfig::new(32, 1);
        config.max_steps = steps;
        config.check_every = u64::MAX; // no tau checks: sampler overhead only
        let mut s = Sampler::new(density, Moves::default(), config, start(density.dim())).unwrap();
        let (t, c) = (Instant::now(), cpu_seconds());
        let summary = s.run(None).unwrap();
        let n = summary.n_evaluations as f64;
        (n / t.elapsed().as_secs_f64(), n / (cpu_seconds() - c))
    })
}

#[test]
#[ignore = "speed measurement"]
fn sampler_overhead_with_a_trivial_density() {
    let d = Trivial(10);
    for threads in [1, 2] {
        let (wall, cpu) = evals_per_second(&d, threads, 5000);
        println!(
            "trivial 10-D density, 4 x 32 walkers, {threads} thread(s): {:.2} M evaluations/s \
             ({:.2} M per CPU second)",
            wall / 1e6,
            cpu / 1e6
        );
    }
}

#[test]
#[ignore = "speed measurement"]
fn speed_up_with_an_expensive_density() {
    let d = Expensive { d: 10, work: 2000 };
    let t = Instant::now();
    for i in 0..1000 {
        black_box(d.ln_density(&[i as f64 * 1e-3; 10]).unwrap());
    }
    println!(
        "artificial density: {:.1} us per evaluation",
        t.elapsed().as_secs_f64() * 1e3
    );
    let one = evals_per_second(&d, 1, 400);
    let two = evals_per_second(&d, 2, 400);
    println!(
        "expensive density: 1 thread {:.0}/s ({:.0} per CPU s), 2 threads {:.0}/s ({:.0} per CPU s), \
         wall speed-up {:.2}",
        one.0,
        one.1,
        two.0,
        two.1,
        two.0 / one.0
    );
}

#[test]
#[ignore = "speed measurement"]
fn ess_per_second_on_the_correlated_gaussian() {
    let target = Gaussian::correlated(10);
    for threads in [1, 2] {
        pool(threads).install(|| {
            let mut config = SamplerConfig::new(32, 3);
            config.max_steps = 20_000;
            config.check_every = 500;
            let sd: Vec<f64> = (0..10).map(|i| target.cov[(i, i)].sqrt()).collect();
            let start = Start::Ball(Ball {
                center: target.mean.clone(),
                scale: sd.iter().map(|s| 0.1 * s).collect(),
            });
            let t = Instant::now();
            let mut s = Sampler::new(&target, Moves::default(), config, start).unwrap();
            let summary = s.run(None).unwrap();
            let draws = s.draws(Burn::Auto).unwrap();
            let secs = t.elapsed().as_secs_f64();
            let ess = draws
                .summary()
                .iter()
                .map(|p| p.diagnostics.ess_bulk)
                .fold(f64::INFINITY, f64::min);
            println!(
                "10-D Gaussian, {threads} thread(s): {} after {} steps in {secs:.2} s, min bulk-ESS {ess:.0} \
                 (of the kept half), {:.0} ESS/s",
                summary.stopped_because, summary.steps, ess / secs
            );
        });
    }
}

#[test]
#[ignore = "speed measurement"]
fn control_plain_rayon_job() {
    // What two threads can get on this machine right now: independent heavy tasks.
    use rayon::prelude::*;
    let d = Expensive { d: 10, work: 2000 };
    for threads in [1, 2] {
        pool(threads).install(|| {
            let (t, c) = (Instant::now(), cpu_seconds());
            let s: f64 = (0..40_000)
                .into_par_iter()
                .map(|i| d.ln_density(&[i as f64 * 1e-6; 10]).unwrap())
                .sum();
            black_box(s);
            let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
            println!(
                "control, {threads} thread(s): {:.0} evaluations/s, CPU/wall {:.2}",
                40_000.0 / wall,
                cpu / wall
            );
        });
    }
}
