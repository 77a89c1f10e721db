//! The posterior's likelihood against the dense Gaussian it stands for, and the
//! measured weights' magnitude bias.

use super::*;

#[test]
fn posterior_prior_is_normalised_and_likelihood_is_the_gaussian() {
    // Data = the model at `base()` times (1 + 3 % complex noise).
    let clean = synthetic();
    let truth = ExtendedModel::new(clean.clone(), None)
        .unwrap()
        .predict(&base(), &[])
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut data = (*clean).clone();
    let mut it = truth.iter();
    for seg in &mut data.segments {
        for ch in &mut seg.channels {
            for h in &mut ch.h {
                let t = it.next().unwrap();
                let e = Complex64::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
                *h = t * (1.0 + 0.06 * e);
            }
        }
    }
    let post = ModelPosterior::new(Arc::new(data), None).unwrap();
    let (lo, hi) = post.bounds();
    let vol: f64 = lo.iter().zip(hi).map(|(l, u)| u - l).product();
    let z = post.sample_prior(&mut rng).unwrap();
    assert!((post.ln_prior(&z) + vol.ln()).abs() < 1e-12);
    let mut out = z.clone();
    out[0] = hi[0] + 1e-9;
    assert_eq!(post.ln_prior(&out), f64::NEG_INFINITY);
    // ln L by hand.
    let pred = post.predict(&z).unwrap();
    let eta = z[post.eta_index()].exp();
    let mut ll = 0.0;
    for (p, h) in pred.iter().zip(post.measured()) {
        let var = (0.01f64.powi(2) + eta * eta) * h.norm_sqr();
        ll += -(p - h).norm_sqr() / (2.0 * var) - (2.0 * std::f64::consts::PI * var).ln();
    }
    let got = post.ln_likelihood(&z).unwrap();
    assert!((got - ll).abs() < 1e-9 * ll.abs(), "{got} {ll}");
    // At the truth: the profiled eta maximises the likelihood, and with it the chi2
    // per dof is near 1 (uniform noise of half-width 0.03 per component: std
    // 0.03 / sqrt(3) = 1.73 %, so eta^2 + 0.01^2 ~ 0.0173^2, eta ~ 1.4 %).
    let z_true = post.z_of(&base(), 0.01, &[]);
    let pred = post.predict(&z_true).unwrap();
    let best = post.profile_eta(&pred);
    let at = |e: f64| post.ln_likelihood_of(&pred, e);
    assert!(at(best) >= at(best * 1.01) && at(best) >= at(best / 1.01));
    assert!((best - 0.0141).abs() < 0.001, "{best}");
    // Against a grid of 4,001 points over the box in ln eta (step 2e-3): Brent's
    // maximum is at least the grid's, and within one step of its argmax.
    let (lo, hi) = (
        crate::discrepancy::posterior::ETA_BOUNDS.0.ln(),
        crate::discrepancy::posterior::ETA_BOUNDS.1.ln(),
    );
    let step = (hi - lo) / 4000.0;
    let grid_best = (0..=4000)
        .map(|i| lo + step * i as f64)
        .max_by(|a, b| at(a.exp()).total_cmp(&at(b.exp())))
        .unwrap();
    assert!(
        at(best) >= at(grid_best.exp()),
        "{best} {}",
        grid_best.exp()
    );
    assert!(
        (best.ln() - grid_best).abs() <= step,
        "{best} {}",
        grid_best.exp()
    );
    let chi2 = post.chi2_per_dof_of(&pred, best);
    assert!((chi2 - 1.0).abs() < 0.05, "{chi2}");
}

#[test]
fn correlated_gain_likelihood_is_the_dense_gaussian() {
    // One hammer segment on 6 frequencies with a random rank-2 gain basis: ln L and the
    // whitened residuals against the dense complex covariance D + V V^*, V = diag(h) U,
    // with the gain on the model's H (`GainCarrier::Model`: V = diag(H) U), and on the
    // model's H at a fixed point (`ModelAtMap`: V = diag(H(z0)) U, evaluated elsewhere).
    // The same with a per-bin basis (a shake-table record's: one coefficient per
    // frequency). With the per-bin basis each point's own variance is its total less the
    // shared one; with the smooth basis, the whole total (the force noise counted twice).
    use crate::discrepancy::data::GainCarrier;
    for per_bin in [false, true] {
        gain_likelihood_against_dense(GainCarrier::Measured, per_bin);
        gain_likelihood_against_dense(GainCarrier::Model, per_bin);
        gain_likelihood_against_dense(GainCarrier::ModelAtMap, per_bin);
    }
}

/// One hammer segment on 6 frequencies with a random gain basis (rank 2, or per bin),
/// random ratios and errors; the posterior (before `at_map`), the evaluation point `z`
/// and a plug-in point `z0` 3 % stiffer.
struct GainFixture {
    post: ModelPosterior,
    z: Vec<f64>,
    z0: Vec<f64>,
    seg: crate::discrepancy::data::SegmentData,
    rank: usize,
    u: Vec<Complex64>,
}

