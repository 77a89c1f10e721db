use super::*;
use crate::frf::{FrfKind, FrfPair};
use crate::modal::PartialOptions;
use crate::predict::{Coordinate, DenseModes, PartialModes, Scale, Variable};
use nalgebra::DMatrix;
use std::f64::consts::PI;

/// Oracle: the receptance at complex frequency `s` by a direct solve of
/// `(K + s C + s^2 M) x = f` with `C = a0 M + a1 K` (Eq. 1; ground excitation:
/// `f = -M iota`).
fn direct_frf(
    model: &StructuralModel,
    alpha: &[f64],
    beta: &[f64],
    (a0, a1): (f64, f64),
    response: usize,
    excitation: Excitation,
    s: Complex64,
) -> Complex64 {
    let (k, m) = (model.stiffness(alpha), model.mass(beta));
    let n = model.n_dof();
    let a = DMatrix::from_fn(n, n, |i, j| {
        k[(i, j)] * (1.0 + s * a1) + m[(i, j)] * (s * a0 + s * s)
    });
    let f = match excitation {
        Excitation::Dof(e) => nalgebra::DVector::from_fn(n, |i, _| {
            Complex64::new(if i == e { 1.0 } else { 0.0 }, 0.0)
        }),
        Excitation::Ground => {
            let mi = &m * model.ground_influence();
            nalgebra::DVector::from_fn(n, |i, _| Complex64::new(-mi[i], 0.0))
        }
    };
    a.lu().solve(&f).expect("regular dynamic stiffness")[response]
}

/// A 5-story frame with one log-scale stiffness and one mass coordinate per story.
fn frame() -> (Arc<StructuralModel>, Parametrisation) {
    let m = [5.0, 4.8, 4.6, 4.4, 4.0];
    let k = [1200.0, 1100.0, 1000.0, 900.0, 800.0];
    let model = Arc::new(StructuralModel::shear_frame(&m, &k).unwrap());
    let mut coords: Vec<Coordinate> = (0..5)
        .map(|r| Coordinate {
            name: format!("ln_k{}", r + 1),
            variable: Variable::Alpha(r),
            scale: Scale::Log { ln_offset: 0.0 },
        })
        .collect();
    coords.extend((0..5).map(|r| Coordinate {
        name: format!("beta{}", r + 1),
        variable: Variable::Beta(r),
        scale: Scale::Linear,
    }));
    let params = Parametrisation::new(&model, coords).unwrap();
    (model, params)
}

fn pairs(kind: FrfKind) -> Vec<FrfPair> {
    vec![
        FrfPair {
            response: 4,
            excitation: Excitation::Dof(1),
            kind,
        },
        FrfPair {
            response: 0,
            excitation: Excitation::Dof(0),
            kind,
        },
        FrfPair {
            response: 2,
            excitation: Excitation::Ground,
            kind,
        },
    ]
}

const THETA_STRUCT: [f64; 10] = [0.05, -0.1, 0.02, 0.0, 0.08, 0.03, -0.02, 0.0, 0.01, -0.04];
const A0_A1: (f64, f64) = (0.3, 2e-4);

/// With every mode kept, the modal sum is the direct solve, for force and ground
/// excitation, every kind, with and without an exponential window: the complex values,
/// and the magnitudes of the fused kernel (window on the modal parameters, its gain on
/// the values).
#[test]
fn all_modes_match_the_direct_solve() {
    let (model, params) = frame();
    let omega: Vec<f64> = (1..60).map(|k| 2.0 * PI * 0.25 * k as f64).collect();
    for kind in [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance] {
        for tau in [None, Some(4.0)] {
            let blocks = [FrfBlock {
                omega_rad_s: omega.clone(),
                pairs: pairs(kind),
            }];
            let predictor = |output| {
                let options = FrfOptions {
                    damping: FrfDamping::Rayleigh,
                    output,
                    n_modes: 5,
                };
                let solver = DenseModes::new(model.clone());
                FrfPredictor::new(
                    solver,
                    model.clone(),
                    params.clone(),
                    options,
                    &blocks,
                    &[tau],
                )
                .unwrap()
            };
            let p = predictor(FrfOutput::Complex);
            let mut theta = THETA_STRUCT.to_vec();
            theta.extend([A0_A1.0.ln(), A0_A1.1.ln()]);
            let mut out = vec![0.0; p.n_outputs()];
            p.predict(&theta, &mut p.workspace(), &mut out).unwrap();
            let pm = predictor(FrfOutput::Magnitude);
            let mut magnitude = vec![0.0; pm.n_outputs()];
            pm.predict(&theta, &mut pm.workspace(), &mut magnitude)
                .unwrap();
            let (mut alpha, mut beta) = (Vec::new(), Vec::new());
            params.apply(&theta[..10], &mut alpha, &mut beta);
            let eps = tau.map_or(0.0, |t| 1.0 / t);
            let mut k = 0;
            for pair in &blocks[0].pairs {
                for &w in &omega {
                    let s = Complex64::new(eps, w);
                    let h = direct_frf(
                        &model,
                        &alpha,
                        &beta,
                        A0_A1,
                        pair.response,
                        pair.excitation,
                        s,
                    ) * s.powi(kind.power());
                    let got = Complex64::new(out[k], out[k + 1]);
                    assert!(
                        (got - h).norm() <= 1e-9 * h.norm(),
                        "{kind:?} tau {tau:?} {pair:?} {w}: {got} vs {h}"
                    );
                    let m = magnitude[k / 2];
                    assert!(
                        (m - h.norm()).abs() <= 1e-9 * h.norm(),
                        "{kind:?} tau {tau:?} {pair:?} {w}: |H| {m} vs {}",
                        h.norm()
                    );
                    k += 2;
                }
            }
        }
    }
}

