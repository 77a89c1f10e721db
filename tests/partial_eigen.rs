//! The sparse shift-invert partial eigen-solver (`frfbayes::modal::partial`) against the
//! full dense solve (static condensation of the massless DOFs, then nalgebra or faer):
//! a synthetic clamped beam with massless rotations and random parameters, the 946-DOF
//! bridge (skipped with a message when `../shared` is absent), the error cases, and an
//! ignored timing study:
//!
//!   FRFBAYES_SHARED_DIR=/work/shared nice -n 10 cargo test --release --test partial_eigen \
//!       -- --ignored --nocapture bridge_speed

use frfbayes::modal::{mac, Modes, PartialOptions, PartialSolver};
#[path = "oracle/condense.rs"]
mod condense_oracle;
use condense_oracle::condense;
use frfbayes::model::sparse::SparsePencil;
use frfbayes::model::{shared_root, ModelManifest, Parameter, StructuralModel};
use frfbayes::predict::{ModalPredictor, Parametrisation, PartialModes, Predict};
use frfbayes::Error;
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Euler-Bernoulli beam on an elastic foundation: `n_el` elements (length 0.1 m, EI
/// 1e4 N m^2), 1 kg lumped on each node's deflection, rotations massless, a grounded
/// 1e3 N/m spring on each deflection; clamped at node 0 when `clamped`. DOFs per node:
/// deflection then rotation. Alphas: five segments of elements and the foundation;
/// betas: the masses of the two halves. (Without the foundation the 150-element beam
/// has lambda_1 = 4.3 against entries of K up to 1e8, and two dense solvers then differ
/// by 5e-9 in lambda_1: no oracle at 1e-9.)
fn beam(n_el: usize, clamped: bool) -> StructuralModel {
    let (l, ei) = (0.1, 1e4);
    let nodes = if clamped { n_el } else { n_el + 1 };
    let n = 2 * nodes;
    let dof = |node: usize, r: usize| -> Option<usize> {
        match (clamped, node) {
            (true, 0) => None,
            (true, k) => Some(2 * (k - 1) + r),
            (false, k) => Some(2 * k + r),
        }
    };
    let c = ei / (l * l * l);
    let ke = [
        [12.0, 6.0 * l, -12.0, 6.0 * l],
        [6.0 * l, 4.0 * l * l, -6.0 * l, 2.0 * l * l],
        [-12.0, -6.0 * l, 12.0, -6.0 * l],
        [6.0 * l, 2.0 * l * l, -6.0 * l, 4.0 * l * l],
    ];
    let mut groups = vec![DMatrix::zeros(n, n); 6];
    for e in 0..n_el {
        let d = [dof(e, 0), dof(e, 1), dof(e + 1, 0), dof(e + 1, 1)];
        let g = &mut groups[e * 5 / n_el];
        for (a, da) in d.iter().enumerate() {
            for (b, db) in d.iter().enumerate() {
                if let (Some(i), Some(j)) = (da, db) {
                    g[(*i, *j)] += c * ke[a][b];
                }
            }
        }
    }
    for node in 0..=n_el {
        if let Some(i) = dof(node, 0) {
            groups[5][(i, i)] = 1e3;
        }
    }
    let mut masses = vec![DMatrix::zeros(n, n); 2];
    for k in 0..nodes {
        let i = 2 * k;
        masses[usize::from(2 * k >= nodes)][(i, i)] = 1.0;
    }
    let k0 = groups.iter().fold(DMatrix::zeros(n, n), |a, b| a + b);
    let m0 = &masses[0] + &masses[1];
    let p = |s: String| Parameter {
        name: s,
        unit: "-".into(),
        nominal: None,
    };
    let ks = groups
        .into_iter()
        .enumerate()
        .map(|(r, g)| (p(format!("k{r}")), g));
    let ms = masses
        .into_iter()
        .enumerate()
        .map(|(r, g)| (p(format!("m{r}")), g));
    StructuralModel::from_matrices(k0, m0, ks.collect(), ms.collect(), None).unwrap()
}

/// The dense oracle: eigenvalues (ascending) and full shapes (mass-normalised) of the
/// lowest `m` modes, by condensing the massless DOFs and nalgebra's dense solve.
fn dense_lowest(k: &DMatrix<f64>, mm: &DMatrix<f64>, m: usize) -> (Vec<f64>, DMatrix<f64>) {
    let c = condense(k, mm).unwrap();
    let iota = DVector::from_element(c.kept.len(), 1.0);
    let modes = Modes::solve(&c.k, &c.m, &iota, Some(m)).unwrap();
    let lambda = modes.omega_rad_s.iter().map(|w| w * w).collect();
    (lambda, expand(k, &c.kept, &c.massless, &modes.phi))
}

/// Full shapes from shapes on the `kept` DOFs: `phi_s = -K_ss^-1 K_sm phi_m`.
fn expand(
    k: &DMatrix<f64>,
    kept: &[usize],
    massless: &[usize],
    phi_m: &DMatrix<f64>,
) -> DMatrix<f64> {
    let sub = |r: &[usize], c: &[usize]| DMatrix::from_fn(r.len(), c.len(), |i, j| k[(r[i], c[j])]);
    let mut full = DMatrix::zeros(k.nrows(), phi_m.ncols());
    for (a, &i) in kept.iter().enumerate() {
        full.row_mut(i).copy_from(&phi_m.row(a));
    }
    if !massless.is_empty() {
        let kss = sub(massless, massless).cholesky().unwrap();
        let phi_s = -kss.solve(&(sub(massless, kept) * phi_m));
        for (a, &i) in massless.iter().enumerate() {
            full.row_mut(i).copy_from(&phi_s.row(a));
        }
    }
    full
}

/// Largest relative eigenvalue difference and smallest MAC of the lowest `m` modes.
fn compare(
    lambda: &[f64],
    phi: &DMatrix<f64>,
    l_ref: &[f64],
    phi_ref: &DMatrix<f64>,
) -> (f64, f64) {
    let mut worst = (0.0_f64, 1.0_f64);
    for i in 0..l_ref.len() {
        worst.0 = worst.0.max((lambda[i] - l_ref[i]).abs() / l_ref[i].abs());
        let m = mac(phi.column(i).as_slice(), phi_ref.column(i).as_slice());
        worst.1 = worst.1.min(m);
    }
    worst
}

#[test]
fn beam_lowest_ten_match_the_dense_solve() {
    let model = beam(150, true);
    assert_eq!(model.n_dof(), 300);
    let solver = PartialSolver::new(
        Arc::new(SparsePencil::from_model(&model)),
        PartialOptions::default(),
    )
    .unwrap();
    let mut ws = solver.workspace();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for point in 0..6 {
        let (alpha, beta): (Vec<f64>, Vec<f64>) = if point == 0 {
            (model.alpha_zero(), model.beta_zero())
        } else {
            (
                (0..6).map(|_| rng.random_range(-0.5..1.0)).collect(),
                (0..2).map(|_| rng.random_range(-0.3..0.5)).collect(),
            )
        };
        let (k, m) = (model.stiffness(&alpha), model.mass(&beta));
        let (l_ref, phi_ref) = dense_lowest(&k, &m, 10);
        let got = solver.solve(&alpha, &beta, 10, &mut ws).unwrap();
        let (rel, mac_min) = compare(&got.eigenvalues_rad2_s2, &got.phi, &l_ref, &phi_ref);
        let res = got.relative_residual.iter().fold(0.0_f64, |a, &b| a.max(b));
        let op = got.operator_residual.iter().fold(0.0_f64, |a, &b| a.max(b));
        println!(
            "beam point {point}: max rel. eigenvalue diff {rel:.2e}, min MAC 1 - {:.2e}, max \
             residual {res:.2e} (operator {op:.2e}), {} solves",
            1.0 - mac_min,
            got.n_solves
        );
        assert!(rel < 1e-9, "point {point}: {rel}");
        assert!(mac_min > 1.0 - 1e-9, "point {point}: {mac_min}");
        // The convergence test; the plain residual only to its rounding floor (module docs).
        assert!(op <= 1e-10, "point {point}: {op}");
        assert!(res < 1e-6, "point {point}: {res}");
        let ptmp = got.phi.transpose() * &m * &got.phi;
        assert!((ptmp - DMatrix::identity(10, 10)).amax() < 1e-10);
        // No spurious mode: every shape obeys the massless rows, K_s phi = 0.
        let kphi = &k * &got.phi;
        for i in (1..300).step_by(2) {
            assert!(kphi.row(i).amax() < 1e-8 * kphi.amax(), "DOF {i}");
        }
    }
}

/// A free-free beam: K only positive semi-definite (two rigid-body modes, eigenvalue 0).
/// With the default shift (just below zero) the rigid-body pair comes first and the
/// flexible modes match the dense solve of the pencil shifted by 1 rad^2/s^2.
#[test]
fn free_free_beam_with_rigid_body_modes() {
    let model = beam(60, false);
    let solver = PartialSolver::new(
        Arc::new(SparsePencil::from_model(&model)),
        PartialOptions::default(),
    )
    .unwrap();
    let mut ws = solver.workspace();
    let (alpha, beta) = (vec![0.2, -0.1, 0.0, 0.3, 0.1, -1.0], vec![0.1, -0.2]);
    let got = solver.solve(&alpha, &beta, 6, &mut ws).unwrap();
    let (k, m) = (model.stiffness(&alpha), model.mass(&beta));
    // Oracle: lambda of (K, M) = lambda of (K + M, M) - 1; K + M condenses (K_ss > 0).
    let (l_ref, phi_ref) = dense_lowest(&(&k + &m), &m, 6);
    let l_ref: Vec<f64> = l_ref.iter().map(|l| l - 1.0).collect();
    println!("free-free: {:?} vs {:?}", got.eigenvalues_rad2_s2, l_ref);
    for i in 0..2 {
        assert!(got.eigenvalues_rad2_s2[i].abs() < 1e-8 * l_ref[2]);
    }
    let (rel, mac_min) = compare(
        &got.eigenvalues_rad2_s2[2..],
        &got.phi.columns(2, 4).into(),
        &l_ref[2..],
        &phi_ref.columns(2, 4).into(),
    );
    assert!(rel < 1e-9 && mac_min > 1.0 - 1e-9, "{rel} {mac_min}");
}

#[test]
fn errors_are_clear() {
    let model = beam(40, true);
    let pencil = Arc::new(SparsePencil::from_model(&model));
    let solver = PartialSolver::new(pencil.clone(), PartialOptions::default()).unwrap();
    let mut ws = solver.workspace();
    let (a0, b0) = (model.alpha_zero(), model.beta_zero());
    let err = |r: frfbayes::Result<_>| r.map(|_: frfbayes::modal::PartialEigen| ()).unwrap_err();
    // More modes than DOFs with mass (40 of 80).
    let e = err(solver.solve(&a0, &b0, 41, &mut ws));
    assert!(
        matches!(e, Error::Usage(_)) && e.to_string().contains("only 40 DOFs have mass"),
        "{e}"
    );
    // All 40 finite eigenvalues are fine.
    let all = solver.solve(&a0, &b0, 40, &mut ws).unwrap();
    let (l_ref, _) = dense_lowest(&model.stiffness(&a0), &model.mass(&b0), 40);
    assert!((all.eigenvalues_rad2_s2[39] / l_ref[39] - 1.0).abs() < 1e-9);
    // Wrong number of parameters; non-finite ones.
    assert!(matches!(
        err(solver.solve(&a0[..3], &b0, 3, &mut ws)),
        Error::Usage(_)
    ));
    assert!(matches!(
        err(solver.solve(&[f64::NAN; 6], &b0, 3, &mut ws)),
        Error::Usage(_)
    ));
    // A shift above the lowest eigenvalue: K - sigma M does not factor.
    let lowest = l_ref[0];
    let above = PartialSolver::new(
        pencil.clone(),
        PartialOptions {
            shift_rad2_s2: Some(2.0 * lowest),
            ..Default::default()
        },
    )
    .unwrap();
    let e = err(above.solve(&a0, &b0, 3, &mut ws));
    assert!(e.to_string().contains("not positive definite"), "{e}");
    // Every stiffness group removed: K = 0, singular on the massless DOFs.
    let e = err(solver.solve(&[-1.0; 6], &b0, 3, &mut ws));
    assert!(e.to_string().contains("not positive definite"), "{e}");
    // No restarts allowed and a tiny space: not converged.
    let tight = PartialSolver::new(
        pencil,
        PartialOptions {
            max_basis: Some(8),
            max_restarts: 0,
            tol: 1e-13,
            ..Default::default()
        },
    )
    .unwrap();
    let e = err(tight.solve(&a0, &b0, 5, &mut ws));
    assert!(
        matches!(e, Error::Numerical(_)) && e.to_string().contains("converged"),
        "{e}"
    );
    assert!(PartialSolver::new(
        Arc::new(SparsePencil::from_model(&model)),
        PartialOptions {
            tol: 0.0,
            ..Default::default()
        }
    )
    .is_err());
}

/// The modal predictor on `PartialModes` predicts the dense solve's frequencies and
/// shapes (up to sign) at the measured DOFs. (`DenseModes` cannot take this model: its
/// `M` is singular.)
#[test]
fn partial_modes_in_the_modal_predictor() {
    let model = Arc::new(beam(50, true));
    let params = Parametrisation::all_alphas(&model).unwrap();
    let dofs = vec![10, 41, 98];
    let modes = vec![0, 1, 2, 4];
    let solver = PartialModes::new(model.clone(), PartialOptions::default()).unwrap();
    let p = ModalPredictor::new(solver, params, dofs.clone(), modes.clone()).unwrap();
    let theta = [0.1, -0.2, 0.3, 0.0, 0.05, 2.0];
    let mut out = vec![0.0; p.n_outputs()];
    p.predict(&theta, &mut p.workspace(), &mut out).unwrap();
    let (l_ref, phi_ref) = dense_lowest(&model.stiffness(&theta), &model.mass(&[0.0; 2]), 5);
    for (i, &m) in modes.iter().enumerate() {
        let f = l_ref[m].sqrt() / std::f64::consts::TAU;
        assert!(
            (out[i] / f - 1.0).abs() < 1e-10,
            "mode {m}: {} vs {f}",
            out[i]
        );
        let shape = &out[p.shape_range(i)];
        let sign = (shape[0] * phi_ref[(dofs[0], m)]).signum();
        for (s, &d) in shape.iter().zip(&dofs) {
            assert!((s * sign - phi_ref[(d, m)]).abs() < 1e-8 * phi_ref.column(m).amax());
        }
    }
}

// ---------------------------------------------------------------- the bridge

fn bridge() -> Option<StructuralModel> {
    let p = shared_root().join("data/real/bridge-fe/SteelPedestrianBridgeExp.mat");
    if !p.is_file() {
        println!(
            "skipped: {} not found (set FRFBAYES_SHARED_DIR)",
            p.display()
        );
        return None;
    }
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/bridge-fe.toml");
    Some(ModelManifest::load(&manifest).unwrap())
}

/// The lowest `m` eigenpairs of a pencil with positive definite `M` by faer's dense
/// self-adjoint solver (`L^-1 K L^-T`, `M = L L^T`): eigenvalues and `M`-normalised shapes.
fn faer_lowest(k: &DMatrix<f64>, mm: &DMatrix<f64>, m: usize) -> (Vec<f64>, DMatrix<f64>) {
    use faer::linalg::triangular_solve::{
        solve_lower_triangular_in_place, solve_upper_triangular_in_place,
    };
    let n = k.nrows();
    let l = faer::Mat::from_fn(n, n, |i, j| mm[(i, j)])
        .llt(faer::Side::Lower)
        .unwrap()
        .L()
        .to_owned();
    let mut x = faer::Mat::from_fn(n, n, |i, j| k[(i, j)]);
    solve_lower_triangular_in_place(l.as_ref(), x.as_mut(), faer::Par::Seq);
    let mut a = x.transpose().to_owned();
    solve_lower_triangular_in_place(l.as_ref(), a.as_mut(), faer::Par::Seq);
    let sym = faer::Mat::from_fn(n, n, |i, j| 0.5 * (a[(i, j)] + a[(j, i)]));
    let eig = sym.self_adjoint_eigen(faer::Side::Lower).unwrap();
    let mut v = eig.U().subcols(0, m).to_owned();
    solve_upper_triangular_in_place(l.transpose(), v.as_mut(), faer::Par::Seq);
    let lambda = (0..m).map(|i| eig.S()[i]).collect();
    (lambda, DMatrix::from_fn(n, m, |i, j| v[(i, j)]))
}

/// A seeded random point of the bridge's prior box.
fn bridge_point(rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
    (0..17)
        .map(|j| match j {
            0 | 1 => rng.random_range(-0.1..0.1),
            2..=12 => rng.random_range(-0.2..0.4),
            _ => rng.random_range(-1.0..10.0),
        })
        .collect()
}

#[test]
fn bridge_lowest_ten_match_the_condensed_dense_solve() {
    let Some(model) = bridge() else { return };
    let solver = PartialSolver::new(
        Arc::new(SparsePencil::from_model(&model)),
        PartialOptions::default(),
    )
    .unwrap();
    println!(
        "bridge: K pattern {} non-zeros, M pattern {}, Cholesky factor {}",
        solver.pencil().stiffness_pattern().nnz(),
        solver.pencil().mass_pattern().nnz(),
        solver.factor_nnz()
    );
    let mut ws = solver.workspace();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2024);
    let m = model.mass(&[]);
    for point in 0..6 {
        let alpha = if point == 0 {
            model.alpha_zero()
        } else {
            bridge_point(&mut rng)
        };
        let k = model.stiffness(&alpha);
        let c = condense(&k, &m).unwrap();
        let (l_ref, phi_ref) = faer_lowest(&c.k, &c.m, 10);
        let got = solver.solve(&alpha, &[], 10, &mut ws).unwrap();
        let kept = DMatrix::from_fn(c.kept.len(), 10, |i, j| got.phi[(c.kept[i], j)]);
        let (rel, mac_min) = compare(&got.eigenvalues_rad2_s2, &kept, &l_ref, &phi_ref);
        let res = got.relative_residual.iter().fold(0.0_f64, |a, &b| a.max(b));
        println!(
            "bridge point {point}: lowest {:.4} rad^2/s^2; max rel. eigenvalue diff {rel:.2e}, \
             min MAC 1 - {:.2e}, max residual {res:.2e}, {} solves",
            got.eigenvalues_rad2_s2[0],
            1.0 - mac_min,
            got.n_solves
        );
        assert!(rel < 1e-9, "point {point}: {rel}");
        assert!(mac_min > 1.0 - 1e-9, "point {point}: {mac_min}");
        if point == 0 {
            // docs/bridge-smu.md section 9 (scipy eigsh, 4 decimals).
            let doc = [857.1665, 938.2199, 1747.9232, 3869.9714, 5113.1540];
            for (a, b) in got.eigenvalues_rad2_s2.iter().zip(doc) {
                assert!((a - b).abs() < 6e-5, "{a} vs {b}");
            }
        }
    }
}

