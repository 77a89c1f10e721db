//! Reproducibility and robustness: bit-identical chains whatever the thread count,
//! checkpoints that resume bit-identically, pointwise log-likelihood storage, output
//! files, and clear errors for bad setups.

use std::ops::ControlFlow;
use std::path::Path;

use frfbayes::mcmc::{
    Ball, Burn, CheckpointConfig, DifferentialEvolution, Draws, Independence, LogDensity, Moves,
    Sampler, SamplerConfig, Snooker, Start, StopReason, Stretch, Walk, REPORT_EVERY_STEPS,
};
use frfbayes::{Error, Result};

/// Linear regression `y_i = a + b t_i + N(0, 0.5^2)` on 6 points (pointwise terms), two
/// more parameters with N(0,1) priors, the last one restricted to `> -3` (so `-inf`
/// occurs). Optionally returns NaN beyond `nan_above` in the first parameter.
struct Regression {
    nan_above: f64,
}

const T: [f64; 6] = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5];
const Y: [f64; 6] = [0.9, 1.7, 2.1, 2.9, 3.2, 4.1];

impl LogDensity for Regression {
    fn dim(&self) -> usize {
        4
    }
    fn ln_density(&self, theta: &[f64]) -> Result<f64> {
        let mut pw = [0.0; 6];
        self.ln_density_with_pointwise(theta, &mut pw)
    }
    fn n_pointwise(&self) -> usize {
        6
    }
    fn ln_density_with_pointwise(&self, theta: &[f64], pw: &mut [f64]) -> Result<f64> {
        if theta[0] > self.nan_above {
            return Ok(f64::NAN);
        }
        if theta[3] <= -3.0 {
            return Ok(f64::NEG_INFINITY);
        }
        let sigma: f64 = 0.5;
        let norm = -(sigma * (2.0 * std::f64::consts::PI).sqrt()).ln();
        for i in 0..6 {
            let r = (Y[i] - theta[0] - theta[1] * T[i]) / sigma;
            pw[i] = -0.5 * r * r + norm;
        }
        Ok(pw.iter().sum::<f64>() - 0.5 * (theta[2] * theta[2] + theta[3] * theta[3]))
    }
}

const OK_DENSITY: Regression = Regression {
    nan_above: f64::INFINITY,
};

fn moves() -> Moves {
    Moves::mixture(vec![
        (Box::new(Stretch::default()), 0.5),
        (Box::new(DifferentialEvolution::default()), 0.3),
        (Box::new(Snooker::default()), 0.2),
        // Fitted to the complement once per split: exercises `Move::for_complement`.
        (Box::new(Independence::default()), 0.2),
    ])
    .unwrap()
}

fn config(max_steps: u64) -> SamplerConfig {
    let mut c = SamplerConfig::new(12, 2718);
    c.max_steps = max_steps;
    c.check_every = 100;
    c.thin_by = 2;
    c.store_pointwise = true;
    c
}

fn start() -> Start {
    Start::Ball(Ball {
        center: vec![1.0, 1.0, 0.0, 0.0],
        scale: vec![0.1; 4],
    })
}

fn all_draws<D: LogDensity + ?Sized>(s: &Sampler<'_, D>) -> Draws {
    s.draws(Burn::Steps {
        discard: 0,
        thin: 1,
    })
    .unwrap()
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Runs `max_steps` in a rayon pool of `threads` threads and returns the checkpoint bytes.
fn run_in_pool(threads: usize, max_steps: u64, dir: &Path) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let path = dir.join(format!("t{threads}.ckpt"));
    pool.install(|| {
        let mut s = Sampler::new(&OK_DENSITY, moves(), config(max_steps), start()).unwrap();
        s.run(None).unwrap();
        s.save_checkpoint(&path).unwrap();
    });
    std::fs::read(&path).unwrap()
}

#[test]
fn chains_are_bit_identical_for_one_and_two_threads() {
    // The checkpoint holds everything: positions, log densities, pointwise terms, RNG
    // states, accept counts, the stored chain and the tau history.
    let dir = tempfile::tempdir().unwrap();
    let one = run_in_pool(1, 400, dir.path());
    let two = run_in_pool(2, 400, dir.path());
    assert!(one == two, "1-thread and 2-thread runs differ");
}

