//! The four-story log posterior (hammer tests, Caughey damping, receptance; 13
//! parameters, 412 points) with `frfbayes sample`'s defaults, or with
//! `FRFBAYES_PROBE_NOISE=independent` the former noise model of `tests/bayes_bench.rs`
//! and the emcee comparison: one evaluation per iteration, at 64 points of a ball
//! around the maximum-likelihood start.
//!
//! ```sh
//! cargo bench --bench posterior
//! ```
//!
//! For load-independent figures (the machine is shared), count instructions instead:
//! with `FRFBAYES_PROBE_EVALS=<n>` the binary skips criterion and evaluates the posterior
//! `n` times at the same points, which `valgrind --tool=callgrind
//! --toggle-collect='*probe_loop*'` counts alone (setup excluded). The problem and the points
//! are cached in `FRFBAYES_PROBE_POINTS` (default `$TMPDIR/frfbayes_probe_points.json`,
//! `..._independent.json` with `FRFBAYES_PROBE_NOISE=independent`, the noise model of the
//! kernel's history) so that runs before and after a change evaluate the same points, and
//! valgrind skips the slow campaign estimate.

use criterion::{criterion_group, Criterion};
use frfbayes::bayes::run::{prepare, sample_posterior, SampleSettings, TestSelection};
use frfbayes::bayes::{
    ball_positions, find_start, BandSelection, BinCorrelation, FrfData, FrfPosterior,
};
use frfbayes::frf::{Excitation, FrfBlock, FrfKind, FrfPair, ModalFrf};
use frfbayes::mcmc::LogDensity;
use frfbayes::modal::Modes;
use frfbayes::model::StructuralModel;
use frfbayes::predict::Predict;
use frfbayes::update::{DampingModel, MultistartOptions};
use std::hint::black_box;
use std::path::PathBuf;

const N_POINTS: usize = 64;

/// One block in the cache: frequencies and pairs `(response, excitation or -1 for
/// ground, power)`.
type CachedBlock = (Vec<f64>, Vec<(usize, i64, i32)>);

/// What the probe needs to rebuild the posterior without reading the campaign.
#[derive(serde::Serialize, serde::Deserialize)]
struct Cache {
    floor_mass_kg: Vec<f64>,
    story_stiffness_n_per_m: Vec<f64>,
    data: FrfData,
    blocks: Vec<CachedBlock>,
    points: Vec<Vec<f64>>,
}

/// `frfbayes sample`'s settings; with `FRFBAYES_PROBE_NOISE=independent` the noise model
/// the kernel's history was measured on (neighbouring bins independent, each point's own
/// noise estimate, the shared force noise truncated at 1e-3, bins selected on the
/// estimates: 22,077 instructions per evaluation before the phase chain became the
/// default).
fn settings() -> SampleSettings {
    let mut s = SampleSettings::new(
        "bundled:four-story".into(),
        DampingModel::Caughey,
        FrfKind::Receptance,
        TestSelection::Hammer,
        1,
    )
    .unwrap();
    if independent_noise() {
        s.bin_correlation = BinCorrelation::Independent;
        s.noise_pool_bins = 0;
        s.band_selection = BandSelection::Measured;
    }
    s
}

fn independent_noise() -> bool {
    match std::env::var("FRFBAYES_PROBE_NOISE").as_deref() {
        Ok("independent") => true,
        Ok(other) => panic!("FRFBAYES_PROBE_NOISE={other}: independent, or unset"),
        Err(_) => false,
    }
}

fn posterior(settings: &SampleSettings, model: StructuralModel, data: FrfData) -> FrfPosterior {
    FrfPosterior::new(
        model,
        data,
        settings.damping,
        &settings.variables,
        settings.posterior,
    )
    .unwrap()
}

