//! Oracle tests: the modal sums (Eqs. 7, 10, 15, 16) against the direct inverse of
//! Eq. (1) and Eq. (14), for random well-conditioned models.

use super::*;
use crate::model::{
    caughey_coefficients, caughey_damping_matrix, rayleigh_damping_matrix, Damping, StructuralModel,
};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Relative agreement required between modal sum and direct solve.
const ORACLE_RTOL: f64 = 1e-10;

fn random_shear_frame(rng: &mut ChaCha8Rng, n: usize) -> StructuralModel {
    let m: Vec<f64> = (0..n).map(|_| rng.random_range(1.0..10.0)).collect();
    let k: Vec<f64> = (0..n).map(|_| rng.random_range(500.0..5000.0)).collect();
    StructuralModel::shear_frame(&m, &k).unwrap()
}

fn all_pairs(n: usize) -> Vec<FrfPair> {
    let mut pairs = Vec::new();
    for kind in [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance] {
        for r in 0..n {
            for e in 0..n {
                pairs.push(FrfPair {
                    response: r,
                    excitation: Excitation::Dof(e),
                    kind,
                });
            }
            pairs.push(FrfPair {
                response: r,
                excitation: Excitation::Ground,
                kind,
            });
        }
    }
    pairs
}

fn check_against_direct(
    model: &StructuralModel,
    alpha: &[f64],
    beta: &[f64],
    damping: &Damping,
    c: &DMatrix<f64>,
) {
    let (k, m) = (model.stiffness(alpha), model.mass(beta));
    let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
    let mut modal_c = vec![0.0; modes.n_modes()];
    damping
        .modal_coefficients(&modes.omega_rad_s, &mut modal_c)
        .unwrap();
    let wmax = modes.omega_rad_s.last().unwrap() * 1.5;
    // Include the natural frequencies themselves, where the sums are most sensitive.
    let mut omega: Vec<f64> = (1..200).map(|i| wmax * i as f64 / 200.0).collect();
    omega.extend(&modes.omega_rad_s);
    let blocks = vec![FrfBlock {
        omega_rad_s: omega,
        pairs: all_pairs(model.n_dof()),
    }];
    let direct = direct::block_frfs(&m, &k, c, model.ground_influence(), &blocks).unwrap();
    let mut fast = ModalFrf::new(blocks.clone());
    let mut h = vec![Complex64::new(0.0, 0.0); fast.len()];
    fast.complex(&modes, &modal_c, &mut h).unwrap();
    let mut mag = vec![0.0; fast.len()];
    fast.magnitudes(&modes, &modal_c, &mut mag).unwrap();
    let mut idx = 0;
    for b in &blocks {
        for p in &b.pairs {
            for &w in &b.omega_rad_s {
                let (a, d) = (h[idx], direct[idx]);
                let rel = (a - d).norm() / d.norm();
                assert!(
                    rel < ORACLE_RTOL,
                    "pair {p:?} at {w} rad/s: modal {a} vs direct {d} (rel {rel:e})"
                );
                assert!((mag[idx] - d.norm()).abs() <= ORACLE_RTOL * d.norm());
                let single = modal_frf(&modes, &modal_c, p, w);
                assert!((single - d).norm() <= ORACLE_RTOL * d.norm());
                idx += 1;
            }
        }
    }
}

#[test]
fn rayleigh_modal_sum_equals_direct_inverse() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for n in [1, 2, 4, 6] {
        for _ in 0..5 {
            let model = random_shear_frame(&mut rng, n);
            let alpha: Vec<f64> = (0..n).map(|_| rng.random_range(-0.3..0.3)).collect();
            let beta: Vec<f64> = (0..n).map(|_| rng.random_range(-0.3..0.3)).collect();
            let (a0, a1) = (rng.random_range(0.01..0.5), rng.random_range(1e-6..1e-3));
            let c = rayleigh_damping_matrix(&model.mass(&beta), &model.stiffness(&alpha), a0, a1);
            check_against_direct(
                &model,
                &alpha,
                &beta,
                &Damping::Rayleigh {
                    a0_per_s: a0,
                    a1_s: a1,
                },
                &c,
            );
        }
    }
}

