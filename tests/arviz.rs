//! ArviZ opens what we write: a small seeded `frfbayes sample` run (the binary, bundled
//! four-story campaign, shake-table tests, Rayleigh damping; a few seconds) writes
//! `inference_data.nc`, and `tests/arviz_support/check_inference_data.py` opens it with
//! one `az.from_netcdf` call, checks the groups and names, that ArviZ's rank-normalised
//! R-hat and bulk/tail ESS match `posterior.json` within their Monte Carlo error
//! (tolerances derived in the script), and that `az.loo` runs.
//!
//! A second test writes a posterior whose log-likelihood group holds every 3rd draw only
//! (the thinned case of large runs) and checks that ArviZ opens it and `az.loo` runs.
//!
//! A third runs `frfbayes real four-story-modal --quick` on the shared data (skipped with
//! a message, checking nothing, without `../shared`) and runs the same script on its
//! file: the `log_likelihood` (one term per likelihood block) and `observed_data` (the
//! blocks' data) groups are there and pair up, and `az.loo` runs.
//!
//! Needs `python3` with `arviz` (which brings `h5netcdf`); without it the test prints a
//! skip message, unless `FRFBAYES_REQUIRE_EXTERNAL=1` (CI), which makes it a failure.

use frfbayes::mcmc::{
    Ball, Burn, InferenceData, LogDensity, Moves, Observed, Sampler, SamplerConfig, Start,
    INFERENCE_DATA_FILE,
};
use std::path::Path;
use std::process::Command;

const SCRIPT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/arviz_support/check_inference_data.py"
);

/// True when python3 can import arviz and h5netcdf; otherwise a skip message, or a panic
/// under `FRFBAYES_REQUIRE_EXTERNAL=1`.
fn have_arviz() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import arviz, h5netcdf"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        let msg = "python3 with arviz and h5netcdf not found (pip install arviz h5netcdf)";
        if std::env::var("FRFBAYES_REQUIRE_EXTERNAL").is_ok_and(|v| v == "1") {
            panic!("{msg}; FRFBAYES_REQUIRE_EXTERNAL=1 makes this a failure");
        }
        eprintln!("skipping: {msg}");
    }
    ok
}

/// Runs the check script on a run folder and returns its JSON report.
fn check(run: &Path) -> serde_json::Value {
    let out = Command::new("python3")
        .arg(SCRIPT)
        .arg(run)
        .output()
        .unwrap();
    report(out)
}

fn report(out: std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "check_inference_data.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn arviz_opens_a_sample_run_and_agrees_on_rhat_ess_and_loo() {
    if !have_arviz() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    let out = Command::new(env!("CARGO_BIN_EXE_frfbayes"))
        .args([
            "sample",
            "--tests",
            "shake_table",
            "--damping",
            "rayleigh",
            "--frf",
            "receptance",
            "--seed",
            "3",
            "--max-steps",
            "1500",
        ])
        .arg("--out")
        .arg(&run)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let nc = run.join("inference_data.nc");
    let bytes = std::fs::read(&nc).unwrap();
    assert_eq!(&bytes[..8], b"\x89HDF\r\n\x1a\n", "netCDF-4 is HDF5");
    let info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("run.json")).unwrap()).unwrap();
    let report = check(&run);
    println!(
        "inference_data.nc: {} bytes; run.json timings {}\n{}",
        bytes.len(),
        info["timings_s"],
        serde_json::to_string_pretty(&report).unwrap()
    );
}

/// `../shared/data/real/<dataset>` (or under `$FRFBAYES_SHARED_DIR`), else a skip message.
fn shared_dataset(dataset: &str) -> Option<std::path::PathBuf> {
    let root = frfbayes::model::shared_root();
    let root = if root.is_relative() {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(root)
    } else {
        root
    };
    if root.join("data/real").join(dataset).is_dir() {
        return Some(root);
    }
    println!(
        "skipped: {}/data/real/{dataset} not found (no ../shared beside the repository and \
         no FRFBAYES_SHARED_DIR): nothing checked",
        root.display()
    );
    None
}

