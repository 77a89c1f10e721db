//! The 946-DOF bridge reduced onto the DOFs of its simulated hammer campaign
//! (`experiments/models/bridge-hammer.toml`: ten accelerometers, three impact DOFs
//! among them) the way `diagnose` reduces it ([`reduce_for_campaign`]): its receptance
//! at the kept DOFs against the full model's direct solve, at the nominal point and at
//! corners of the prior box, over the analysed band (to 15.5 Hz).
//!
//! Skips (prints `SKIPPED: ...` and returns) when the shared data are absent.

use frfbayes::discrepancy::reduction::reduce_for_campaign;
use frfbayes::io::{Campaign, Channel, NominalModel, Quantity, Test, TestKind};
use frfbayes::model::{shared_root, ModelManifest};
use frfbayes::predict::kept::compare_frf_with_full;
use std::path::Path;

const ACCELEROMETERS: [usize; 10] = [167, 201, 444, 472, 632, 818, 870, 894, 919, 931];
const IMPACTS: [usize; 3] = [931, 167, 472];
/// The campaign's true stiffness variables.
const TRUTH: [f64; 17] = [
    0.05, -0.05, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, -0.1, 0.0, 0.0, 0.0, 0.0, 0.15, 0.0, -0.1, 0.0,
];

/// A campaign with the bridge campaign's channels and impacts (no samples: the
/// reduction reads only where the sensors and impacts are, and the sample rate).
fn skeleton(n_dof: usize) -> Campaign {
    let tests = IMPACTS
        .iter()
        .map(|&d| {
            let mut channels = vec![Channel {
                name: "force".into(),
                quantity: Quantity::Force,
                floor: d,
                unit: "N".into(),
            }];
            channels.extend(ACCELEROMETERS.iter().map(|&a| Channel {
                name: format!("acc{a}"),
                quantity: Quantity::Acceleration,
                floor: a,
                unit: "m/s^2".into(),
            }));
            Test {
                name: format!("hammer-dof{d}"),
                kind: TestKind::Hammer { excited_floor: d },
                sample_rate_hz: 60.0,
                data: vec![Vec::new(); channels.len()],
                channels,
            }
        })
        .collect();
    Campaign {
        root: Default::default(),
        title: "bridge skeleton".into(),
        nominal: NominalModel::general("bridge-fe.toml".into(), n_dof),
        tests,
        warnings: Vec::new(),
    }
}

/// Oracle: the reduced receptance at the kept DOFs against the full model's direct
/// solve (largest entry at each of 40 frequencies, 2-15.5 Hz), Rayleigh damping of the
/// campaign (1.5 % at 4.7 and 14 Hz): at its anchor (the nominal point; the campaign's
/// truth after re-anchoring) and 0.02 away in every group. About 4 minutes (120 dense
/// complex solves of 946 DOFs):
/// `cargo test --release --test bridge_reduction -- --ignored --nocapture`.
#[test]
#[ignore = "about 4 minutes; needs ../shared"]
fn reduced_bridge_matches_the_full_solve_over_the_band() {
    let p = shared_root().join("data/real/bridge-fe/SteelPedestrianBridgeExp.mat");
    if !p.is_file() {
        println!("SKIPPED: {} not found (no ../shared)", p.display());
        return;
    }
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/bridge-fe.toml");
    let full = ModelManifest::load(&manifest).unwrap();
    let campaign = skeleton(full.n_dof());
    let (renumbered, reduced, red) = reduce_for_campaign(&campaign, &full, Some(15.5)).unwrap();
    assert_eq!(red.kept_dof, ACCELEROMETERS.to_vec());
    assert_eq!(renumbered.tests[0].channels[0].floor, 10); // DOF 931 is the 10th kept
    println!(
        "kept {} DOFs + {} generalised of {}; connections {:?}",
        red.kept_dof.len(),
        red.n_generalised,
        red.full.n_dof(),
        red.connections
    );
    let m = reduced.model.nominal_mass();
    let diag = nalgebra::DVector::from_iterator(
        red.kept_dof.len(),
        (0..red.kept_dof.len()).map(|i| m[(i, i)]),
    );
    println!("reduced mass at the kept DOFs: {diag:.3e}");
    let freq: Vec<f64> = (0..40).map(|i| 2.0 + 13.5 * i as f64 / 39.0).collect();
    let rayleigh = (0.6596, 2.553e-4);
    let worst = |red: &frfbayes::predict::kept::KeptDofModel, alpha: &[f64]| {
        let e = compare_frf_with_full(&full, red, alpha, &[], rayleigh, &freq).unwrap();
        e.into_iter().fold(0.0, f64::max)
    };
    let nominal = worst(&reduced, &full.alpha_zero());
    // Re-anchored at the campaign's truth; then 0.02 away from it in every group, with
    // alternating signs (a uniform scale would keep the shapes).
    let (anchored, _) = red.reanchored(&TRUTH, &[]).unwrap();
    let at_anchor = worst(&anchored, &TRUTH);
    let near: Vec<f64> = TRUTH
        .iter()
        .enumerate()
        .map(|(r, a)| a + if r % 2 == 0 { 0.02 } else { -0.02 })
        .collect();
    let off_anchor = worst(&anchored, &near);
    let unanchored = worst(&reduced, &TRUTH);
    println!(
        "largest relative error: nominal {nominal:.2e}; truth {at_anchor:.2e} anchored there \
         ({unanchored:.2e} on the nominal basis); 0.02 off it {off_anchor:.2e}"
    );
    // Measured 2026-11-28: 1.2e-4, 1.3e-4 (5.4e-2 on the nominal basis), 8.5e-3. With the
    // static constraint modes of K0 instead of the anchor's K, the re-anchored figure was
    // 2.4e-3: the bound below fails on that basis.
    assert!(
        nominal < 5e-4 && at_anchor < 5e-4,
        "{nominal:e} {at_anchor:e}"
    );
    assert!(off_anchor < 2e-2, "{off_anchor:e}");
}
