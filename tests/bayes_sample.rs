//! `frfbayes sample` end to end on the bundled four-story campaign: a run killed with
//! SIGKILL resumes to bit-identical output; the hammer Caughey receptance posterior
//! converges (R-hat < 1.01 and bulk ESS > 400 for every parameter); all twelve
//! variants converge (ignored: ~1 min).

use frfbayes::bayes::run::{run_sample, SampleSettings, TestSelection};
use frfbayes::frf::FrfKind;
use frfbayes::update::DampingModel;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A private copy of the binary, so that nothing replaces it while the test runs.
fn binary() -> &'static Path {
    static COPY: std::sync::OnceLock<(tempfile::TempDir, std::path::PathBuf)> =
        std::sync::OnceLock::new();
    let (_, path) = COPY.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frfbayes");
        std::fs::copy(env!("CARGO_BIN_EXE_frfbayes"), &path).unwrap();
        (dir, path)
    });
    path
}

fn sample(args: &[&str]) -> Command {
    let mut c = Command::new(binary());
    c.arg("sample")
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

const RUN: [&str; 12] = [
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
    "--checkpoint-every",
    "100",
];

fn read(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(name).display()))
}

#[test]
fn killed_run_resumes_bit_identical() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));

    let out = sample(&RUN).arg("--out").arg(&a).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let converged = |d: &Path| {
        let v: serde_json::Value = serde_json::from_slice(&read(d, "posterior.json")).unwrap();
        v["converged"].as_bool().unwrap()
    };
    // A converged run removes its checkpoint, an unconverged one keeps it for extension.
    assert_eq!(a.join("checkpoint.mcmc").exists(), !converged(&a));

    // Kill the second run (SIGKILL) as soon as its first checkpoint (step 100 of 1500)
    // is on disk (the run goes on beside `b`, in `.b.frfbayes-partial`).
    let mut child = sample(&RUN).arg("--out").arg(&b).spawn().unwrap();
    let t0 = Instant::now();
    let partial_checkpoint = tmp.path().join(".b.frfbayes-partial/checkpoint.mcmc");
    loop {
        if partial_checkpoint.exists() {
            child.kill().unwrap();
            child.wait().unwrap();
            break;
        }
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                std::io::Read::read_to_string(&mut e, &mut err).unwrap();
            }
            panic!("the run ended ({status}) before it could be killed: {err}");
        }
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "no checkpoint after 300 s"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(!b.exists(), "the killed run must leave nothing at --out");

    // Resuming takes no problem flags.
    let out = sample(&["--resume", "--damping", "caughey"])
        .arg("--out")
        .arg(&b)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("drop --damping"));
    // A fresh run refuses to discard the interrupted run.
    let out = sample(&RUN).arg("--out").arg(&b).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("interrupted run"));

    let out = sample(&["--resume"]).arg("--out").arg(&b).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "draws.npy",
        "ln_posterior.npy",
        "log_likelihood.npy",
        "draws.csv",
        "settings.toml",
    ] {
        assert!(
            read(&a, f) == read(&b, f),
            "{f} differs after kill and resume"
        );
    }
    let summary = |d: &Path| {
        let mut v: serde_json::Value = serde_json::from_slice(&read(d, "posterior.json")).unwrap();
        v.as_object_mut().unwrap().remove("wall_s");
        v
    };
    assert_eq!(summary(&a), summary(&b));

    let out = sample(&["--resume"]).arg("--out").arg(&b).output().unwrap();
    if converged(&b) {
        assert!(String::from_utf8_lossy(&out.stderr).contains("no checkpoint"));
    } else {
        // At its step cap: resuming changes nothing.
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(read(&a, "draws.npy") == read(&b, "draws.npy"));
    }
}

