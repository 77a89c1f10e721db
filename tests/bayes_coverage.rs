//! Coverage of the posterior's central 90 % intervals over simulated hammer campaigns,
//! with the FRF estimator in the loop (`frfbayes::bayes::coverage`). Slow (about 7 s of
//! CPU per campaign); run on demand, one thread:
//!
//! ```sh
//! FRFBAYES_COVERAGE_LABEL=after nice -n 10 cargo test --release --test bayes_coverage \
//!     -- --ignored --nocapture
//! ```
//!
//! Environment: `FRFBAYES_COVERAGE_N` campaigns (default 20), `FRFBAYES_COVERAGE_NOISE`
//! (`all`, `force_only`, `responses_only`; default `all`), `FRFBAYES_COVERAGE_SEED`
//! (default 1), `FRFBAYES_COVERAGE_INPUT_NOISE` (`shared`, the default of `sample`, or
//! `per_point`, the model before), `FRFBAYES_COVERAGE_BAND_SELECTION` (`measured` or
//! `model`, as `sample`'s `--band-selection`; default `sample`'s, `model`), `FRFBAYES_COVERAGE_NOISE_POOL_BINS`
//! (as `sample`'s `--noise-pool-bins`; default `sample`'s, 8), `FRFBAYES_COVERAGE_BINS`
//! (`independent`, `window` or `phase`, as `sample`'s `--bin-correlation`; default
//! `sample`'s, `phase`),
//! `FRFBAYES_COVERAGE_REL_SIGMA_FLOOR` (as `--rel-sigma-floor`), `FRFBAYES_COVERAGE_LABEL` (file name prefix, default `run`),
//! `FRFBAYES_COVERAGE_OUT` (default `results/coverage`). Writes `<label>_<noise>.md` and
//! `.csv` there.

use frfbayes::bayes::coverage::{binomial_bounds, run_coverage, CoverageOptions, NoiseSources};
use frfbayes::bayes::run::{SampleSettings, TestSelection};
use frfbayes::bayes::{BandSelection, BinCorrelation, InputNoiseModel};
use frfbayes::frf::FrfKind;
use frfbayes::io::write_atomic;
use frfbayes::simulate::SimModel;
use frfbayes::update::DampingModel;
use std::path::{Path, PathBuf};

fn env_or(key: &str, default: &str) -> String {
    std::env::var(key).unwrap_or_else(|_| default.to_string())
}

#[test]
#[ignore = "slow: 20 simulated campaigns sampled one after the other"]
fn coverage_of_ninety_percent_intervals() {
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let n: usize = env_or("FRFBAYES_COVERAGE_N", "20").parse().unwrap();
    let seed: u64 = env_or("FRFBAYES_COVERAGE_SEED", "1").parse().unwrap();
    let label = env_or("FRFBAYES_COVERAGE_LABEL", "run");
    let (noise, noise_name) = match env_or("FRFBAYES_COVERAGE_NOISE", "all").as_str() {
        "all" => (NoiseSources::All, "all"),
        "force_only" => (NoiseSources::ForceOnly, "force_only"),
        "responses_only" => (NoiseSources::ResponsesOnly, "responses_only"),
        other => panic!("FRFBAYES_COVERAGE_NOISE={other}: use all, force_only or responses_only"),
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(env_or(
        "FRFBAYES_COVERAGE_OUT",
        root.join("results/coverage").to_str().unwrap(),
    ));
    let base = SimModel::from_path(&root.join("experiments/models/four-story-truth.toml")).unwrap();
    let mut settings = SampleSettings::new(
        "<simulated>".into(),
        DampingModel::Caughey,
        FrfKind::Receptance,
        TestSelection::Hammer,
        seed,
    )
    .unwrap();
    settings.input_noise = match env_or("FRFBAYES_COVERAGE_INPUT_NOISE", "shared").as_str() {
        "shared" => InputNoiseModel::Shared,
        "per_point" => InputNoiseModel::PerPoint,
        other => panic!("FRFBAYES_COVERAGE_INPUT_NOISE={other}: use shared or per_point"),
    };
    if let Ok(v) = std::env::var("FRFBAYES_COVERAGE_NOISE_POOL_BINS") {
        settings.noise_pool_bins = v.parse().expect("FRFBAYES_COVERAGE_NOISE_POOL_BINS: bins");
    }
    if let Ok(v) = std::env::var("FRFBAYES_COVERAGE_BAND_SELECTION") {
        settings.band_selection = match v.as_str() {
            "measured" => BandSelection::Measured,
            "model" => BandSelection::Model,
            other => panic!("FRFBAYES_COVERAGE_BAND_SELECTION={other}: use measured or model"),
        };
    }
    if let Ok(v) = std::env::var("FRFBAYES_COVERAGE_BINS") {
        settings.bin_correlation = match v.as_str() {
            "independent" => BinCorrelation::Independent,
            "window" => BinCorrelation::Window,
            "phase" => BinCorrelation::Phase,
            other => panic!("FRFBAYES_COVERAGE_BINS={other}: use independent, window or phase"),
        };
    }
    if let Ok(v) = std::env::var("FRFBAYES_COVERAGE_REL_SIGMA_FLOOR") {
        settings.rel_sigma_floor = v.parse().expect("FRFBAYES_COVERAGE_REL_SIGMA_FLOOR");
    }
    let opts = CoverageOptions {
        base,
        n_campaigns: n,
        seed,
        level: 0.9,
        noise,
        settings,
        // around the recorded campaign's Caughey estimates (masses 1.065-1.11 x nominal,
        // stiffnesses 0.97-1.08 x nominal), inside the prior box
        mass_factor: [1.02, 1.09],
        stiffness_factor: [0.95, 1.12],
        damping_factor: [0.8, 1.25],
    };
    let report = run_coverage(&opts, &|c| {
        let z = c.z();
        let worst = z.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        eprintln!(
            "campaign {:2}: covered {:2}/{}, max |z| {:.2}, noise scale {:.3}, {:.1} s",
            c.index,
            c.covered().iter().filter(|&&v| v).count(),
            z.len(),
            worst,
            c.noise_scale,
            c.wall_s
        );
    })
    .unwrap();
    let title = format!("Coverage ({label}, noise {noise_name})");
    let md = report.to_markdown(&title).unwrap();
    std::fs::create_dir_all(&out).unwrap();
    write_atomic(&out.join(format!("{label}_{noise_name}.md")), md.as_bytes()).unwrap();
    write_atomic(
        &out.join(format!("{label}_{noise_name}.csv")),
        report.to_csv().as_bytes(),
    )
    .unwrap();
    println!("{md}");
    assert_eq!(report.campaigns.len(), n);
    // the files are written first, so a failing run still leaves its table
    let (lo, hi) = binomial_bounds(n, 0.9, 0.05).unwrap();
    for p in report.per_parameter() {
        assert!(
            (lo..=hi).contains(&(p.covered as u64)),
            "{}: covered in {}/{n} campaigns, outside the binomial bounds {lo}..={hi}",
            p.name,
            p.covered
        );
    }
}
