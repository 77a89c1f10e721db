//! Unit tests of the posterior, its start and its summaries on the small SBC problem.

use super::sbc::small_problem;
use super::summary::stuck_walkers;
use super::*;
use crate::mcmc::{Draws, LogDensity};
use crate::update::{Measurements, MultistartOptions, ObjectiveOptions, Problem, ResidualForm};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn inside(post: &FrfPosterior) -> Vec<f64> {
    // k1, k2, k3, ln a0, ln s
    let z = vec![0.05, -0.08, 0.1, 0.25f64.ln(), 1.3f64.ln()];
    assert_eq!(z.len(), post.dim());
    z
}

/// Oracle: the Gaussian log-likelihood written out with magnitudes from
/// `update::Problem` (an independent path through the modal sums; no window here).
#[test]
fn log_density_is_the_stated_gaussian() {
    for residual in [ResidualForm::Magnitude, ResidualForm::LogMagnitude] {
        let post = small_problem(residual, PriorKind::Uniform).unwrap();
        let data = post.data();
        let z = inside(&post);
        let theta = post.theta(&z);
        let problem = Problem::new(
            post.model().clone(),
            Measurements {
                blocks: data.blocks.clone(),
                magnitude: data.magnitude.clone(),
                sigma: None,
            },
            post.variables().damping_model(),
            &crate::update::VariablesConfig::default(),
            ObjectiveOptions::default(),
        )
        .unwrap();
        let h = problem.magnitudes(&theta).unwrap();
        let s = 1.3;
        let expect: Vec<f64> = h
            .iter()
            .zip(&data.magnitude)
            .zip(&data.sigma)
            .map(|((&h, &y), &sigma)| {
                let sd = s * sigma;
                let (a, b, jac) = match residual {
                    ResidualForm::Magnitude => (h, y, 0.0),
                    ResidualForm::LogMagnitude => (h.ln(), y.ln(), -y.ln()),
                };
                -0.5 * ((a - b) / sd).powi(2) - sd.ln() - 0.5 * (2.0 * std::f64::consts::PI).ln()
                    + jac
            })
            .collect();
        let mut pw = vec![0.0; post.n_pointwise()];
        let lp = post.ln_density_with_pointwise(&z, &mut pw).unwrap();
        let total: f64 = expect.iter().sum();
        assert!(
            (lp - total).abs() < 1e-9 * total.abs(),
            "{residual:?}: {lp} vs {total}"
        );
        for (a, b) in pw.iter().zip(&expect) {
            assert!((a - b).abs() < 1e-9 * b.abs().max(1.0));
        }
        assert_eq!(post.ln_density(&z).unwrap(), lp);
        // ln L = sum of the pointwise terms; the uniform prior adds a constant 0.
        assert!((post.ln_likelihood(&z, &mut []).unwrap() - lp).abs() < 1e-9 * lp.abs());
    }
}

/// At two noise scales: the posterior's log-likelihood equals the dense Gaussian's
/// (1e-9 relative), its pointwise terms sum to it, and it is the same without them.
fn assert_dense_gaussian(post: &FrfPosterior, data: &FrfData, label: &str) {
    for s in [1.3, 0.4] {
        let mut z = inside(post);
        z[4] = f64::ln(s);
        let expect = dense_ln_likelihood(data, &post.magnitudes(&z).unwrap(), s);
        let mut pw = vec![0.0; data.len()];
        let ll = post.ln_likelihood(&z, &mut pw).unwrap();
        assert!(
            (ll - expect).abs() < 1e-9 * expect.abs(),
            "{label}, s {s}: {ll} vs {expect}"
        );
        let sum: f64 = pw.iter().sum();
        assert!(
            (sum - ll).abs() < 1e-9 * ll.abs(),
            "pointwise {sum} vs {ll}"
        );
        assert_eq!(post.ln_likelihood(&z, &mut []).unwrap(), ll);
    }
}

