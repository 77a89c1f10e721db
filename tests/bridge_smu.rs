//! SMU's bridge objective on the inference layer against an independent implementation:
//! `tests/fixtures/bridge_smu_reference.json`, written by `experiments/bridge/smu_scipy.py`
//! (scipy sparse shift-invert eigsh). At four points of the box (the nominal model, SMU's
//! published optimum and two random points) f = sum r^2 of both weightings and the five
//! lowest eigenvalues must agree; the reduced basis of the study must agree with the exact
//! solve there too. Skips with a message when the shared data are absent (and then checks
//! nothing).

use frfbayes::predict::modal::ModeSolver;
use frfbayes::predict::reduced::CondensedModes;
use frfbayes::real::bridge::{load, smu_posterior, Weighting};
use frfbayes::real::bridge_run::{build_basis, BridgeSettings};
use std::path::PathBuf;

fn data_dir() -> Option<PathBuf> {
    let p = frfbayes::model::shared_root().join("data/real/bridge-fe");
    let p = if p.is_relative() {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(p)
    } else {
        p
    };
    if p.join("ExpModeInfo_FEM.mat").is_file() {
        Some(p)
    } else {
        println!(
            "skipped: {} not found (no ../shared beside the repository and no \
             FRFBAYES_SHARED_DIR): nothing checked",
            p.display()
        );
        None
    }
}

fn fixture() -> serde_json::Value {
    let p =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bridge_smu_reference.json");
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

fn vec_of(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn smu_objective_matches_the_scipy_reference() {
    let Some(dir) = data_dir() else {
        return;
    };
    let data = load(&dir).unwrap();
    assert_eq!(
        data.reference,
        vec![11, 28, 6, 4, 38],
        "SMU's q(i), 0-based"
    );
    let fx = fixture();
    let solver = || CondensedModes::new(data.model.clone());
    let smu = smu_posterior(&data, solver(), Weighting::SmuLinearIndex).unwrap();
    let per = smu_posterior(&data, solver(), Weighting::PerEntry).unwrap();
    let f = |post: &frfbayes::infer::Posterior<_>, a: &[f64]| -> f64 {
        post.residuals(a).unwrap().iter().map(|r| r * r).sum()
    };
    for case in fx["cases"].as_array().unwrap() {
        let alpha = vec_of(&case["alpha"]);
        let name = case["name"].as_str().unwrap();
        for (post, key) in [(&smu, "objective_smu"), (&per, "objective_per_entry")] {
            let want = case[key].as_f64().unwrap();
            let got = f(post, &alpha);
            assert!(
                (got / want - 1.0).abs() < 1e-6,
                "{name} {key}: {got} vs {want}"
            );
        }
        let (mut ev, mut sh) = (vec![0.0; 5], vec![0.0; 5 * 58]);
        solver()
            .lowest_modes(&alpha, &[], &data.meas_dofs, &mut (), &mut ev, &mut sh)
            .unwrap();
        for (g, w) in ev.iter().zip(vec_of(&case["eigenvalues_rad2_s2"])) {
            assert!((g / w - 1.0).abs() < 1e-9, "{name}: eigenvalue {g} vs {w}");
        }
    }
}

/// The study's reduced basis stays within its measured accuracy: eigenvalues within 5e-3
/// relative at random points of the box (2.5e-3 measured at 40 points) and SMU's objective
/// within 5 % at the fixture's points (3 % at the optimum, where the Rayleigh-Ritz upper
/// bounds of the eigenvalues weigh most; the exact polish of the study removes it).
#[test]
fn reduced_basis_objective_is_close_to_the_exact_one() {
    let Some(dir) = data_dir() else {
        return;
    };
    let data = load(&dir).unwrap();
    let settings = BridgeSettings {
        n_check_points: 4,
        ..BridgeSettings::default()
    };
    let (reduced, check) = build_basis(&data, &settings).unwrap();
    println!(
        "basis {} vectors from {} snapshots in {:.1} s; max eigenvalue error {:.2e}, max 1-MAC {:.2e}; \
         evaluation {:.1} us reduced, {:.1} ms exact",
        check.size,
        check.n_snapshots,
        check.build_s,
        check.max_eigenvalue_rel,
        check.max_one_minus_mac,
        1e6 * check.reduced_eval_s,
        1e3 * check.exact_eval_s
    );
    assert!(check.max_eigenvalue_rel < 5e-3, "{check:?}");
    let post = smu_posterior(&data, reduced, Weighting::SmuLinearIndex).unwrap();
    for case in fixture()["cases"].as_array().unwrap() {
        let alpha = vec_of(&case["alpha"]);
        let want = case["objective_smu"].as_f64().unwrap();
        let got: f64 = post.residuals(&alpha).unwrap().iter().map(|r| r * r).sum();
        assert!(
            (got / want - 1.0).abs() < 5e-2,
            "{}: {got} vs {want}",
            case["name"]
        );
    }
}
