//! End to end: simulate the noise-free four-story campaign (known truth), run the paper's
//! reproduction pipeline on it, and check what it writes and what it recovers.

use frfbayes::experiment::driver::run_experiment;
use frfbayes::experiment::ExperimentConfig;
use frfbayes::io::write_campaign;
use frfbayes::simulate::{SimModel, Simulator};
use std::path::Path;

fn truth_campaign(dir: &Path) -> SimModel {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("experiments/models/four-story-truth-noise-free.toml");
    let model = SimModel::from_path(&path).unwrap();
    let campaign = Simulator::new(model.clone())
        .unwrap()
        .run(1, &|_| {})
        .unwrap();
    write_campaign(&campaign, dir).unwrap();
    model
}

#[test]
fn repro_on_noise_free_simulation_recovers_truth_and_writes_everything() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("campaign");
    truth_campaign(&data);
    let mut cfg = ExperimentConfig::paper_repro().unwrap();
    cfg.data = data.to_string_lossy().into_owned();
    cfg.out = tmp.path().join("out");
    cfg.update.starts = 8;
    // One posterior keeps the test short.
    let bayes = cfg
        .bayes
        .as_mut()
        .expect("paper_repro.toml has a [bayes] section");
    bayes.variants = vec!["table2 caughey_receptance".into()];
    let outcome = run_experiment(&cfg, &|_, _, _| {}).unwrap();
    for f in [
        "table1.csv",
        "table1.md",
        "table2.csv",
        "table2.md",
        "comparison.md",
        "summary.json",
        "run.json",
        "fig4_hammer_rayleigh.png",
        "fig4_hammer_rayleigh.svg",
        "fig5_hammer_caughey.png",
        "fig8_shake_table_rayleigh.svg",
        "fig9_shake_table_caughey.png",
        "frf/hammer-floor1/frf.csv",
        "frf/shake-table-chirp/frf_receptance.png",
        "identifiability.md",
        "posterior.json",
        "posterior_ridge_km.png",
        "posterior_corner_table2_caughey_receptance.png",
        "posterior_correlation_table2_caughey_receptance.svg",
        "posterior_cv_table2.png",
        "report.html",
    ] {
        assert!(outcome.out.join(f).is_file(), "missing {f}");
    }
    let html = std::fs::read_to_string(outcome.out.join("report.html")).unwrap();
    let at = |n: &str| {
        html.find(n)
            .unwrap_or_else(|| panic!("report.html lacks {n:?}"))
    };
    assert!(at("<h3>In short</h3>") < at("<h2>Table 1"));
    assert!(at("<img src=\"data:image/png;base64,") < at("Settings of the run"));
    // The truth of four-story-truth-noise-free.toml.
    let mass_kg = [5.155, 4.953, 4.949, 5.090];
    let stiffness = [1090.0, 1258.0, 1378.0, 2666.0];
    let xi = [0.017, 0.0115, 0.006, 0.004];
    // Hammer data with modal (Caughey) damping: the Caughey variants must recover the
    // truth. Errors come only from the estimates (finite resolution, window, anti-alias
    // filter): 0.5 % on mass and stiffness, 10 % on damping after the window correction.
    for r in outcome
        .runs
        .iter()
        .filter(|r| r.variant.table.key() == "table1" && r.variant.column().starts_with("caughey"))
    {
        let get = |n: &str| r.corrected.iter().find(|(k, _)| k == n).unwrap().1;
        for i in 0..4 {
            let (m, k, x) = (
                get(&format!("m{}", i + 1)),
                get(&format!("k{}", i + 1)),
                get(&format!("xi{}", i + 1)),
            );
            assert!(
                (m / mass_kg[i] - 1.0).abs() < 5e-3,
                "{}: m{} = {m}",
                r.variant.column(),
                i + 1
            );
            assert!(
                (k / stiffness[i] - 1.0).abs() < 5e-3,
                "{}: k{} = {k}",
                r.variant.column(),
                i + 1
            );
            assert!(
                (x / xi[i] - 1.0).abs() < 0.1,
                "{}: xi{} = {x}",
                r.variant.column(),
                i + 1
            );
        }
        assert!(r.fdac.iter().all(|f| f.2 > 0.999), "{:?}", r.fdac);
    }
    let csv = std::fs::read_to_string(outcome.out.join("table1.csv")).unwrap();
    assert!(csv.starts_with("parameter,initial,rayleigh_receptance,rayleigh_accelerance,caughey_receptance,caughey_accelerance,rsd_percent\n"));
    // The posteriors converged and the report says so.
    let post: serde_json::Value =
        serde_json::from_slice(&std::fs::read(outcome.out.join("posterior.json")).unwrap())
            .unwrap();
    let variants = post["variants"].as_array().unwrap();
    assert_eq!(variants.len(), 1);
    for v in variants {
        assert!(v["summary"]["converged"].as_bool().unwrap(), "{v}");
    }
    let md = std::fs::read_to_string(outcome.out.join("identifiability.md")).unwrap();
    for section in [
        "## Posterior (ensemble MCMC)",
        "1 of 1 variants meet R-hat < 1.01",
        "### The k/m ridge of ground excitation",
        "### In short",
    ] {
        assert!(md.contains(section), "identifiability.md lacks {section:?}");
    }
}
