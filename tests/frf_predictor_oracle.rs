//! Oracle: the FRF posterior's forward model on the inference layer
//! (`predict::FrfPredictor` on the dense solver, as `bayes::layer::frf_predictor` builds
//! it) gives the windowed modal sum at the complex frequency `omega - j/tau`
//! (`signal::windowed_modal_frf`, point by point) on the four-story campaign's hammer
//! and shake-table blocks, with their exponential windows and without, for receptance,
//! mobility and accelerance, Rayleigh and Caughey damping, at points drawn across the
//! prior box. (Before `bayes::ForwardModel` was deleted, the predictor equalled it to
//! 1e-12 relative on the same blocks, 59,520 of 59,520 values bit for bit.)

use frfbayes::bayes::layer::frf_predictor;
use frfbayes::bayes::run::{prepare, SampleSettings, TestSelection};
use frfbayes::frf::{FrfBlock, FrfKind};
use frfbayes::modal::Modes;
use frfbayes::predict::Predict;
use frfbayes::signal::windowed_modal_frf;
use frfbayes::update::{DampingModel, Variables};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Relative tolerance: the fused kernel's batch inversion and the oracle's complex
/// divisions differ by a few ulps per pole.
const REL_TOL: f64 = 1e-11;

#[test]
fn frf_predictor_equals_the_windowed_modal_sum_on_the_four_story_campaign() {
    let settings = SampleSettings::new(
        "bundled:four-story".into(),
        DampingModel::Caughey,
        FrfKind::Receptance,
        TestSelection::All,
        1,
    )
    .unwrap();
    let prepared = prepare(&settings).unwrap();
    let data = prepared.posterior.data().clone();
    let model = std::sync::Arc::new(prepared.posterior.model().clone());
    let solver = prepared.posterior.mode_solver().clone();
    assert!(
        data.window_tau_s.iter().any(Option::is_some),
        "no windowed block"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    for damping in [DampingModel::Rayleigh, DampingModel::Caughey] {
        let vars = Variables::new(&model, damping, 4, &settings.variables).unwrap();
        let bounds = vars.internal_bounds();
        for kind in [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance] {
            let blocks: Vec<FrfBlock> = data
                .blocks
                .iter()
                .map(|b| {
                    let mut b = b.clone();
                    b.pairs.iter_mut().for_each(|p| p.kind = kind);
                    b
                })
                .collect();
            let none = vec![None; blocks.len()];
            for taus in [&data.window_tau_s, &none] {
                let fp = frf_predictor(&model, &vars, 4, &blocks, taus, solver.clone()).unwrap();
                let mut ws = fp.workspace();
                let mut out = vec![0.0; fp.n_outputs()];
                for _ in 0..5 {
                    let z: Vec<f64> = (0..bounds.len())
                        .map(|i| rng.random_range(bounds.lower()[i]..bounds.upper()[i]))
                        .collect();
                    fp.predict(&z, &mut ws, &mut out).unwrap();
                    let theta = vars.theta(&z);
                    let (alpha, beta, d) = vars.split(&theta);
                    let (k, m) = (model.stiffness(alpha), model.mass(beta));
                    let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
                    let mut c = vec![0.0; 4];
                    d.modal_coefficients(&modes.omega_rad_s, &mut c).unwrap();
                    let mut i = 0;
                    for (b, tau) in blocks.iter().zip(taus.iter()) {
                        for pair in &b.pairs {
                            for &w in &b.omega_rad_s {
                                let tau = tau.unwrap_or(f64::INFINITY);
                                let h = windowed_modal_frf(&modes, &c, pair, w, tau).norm();
                                assert!(
                                    (out[i] - h).abs() <= REL_TOL * h,
                                    "{damping:?} {kind:?} value {i}: {} vs {h}",
                                    out[i]
                                );
                                i += 1;
                            }
                        }
                    }
                    assert_eq!(i, out.len());
                }
            }
        }
    }
}