#[test]
fn caughey_modal_sum_equals_direct_inverse() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for n in [1, 2, 4, 5] {
        for _ in 0..5 {
            let model = random_shear_frame(&mut rng, n);
            let alpha: Vec<f64> = (0..n).map(|_| rng.random_range(-0.3..0.3)).collect();
            let beta: Vec<f64> = (0..n).map(|_| rng.random_range(-0.3..0.3)).collect();
            let xi: Vec<f64> = (0..n).map(|_| rng.random_range(0.002..0.05)).collect();
            let (k, m) = (model.stiffness(&alpha), model.mass(&beta));
            let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
            let a = caughey_coefficients(&modes.omega_rad_s, &xi).unwrap();
            let c = caughey_damping_matrix(&m, &k, &a).unwrap();
            check_against_direct(&model, &alpha, &beta, &Damping::Caughey { xi }, &c);
        }
    }
}

#[test]
fn general_model_with_full_matrices() {
    // A random SPD stiffness and mass (not a chain), with Rayleigh damping.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 5;
    let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    let k0 = &a * a.transpose() + DMatrix::identity(n, n) * 2.0;
    let b = DMatrix::from_fn(n, n, |_, _| rng.random_range(-0.3..0.3));
    let m0 = &b * b.transpose() + DMatrix::identity(n, n);
    let model =
        StructuralModel::from_matrices(k0.clone(), m0.clone(), vec![], vec![], None).unwrap();
    let c = rayleigh_damping_matrix(&m0, &k0, 0.05, 0.002);
    check_against_direct(
        &model,
        &[],
        &[],
        &Damping::Rayleigh {
            a0_per_s: 0.05,
            a1_s: 0.002,
        },
        &c,
    );
}

#[test]
fn truncation_keeps_leading_modes() {
    let model =
        StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0]).unwrap();
    let (k, m) = (model.stiffness(&[0.0; 4]), model.mass(&[0.0; 4]));
    let all = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
    let two = Modes::solve(&k, &m, model.ground_influence(), Some(2)).unwrap();
    assert_eq!(&all.omega_rad_s[..2], &two.omega_rad_s[..]);
    // Near mode 1, the truncated sum is close to the full one (other modes are far).
    let p = FrfPair {
        response: 3,
        excitation: Excitation::Dof(0),
        kind: FrfKind::Receptance,
    };
    let w = all.omega_rad_s[0];
    let c = [0.04 * w, 0.04 * all.omega_rad_s[1]];
    let full_c: Vec<f64> = all.omega_rad_s.iter().map(|w| 0.04 * w).collect();
    let h_all = modal_frf(&all, &full_c, &p, w);
    let h_two = modal_frf(&two, &c, &p, w);
    assert!((h_all - h_two).norm() / h_all.norm() < 0.01);
}

/// The fused magnitude kernel (chunks of `LANES` frequencies plus a scalar remainder)
/// against the direct inverse of Eq. (1), on several blocks whose grid lengths 1..=9
/// cover every remainder, in one evaluator (so block offsets and the reused scratch are
/// exercised too).
#[test]
fn fused_magnitudes_equal_direct_inverse_for_every_grid_length() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let model = random_shear_frame(&mut rng, 4);
    let (alpha, beta) = ([0.1, -0.2, 0.05, 0.0], [0.0, 0.1, -0.1, 0.2]);
    let (k, m) = (model.stiffness(&alpha), model.mass(&beta));
    let xi = [0.02, 0.01, 0.03, 0.015];
    let damping = Damping::Caughey { xi: xi.to_vec() };
    let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
    let mut modal_c = vec![0.0; 4];
    damping
        .modal_coefficients(&modes.omega_rad_s, &mut modal_c)
        .unwrap();
    let a = caughey_coefficients(&modes.omega_rad_s, &xi).unwrap();
    let c = caughey_damping_matrix(&m, &k, &a).unwrap();
    let wmax = modes.omega_rad_s[3] * 1.3;
    let blocks: Vec<FrfBlock> = (1..=9)
        .map(|nw| FrfBlock {
            omega_rad_s: (0..nw)
                .map(|i| wmax * (i as f64 + 0.5 + 0.1 * nw as f64) / 10.0)
                .collect(),
            pairs: all_pairs(4),
        })
        .collect();
    let direct = direct::block_frfs(&m, &k, &c, model.ground_influence(), &blocks).unwrap();
    let mut fast = ModalFrf::new(blocks);
    let mut mag = vec![0.0; fast.len()];
    fast.magnitudes(&modes, &modal_c, &mut mag).unwrap();
    assert_eq!(mag.len(), direct.len());
    for (i, (a, d)) in mag.iter().zip(&direct).enumerate() {
        assert!(
            (a - d.norm()).abs() <= ORACLE_RTOL * d.norm(),
            "point {i}: {a} vs {}",
            d.norm()
        );
    }
}