#[test]
fn resume_from_checkpoint_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let straight = dir.path().join("straight.ckpt");
    let mut a = Sampler::new(&OK_DENSITY, moves(), config(400), start()).unwrap();
    a.run(None).unwrap();
    a.save_checkpoint(&straight).unwrap();

    let half = dir.path().join("half.ckpt");
    let mut b = Sampler::new(&OK_DENSITY, moves(), config(200), start()).unwrap();
    assert_eq!(b.run(None).unwrap().stopped_because, StopReason::StepCap);
    b.save_checkpoint(&half).unwrap();
    drop(b);
    let mut c = Sampler::resume(&OK_DENSITY, moves(), &half).unwrap();
    assert_eq!(c.step_count(), 200);
    c.set_max_steps(400);
    c.run(None).unwrap();
    let resumed = dir.path().join("resumed.ckpt");
    c.save_checkpoint(&resumed).unwrap();
    assert!(
        std::fs::read(&straight).unwrap() == std::fs::read(&resumed).unwrap(),
        "resumed run differs from the straight run"
    );
    let (da, dc) = (all_draws(&a), all_draws(&c));
    assert_eq!(bits(&da.values), bits(&dc.values));
    assert_eq!(a.tau_history(), c.tau_history());
}

#[test]
fn interrupted_run_with_periodic_checkpoints_resumes_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = Sampler::new(&OK_DENSITY, moves(), config(400), start()).unwrap();
    a.run(None).unwrap();

    let path = dir.path().join("run.ckpt");
    let mut cfg = config(400);
    cfg.checkpoint = Some(CheckpointConfig {
        path: path.clone(),
        every_steps: 100,
    });
    let mut b = Sampler::new(&OK_DENSITY, moves(), cfg, start()).unwrap();
    // Reports come every REPORT_EVERY_STEPS steps (a divisor of 250 and of the checkpoint
    // interval), so a break is honoured exactly at step 250.
    assert_eq!(250 % REPORT_EVERY_STEPS, 0);
    let mut seen = 0;
    let mut stop_at_250 = |p: &frfbayes::mcmc::Progress| {
        seen += REPORT_EVERY_STEPS;
        assert_eq!(p.step, seen);
        assert_eq!(p.n_evaluations, 48 * (p.step + 1));
        if p.step == 250 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    let summary = b.run(Some(&mut stop_at_250)).unwrap();
    assert_eq!(summary.stopped_because, StopReason::Interrupted);
    assert_eq!(summary.steps, 250);
    drop(b);
    // The checkpoint written on interruption continues exactly.
    let mut c = Sampler::resume(&OK_DENSITY, moves(), &path).unwrap();
    assert_eq!(c.step_count(), 250);
    c.run(None).unwrap();
    let (da, dc) = (all_draws(&a), all_draws(&c));
    assert_eq!(bits(&da.values), bits(&dc.values));
    assert_eq!(bits(&da.ln_density), bits(&dc.ln_density));
    assert_eq!(bits(&da.pointwise), bits(&dc.pointwise));
    assert_eq!(a.positions(), c.positions());
    assert_eq!(a.acceptance_fractions(), c.acceptance_fractions());
    assert_eq!(a.tau_history(), c.tau_history());
}

#[test]
fn pointwise_terms_and_output_files() {
    let mut s = Sampler::new(&OK_DENSITY, moves(), config(300), start()).unwrap();
    s.run(None).unwrap();
    let draws = s
        .draws(Burn::Steps {
            discard: 100,
            thin: 10,
        })
        .unwrap();
    assert_eq!((draws.n_chains, draws.n_draws, draws.dim), (48, 20, 4));
    assert_eq!((draws.discarded_steps, draws.thin_steps), (100, 10));
    // Stored pointwise terms are those of the stored state, and sum with the prior to
    // the stored log density.
    for c in 0..draws.n_chains {
        for d in 0..draws.n_draws {
            let theta = draws.draw(c, d);
            let mut pw = [0.0; 6];
            let lp = OK_DENSITY
                .ln_density_with_pointwise(theta, &mut pw)
                .unwrap();
            let k = c * draws.n_draws + d;
            assert_eq!(lp.to_bits(), draws.ln_density[k].to_bits());
            assert_eq!(bits(&pw), bits(&draws.pointwise[k * 6..(k + 1) * 6]));
        }
    }
    let mut recomputed = draws.clone();
    recomputed.pointwise.clear();
    recomputed.compute_pointwise(&OK_DENSITY).unwrap();
    assert_eq!(bits(&recomputed.pointwise), bits(&draws.pointwise));

    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("draws.npy");
    draws.write_npy(&npy).unwrap();
    let back: ndarray::Array3<f64> = ndarray_npy::read_npy(&npy).unwrap();
    assert_eq!(back.shape(), &[48, 20, 4]);
    assert_eq!(back[[3, 7, 2]], draws.draw(3, 7)[2]);
    let pw = dir.path().join("log_likelihood.npy");
    draws.write_pointwise_npy(&pw).unwrap();
    let back: ndarray::Array3<f64> = ndarray_npy::read_npy(&pw).unwrap();
    assert_eq!(back.shape(), &[48, 20, 6]);
    assert_eq!(back[[5, 1, 4]], draws.pointwise[(5 * 20 + 1) * 6 + 4]);
    let lp = dir.path().join("ln_density.npy");
    draws.write_ln_density_npy(&lp).unwrap();
    let back: ndarray::Array2<f64> = ndarray_npy::read_npy(&lp).unwrap();
    assert_eq!(back.shape(), &[48, 20]);

    let csv = dir.path().join("draws.csv");
    let names: Vec<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
    draws.write_csv(&csv, &names).unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "chain,draw,a,b,c,d,ln_density");
    let first: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(&first[2..6], draws.draw(0, 0));
    assert_eq!(text.lines().count(), 1 + 48 * 20);
    assert!(draws.write_csv(&csv, &names[..3]).is_err());
}