/// Median seconds of `reps` calls of `f`.
fn median_secs(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[reps / 2]
}

/// Time per solve on the bridge at a random point of the box: the partial solver (5 and
/// 10 modes) against the dense condensed solves (condensation included; nalgebra's
/// `Modes` and faer's self-adjoint solver), medians of repeated runs in one process.
#[test]
#[ignore]
fn bridge_speed() {
    let Some(model) = bridge() else { return };
    let solver = PartialSolver::new(
        Arc::new(SparsePencil::from_model(&model)),
        PartialOptions::default(),
    )
    .unwrap();
    let mut ws = solver.workspace();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let alpha = bridge_point(&mut rng);
    let m = model.mass(&[]);
    let dense_nalgebra = median_secs(5, || {
        let k = model.stiffness(&alpha);
        let c = condense(&k, &m).unwrap();
        let iota = DVector::from_element(c.kept.len(), 1.0);
        std::hint::black_box(Modes::solve(&c.k, &c.m, &iota, Some(10)).unwrap());
    });
    let dense_faer = median_secs(5, || {
        let k = model.stiffness(&alpha);
        let c = condense(&k, &m).unwrap();
        std::hint::black_box(faer_lowest(&c.k, &c.m, 10));
    });
    let condense_only = median_secs(5, || {
        std::hint::black_box(condense(&model.stiffness(&alpha), &m).unwrap());
    });
    println!(
        "dense, condensation + nalgebra: {:.2} ms",
        dense_nalgebra * 1e3
    );
    println!("dense, condensation + faer:     {:.2} ms", dense_faer * 1e3);
    println!(
        "  (condensation alone, with K(alpha) dense: {:.2} ms)",
        condense_only * 1e3
    );
    for n_modes in [5, 10] {
        let mut solves = 0;
        let t = median_secs(51, || {
            solves = solver
                .solve(&alpha, &[], n_modes, &mut ws)
                .unwrap()
                .n_solves;
        });
        println!(
            "partial, lowest {n_modes}: {:.3} ms ({solves} solves); dense nalgebra / partial = \
             {:.0}, dense faer / partial = {:.0}",
            t * 1e3,
            dense_nalgebra / t,
            dense_faer / t
        );
    }
}