fn gain_fixture(carrier: crate::discrepancy::data::GainCarrier, per_bin: bool) -> GainFixture {
    use crate::discrepancy::data::InputGainBasis;
    let mut data = (*synthetic()).clone();
    let freq: Vec<f64> = (1..=6).map(|i| 0.7 * i as f64).collect();
    let mut seg = segment(
        "h1",
        InputKind::Force {
            floor: 2,
            channel: "force".into(),
        },
        Some(19.4),
        &freq,
    );
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut c = || Complex64::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5);
    // The dense `U` (6 x rank) either way.
    let (rank, u) = match per_bin {
        false => (2, (0..12).map(|_| c() * 0.05).collect::<Vec<_>>()),
        true => (6, vec![Complex64::new(0.0, 0.0); 36]),
    };
    let mut u = u;
    seg.input_gain = Some(match per_bin {
        false => InputGainBasis::Smooth { rank, u: u.clone() },
        true => {
            let sd: Vec<f64> = (0..6).map(|_| 0.03 * c().re.abs()).collect();
            for (k, v) in sd.iter().enumerate() {
                u[k * 6 + k] = Complex64::new(*v, 0.0);
            }
            InputGainBasis::PerBin { sd }
        }
    });
    for ch in &mut seg.channels {
        for (h, e) in ch.h.iter_mut().zip(ch.rel_err.iter_mut()) {
            *h = c() * 0.01;
            *e = 0.02 + 0.1 * c().re.abs();
        }
    }
    data.segments = vec![seg.clone()];
    data.options.gain_carrier = carrier;
    let post = ModelPosterior::new(Arc::new(data), None).unwrap();
    let z = post.z_of(&base(), 0.01, &[]);
    // The plug-in point: 3 % stiffer, so its H differs from the evaluated one.
    let z0: Vec<f64> = z
        .iter()
        .enumerate()
        .map(|(i, v)| if i < 4 { v + 0.03 } else { *v })
        .collect();
    GainFixture {
        post,
        z,
        z0,
        seg,
        rank,
        u,
    }
}

fn gain_likelihood_against_dense(carrier: crate::discrepancy::data::GainCarrier, per_bin: bool) {
    use crate::discrepancy::data::{GainCarrier, MAX_COMMON_SHARE};
    let GainFixture {
        post,
        z,
        z0,
        seg,
        rank,
        u,
    } = gain_fixture(carrier, per_bin);
    let at_z0 = post.predict(&z0).unwrap();
    let post = post.at_map(&z0).unwrap();
    let pred = post.predict(&z).unwrap();
    let n = pred.len();
    let h = post.measured().to_vec();
    let eta2 = 1e-4;
    let mut sigma = DMatrix::<Complex64>::zeros(n, n);
    let mut v = DMatrix::<Complex64>::zeros(n, rank);
    let mut i = 0;
    for ch in &seg.channels {
        for (p, &k) in ch.freq_index.iter().enumerate() {
            let total = ch.rel_err[p].powi(2);
            let shared: f64 = (0..rank).map(|m| 0.5 * u[k * rank + m].norm_sqr()).sum();
            // Only the whole-record estimate's coherence holds the shared part.
            let own = match per_bin {
                true => (total - shared).max((1.0 - MAX_COMMON_SHARE) * total),
                false => total,
            };
            let d = 2.0 * (own + eta2) * ch.h[p].norm_sqr();
            sigma[(i, i)] = Complex64::new(d, 0.0);
            let carrier = match carrier {
                GainCarrier::Measured => ch.h[p],
                GainCarrier::Model => pred[i],
                GainCarrier::ModelAtMap => at_z0[i],
            };
            for m in 0..rank {
                v[(i, m)] = carrier * u[k * rank + m];
            }
            i += 1;
        }
    }
    let sigma = sigma + &v * v.adjoint();
    let e = DVector::from_iterator(n, h.iter().zip(&pred).map(|(a, b)| a - b));
    let chol = sigma.clone().cholesky().unwrap();
    let quad = (e.adjoint() * chol.solve(&e))[(0, 0)].re;
    let ln_det: f64 = chol.l().diagonal().iter().map(|d| 2.0 * d.re.ln()).sum();
    let expect = -quad - ln_det - n as f64 * std::f64::consts::PI.ln();
    let got = post.ln_likelihood_of(&pred, 0.01);
    assert!(
        (got - expect).abs() < 1e-9 * expect.abs(),
        "{got} vs {expect}"
    );
    let mut r = vec![0.0; post.n_whitened_residuals()];
    post.whitened_residuals(&z, 0.01, &mut r).unwrap();
    let half: f64 = 0.5 * r.iter().map(|x| x * x).sum::<f64>();
    assert!((half - quad).abs() < 1e-9 * quad, "{half} vs {quad}");
    assert!((post.chi2_per_dof_of(&pred, 0.01) - quad / n as f64).abs() < 1e-9 * quad);
}