fn usage_error(r: Result<impl Sized>) -> String {
    match r {
        Err(Error::Usage(m)) => m,
        Err(e) => panic!("expected a usage error, got {e}"),
        Ok(_) => panic!("expected a usage error"),
    }
}

#[test]
fn bad_setups_are_clear_errors() {
    let d = &OK_DENSITY;
    let mut c = config(10);
    c.n_walkers = 7;
    let m = usage_error(Sampler::new(d, moves(), c, start()));
    assert!(m.contains("at least 2 x 4 = 8 walkers"), "{m}");

    let mut c = config(10);
    c.n_ensembles = 3;
    assert!(usage_error(Sampler::new(d, moves(), c, start())).contains("at least 4"));

    let mut c = config(10);
    c.n_walkers = 8;
    let m = usage_error(Sampler::new(
        d,
        Moves::single(Walk { subset: Some(6) }),
        c,
        start(),
    ));
    assert!(m.contains("needs 6 complementary walkers"), "{m}");

    // Walkers on a line: rank 1.
    let line = |i: usize, second: f64| {
        let t = (i % 12) as f64 + 0.1 * (i / 12) as f64;
        vec![1.0 + 0.01 * t, second + 0.02 * t, 0.1 * t, -0.02 * t]
    };
    let on_line: Vec<Vec<f64>> = (0..48).map(|i| line(i, 1.0)).collect();
    let m = usage_error(Sampler::new(
        d,
        moves(),
        config(10),
        Start::Positions(on_line),
    ));
    assert!(m.contains("degenerate"), "{m}");
    let constant: Vec<Vec<f64>> = (0..48)
        .map(|i| {
            let mut p = line(i, 1.0);
            p[1] = 1.0;
            p
        })
        .collect();
    let m = usage_error(Sampler::new(
        d,
        moves(),
        config(10),
        Start::Positions(constant),
    ));
    assert!(m.contains("same value of parameter 1"), "{m}");

    let flat = Start::Ball(Ball {
        center: vec![1.0; 4],
        scale: vec![0.1, 0.0, 0.1, 0.1],
    });
    let m = usage_error(Sampler::new(d, moves(), config(10), flat));
    assert!(m.contains("scale of parameter 1"), "{m}");

    let outside = Start::Ball(Ball {
        center: vec![1.0, 1.0, 0.0, -3.0],
        scale: vec![0.1; 4],
    });
    let m = usage_error(Sampler::new(d, moves(), config(10), outside));
    assert!(m.contains("log density -inf"), "{m}");

    let balls = Start::Balls(vec![
        Ball {
            center: vec![0.0; 4],
            scale: vec![0.1; 4]
        };
        3
    ]);
    assert!(usage_error(Sampler::new(d, moves(), config(10), balls)).contains("3 initial balls"));
}

#[test]
fn nan_density_stops_the_run_with_a_numerical_error() {
    let d = Regression { nan_above: 1.3 };
    let mut s = Sampler::new(&d, moves(), config(500), start()).unwrap();
    match s.run(None) {
        Err(Error::Numerical(m)) => assert!(m.contains("NaN"), "{m}"),
        other => panic!("expected a numerical error, got {other:?}"),
    }
    assert!(usage_error(s.run(None)).contains("failed earlier"));
    let dir = tempfile::tempdir().unwrap();
    assert!(usage_error(s.save_checkpoint(&dir.path().join("x"))).contains("failed run"));
}

#[test]
fn resume_checks_moves_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.ckpt");
    let mut s = Sampler::new(&OK_DENSITY, moves(), config(20), start()).unwrap();
    s.run(None).unwrap();
    s.save_checkpoint(&path).unwrap();
    match Sampler::resume(&OK_DENSITY, Moves::default(), &path) {
        Err(Error::Invalid { what, .. }) => assert!(what.contains("moves"), "{what}"),
        _ => panic!("expected a moves mismatch"),
    }
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 8]).unwrap();
    match Sampler::resume(&OK_DENSITY, moves(), &path) {
        Err(Error::Invalid { what, .. }) => assert!(what.contains("truncated"), "{what}"),
        _ => panic!("expected a truncated-file error"),
    }
    std::fs::write(&path, b"not a checkpoint at all").unwrap();
    assert!(matches!(
        Sampler::resume(&OK_DENSITY, moves(), &path),
        Err(Error::Invalid { .. })
    ));
}