/// The dense Gaussian log density of `data` at model magnitudes `h` with covariance
/// `s^2 D^1/2 C D^1/2 + L L^T` (`D = diag(sigma^2)`, `C` the chain of
/// [`FrfData::bin_correlation`], the identity without it), by Cholesky (the oracle of
/// the Woodbury form and of the whitening).
fn dense_ln_likelihood(data: &FrfData, h: &[f64], s: f64) -> f64 {
    use nalgebra::{DMatrix, DVector};
    let n = data.len();
    let log = data.residual == ResidualForm::LogMagnitude;
    // s^2 D^1/2 C D^1/2, C_ij the product of the chain's rho between i and j
    let rho = &data.bin_correlation;
    let mut cov = DMatrix::from_fn(n, n, |i, j| {
        let (a, b) = (i.min(j), i.max(j));
        let c: f64 = (a + 1..=b)
            .map(|k| rho.get(k).copied().unwrap_or(0.0))
            .product();
        s * s * data.sigma[i] * data.sigma[j] * c
    });
    for c in &data.correlated {
        let l = DMatrix::from_row_slice(c.len, c.rank, &c.loadings);
        let mut sub = cov.view_mut((c.start, c.start), (c.len, c.len));
        sub += &l * l.transpose();
    }
    let r = DVector::from_iterator(
        n,
        h.iter()
            .zip(&data.magnitude)
            .map(|(&h, &y)| if log { h.ln() - y.ln() } else { h - y }),
    );
    let chol = cov.cholesky().unwrap();
    let quad = r.dot(&chol.solve(&r));
    let ln_det: f64 = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
    let jac: f64 = if log {
        -data.magnitude.iter().map(|y| y.ln()).sum::<f64>()
    } else {
        0.0
    };
    -0.5 * quad - 0.5 * ln_det - 0.5 * n as f64 * (2.0 * std::f64::consts::PI).ln() + jac
}

/// The shared noise (Woodbury form, ranks 2, 5 and 3 on runs of lengths not multiples
/// of four) against the dense Gaussian with covariance `s^2 diag(sigma^2) + L L^T`, at
/// noise scales below and above 1: the scale acts on the per-point part only.
#[test]
fn shared_noise_is_the_dense_gaussian() {
    for residual in [ResidualForm::Magnitude, ResidualForm::LogMagnitude] {
        let base = small_problem(residual, PriorKind::Uniform).unwrap();
        let mut data = base.data().clone();
        let n = data.len();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut block = |start: usize, len: usize, rank: usize| {
            use rand::RngExt;
            let loadings = (0..len * rank)
                .map(|i| {
                    let s = data.sigma[start + i / rank];
                    s * (2.0 * rng.random::<f64>() - 1.0) * 3.0
                })
                .collect();
            CorrelatedNoise {
                start,
                len,
                rank,
                loadings,
                magnitude: Vec::new(),
            }
        };
        data.correlated = vec![
            block(2, n / 4 + 1, 2),
            block(n / 4 + 4, n / 4 - 5, 5),
            block(n / 2 + 1, n / 2 - 2, 3),
        ];
        let post = base.with_data(data.clone()).unwrap();
        assert_dense_gaussian(&post, &data, &format!("{residual:?}"));
        // without shared noise, the same bits as the independent posterior
        data.correlated.clear();
        let plain = base.with_data(data).unwrap();
        let z = inside(&post);
        assert_eq!(
            plain.ln_likelihood(&z, &mut []).unwrap(),
            base.ln_likelihood(&z, &mut []).unwrap()
        );
    }
}