/// The AVX build of the magnitude kernel gives the bits of the portable build (the
/// crate docs promise CPU-independent results), on grids of 1..=9 frequencies (every
/// partial chunk) and 1..=10 modes (every batch-inversion group size, the kernels for
/// a fixed mode count and the general one).
#[test]
fn magnitude_kernel_bits_do_not_depend_on_the_instruction_set() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for m in 1..=MAX_FIXED_MODES + 2 {
        for nw in 1..=9 {
            let omega: Vec<f64> = (0..nw).map(|_| rng.random_range(1.0..200.0)).collect();
            let omega_n: Vec<f64> = (0..m).map(|_| rng.random_range(1.0..200.0)).collect();
            let modal_c: Vec<f64> = (0..m).map(|_| rng.random_range(0.01..5.0)).collect();
            let pairs = all_pairs(2);
            let coef: Vec<f64> = (0..pairs.len() * m)
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            let run = |avx: bool| {
                let mut chunk = vec![[0.0; LANES]; 3 * m];
                let mut out = vec![0.0; nw * pairs.len()];
                let args = BlockArgs {
                    omega_rad_s: &omega,
                    pairs: &pairs,
                    omega_n_rad_s: &omega_n,
                    modal_c: &modal_c,
                    coef: &coef,
                    chunk: &mut chunk,
                    out: &mut out,
                };
                if avx {
                    #[cfg(target_arch = "x86_64")]
                    // SAFETY: only called when the CPU supports AVX.
                    unsafe {
                        block_magnitudes_avx(args)
                    };
                } else {
                    block_magnitudes(args);
                }
                out
            };
            let portable = run(false);
            // Against the modal sum with one division per pole, to rounding.
            for (p, pair) in pairs.iter().enumerate() {
                for (k, &w) in omega.iter().enumerate() {
                    let mut h = Complex64::new(0.0, 0.0);
                    for i in 0..m {
                        let den = Complex64::new(omega_n[i].powi(2) - w * w, modal_c[i] * w);
                        h += coef[p * m + i] / den;
                    }
                    let want = h.norm() * w.powi(pair.kind.power());
                    let got = portable[p * nw + k];
                    assert!((got - want).abs() <= 1e-12 * want, "{got} vs {want}");
                }
            }
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                assert_eq!(run(true), portable, "{m} modes, {nw} frequencies");
            }
        }
    }
}

/// Batch inversion: within a few ulps of `1 / x` for groups of every size, and exactly
/// `1 / x` for a group whose product leaves the normal range in some lane.
#[test]
fn batch_reciprocals_match_division() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for n in 1..=9 {
        let x: Vec<Lanes> = (0..n)
            .map(|_| std::array::from_fn(|_| 10f64.powf(rng.random_range(-8.0..8.0))))
            .collect();
        let mut r = x.clone();
        reciprocals(&mut r);
        for (a, b) in x.iter().flatten().zip(r.iter().flatten()) {
            // Each reciprocal takes at most 2 GROUP roundings: relative error < 8 eps.
            assert!((a * b - 1.0).abs() < 8.0 * f64::EPSILON, "{a} * {b}");
        }
    }
    for odd in [0.0, 1e-320, 1e307, f64::NAN, f64::INFINITY] {
        let x = vec![[2.0, 4.0, odd, 8.0], [1e3; LANES], [3.0; LANES]];
        let mut r = x.clone();
        reciprocals(&mut r);
        for (a, b) in x.iter().flatten().zip(r.iter().flatten()) {
            assert!(b.to_bits() == (1.0 / a).to_bits() || (b.is_nan() && a.is_nan()));
        }
    }
}

/// No modes: all magnitudes zero (no panic on the empty coefficient table).
#[test]
fn magnitudes_without_modes_are_zero() {
    let model = StructuralModel::shear_frame(&[1.0, 2.0], &[100.0, 200.0]).unwrap();
    let (k, m) = (model.stiffness(&[0.0; 2]), model.mass(&[0.0; 2]));
    let modes = Modes::solve(&k, &m, model.ground_influence(), Some(0)).unwrap();
    let mut fast = ModalFrf::new(vec![FrfBlock {
        omega_rad_s: vec![1.0, 2.0],
        pairs: all_pairs(2),
    }]);
    let mut mag = vec![1.0; fast.len()];
    fast.magnitudes(&modes, &[], &mut mag).unwrap();
    assert!(mag.iter().all(|&x| x == 0.0));
}