/// The posterior and the evaluation points, from the cache when there is one (reading
/// and estimating the campaign is slow under valgrind).
fn setup() -> (FrfPosterior, Vec<Vec<f64>>) {
    let settings = settings();
    let path = std::env::var_os("FRFBAYES_PROBE_POINTS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let name = match independent_noise() {
                true => "frfbayes_probe_points_independent.json",
                false => "frfbayes_probe_points.json",
            };
            std::env::temp_dir().join(name)
        });
    if let Some(cache) = std::fs::read_to_string(&path)
        .ok()
        .and_then(|s| serde_json::from_str::<Cache>(&s).ok())
    {
        let model =
            StructuralModel::shear_frame(&cache.floor_mass_kg, &cache.story_stiffness_n_per_m)
                .unwrap();
        let mut data = cache.data;
        data.blocks = cache
            .blocks
            .into_iter()
            .map(|(omega_rad_s, pairs)| FrfBlock {
                omega_rad_s,
                pairs: pairs
                    .into_iter()
                    .map(|(response, e, power)| FrfPair {
                        response,
                        excitation: if e < 0 {
                            Excitation::Ground
                        } else {
                            Excitation::Dof(e as usize)
                        },
                        kind: [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance]
                            [power as usize],
                    })
                    .collect(),
            })
            .collect();
        return (posterior(&settings, model, data), cache.points);
    }
    let post = prepare(&settings).unwrap().posterior;
    // The shear frame's story stiffnesses from K0 (off-diagonals -k_r, K0[0][0] = k_1 + k_2).
    let model = post.model();
    let (k0, m0) = (
        model.stiffness(&model.alpha_zero()),
        model.mass(&model.beta_zero()),
    );
    let n = k0.nrows();
    let mut stiffness: Vec<f64> = (0..n)
        .map(|r| if r == 0 { 0.0 } else { -k0[(r - 1, r)] })
        .collect();
    stiffness[0] = k0[(0, 0)] - if n > 1 { stiffness[1] } else { 0.0 };
    let options = MultistartOptions {
        n_starts: 8,
        seed: 1,
        ..Default::default()
    };
    let start = find_start(&post, &options).unwrap();
    let cache = Cache {
        floor_mass_kg: m0.diagonal().iter().copied().collect(),
        story_stiffness_n_per_m: stiffness,
        data: post.data().clone(),
        blocks: post
            .data()
            .blocks
            .iter()
            .map(|b| {
                let pairs = b.pairs.iter().map(|p| {
                    let e = match p.excitation {
                        Excitation::Dof(e) => e as i64,
                        Excitation::Ground => -1,
                    };
                    (p.response, e, p.kind.power())
                });
                (b.omega_rad_s.clone(), pairs.collect())
            })
            .collect(),
        points: ball_positions(&post, &start, N_POINTS, 1.0, 7).unwrap(),
    };
    std::fs::write(&path, serde_json::to_string(&cache).unwrap()).unwrap();
    (post, cache.points)
}

/// `n` evaluations cycling over `points` (the region callgrind counts).
#[inline(never)]
fn probe_loop(post: &FrfPosterior, points: &[Vec<f64>], n: usize) -> f64 {
    let mut acc = 0.0;
    for z in points.iter().cycle().take(n) {
        acc += post.ln_density(black_box(z)).unwrap();
    }
    acc
}