/// Correlated neighbouring bins (a Gauss-Markov chain per run, restarting where the
/// shared runs start and end), with and without shared noise, against the dense
/// Gaussian: the whitened likelihood, its pointwise terms and the draws of `simulate`
/// (lag-1 correlation of 4000 draws within 5 sampling sd).
#[test]
fn correlated_bins_are_the_dense_gaussian() {
    for residual in [ResidualForm::Magnitude, ResidualForm::LogMagnitude] {
        let base = small_problem(residual, PriorKind::Uniform).unwrap();
        let mut data = base.data().clone();
        let n = data.len();
        let half = n / 2;
        data.bin_correlation = (0..n)
            .map(|k| match k {
                0 => 0.0,
                _ if k == half => 0.0,
                // negative too: the phase-turned window's correlation can be
                _ => 0.9 * ((k as f64) * 0.37).sin(),
            })
            .collect();
        for shared in [false, true] {
            data.correlated = match shared {
                false => Vec::new(),
                true => vec![CorrelatedNoise {
                    start: half,
                    len: n - half,
                    rank: 2,
                    loadings: (half..n)
                        .flat_map(|k| {
                            [
                                0.8 * data.sigma[k],
                                -0.3 * data.sigma[k] * k as f64 / n as f64,
                            ]
                        })
                        .collect(),
                    magnitude: Vec::new(),
                }],
            };
            let post = base.with_data(data.clone()).unwrap();
            assert_dense_gaussian(&post, &data, &format!("{residual:?}, shared {shared}"));
        }
        // a shared run that cuts a chain is refused
        data.correlated[0].start = half - 1;
        data.correlated[0].len = n - half + 1;
        data.correlated[0].loadings.extend([0.0, 0.0]);
        assert!(base.with_data(data).is_err());
    }
    let base = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    let mut data = base.data().clone();
    let rho = 0.69;
    data.bin_correlation = (0..data.len())
        .map(|k| if k == 0 { 0.0 } else { rho })
        .collect();
    let post = base.with_data(data.clone()).unwrap();
    let z = inside(&post);
    let h = post.magnitudes(&z).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let draws = 4000;
    let (mut c, mut v) = (0.0, 0.0);
    for _ in 0..draws {
        let y = post.simulate(&z, &mut rng).unwrap();
        let (e1, e2) = ((y[1] - h[1]) / data.sigma[1], (y[2] - h[2]) / data.sigma[2]);
        c += e1 * e2;
        v += 0.5 * (e1 * e1 + e2 * e2);
    }
    // sd of a sample correlation ~ (1 - rho^2) / sqrt(n)
    let r = c / v;
    assert!(
        (r - rho).abs() < 5.0 * (1.0 - rho * rho) / (draws as f64).sqrt(),
        "{r}"
    );
}

/// Draws of `simulate` with shared noise: per-point variances and one covariance as
/// stated (2000 draws; tolerances 5 sampling sd).
#[test]
fn simulated_shared_noise_has_the_stated_covariance() {
    let base = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    let mut data = base.data().clone();
    let n = data.len();
    let loadings: Vec<f64> = (0..n)
        .map(|k| data.sigma[k] * (1.0 + k as f64 / n as f64))
        .collect();
    data.correlated = vec![CorrelatedNoise {
        start: 0,
        len: n,
        rank: 1,
        loadings: loadings.clone(),
        magnitude: Vec::new(),
    }];
    let post = base.with_data(data.clone()).unwrap();
    let z = inside(&post);
    let s = post.noise_scale(&z);
    let h = post.magnitudes(&z).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let draws = 2000;
    let (mut v0, mut c01) = (0.0, 0.0);
    for _ in 0..draws {
        let y = post.simulate(&z, &mut rng).unwrap();
        let (e0, e1) = (y[0] - h[0], y[1] - h[1]);
        v0 += e0 * e0 / draws as f64;
        c01 += e0 * e1 / draws as f64;
    }
    let var0 = s * s * data.sigma[0].powi(2) + loadings[0].powi(2);
    let var1 = s * s * data.sigma[1].powi(2) + loadings[1].powi(2);
    let cov01 = loadings[0] * loadings[1];
    let tol = 5.0 / (draws as f64).sqrt();
    assert!(
        (v0 / var0 - 1.0).abs() < tol * 2f64.sqrt(),
        "{v0} vs {var0}"
    );
    assert!(
        (c01 - cov01).abs() < tol * (var0 * var1).sqrt() * 1.5,
        "{c01} vs {cov01}"
    );
}