fn converge(damping: DampingModel, frf: FrfKind, tests: TestSelection) {
    let tmp = tempfile::tempdir().unwrap();
    let settings =
        SampleSettings::new("bundled:four-story".into(), damping, frf, tests, 1).unwrap();
    let t0 = Instant::now();
    let o = run_sample(&settings, tmp.path(), &|_| {}, None).unwrap();
    let s = &o.summary;
    println!(
        "{damping:?} {frf:?} {tests:?}: {} points ({} at the sigma floor), {} steps, {:.0} evaluations/s, sampling {:.1} s \
         (run {:.1} s), max R-hat {:.4}, min bulk ESS {:.0} ({:.0}/s), stuck walkers {}",
        s.n_data_points,
        s.n_points_at_sigma_floor.unwrap_or(0),
        s.n_steps,
        s.n_likelihood_evals as f64 / s.wall_s,
        s.wall_s,
        t0.elapsed().as_secs_f64(),
        s.rhat_max,
        s.ess_bulk_min,
        s.ess_bulk_min / s.wall_s,
        s.n_stuck_walkers
    );
    for p in &s.parameters {
        assert!(p.rhat < 1.01, "{}: R-hat {}", p.name, p.rhat);
        assert!(p.ess_bulk > 400.0, "{}: bulk ESS {}", p.name, p.ess_bulk);
        assert!(p.sd > 0.0 && p.q2_5 <= p.q50 && p.q50 <= p.q97_5, "{p:?}");
    }
    assert!(s.converged && s.n_stuck_walkers == 0);
    let names: Vec<&str> = s.parameters.iter().map(|p| p.name.as_str()).collect();
    let damping_names: &[&str] = match damping {
        DampingModel::Rayleigh => &["a0", "a1"],
        DampingModel::Caughey => &["xi1", "xi2", "xi3", "xi4"],
    };
    let expect: Vec<&str> = ["m1", "m2", "m3", "m4", "k1", "k2", "k3", "k4"]
        .into_iter()
        .chain(damping_names.iter().copied())
        .chain(["noise_scale"])
        .collect();
    assert_eq!(names, expect);
    for f in [
        "posterior.json",
        "draws.csv",
        "draws.npy",
        "ln_posterior.npy",
        "log_likelihood.npy",
        "corner.png",
        "traces.svg",
        "predictive.png",
        "cv.png",
        "run.json",
        "start.json",
        "summary.md",
        "report.html",
    ] {
        assert!(tmp.path().join(f).exists(), "{f} missing");
    }
    // The page: verdict first, the parameter table, figures inline, settings last.
    let html = String::from_utf8(read(tmp.path(), "report.html")).unwrap();
    let at = |n: &str| {
        html.find(n)
            .unwrap_or_else(|| panic!("report.html lacks {n:?}"))
    };
    assert!(at("<h2>Verdict</h2>") < at("<td>k1</td>"));
    assert!(at("<td>k1</td>") < at("data:image/png;base64,"));
    assert!(at("data:image/png;base64,") < at("<h2>Settings"));
    // draws.npy: (chain, draw, parameter), f8, C order.
    let npy = read(tmp.path(), "draws.npy");
    let header = String::from_utf8_lossy(&npy[10..128]);
    let shape = format!(
        "({}, {}, {})",
        s.n_walkers * s.n_ensembles,
        s.n_draws_per_walker,
        s.parameters.len()
    );
    assert!(
        header.contains(&shape) && header.contains("<f8"),
        "{header}"
    );
}

#[test]
fn hammer_caughey_receptance_converges() {
    converge(
        DampingModel::Caughey,
        FrfKind::Receptance,
        TestSelection::Hammer,
    );
}

#[test]
#[ignore = "all twelve variants, ~1 min"]
fn every_variant_converges() {
    for tests in [
        TestSelection::Hammer,
        TestSelection::ShakeTable,
        TestSelection::All,
    ] {
        for damping in [DampingModel::Rayleigh, DampingModel::Caughey] {
            for frf in [FrfKind::Receptance, FrfKind::Accelerance] {
                converge(damping, frf, tests);
            }
        }
    }
}
