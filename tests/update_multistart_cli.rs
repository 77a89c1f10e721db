//! Problem files and `frfbayes multistart`: a problem written to disk and read back is
//! the same objective bit for bit; the command reports what `update` finds and exports
//! the starts `update` uses. The ignored `write_synthetic_problems` writes the eight
//! synthetic four-story variants used for the scipy speed comparison:
//!
//! ```text
//! FRFBAYES_PROBLEM_DIR=/tmp/frfbayes-problems cargo test --release \
//!     --test update_multistart_cli -- --ignored --nocapture
//! paper_repro/scipy_multistart.py --problems /tmp/frfbayes-problems --starts 64 \
//!     --report results/paper_repro/speed/synthetic
//! ```

mod update_common;

use frfbayes::frf::FrfKind;
use frfbayes::update::{
    start_points, DampingModel, MultistartOptions, ObjectiveOptions, Problem, ProblemSpec,
    VariablesConfig,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::path::Path;
use std::process::Command;
use update_common::*;

/// Relative noise of the synthetic magnitudes (log-normal, 3 %), so that minima have a
/// positive cost the two solvers can be compared on.
const NOISE_REL: f64 = 0.03;

/// One synthetic variant with seeded noise.
fn variant(test: Test, kind: FrfKind, damping: DampingModel, points_per_band: usize) -> Problem {
    let grid = half_power_grid(damping, points_per_band);
    let blocks = blocks(test, kind, &grid);
    let seed = (test as u64) * 4 + (kind.power() as u64) * 2 + (damping as u64);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let magnitude = true_magnitudes(damping, &blocks)
        .into_iter()
        .map(|m| m * (NOISE_REL * rng.sample::<f64, _>(StandardNormal)).exp())
        .collect();
    problem(
        damping,
        blocks,
        magnitude,
        None,
        &VariablesConfig::default(),
        ObjectiveOptions::default(),
    )
}

fn name(test: Test, kind: FrfKind, damping: DampingModel) -> String {
    format!("{test:?}-{kind:?}-{damping:?}").to_lowercase()
}

#[test]
fn problem_file_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let p = variant(Test::Ground, FrfKind::Accelerance, DampingModel::Caughey, 7);
    let path = dir.path().join("p.json");
    p.spec().write(&path).unwrap();
    let q = Problem::from_spec(&ProblemSpec::read(&path).unwrap()).unwrap();
    let opts = MultistartOptions {
        n_starts: 5,
        seed: 11,
        ..Default::default()
    };
    for theta in start_points(&p, &opts).unwrap() {
        let (a, b) = (
            p.residuals_at(&theta).unwrap(),
            q.residuals_at(&theta).unwrap(),
        );
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
    std::fs::write(
        &path,
        "{\"format\": \"frfbayes-problem/1\",\n \"model\": 3}",
    )
    .unwrap();
    let e = ProblemSpec::read(&path).unwrap_err().to_string();
    assert!(e.contains("p.json") && e.contains("line 2"), "{e}");
}

#[test]
fn multistart_command_reports_update_and_exports_its_starts() {
    let dir = tempfile::tempdir().unwrap();
    let problems = dir.path().join("problems");
    let variants = [
        (Test::Hammer, FrfKind::Receptance, DampingModel::Rayleigh),
        (Test::Ground, FrfKind::Accelerance, DampingModel::Caughey),
    ];
    for (t, k, d) in variants {
        variant(t, k, d, 5)
            .spec()
            .write(&problems.join(format!("{}.json", name(t, k, d))))
            .unwrap();
    }
    let out_path = dir.path().join("out/rust.json");
    let out = Command::new(env!("CARGO_BIN_EXE_frfbayes"))
        .args(["multistart", "--starts", "6", "--seed", "4", "--problems"])
        .arg(&problems)
        .arg("--out")
        .arg(&out_path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out_path).unwrap()).unwrap();
    let reports = report["problems"].as_array().unwrap();
    // Sorted by file name: ground-... before hammer-...
    assert_eq!(reports.len(), 2);
    assert_eq!(reports[0]["name"], "ground-accelerance-caughey");
    let opts = MultistartOptions {
        n_starts: 6,
        seed: 4,
        ..Default::default()
    };
    for r in reports {
        let name = r["name"].as_str().unwrap();
        let p =
            Problem::from_spec(&ProblemSpec::read(&problems.join(format!("{name}.json"))).unwrap())
                .unwrap();
        // The reported best is a point of this objective with this cost.
        let theta: Vec<f64> = serde_json::from_value(r["theta"].clone()).unwrap();
        let cost = r["best_cost"].as_f64().unwrap();
        assert_eq!(p.cost_at(&theta).unwrap(), cost);
        assert!(r["n_at_best"].as_u64().unwrap() >= 1);
        // The exported starts are update()'s, with residuals of this objective.
        let starts: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("out/{name}.starts.json"))).unwrap(),
        )
        .unwrap();
        let theta0: Vec<Vec<f64>> = serde_json::from_value(starts["starts_theta"].clone()).unwrap();
        assert_eq!(theta0, start_points(&p, &opts).unwrap());
        let check = &starts["checks"][1];
        let t: Vec<f64> = serde_json::from_value(check["theta"].clone()).unwrap();
        let res: Vec<f64> = serde_json::from_value(check["residuals"].clone()).unwrap();
        assert_eq!(res, p.residuals_at(&t).unwrap());
    }
    // Start files in the problem folder are not problems.
    std::fs::copy(
        dir.path()
            .join("out/hammer-receptance-rayleigh.starts.json"),
        problems.join("hammer-receptance-rayleigh.starts.json"),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_frfbayes"))
        .args(["multistart", "--starts", "2", "--problems"])
        .arg(&problems)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(stdout["problems"].as_array().unwrap().len(), 2);
    // A broken problem file is named.
    std::fs::write(problems.join("zz.json"), "{}").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_frfbayes"))
        .args(["multistart", "--starts", "2", "--problems"])
        .arg(&problems)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("zz.json"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// The eight paper variants ({hammer 16 pairs, shake table 4 ground pairs} x
/// {receptance, accelerance} x {Rayleigh, Caughey}), 400 points per FRF (100 per
/// half-power band), 3 % log-normal noise, all variables free.
#[test]
#[ignore = "writes files for the scipy speed comparison; set FRFBAYES_PROBLEM_DIR"]
fn write_synthetic_problems() {
    let Some(dir) = std::env::var_os("FRFBAYES_PROBLEM_DIR") else {
        println!("FRFBAYES_PROBLEM_DIR is not set; nothing written");
        return;
    };
    let dir = Path::new(&dir);
    for test in [Test::Hammer, Test::Ground] {
        for kind in [FrfKind::Receptance, FrfKind::Accelerance] {
            for damping in [DampingModel::Rayleigh, DampingModel::Caughey] {
                let p = variant(test, kind, damping, 100);
                let path = dir.join(format!("{}.json", name(test, kind, damping)));
                p.spec().write(&path).unwrap();
                println!("wrote {} ({} points)", path.display(), p.measured().len());
            }
        }
    }
}