/// A `real` study's file: ArviZ opens it, its log-likelihood blocks pair with the
/// observed data (8 blocks: each mode's frequency and shape) and `az.loo` runs.
#[test]
fn arviz_opens_a_real_study_with_log_likelihood_and_observed_data() {
    if !have_arviz() {
        return;
    }
    let Some(shared) = shared_dataset("four-story-modal") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("four-story-modal");
    let out = Command::new(env!("CARGO_BIN_EXE_frfbayes"))
        .args(["real", "four-story-modal", "--quick", "--seed", "4"])
        .arg("--shared")
        .arg(&shared)
        .arg("--out")
        .arg(&run)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = check(&run);
    println!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert_eq!(r["blocks"]["blocks"], serde_json::json!(8), "{r}");
    // 4 frequencies and 4 shapes of 4 floors.
    assert_eq!(r["blocks"]["values"], serde_json::json!(20), "{r}");
    assert!(r["loo"]["elpd_loo"].as_f64().unwrap().is_finite());
}

/// `y_i ~ N(mu, 1)`, 30 observations, flat prior on `mu`: the pointwise terms are
/// `-(y_i - mu)^2 / 2 - ln(2 pi) / 2`.
struct GaussianMean {
    y: Vec<f64>,
}

impl LogDensity for GaussianMean {
    fn dim(&self) -> usize {
        1
    }
    fn ln_density(&self, theta: &[f64]) -> frfbayes::Result<f64> {
        self.ln_density_with_pointwise(theta, &mut vec![0.0; self.y.len()])
    }
    fn n_pointwise(&self) -> usize {
        self.y.len()
    }
    fn ln_density_with_pointwise(&self, theta: &[f64], pw: &mut [f64]) -> frfbayes::Result<f64> {
        let c = -0.5 * (2.0 * std::f64::consts::PI).ln();
        for (p, y) in pw.iter_mut().zip(&self.y) {
            *p = -0.5 * (y - theta[0]).powi(2) + c;
        }
        Ok(pw.iter().sum())
    }
}

/// The thinned case (`log_likelihood_thin.json` of a large `sample` run): the
/// log-likelihood group holds every 3rd draw of each walker; ArviZ opens the file and
/// `az.loo` runs on it; the posterior keeps every draw.
#[test]
fn arviz_opens_a_thinned_log_likelihood() {
    if !have_arviz() {
        return;
    }
    let y: Vec<f64> = (0..30)
        .map(|i| 1.0 + ((i * 37 % 29) as f64 - 14.0) / 8.0)
        .collect();
    let density = GaussianMean { y: y.clone() };
    let mut config = SamplerConfig::new(8, 11);
    config.max_steps = 400;
    let start = Start::Ball(Ball {
        center: vec![1.0],
        scale: vec![0.1],
    });
    let mut sampler = Sampler::new(&density, Moves::default(), config, start).unwrap();
    sampler.run(None).unwrap();
    let discard = sampler.step_count() / 2;
    let draws = sampler.draws(Burn::Steps { discard, thin: 1 }).unwrap();
    let mut thinned = draws.thinned(3);
    thinned.compute_pointwise(&density).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join(INFERENCE_DATA_FILE);
    let observed = Observed {
        name: "y".into(),
        dim: "obs".into(),
        values: y,
        unit: "1".into(),
        coords: Vec::new(),
        attrs: Vec::new(),
    };
    InferenceData::new(&draws, &["mu".into()], &["1".into()])
        .unwrap()
        .with_observed(observed)
        .unwrap()
        .with_log_likelihood("y", "obs", &thinned)
        .unwrap()
        .write(&path)
        .unwrap();
    let script = format!(
        "import arviz as az, json\n\
         idata = az.from_netcdf({path:?})\n\
         loo = az.loo(idata)\n\
         print(json.dumps([idata.posterior.sizes['draw'], idata.log_likelihood.sizes['draw'], \
         int(idata.log_likelihood.attrs['walker_draws_every']), float(loo['elpd_loo'])]))",
        path = path.to_str().unwrap()
    );
    let out = Command::new("python3")
        .args(["-c", &script])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: (usize, usize, u64, f64) = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v.0, draws.n_walkers * draws.n_draws);
    assert_eq!(v.1, draws.n_walkers * draws.n_draws.div_ceil(3));
    assert_eq!(v.2, 3);
    assert!(v.3.is_finite(), "elpd_loo {}", v.3);
}
