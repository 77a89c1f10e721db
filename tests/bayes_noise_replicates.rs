//! What the likelihood's noise model leaves out, measured: one noise-free simulated hammer
//! campaign (`experiments/models/four-story-truth.toml`, hammer tests), then `R` noise
//! replicates (white noise of the model's size added to every channel, as the simulator
//! adds it), each estimated as `frfbayes sample` does, at the bins the noise-free estimate
//! selects. For the receptance magnitudes it compares the empirical covariance of the
//! relative errors `|H1| / |H1_clean| - 1` with what the likelihood assumes, per point
//! (Bendat & Piersol, `InputNoiseModel::PerPoint`) and with the force noise shared
//! (`InputNoiseModel::Shared`). Slow (about a minute); on demand:
//!
//! ```sh
//! nice -n 10 cargo test --release --test bayes_noise_replicates -- --ignored --nocapture
//! ```
//!
//! Writes `results/coverage/noise_replicates.md` (or `FRFBAYES_COVERAGE_OUT`). Other models:
//! `FRFBAYES_REPLICATES_MODEL` (a model file), `FRFBAYES_REPLICATES_FRF=accelerance`,
//! `FRFBAYES_REPLICATES_FREQ_MAX_HZ`, `FRFBAYES_REPLICATES_LABEL` (the file name),
//! `FRFBAYES_REPLICATES_SELECT=noisy` (the bins a noisy campaign's estimate selects, not
//! the noise-free one's: those reach where the noisy estimator never would); the
//! bridge: `experiments/models/bridge-hammer.toml`, accelerance, 15.5 Hz.

use frfbayes::bayes::run::{SampleSettings, TestSelection};
use frfbayes::bayes::{FrfData, InputNoiseModel};
use frfbayes::frf::FrfKind;
use frfbayes::io::{write_atomic, Campaign, Quantity};
use frfbayes::signal::{estimate_campaign, TestFrf};
use frfbayes::simulate::{NoiseSpec, SimModel, Simulator, TestSpec};
use frfbayes::update::DampingModel;
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::path::{Path, PathBuf};

const REPLICATES: u64 = 40;

fn noisy(clean: &Campaign, noise: &NoiseSpec, seed: u64) -> Campaign {
    let mut c = clean.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for t in &mut c.tests {
        for (ch, d) in t.channels.iter().zip(t.data.iter_mut()) {
            let sd = match ch.quantity {
                Quantity::Force => noise.force_n,
                Quantity::GroundAcceleration => noise.ground_acceleration_m_per_s2,
                Quantity::Acceleration => noise.acceleration_m_per_s2,
                Quantity::Displacement => noise.displacement_m,
            };
            let nd = Normal::new(0.0, sd).unwrap();
            d.iter_mut().for_each(|v| *v += nd.sample(&mut rng));
        }
    }
    c
}

/// Restricts every estimate's selected bins to those where no estimate has a response of
/// kind `kind` with zero coherence (no finite error), so all have the same points.
fn keep_common_bins(reference: &mut [TestFrf], replicates: &mut [Vec<TestFrf>], kind: FrfKind) {
    // per selected bin of `f`: every response of kind `kind` has a finite error there
    let finite = |f: &TestFrf| -> Vec<bool> {
        let (nw, rel) = (f.selected.len(), f.selected_rel_std());
        let block = f.frf_block().unwrap();
        let used: Vec<usize> = (0..block.pairs.len())
            .filter(|&j| block.pairs[j].kind == kind)
            .collect();
        (0..nw)
            .map(|i| used.iter().all(|&j| rel[j * nw + i].is_finite()))
            .collect()
    };
    for t in 0..reference.len() {
        let mut keep = finite(&reference[t]);
        for r in replicates.iter() {
            keep.iter_mut()
                .zip(finite(&r[t]))
                .for_each(|(k, f)| *k &= f);
        }
        let cut = |f: &mut TestFrf| {
            let kept = f.selected.iter().zip(&keep).filter(|(_, k)| **k);
            f.selected = kept.map(|(b, _)| *b).collect();
        };
        cut(&mut reference[t]);
        replicates.iter_mut().for_each(|r| cut(&mut r[t]));
    }
}

