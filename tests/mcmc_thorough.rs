//! Thorough (slow, ignored) checks:
//! `cargo test --release --test mcmc_thorough -- --ignored --nocapture`.

mod mcmc_support;

use frfbayes::mcmc::{
    Ball, Burn, Complement, Move, Moves, Sampler, SamplerConfig, Snooker, Start, Stretch,
};
use mcmc_support::{check_gaussian_moments, z_score, Gaussian};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

fn good_start(target: &Gaussian) -> Start {
    let d = target.mean.len();
    Start::Ball(Ball {
        center: target.mean.clone(),
        scale: (0..d).map(|i| 0.1 * target.cov[(i, i)].sqrt()).collect(),
    })
}

#[test]
#[ignore = "thorough: 100 replicate runs (~1 min)"]
fn ess_based_standard_errors_match_replicate_spread() {
    // R independent runs; for E[x_0] and E[(x_9 - mu_9)^2] compare the spread of the
    // estimates over runs with the root-mean-square ESS-based standard error. The
    // sample sd of R normal estimates has relative sd ~ 1/sqrt(2(R-1)) = 7% for R = 100,
    // so the ratio must lie within 1 +- 0.28 (4 sd) if the ESS is right.
    let target = Gaussian::correlated(10);
    let reps = 100;
    let mut est = [vec![], vec![]];
    let mut se2 = [0.0, 0.0];
    let mut zs = vec![];
    for r in 0..reps {
        let mut config = SamplerConfig::new(32, 1000 + r);
        config.max_steps = 3000;
        config.check_every = 1000;
        let mut s = Sampler::new(&target, Moves::default(), config, good_start(&target)).unwrap();
        s.run(None).unwrap();
        let draws = s.draws(Burn::Auto).unwrap();
        let (mu0, mu9, v9) = (target.mean[0], target.mean[9], target.cov[(9, 9)]);
        for (k, (z, e)) in [
            {
                let (z, e, _) = z_score(&draws, |x| x[0], mu0);
                (z, e)
            },
            {
                let (z, e, _) = z_score(&draws, |x| (x[9] - mu9).powi(2), v9);
                (z, e)
            },
        ]
        .into_iter()
        .enumerate()
        {
            let truth = if k == 0 { mu0 } else { v9 };
            est[k].push(e);
            se2[k] += ((e - truth) / z).powi(2) / reps as f64;
            zs.push(z);
        }
    }
    for k in 0..2 {
        let m = est[k].iter().sum::<f64>() / reps as f64;
        let sd = (est[k].iter().map(|e| (e - m).powi(2)).sum::<f64>() / (reps as f64 - 1.0)).sqrt();
        let ratio = sd / se2[k].sqrt();
        println!(
            "quantity {k}: replicate sd {sd:.3e}, ESS-based se {:.3e}, ratio {ratio:.3}",
            se2[k].sqrt()
        );
        assert!((ratio - 1.0).abs() < 0.28, "ratio {ratio}");
    }
    let beyond2 = zs.iter().filter(|z| z.abs() > 2.0).count();
    println!("|z| > 2 in {beyond2} of {} (expect ~4.6%)", zs.len());
}

#[test]
#[ignore = "thorough: stretch move on the correlated 10-D Gaussian for 5 seeds (~30 s)"]
fn stretch_gaussian_moments_for_several_seeds() {
    let target = Gaussian::correlated(10);
    for seed in 0..5 {
        let mut config = SamplerConfig::new(40, 500 + seed);
        config.max_steps = 40_000;
        config.check_every = 500;
        let mut s = Sampler::new(&target, Moves::default(), config, good_start(&target)).unwrap();
        let summary = s.run(None).unwrap();
        let draws = s.draws(Burn::Auto).unwrap();
        let (worst, ess) = check_gaussian_moments(&draws, &target, &format!("seed {seed}"));
        println!(
            "seed {seed}: {} after {} steps, worst |z| {worst:.2}, min ESS {ess:.0}",
            summary.stopped_because, summary.steps
        );
    }
}

/// emcee 3.1's `DESnookerMove` as written (direction `delta / sqrt(|delta|)`, factor
/// `(d-1)/2 ln(|q - z| / |x - z|)`), to document why [`Snooker`] follows the paper.
struct EmceeSnooker;

impl Move for EmceeSnooker {
    fn name(&self) -> String {
        "emcee-snooker".into()
    }
    fn min_complement(&self) -> usize {
        3
    }
    fn propose(&self, x: &[f64], c: &Complement<'_>, rng: &mut ChaCha8Rng, q: &mut [f64]) -> f64 {
        let n = c.len();
        let mut idx = [0usize; 3];
        for k in 0..3 {
            loop {
                let i = rng.random_range(0..n);
                if !idx[..k].contains(&i) {
                    idx[k] = i;
                    break;
                }
            }
        }
        let (z, z1, z2) = (c.get(idx[0]), c.get(idx[1]), c.get(idx[2]));
        let norm = x
            .iter()
            .zip(z)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let u: Vec<f64> = x
            .iter()
            .zip(z)
            .map(|(a, b)| (a - b) / norm.sqrt())
            .collect();
        let proj: f64 = (0..x.len()).map(|i| u[i] * (z1[i] - z2[i])).sum();
        for i in 0..x.len() {
            q[i] = x[i] + u[i] * 1.7 * proj;
        }
        let qn = q
            .iter()
            .zip(z)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        0.5 * (x.len() as f64 - 1.0) * (qn.ln() - norm.ln())
    }
}

#[test]
#[ignore = "experiment: emcee's snooker variant vs the paper's on a 10-D Gaussian (~20 s)"]
fn emcee_snooker_variant_compared_with_the_papers() {
    // Standard normal in 10-D. The paper's snooker must give unit variances (|z| < 4);
    // emcee's variant gives ~0.62 (z ~ -50). emcee 3.1.6 itself, run on the same target
    // (32 walkers, 8000 steps), gave variances 0.58-0.66 and acceptance 0.160, as this
    // reproduction does; its StretchMove gave 0.94-1.03.
    let target = Gaussian::new(vec![0.0; 10], nalgebra::DMatrix::identity(10, 10));
    for (label, moves) in [
        ("paper snooker", Moves::single(Snooker::default())),
        ("emcee snooker", Moves::single(EmceeSnooker)),
        ("stretch", Moves::single(Stretch::default())),
    ] {
        let mut config = SamplerConfig::new(32, 99);
        config.max_steps = 20_000;
        config.check_every = 1000;
        let mut s = Sampler::new(&target, moves, config, good_start(&target)).unwrap();
        let summary = s.run(None).unwrap();
        let draws = s.draws(Burn::Auto).unwrap();
        let z_var: Vec<f64> = (0..10)
            .map(|i| z_score(&draws, |x| x[i] * x[i], 1.0).0)
            .collect();
        let mean_var: f64 = (0..10)
            .map(|i| z_score(&draws, |x| x[i] * x[i], 1.0).1)
            .sum::<f64>()
            / 10.0;
        println!(
            "{label}: {} steps, acceptance {:.3}, mean of the 10 variances {mean_var:.4} (truth 1), \
             variance z-scores {:?}",
            summary.steps,
            summary.acceptance,
            z_var.iter().map(|z| (z * 10.0).round() / 10.0).collect::<Vec<_>>()
        );
        if label == "emcee snooker" {
            assert!(mean_var < 0.8, "emcee's variant unexpectedly unbiased");
        } else {
            assert!(z_var.iter().all(|z| z.abs() < 4.0), "{label}: {z_var:?}");
        }
    }
}