/// CPU time per call of the parts of an evaluation: the eigen-solve, the modal sums
/// (the forward model's blocks, one evaluator per block, no window), the forward model
/// and the whole log posterior.
fn parts(post: &FrfPosterior, points: &[Vec<f64>], n: usize) {
    let model = post.model();
    let thetas: Vec<Vec<f64>> = points.iter().map(|z| post.theta(z)).collect();
    let (n_alpha, n_beta) = (post.variables().n_alpha(), post.variables().n_beta());
    let km: Vec<_> = thetas
        .iter()
        .map(|t| {
            let (k, m) = (
                model.stiffness(&t[..n_alpha]),
                model.mass(&t[n_alpha..n_alpha + n_beta]),
            );
            let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
            let c: Vec<f64> = modes.omega_rad_s.iter().map(|w| 0.02 * w).collect();
            (k, m, modes, c)
        })
        .collect();
    let time = |name: &str, f: &mut dyn FnMut(usize)| {
        let cpu0 = thread_cpu_seconds();
        for i in 0..n {
            f(i % points.len());
        }
        let us = 1e6 * (thread_cpu_seconds() - cpu0) / n as f64;
        println!("{name}: {us:.3} us per call");
    };
    let mut modes = km[0].2.clone();
    time("eigen-solve", &mut |i| {
        let (k, m, ..) = &km[i];
        modes
            .solve_into(black_box(k), m, model.ground_influence(), None)
            .unwrap();
    });
    let mut frfs: Vec<ModalFrf> = post
        .data()
        .blocks
        .iter()
        .map(|b| ModalFrf::new(vec![b.clone()]))
        .collect();
    let mut out = vec![0.0; post.data().len()];
    time("modal sums", &mut |i| {
        let (_, _, modes, c) = &km[i];
        let mut offset = 0;
        for f in frfs.iter_mut() {
            let len = f.len();
            f.magnitudes(black_box(modes), c, &mut out[offset..offset + len])
                .unwrap();
            offset += len;
        }
    });
    let fp = post.predictor();
    let mut ws = fp.workspace();
    let n_free = post.n_free();
    time("forward model", &mut |i| {
        fp.predict(black_box(&points[i][..n_free]), &mut ws, &mut out)
            .unwrap();
    });
    time("log posterior", &mut |i| {
        black_box(post.ln_density(black_box(&points[i])).unwrap());
    });
}

/// CPU time of the calling thread, s, from /proc (Linux; 100 Hz ticks); NaN elsewhere.
fn thread_cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/thread-self/stat")
        .ok()
        .and_then(|s| {
            let rest = &s[s.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f[11].parse::<f64>().ok()? + f[12].parse::<f64>().ok()?) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

fn bench(c: &mut Criterion) {
    let (post, points) = setup();
    let mut i = 0;
    c.bench_function("four_story_ln_posterior", |b| {
        b.iter(|| {
            i = (i + 1) % points.len();
            black_box(post.ln_density(black_box(&points[i])).unwrap())
        })
    });
}

criterion_group!(benches, bench);

fn main() {
    if let Some(n) = std::env::var("FRFBAYES_PROBE_EVALS")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        let (post, points) = setup();
        let data = post.data();
        for (b, tau) in data.blocks.iter().zip(&data.window_tau_s) {
            println!(
                "block: {} frequencies x {} pairs, window {tau:?} s",
                b.omega_rad_s.len(),
                b.pairs.len()
            );
        }
        // Under `valgrind --instr-atstart=no` (fast setup): wait until the driver has
        // switched instrumentation on (`callgrind_control -i on`) and created this file.
        if let Some(go) = std::env::var_os("FRFBAYES_PROBE_GO") {
            println!("ready");
            while !std::path::Path::new(&go).exists() {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
        if std::env::var_os("FRFBAYES_PROBE_SAMPLE").is_some() {
            // `n` sampler steps of `frfbayes sample`'s settings (use RAYON_NUM_THREADS).
            let mut s = settings();
            s.max_steps = n as u64;
            let cpu0 = thread_cpu_seconds();
            let run = sample_posterior(&post, &s).unwrap();
            println!(
                "{} steps, {} evaluations, sampling {:.3} s wall ({:.3} s CPU of this thread \
                 for the whole call)",
                run.summary.n_steps,
                run.summary.n_likelihood_evals,
                run.summary.wall_s,
                thread_cpu_seconds() - cpu0
            );
            return;
        }
        if std::env::var_os("FRFBAYES_PROBE_PARTS").is_some() {
            parts(&post, &points, n);
            return;
        }
        let cpu0 = thread_cpu_seconds();
        let acc = probe_loop(&post, &points, n);
        let cpu = thread_cpu_seconds() - cpu0;
        println!(
            "{n} evaluations, sum of ln p {acc:.17e}, {:.3} us per evaluation (CPU time, \
             10 ms resolution)",
            1e6 * cpu / n as f64
        );
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
