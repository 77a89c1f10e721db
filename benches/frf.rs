//! The inner loop of everything: modal-sum FRF magnitudes for the 4-DOF frame,
//! 4 excitations x 4 responses x 500 frequency points, Caughey damping, including the
//! eigen-solve (Eq. 22b). Baseline: the naive direct solve of Eq. (1) at every frequency.

use criterion::{criterion_group, criterion_main, Criterion};
use frfbayes::frf::{direct, Excitation, FrfBlock, FrfKind, FrfPair, ModalFrf};
use frfbayes::modal::Modes;
use frfbayes::model::{caughey_coefficients, caughey_damping_matrix, Damping, StructuralModel};
use num_complex::Complex64;
use std::hint::black_box;

const N_FREQ: usize = 500;

fn setup() -> (StructuralModel, FrfBlock, Damping) {
    let model =
        StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0]).unwrap();
    let omega: Vec<f64> = (0..N_FREQ)
        .map(|i| 2.0 * std::f64::consts::PI * (0.2 + 7.8 * i as f64 / N_FREQ as f64))
        .collect();
    let pairs = (0..4)
        .flat_map(|e| {
            (0..4).map(move |r| FrfPair {
                response: r,
                excitation: Excitation::Dof(e),
                kind: FrfKind::Accelerance,
            })
        })
        .collect();
    (
        model,
        FrfBlock {
            omega_rad_s: omega,
            pairs,
        },
        Damping::Caughey {
            xi: vec![0.016, 0.011, 0.005, 0.002],
        },
    )
}

fn bench(c: &mut Criterion) {
    let (model, block, damping) = setup();
    let alpha = [0.07, 0.03, -0.02, 0.08];
    let beta = [0.1, 0.07, 0.06, 0.1];
    let mut eval = ModalFrf::new(vec![block.clone()]);
    let mut out = vec![0.0; eval.len()];
    let mut modal_c = [0.0; 4];
    c.bench_function("modal_sum_4dof_16pairs_500f_caughey_magnitudes", |b| {
        b.iter(|| {
            let k = model.stiffness(black_box(&alpha));
            let m = model.mass(black_box(&beta));
            let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
            damping
                .modal_coefficients(&modes.omega_rad_s, &mut modal_c)
                .unwrap();
            eval.magnitudes(&modes, &modal_c, &mut out).unwrap();
            black_box(&out);
        })
    });
    c.bench_function("eigen_solve_4dof", |b| {
        b.iter(|| {
            let k = model.stiffness(black_box(&alpha));
            let m = model.mass(black_box(&beta));
            black_box(Modes::solve(&k, &m, model.ground_influence(), None).unwrap());
        })
    });
    let mut group = c.benchmark_group("baseline");
    group.sample_size(10);
    group.bench_function("direct_solve_4dof_16pairs_500f_caughey_magnitudes", |b| {
        b.iter(|| {
            let k = model.stiffness(black_box(&alpha));
            let m = model.mass(black_box(&beta));
            let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
            let xi = match &damping {
                Damping::Caughey { xi } => xi.clone(),
                Damping::Rayleigh { .. } => unreachable!(),
            };
            let a = caughey_coefficients(&modes.omega_rad_s, &xi).unwrap();
            let cm = caughey_damping_matrix(&m, &k, &a).unwrap();
            let h: Vec<Complex64> = direct::block_frfs(
                &m,
                &k,
                &cm,
                model.ground_influence(),
                std::slice::from_ref(&block),
            )
            .unwrap();
            let mags: Vec<f64> = h.iter().map(|z| z.norm()).collect();
            black_box(mags);
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
