//! Oracle: the inference layer's FRF predictor (`predict::FrfPredictor` on the dense
//! solver, as `bayes::layer::frf_predictor` builds it) gives the magnitudes of the
//! posterior's forward model (`bayes::ForwardModel`) on the four-story campaign's hammer
//! and shake-table blocks, with their exponential windows and without, for receptance,
//! mobility and accelerance, Rayleigh and Caughey damping, at points drawn across the
//! prior box.

use frfbayes::bayes::layer::frf_predictor;
use frfbayes::bayes::run::{prepare, SampleSettings, TestSelection};
use frfbayes::bayes::ForwardModel;
use frfbayes::frf::{FrfBlock, FrfKind};
use frfbayes::predict::Predict;
use frfbayes::update::{DampingModel, Variables};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Relative tolerance of the comparison.
const REL_TOL: f64 = 1e-12;

#[test]
fn frf_predictor_equals_the_forward_model_on_the_four_story_campaign() {
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
    let model = prepared.posterior.forward().model().clone();
    assert!(
        data.window_tau_s.iter().any(Option::is_some),
        "no windowed block"
    );
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let (mut n_values, mut n_exact) = (0usize, 0usize);
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
                let fm = ForwardModel::new(model.clone(), vars.clone(), 4, blocks.clone(), taus)
                    .unwrap();
                let fp = frf_predictor(&model, &vars, 4, &blocks, taus).unwrap();
                assert_eq!(fp.n_outputs(), fm.len());
                let (mut ws, mut fws) = (fp.workspace(), fm.workspace());
                let (mut a, mut b) = (vec![0.0; fm.len()], vec![0.0; fm.len()]);
                for _ in 0..10 {
                    let z: Vec<f64> = (0..bounds.len())
                        .map(|i| rng.random_range(bounds.lower()[i]..bounds.upper()[i]))
                        .collect();
                    fp.predict(&z, &mut ws, &mut a).unwrap();
                    fm.magnitudes(&vars.theta(&z), &mut fws, &mut b).unwrap();
                    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
                        assert!(
                            (x - y).abs() <= REL_TOL * y.abs(),
                            "{damping:?} {kind:?} windows {}: value {k}: {x} vs {y}",
                            taus.iter().any(Option::is_some)
                        );
                    }
                    n_values += a.len();
                    n_exact += a.iter().zip(&b).filter(|(x, y)| x == y).count();
                }
            }
        }
    }
    println!("{n_exact} of {n_values} values bit for bit equal");
}