/// Modal damping: `c_i = 2 xi_i omega_i`, as the reference modal sum of `crate::frf`.
#[test]
fn modal_damping_matches_the_reference_modal_sum() {
    let (model, params) = frame();
    let omega: Vec<f64> = (1..40).map(|k| 2.0 * PI * 0.3 * k as f64).collect();
    let blocks = [FrfBlock {
        omega_rad_s: omega.clone(),
        pairs: pairs(FrfKind::Accelerance),
    }];
    let p = FrfPredictor::new(
        DenseModes::new(model.clone()),
        model.clone(),
        params.clone(),
        FrfOptions {
            damping: FrfDamping::Modal,
            output: FrfOutput::LogMagnitude,
            n_modes: 5,
        },
        &blocks,
        &[None],
    )
    .unwrap();
    let xi = [0.02, 0.01, 0.015, 0.005, 0.03];
    let mut theta = THETA_STRUCT.to_vec();
    theta.extend(xi.iter().map(|x: &f64| x.ln()));
    let mut out = vec![0.0; p.n_outputs()];
    p.predict(&theta, &mut p.workspace(), &mut out).unwrap();
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    params.apply(&theta[..10], &mut alpha, &mut beta);
    let modes = crate::modal::Modes::solve(
        &model.stiffness(&alpha),
        &model.mass(&beta),
        model.ground_influence(),
        None,
    )
    .unwrap();
    let c: Vec<f64> = modes
        .omega_rad_s
        .iter()
        .zip(xi)
        .map(|(w, x)| 2.0 * x * w)
        .collect();
    let mut k = 0;
    for pair in &blocks[0].pairs {
        for &w in &omega {
            let h = crate::frf::modal_frf(&modes, &c, pair, w).norm().ln();
            assert!(
                (out[k] - h).abs() < 1e-10,
                "{pair:?} {w}: {} vs {h}",
                out[k]
            );
            k += 1;
        }
    }
}

/// The sparse partial solver gives the dense solver's FRFs over its lowest modes.
#[test]
fn partial_solver_matches_the_dense_one() {
    let n = 40;
    let model = Arc::new(
        StructuralModel::shear_frame(
            &vec![2.0; n],
            &(0..n).map(|i| 900.0 + 10.0 * i as f64).collect::<Vec<_>>(),
        )
        .unwrap(),
    );
    let params = Parametrisation::all_alphas(&model).unwrap();
    let omega: Vec<f64> = (1..30).map(|k| 2.0 * PI * 0.05 * k as f64).collect();
    let blocks = [FrfBlock {
        omega_rad_s: omega,
        pairs: vec![FrfPair {
            response: n - 1,
            excitation: Excitation::Dof(n / 2),
            kind: FrfKind::Accelerance,
        }],
    }];
    let mut theta = vec![0.01; n];
    theta.extend([0.2f64.ln(), 1e-4f64.ln()]);
    let run = |p: &dyn Fn(&[f64], &mut [f64])| {
        let mut out = vec![0.0; 29];
        p(&theta, &mut out);
        out
    };
    let dense = FrfPredictor::new(
        DenseModes::new(model.clone()),
        model.clone(),
        params.clone(),
        FrfOptions {
            damping: FrfDamping::Rayleigh,
            output: FrfOutput::Magnitude,
            n_modes: 6,
        },
        &blocks,
        &[Some(10.0)],
    )
    .unwrap();
    let partial = FrfPredictor::new(
        PartialModes::new(model.clone(), PartialOptions::default()).unwrap(),
        model.clone(),
        params,
        FrfOptions {
            damping: FrfDamping::Rayleigh,
            output: FrfOutput::Magnitude,
            n_modes: 6,
        },
        &blocks,
        &[Some(10.0)],
    )
    .unwrap();
    let a = run(&|t, o| dense.predict(t, &mut dense.workspace(), o).unwrap());
    let b = run(&|t, o| partial.predict(t, &mut partial.workspace(), o).unwrap());
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= 1e-9 * x.abs(), "{x} vs {y}");
    }
}

#[test]
fn rejects_bad_pairs_modes_and_windows() {
    let (model, params) = frame();
    let mk = |pairs: Vec<FrfPair>, n_modes: usize, tau: Option<f64>| {
        FrfPredictor::new(
            DenseModes::new(model.clone()),
            model.clone(),
            params.clone(),
            FrfOptions {
                damping: FrfDamping::Rayleigh,
                output: FrfOutput::Magnitude,
                n_modes,
            },
            &[FrfBlock {
                omega_rad_s: vec![1.0, 2.0],
                pairs,
            }],
            &[tau],
        )
        .map(|_| ())
    };
    let good = pairs(FrfKind::Receptance);
    assert!(mk(good.clone(), 5, None).is_ok());
    let bad = vec![FrfPair {
        response: 5,
        excitation: Excitation::Dof(0),
        kind: FrfKind::Receptance,
    }];
    assert!(mk(bad, 5, None)
        .unwrap_err()
        .to_string()
        .contains("outside the 5-DOF model"));
    assert!(mk(good.clone(), 0, None).is_err());
    assert!(mk(good.clone(), 6, None).is_err());
    assert!(mk(good, 5, Some(-1.0)).is_err());
}
