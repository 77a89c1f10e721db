//! Every experiment file in `experiments/` parses and validates.

use frfbayes::experiment::ExperimentConfig;
use std::path::Path;

#[test]
fn every_experiment_file_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            ExperimentConfig::load(&path).unwrap_or_else(|e| panic!("{e}"));
            n += 1;
        }
    }
    assert!(n >= 2, "expected experiment files in {}", dir.display());
}

#[test]
fn bad_experiment_file_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.toml");
    std::fs::write(&p, "name = \"x\"\nout = \"o\"\n[update]\nstarts = 0\n").unwrap();
    let e = ExperimentConfig::load(&p).unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("starts"), "{e}");
    std::fs::write(&p, "name = \"x\"\nout = \"o\"\nunknown_key = 1\n").unwrap();
    let e = ExperimentConfig::load(&p).unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("unknown_key"), "{e}");
}

#[test]
fn hammer_estimator_is_chosen_in_the_file() {
    use frfbayes::signal::HammerEstimator;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("blocks.toml");
    let write = |estimator: &str| {
        std::fs::write(
            &p,
            format!("name = \"x\"\nout = \"o\"\n[estimate]\nhammer_estimator = \"{estimator}\"\n"),
        )
        .unwrap()
    };
    write("impact_blocks");
    let c = ExperimentConfig::load(&p).unwrap();
    assert_eq!(
        c.estimate.options().hammer.estimator,
        HammerEstimator::ImpactBlocks
    );
    write("whole_record");
    let c = ExperimentConfig::load(&p).unwrap();
    assert_eq!(
        c.estimate.options().hammer.estimator,
        HammerEstimator::WholeRecord
    );
    write("welch");
    let e = ExperimentConfig::load(&p).unwrap_err().to_string();
    assert!(e.contains("blocks.toml") && e.contains("welch"), "{e}");
}