#[test]
fn support_and_dimension() {
    let post = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    assert_eq!(post.names(), ["k1", "k2", "k3", "ln_a0", "ln_noise_scale"]);
    let mut z = inside(&post);
    z[1] = 0.2;
    assert_eq!(post.ln_density(&z).unwrap(), f64::NEG_INFINITY);
    z[1] = 0.0;
    z[4] = 3f64.ln();
    assert_eq!(post.ln_density(&z).unwrap(), f64::NEG_INFINITY);
    assert!(post.ln_density(&z[..4]).is_err());
    let e = post
        .ln_density_with_pointwise(&inside(&post), &mut [0.0; 3])
        .unwrap_err();
    assert!(e.to_string().contains("pointwise"), "{e}");
}

/// Simulated data carry exactly the likelihood's noise: over 100 simulations x 80
/// points, the standardised residuals `(y - h) / (s sigma)` have mean 0 (se
/// 1/sqrt(8000) = 0.011) and variance 1 (se sqrt(2/8000) = 0.016); tolerances 5 se.
#[test]
fn simulated_noise_has_the_likelihood_law() {
    for residual in [ResidualForm::Magnitude, ResidualForm::LogMagnitude] {
        let post = small_problem(residual, PriorKind::Uniform).unwrap();
        let z = inside(&post);
        let h = post.magnitudes(&z).unwrap();
        let s = post.noise_scale(&z);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut e = Vec::new();
        for _ in 0..100 {
            let y = post.simulate(&z, &mut rng).unwrap();
            for ((y, h), sigma) in y.iter().zip(&h).zip(&post.data().sigma) {
                e.push(match residual {
                    ResidualForm::Magnitude => (y - h) / (s * sigma),
                    ResidualForm::LogMagnitude => (y / h).ln() / (s * sigma),
                });
            }
        }
        let n = e.len() as f64;
        let mean = e.iter().sum::<f64>() / n;
        let var = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!(mean.abs() < 5.0 / n.sqrt(), "{residual:?} mean {mean}");
        assert!(
            (var - 1.0).abs() < 5.0 * (2.0 / n).sqrt(),
            "{residual:?} var {var}"
        );
    }
}

/// On noise-free data the maximum-likelihood start is the truth (to the solver's
/// tolerance) and the noise scale sits on its lower bound.
#[test]
fn start_recovers_noise_free_truth() {
    let base = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    let truth = inside(&base);
    let post = base
        .with_magnitude(base.magnitudes(&truth).unwrap())
        .unwrap();
    assert_eq!(post.names(), base.names());
    assert_eq!(post.prior(), base.prior());
    let ms = MultistartOptions {
        n_starts: 4,
        seed: 1,
        ..Default::default()
    };
    let start = find_start(&post, &ms).unwrap();
    for j in 0..4 {
        assert!(
            (start.z[j] - truth[j]).abs() < 1e-6,
            "{j}: {:?} vs {truth:?}",
            start.z
        );
    }
    assert_eq!(start.z[4], post.prior().lower()[4]);
    assert!(start.cost < 1e-10, "{}", start.cost);
}

#[test]
fn ball_is_inside_the_box_and_reproducible() {
    let base = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let truth = inside(&base);
    let post = base
        .with_magnitude(base.simulate(&truth, &mut rng).unwrap())
        .unwrap();
    let ms = MultistartOptions {
        n_starts: 4,
        seed: 1,
        ..Default::default()
    };
    let mut start = find_start(&post, &ms).unwrap();
    // A center on a bound still gives walkers strictly inside.
    start.z[0] = post.prior().upper()[0];
    let a = ball_positions(&post, &start, 40, 1.0, 5).unwrap();
    let b = ball_positions(&post, &start, 40, 1.0, 5).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, ball_positions(&post, &start, 40, 1.0, 6).unwrap());
    for z in &a {
        assert!(post.ln_density(z).unwrap().is_finite());
        assert!(z[0] < post.prior().upper()[0]);
    }
    assert!(ball_positions(&post, &start, 4, 0.0, 5).is_err());
}