/// The overall magnitude `a` of `truth` that `post` likes best (grid of step 0.0005 on
/// 0.9..1.1, error floor 1e-6).
fn best_overall_scale(post: &ModelPosterior, truth: &[Complex64]) -> f64 {
    (0..=400)
        .map(|i| 0.9 + 0.0005 * i as f64)
        .max_by(|&a, &b| {
            let at = |s: f64| {
                let p: Vec<Complex64> = truth.iter().map(|v| v * s).collect();
                post.ln_likelihood_of(&p, 1e-6)
            };
            at(a).total_cmp(&at(b))
        })
        .unwrap()
}

#[test]
fn the_weight_bias_correction_removes_the_magnitude_bias_of_measured_weights() {
    // Data = the model at `base()` times (1 + x), x complex with std(Re) = std(Im) =
    // eps = 10 %, the likelihood's own convention (E|x|^2 = 2 eps^2). With errors scaled
    // by the measured |h| the best overall magnitude is about 1 / (1 + 2 eps^2) = 0.980;
    // comparing with h (1 + 2 eps^2) ([`crate::discrepancy::data::weight_bias`]) it is 1 to
    // second order (left: about 2 (2 eps^2)^2 = 0.0008). sd of the scale: eps / sqrt(N)
    // = 0.002 (N = 2400 points); tolerance 4 sd. Measured: 0.979 and 0.9985.
    let eps = 0.1;
    let (truth, mut data) = noisy_synthetic(eps, 6);
    let measured = ModelPosterior::new(Arc::new(data.clone()), None).unwrap();
    data.options.weight_bias_correction = true;
    let corrected = ModelPosterior::new(Arc::new(data), None).unwrap();
    let sd = eps / (truth.len() as f64).sqrt();
    let a_measured = best_overall_scale(&measured, &truth);
    let a_corrected = best_overall_scale(&corrected, &truth);
    let expected = 1.0 / (1.0 + 2.0 * eps * eps);
    assert!((a_measured - expected).abs() < 4.0 * sd, "{a_measured}");
    assert!((a_corrected - 1.0).abs() < 4.0 * sd, "{a_corrected}");
}

#[test]
fn the_kept_gain_factors_give_the_bits_of_factoring_anew() {
    // The factors of `G` are kept per thread while `eta` and the carrier stay: every
    // evaluation equals, bit for bit, a fresh posterior's (an empty cache), and the
    // factors are built once per change of `eta` (the measured or plug-in carrier), on
    // every evaluation when the carrier is the prediction itself.
    use crate::discrepancy::data::GainCarrier;
    use rayon::prelude::*;
    for (carrier, per_bin) in [
        (GainCarrier::Measured, false),
        (GainCarrier::ModelAtMap, false),
        (GainCarrier::ModelAtMap, true),
        (GainCarrier::Model, false),
    ] {
        let GainFixture { post, z, z0, .. } = gain_fixture(carrier, per_bin);
        let post = post.at_map(&z0).unwrap();
        let points: Vec<(Vec<f64>, f64)> = (0..12)
            .map(|j| {
                let zj: Vec<f64> = z.iter().map(|v| v + 0.004 * (j % 5) as f64).collect();
                (zj, [0.01, 0.01, 0.01, 0.02][j % 4] * (1.0 + (j / 8) as f64))
            })
            .collect();
        let fresh = |zj: &[f64], eta: f64| {
            let p = post.clone();
            let pred = p.predict(zj).unwrap();
            let mut r = vec![0.0; p.n_whitened_residuals()];
            p.whitened_residuals(zj, eta, &mut r).unwrap();
            (p.ln_likelihood_of(&pred, eta).to_bits(), r)
        };
        let kept = |zj: &[f64], eta: f64| {
            let pred = post.predict(zj).unwrap();
            let mut r = vec![0.0; post.n_whitened_residuals()];
            post.whitened_residuals(zj, eta, &mut r).unwrap();
            (post.ln_likelihood_of(&pred, eta).to_bits(), r)
        };
        let expect: Vec<_> = points.iter().map(|(zj, e)| fresh(zj, *e)).collect();
        let got: Vec<_> = points.iter().map(|(zj, e)| kept(zj, *e)).collect();
        assert_eq!(got, expect, "{carrier:?}, per bin {per_bin}");
        // Two evaluations (likelihood, residuals) per point, one build per new eta.
        let changes = 1 + points.windows(2).filter(|w| w[0].1 != w[1].1).count();
        let builds = post.gain_factor_builds();
        match carrier {
            GainCarrier::Model => assert_eq!(builds, 0),
            _ => assert_eq!(builds, changes, "{carrier:?}"),
        }
        // The same from several threads at once.
        let par: Vec<_> = (0..64)
            .into_par_iter()
            .map(|j| kept(&points[j % 12].0, points[j % 12].1))
            .collect();
        for (j, v) in par.iter().enumerate() {
            assert_eq!(v, &expect[j % 12], "{carrier:?}: thread evaluation {j}");
        }
    }
}
