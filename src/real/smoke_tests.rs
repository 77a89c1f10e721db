//! One fast end-to-end run per dataset (skipped without ../shared): every run samples
//! only a few hundred steps, so the numbers are not converged; the tests check that
//! the command's whole chain runs on the real data and writes a complete, well-formed
//! output folder.

use super::posterior::Sampling;
use super::{run, shared_dataset, Dataset, StudyOptions};

/// Steps per sampled posterior in the smoke runs.
const SMOKE_STEPS: u64 = 200;

fn smoke(dataset: Dataset, figures: &[&str]) {
    let Some(data) = shared_dataset(dataset) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(dataset.name());
    let options = StudyOptions::full(3);
    let timings = run(
        dataset,
        &data,
        &out,
        options,
        &mut Sampling::capped(SMOKE_STEPS),
    )
    .unwrap();
    assert!(!timings.is_empty());
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.starts_with("# "), "{report}");
    assert!(
        !report.contains("NaN"),
        "a NaN in the report of {}",
        dataset.name()
    );
    let post: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("posterior.json")).unwrap()).unwrap();
    let params = post["parameters"].as_array().unwrap();
    assert!(!params.is_empty());
    for key in [
        "name", "unit", "mean", "sd", "cv", "q2.5", "q50", "q97.5", "rhat",
    ] {
        assert!(params[0].get(key).is_some(), "missing {key}");
    }
    assert!(post["n_steps"].as_u64().unwrap() <= SMOKE_STEPS);
    assert_eq!(post["stopped_because"], serde_json::json!("step_cap"));
    assert!(out.join("run.json").is_file());
    let findings: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("findings.json")).unwrap()).unwrap();
    assert!(
        findings.as_object().is_some_and(|o| !o.is_empty()),
        "findings.json of {} is empty",
        dataset.name()
    );
    for stem in figures {
        for ext in ["png", "svg"] {
            let p = out.join(format!("{stem}.{ext}"));
            assert!(
                std::fs::metadata(&p).map(|m| m.len() > 0).unwrap_or(false),
                "{} missing",
                p.display()
            );
        }
    }
}

#[test]
fn four_story_modal_runs_end_to_end() {
    smoke(
        Dataset::FourStoryModal,
        &["corner", "traces", "frequency_errors", "mode_shapes"],
    );
}

#[test]
fn wheel_frf_runs_end_to_end() {
    smoke(Dataset::WheelFrf, &["overview", "cov", "band1_frf"]);
}

#[test]
fn tower_hmd_runs_end_to_end() {
    smoke(
        Dataset::TowerHmd,
        &["frf_fit", "residual_map", "residual_map_low", "traces"],
    );
}

/// The bridge study with few starts, a small check set and 100 sampler steps: the chain
/// runs and writes `smu.json` with SMU's keys, the report and every figure.
#[test]
fn bridge_fe_runs_end_to_end() {
    use super::{bridge, bridge_report, bridge_run};
    let Some(data_dir) = shared_dataset(Dataset::BridgeFe) else {
        return;
    };
    let data = bridge::load(&data_dir).unwrap();
    let settings = bridge_run::BridgeSettings::quick(1);
    let study = bridge_run::run(&data, &settings, &mut Sampling::capped(100)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    bridge_report::write(&study, dir.path(), &[("all".into(), 1.0)]).unwrap();
    let smu: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("smu.json")).unwrap()).unwrap();
    assert_eq!(smu["alpha"].as_array().unwrap().len(), 17);
    for key in ["objective", "n_starts", "n_reached", "wall_s"] {
        assert!(smu.get(key).is_some(), "smu.json misses {key}");
    }
    let findings: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("findings.json")).unwrap()).unwrap();
    assert_eq!(findings["predictive"].as_array().unwrap().len(), 5);
    assert_eq!(smu["n_starts"], serde_json::json!(4));
    let report = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    assert!(
        report.starts_with("# ") && !report.contains("NaN"),
        "{report}"
    );
    for stem in [
        "fig_contraction",
        "fig_box_positions",
        "fig_predictive_frequencies",
        "fig_basis_error",
        "fig_multistart",
        "fig_traces",
    ] {
        assert!(dir.path().join(format!("{stem}.png")).is_file(), "{stem}");
        assert!(dir.path().join(format!("{stem}.svg")).is_file(), "{stem}");
    }
}