/// Predicted covariance of the relative errors of one test's points under `data`'s model.
fn predicted(data: &FrfData, range: std::ops::Range<usize>) -> DMatrix<f64> {
    let n = range.len();
    let y = &data.magnitude[range.clone()];
    let mut c = DMatrix::from_fn(n, n, |i, j| {
        if i == j {
            (data.sigma[range.start + i] / y[i]).powi(2)
        } else {
            0.0
        }
    });
    for blk in &data.correlated {
        if blk.start != range.start {
            continue;
        }
        for i in 0..n {
            for j in 0..n {
                let v: f64 = (0..blk.rank)
                    .map(|r| blk.loadings[i * blk.rank + r] * blk.loadings[j * blk.rank + r])
                    .sum();
                c[(i, j)] += v / (y[i] * y[j]);
            }
        }
    }
    c
}

#[test]
#[ignore = "slow: 40 noise replicates of a simulated hammer campaign"]
fn force_noise_is_shared_by_the_points_of_a_test() {
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(
        std::env::var("FRFBAYES_COVERAGE_OUT")
            .unwrap_or_else(|_| root.join("results/coverage").display().to_string()),
    );
    let model_file = std::env::var("FRFBAYES_REPLICATES_MODEL")
        .unwrap_or_else(|_| "experiments/models/four-story-truth.toml".into());
    let mut model = SimModel::from_path(&root.join(&model_file)).unwrap();
    model.tests.retain(|t| matches!(t, TestSpec::Hammer { .. }));
    let noise = std::mem::take(&mut model.noise);
    let clean = Simulator::new(model).unwrap().run(0, &|_| {}).unwrap();
    let kind = match std::env::var("FRFBAYES_REPLICATES_FRF").as_deref() {
        Ok("accelerance") => FrfKind::Accelerance,
        _ => FrfKind::Receptance,
    };
    let mut settings = SampleSettings::new(
        "<simulated>".into(),
        DampingModel::Caughey,
        kind,
        TestSelection::Hammer,
        1,
    )
    .unwrap();
    settings.estimate.freq_max_hz = std::env::var("FRFBAYES_REPLICATES_FREQ_MAX_HZ")
        .ok()
        .map(|v| v.parse().expect("FRFBAYES_REPLICATES_FREQ_MAX_HZ: Hz"));
    let opts = settings.estimate.options();
    let mut reference = estimate_campaign(&clean, &opts).unwrap();
    if std::env::var("FRFBAYES_REPLICATES_SELECT").as_deref() == Ok("noisy") {
        // the bins a noisy campaign's own estimate selects (seed 999, not a replicate)
        let noisy0 = estimate_campaign(&noisy(&clean, &noise, 999), &opts).unwrap();
        for (f, f1) in reference.iter_mut().zip(&noisy0) {
            f.selected = f1.selected.clone();
        }
    }
    // every replicate at the reference's selected bins, then all at the bins that none
    // of them drops (zero coherence: `FrfData::n_dropped_bins`)
    let mut replicates: Vec<Vec<TestFrf>> = (0..REPLICATES)
        .map(|rep| {
            let mut frfs = estimate_campaign(&noisy(&clean, &noise, 1000 + rep), &opts).unwrap();
            for (f, f0) in frfs.iter_mut().zip(&reference) {
                f.selected = f0.selected.clone();
            }
            frfs
        })
        .collect();
    keep_common_bins(&mut reference, &mut replicates, kind);
    let build = |frfs: &[TestFrf], m: InputNoiseModel| {
        let refs: Vec<&TestFrf> = frfs.iter().collect();
        FrfData::with_input_noise(&refs, kind, settings.residual, 1e-3, m).unwrap()
    };
    let y0 = build(&reference, InputNoiseModel::PerPoint).magnitude;
    // point ranges of the tests (the blocks of the long vector)
    let d0 = build(&reference, InputNoiseModel::PerPoint);
    let mut ranges = Vec::new();
    let mut start = 0;
    for b in &d0.blocks {
        let n = b.omega_rad_s.len() * b.pairs.len();
        ranges.push(start..start + n);
        start += n;
    }
    let n_tests = ranges.len();
    // per test: sum over replicates of eps eps^T and of the two predicted covariances
    let zeros = |r: &std::ops::Range<usize>| DMatrix::<f64>::zeros(r.len(), r.len());
    let mut emp: Vec<DMatrix<f64>> = ranges.iter().map(zeros).collect();
    let mut pred_pp: Vec<DMatrix<f64>> = ranges.iter().map(zeros).collect();
    let mut pred_sh: Vec<DMatrix<f64>> = ranges.iter().map(zeros).collect();
    for frfs in &replicates {
        let pp = build(frfs, InputNoiseModel::PerPoint);
        let sh = build(frfs, InputNoiseModel::Shared);
        let eps: Vec<f64> = pp
            .magnitude
            .iter()
            .zip(&y0)
            .map(|(y, y0)| y / y0 - 1.0)
            .collect();
        for (t, r) in ranges.iter().enumerate() {
            let e = DMatrix::from_column_slice(r.len(), 1, &eps[r.clone()]);
            emp[t] += &e * e.transpose();
            pred_pp[t] += predicted(&pp, r.clone());
            pred_sh[t] += predicted(&sh, r.clone());
        }
    }
    let r = REPLICATES as f64;
    let mut md = format!(
        "## Noise replicates at the true model\n\n{REPLICATES} noise replicates of the \
         simulated hammer campaign (`{model_file}`, hammer tests, the model file's \
         noise), {kind:?}, the bins the noise-free estimate selects. \
         `eps = |H1| / |H1_clean| - 1`; the noise-free estimate's own error is below \
         1e-5. Per test: the mean variance of a point, the variance of the test's mean \
         error (what a common gain of mass and stiffness sees), the mean correlation \
         between two points of the test, and the Mahalanobis statistic \
         `eps^T C^-1 eps / n` (1 if `C` is right).\n\n\
         | test | points | var(eps) emp. | per point | shared | var(mean eps) emp. | per point | shared | mean corr. emp. | per point | shared | Mahalanobis per point | shared |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
    let mean_var = |c: &DMatrix<f64>| c.diagonal().mean();
    let var_mean = |c: &DMatrix<f64>| c.sum() / (c.nrows() * c.nrows()) as f64;
    let mean_corr = |c: &DMatrix<f64>| {
        let n = c.nrows();
        let mut s = 0.0;
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    s += c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt();
                }
            }
        }
        s / (n * (n - 1)) as f64
    };
    let mut ratio_pp = Vec::new();
    let mut ratio_sh = Vec::new();
    for t in 0..n_tests {
        let e = &emp[t] / r;
        let p = &pred_pp[t] / r;
        let s = &pred_sh[t] / r;
        let n = e.nrows() as f64;
        let maha = |c: &DMatrix<f64>| (c.clone().try_inverse().unwrap() * &e).trace() / n;
        ratio_pp.push(var_mean(&e) / var_mean(&p));
        ratio_sh.push(var_mean(&e) / var_mean(&s));
        md += &format!(
            "| {} | {} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |\n",
            d0.tests[t],
            e.nrows(),
            mean_var(&e),
            mean_var(&p),
            mean_var(&s),
            var_mean(&e),
            var_mean(&p),
            var_mean(&s),
            mean_corr(&e),
            mean_corr(&p),
            mean_corr(&s),
            maha(&p),
            maha(&s),
        );
    }
    let gm = |v: &[f64]| (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp();
    md += &format!(
        "\nVariance of a test's mean error, empirical over predicted (geometric mean over \
         the tests; sampling error about {:.0} % for {REPLICATES} replicates and {n_tests} \
         tests): per point {:.1}, shared {:.2}.\n",
        100.0 * (2.0 / (r * n_tests as f64)).sqrt(),
        gm(&ratio_pp),
        gm(&ratio_sh)
    );
    println!("{md}");
    std::fs::create_dir_all(&out).unwrap();
    let label = std::env::var("FRFBAYES_REPLICATES_LABEL").unwrap_or("noise_replicates".into());
    write_atomic(&out.join(format!("{label}.md")), md.as_bytes()).unwrap();
    // the shared model must predict the test-mean variance within 3 sampling sd
    // (2 / sqrt(R n_tests) relative in log); the per-point model is what is measured
    let tol = 3.0 * (2.0 / (r * n_tests as f64)).sqrt();
    assert!(gm(&ratio_sh).ln().abs() < tol, "shared: {}", gm(&ratio_sh));
}