#[test]
fn stuck_walkers_are_found() {
    // 6 chains of 50 draws; chain 4 sits 40 log units below the others.
    let (n_chains, n_draws) = (6, 50);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let ln_density: Vec<f64> = (0..n_chains * n_draws)
        .map(|i| {
            let e: f64 = rand::RngExt::sample(&mut rng, rand_distr::StandardNormal);
            e - if i / n_draws == 4 { 40.0 } else { 0.0 }
        })
        .collect();
    let mut draws = Draws {
        n_chains,
        n_walkers: 3,
        n_draws,
        dim: 1,
        n_pointwise: 0,
        values: vec![0.0; n_chains * n_draws],
        ln_density,
        pointwise: Vec::new(),
        discarded_steps: 0,
        thin_steps: 1,
    };
    assert_eq!(stuck_walkers(&draws), vec![4]);
    for v in &mut draws.ln_density[4 * n_draws..5 * n_draws] {
        *v += 40.0;
    }
    assert!(stuck_walkers(&draws).is_empty());
}

/// The two-stage plug-in (`LoadingMagnitude::Model`): each shared-noise row becomes
/// `|H^A_k(theta_ML)| a_k` (the model's magnitude at the start, exactly), so it no longer
/// follows the point's own measured magnitude. Raising one measured magnitude by 10 %
/// scales its row by exactly 1.1 with measured-magnitude loadings; with the plug-in the
/// row moves only as the fitted model does there, by the point's leverage times 10 %
/// (80 points, 4 parameters: 0.05 on average); the bound 2.5 % allows a leverage of 0.25.
#[test]
fn plug_in_loadings_do_not_follow_the_point_s_own_magnitude() {
    let base = small_problem(ResidualForm::Magnitude, PriorKind::Uniform).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let y = base.simulate(&inside(&base), &mut rng).unwrap();
    let n = y.len();
    let rel: Vec<f64> = (0..n).map(|k| 0.01 * (1.0 + k as f64 / n as f64)).collect();
    let with_shared = |y: &[f64]| {
        let mut data = base.data().clone();
        data.magnitude = y.to_vec();
        data.correlated = vec![CorrelatedNoise {
            start: 0,
            len: n,
            rank: 1,
            loadings: rel.iter().zip(y).map(|(a, m)| a * m).collect(),
            magnitude: y.to_vec(),
        }];
        base.with_data(data).unwrap()
    };
    let ms = MultistartOptions {
        n_starts: 4,
        seed: 1,
        ..Default::default()
    };
    let (post, start) = plug_in_start(with_shared(&y), LoadingMagnitude::Model, &ms).unwrap();
    let mut z = start.z.clone();
    *z.last_mut().unwrap() = 0.0;
    let h = post.magnitudes(&z).unwrap();
    let c = &post.data().correlated[0];
    for k in 0..n {
        assert!((c.loadings[k] - rel[k] * h[k]).abs() <= 1e-12 * c.loadings[k]);
        assert_eq!(c.magnitude[k], h[k]);
    }
    // the start is that of the unscaled posterior (the loadings do not enter its fit)
    let plain = find_start(&with_shared(&y), &ms).unwrap();
    assert_eq!(start.z[..4], plain.z[..4]);
    let k0 = 37;
    let mut y2 = y.clone();
    y2[k0] *= 1.1;
    let (measured, _) = plug_in_start(with_shared(&y2), LoadingMagnitude::Measured, &ms).unwrap();
    let ratio = measured.data().correlated[0].loadings[k0] / (rel[k0] * y[k0]);
    assert!((ratio - 1.1).abs() < 1e-12, "measured: {ratio}");
    let (model, _) = plug_in_start(with_shared(&y2), LoadingMagnitude::Model, &ms).unwrap();
    let moved = model.data().correlated[0].loadings[k0] / c.loadings[k0] - 1.0;
    assert!(moved.abs() < 0.025, "plug-in row moved by {moved}");
    // log residuals: loadings `a_k`, no magnitude, nothing to rescale
    let log = small_problem(ResidualForm::LogMagnitude, PriorKind::Uniform).unwrap();
    let (same, _) = plug_in_start(log.clone(), LoadingMagnitude::Model, &ms).unwrap();
    assert_eq!(same.data(), log.data());
}
