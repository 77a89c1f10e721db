//! The analytical residual Jacobian against central finite differences, on random
//! models (shear frames and general matrices), both excitations, all three FRF kinds,
//! both damping models, all residual forms, full and truncated modal sums.

use frfbayes::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
use frfbayes::model::{Parameter, StructuralModel};
use frfbayes::update::lsq::LeastSquaresProblem;
use frfbayes::update::{
    DampingModel, Measurements, ObjectiveOptions, Problem, ResidualForm, Scale, VariablesConfig,
};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Required agreement: every entry of a column within `JAC_RTOL` times the column's
/// largest entry. The five-point stencil has truncation error O(h^4 f^(5)); with the
/// FRF varying on a relative scale of the damping ratio xi >= 0.005 and h = 1e-4
/// (relative), that is about (h/xi)^4 = 1.6e-7 of the derivative at worst, and the
/// rounding error eps |r| / h ~ 1e-12 is negligible.
const JAC_RTOL: f64 = 1e-6;
const FD_STEP: f64 = 1e-4;

fn random_shear_frame(rng: &mut ChaCha8Rng, n: usize) -> StructuralModel {
    let m: Vec<f64> = (0..n).map(|_| rng.random_range(2.0..8.0)).collect();
    let k: Vec<f64> = (0..n).map(|_| rng.random_range(800.0..3000.0)).collect();
    StructuralModel::shear_frame(&m, &k).unwrap()
}

/// A general model: random SPD K0, M0, full symmetric PSD influence matrices and a
/// non-trivial ground influence vector.
fn random_general_model(rng: &mut ChaCha8Rng, n: usize) -> StructuralModel {
    let spd = |rng: &mut ChaCha8Rng, scale: f64| {
        let b = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        (&b * b.transpose() + DMatrix::identity(n, n) * n as f64) * scale
    };
    let psd_rank1 = |rng: &mut ChaCha8Rng, scale: f64| {
        let v = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
        &v * v.transpose() * scale
    };
    let k0 = spd(rng, 1000.0);
    let m0 = spd(rng, 1.0);
    let param = |name: String| Parameter {
        name,
        unit: "1".into(),
        nominal: None,
    };
    let k_infl = (0..2)
        .map(|r| (param(format!("a{r}")), psd_rank1(rng, 800.0)))
        .collect();
    let m_infl = (0..2)
        .map(|r| (param(format!("b{r}")), psd_rank1(rng, 0.8)))
        .collect();
    let iota = DVector::from_fn(n, |_, _| rng.random_range(0.5..1.5));
    StructuralModel::from_matrices(k0, m0, k_infl, m_infl, Some(iota)).unwrap()
}

/// Two blocks: force excitation at two DOFs (responses at every DOF) and ground
/// excitation, with the three FRF kinds mixed, on grids spanning all modes.
fn blocks(rng: &mut ChaCha8Rng, model: &StructuralModel) -> Vec<FrfBlock> {
    let n = model.n_dof();
    let modes = frfbayes::modal::Modes::solve(
        &model.stiffness(&model.alpha_zero()),
        &model.mass(&model.beta_zero()),
        model.ground_influence(),
        None,
    )
    .unwrap();
    let (w_lo, w_hi) = (modes.omega_rad_s[0] * 0.6, modes.omega_rad_s[n - 1] * 1.3);
    let mut grid = |count: usize| {
        let mut w: Vec<f64> = (0..count).map(|_| rng.random_range(w_lo..w_hi)).collect();
        // Points near each resonance, where the FRF is most sensitive.
        w.extend(modes.omega_rad_s.iter().map(|x| x * 1.003));
        w
    };
    let kinds = [FrfKind::Receptance, FrfKind::Mobility, FrfKind::Accelerance];
    let mut force_pairs = Vec::new();
    for (k, e) in [0, n - 1].into_iter().enumerate() {
        for r in 0..n {
            force_pairs.push(FrfPair {
                response: r,
                excitation: Excitation::Dof(e),
                kind: kinds[(r + k) % 3],
            });
        }
    }
    let ground_pairs = (0..n)
        .map(|r| FrfPair {
            response: r,
            excitation: Excitation::Ground,
            kind: kinds[r % 3],
        })
        .collect();
    vec![
        FrfBlock {
            omega_rad_s: grid(25),
            pairs: force_pairs,
        },
        FrfBlock {
            omega_rad_s: grid(20),
            pairs: ground_pairs,
        },
    ]
}

/// Five-point central difference of the residuals along `e_v` with step `h`.
fn fd_column(problem: &Problem, theta: &[f64], v: usize, h: f64) -> Vec<f64> {
    let at = |t: f64| {
        let mut th = theta.to_vec();
        th[v] += t;
        problem.residuals_at(&th).unwrap()
    };
    let (p1, m1, p2, m2) = (at(h), at(-h), at(2.0 * h), at(-2.0 * h));
    (0..p1.len())
        .map(|k| (8.0 * (p1[k] - m1[k]) - (p2[k] - m2[k])) / (12.0 * h))
        .collect()
}

fn assert_columns_close(analytical: &[f64], fd: &[f64], what: &str) {
    let scale = fd.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    assert!(scale > 0.0, "{what}: zero column");
    for (k, (a, f)) in analytical.iter().zip(fd).enumerate() {
        assert!(
            (a - f).abs() <= JAC_RTOL * scale,
            "{what}: row {k}: analytical {a:e}, finite difference {f:e} (column max {scale:e})"
        );
    }
}

fn random_theta(rng: &mut ChaCha8Rng, problem: &Problem) -> Vec<f64> {
    problem
        .variables()
        .variables()
        .iter()
        .map(|v| match v.kind {
            frfbayes::update::VariableKind::Alpha(_) => rng.random_range(-0.2..0.2),
            frfbayes::update::VariableKind::Beta(_) => rng.random_range(-0.05..0.1),
            frfbayes::update::VariableKind::A0 => rng.random_range(0.05..0.5),
            frfbayes::update::VariableKind::A1 => rng.random_range(1e-5..1e-4),
            frfbayes::update::VariableKind::Xi(_) => rng.random_range(0.005..0.05),
        })
        .collect()
}

fn check_model(rng: &mut ChaCha8Rng, model: StructuralModel, n_modes: Option<usize>, label: &str) {
    let blocks = blocks(rng, &model);
    let len: usize = blocks
        .iter()
        .map(|b| b.omega_rad_s.len() * b.pairs.len())
        .sum();
    let magnitude: Vec<f64> = (0..len).map(|_| rng.random_range(1e-4..1e-2)).collect();
    let sigma: Vec<f64> = (0..len).map(|_| rng.random_range(0.01..0.1)).collect();
    for damping in [DampingModel::Rayleigh, DampingModel::Caughey] {
        for (form, weighted) in [
            (ResidualForm::Magnitude, false),
            (ResidualForm::Magnitude, true),
            (ResidualForm::LogMagnitude, false),
            (ResidualForm::LogMagnitude, true),
        ] {
            let data = Measurements {
                blocks: blocks.clone(),
                magnitude: magnitude.clone(),
                sigma: weighted.then(|| sigma.clone()),
            };
            let options = ObjectiveOptions {
                residual: form,
                n_modes,
            };
            let problem = Problem::new(
                model.clone(),
                data,
                damping,
                &VariablesConfig::default(),
                options,
            )
            .unwrap();
            let theta = random_theta(rng, &problem);
            let what = format!("{label} {damping:?} {form:?} weighted={weighted}");
            // Physical Jacobian, every variable.
            let jac = problem.jacobian_at(&theta).unwrap();
            for (v, var) in problem.variables().variables().iter().enumerate() {
                let h = FD_STEP
                    * theta[v]
                        .abs()
                        .max(if var.scale == Scale::Log { 0.0 } else { 1.0 });
                let fd = fd_column(&problem, &theta, v, h);
                assert_columns_close(
                    jac.column(v).as_slice(),
                    &fd,
                    &format!("{what} d/d{}", var.name),
                );
            }
            // Internal Jacobian (log-scaled damping) through the solver's interface.
            let z = problem.to_internal(&theta);
            let mut ws = problem.workspace();
            let mut jz = DMatrix::zeros(problem.n_residuals(), problem.n_params());
            problem.jacobian(&z, &mut ws, &mut jz).unwrap();
            let mut r0 = vec![0.0; problem.n_residuals()];
            problem.residuals(&z, &mut ws, &mut r0).unwrap();
            // exp(ln x) round trips to within a few ulps.
            let r_theta = problem.residuals_at(&theta).unwrap();
            for (a, b) in r0.iter().zip(&r_theta) {
                assert!(
                    (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                    "{what}: {a} vs {b}"
                );
            }
            for c in 0..problem.n_params() {
                let h = FD_STEP;
                let col: Vec<f64> = {
                    let mut eval = |t: f64| {
                        let mut zz = z.clone();
                        zz[c] += t;
                        let mut r = vec![0.0; problem.n_residuals()];
                        problem.residuals(&zz, &mut ws, &mut r).unwrap();
                        r
                    };
                    let (p1, m1, p2, m2) = (eval(h), eval(-h), eval(2.0 * h), eval(-2.0 * h));
                    (0..p1.len())
                        .map(|k| (8.0 * (p1[k] - m1[k]) - (p2[k] - m2[k])) / (12.0 * h))
                        .collect()
                };
                assert_columns_close(
                    jz.column(c).as_slice(),
                    &col,
                    &format!("{what} internal z{c}"),
                );
            }
        }
    }
}

#[test]
fn jacobian_matches_finite_differences_shear_frames() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for (n, n_modes) in [(4, None), (3, None), (5, Some(3))] {
        let model = random_shear_frame(&mut rng, n);
        check_model(
            &mut rng,
            model,
            n_modes,
            &format!("shear frame n={n} modes={n_modes:?}"),
        );
    }
}

#[test]
fn jacobian_matches_finite_differences_general_model() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for n_modes in [None, Some(2)] {
        let model = random_general_model(&mut rng, 4);
        check_model(
            &mut rng,
            model,
            n_modes,
            &format!("general n=4 modes={n_modes:?}"),
        );
    }
}

#[test]
fn fixed_variables_are_not_solver_columns() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let model = random_shear_frame(&mut rng, 3);
    let blocks = blocks(&mut rng, &model);
    let len: usize = blocks
        .iter()
        .map(|b| b.omega_rad_s.len() * b.pairs.len())
        .sum();
    let mut config = VariablesConfig::default();
    config.fixed.insert("m2".into(), 0.02);
    let data = Measurements {
        blocks,
        magnitude: vec![1e-3; len],
        sigma: None,
    };
    let problem = Problem::new(
        model,
        data,
        DampingModel::Rayleigh,
        &config,
        ObjectiveOptions::default(),
    )
    .unwrap();
    assert_eq!(problem.n_params(), problem.variables().len() - 1);
    let theta = problem.variables().initial();
    assert_eq!(theta[4], 0.02);
    let z = problem.to_internal(&theta);
    let mut ws = problem.workspace();
    let mut jz = DMatrix::zeros(problem.n_residuals(), problem.n_params());
    problem.jacobian(&z, &mut ws, &mut jz).unwrap();
    let full = problem.jacobian_at(&theta).unwrap();
    // 3 floors: theta = (k1, k2, k3, m1, m2, m3, a0, a1); z skips m2 (theta index 4); damping columns carry the log chain factor.
    // (z -> theta goes through exp(ln a0), which moves a0 by a few ulps.)
    let close = |a: nalgebra::DVectorView<f64>, b: DVector<f64>| {
        assert!((a - &b).amax() <= 1e-12 * b.amax(), "columns differ");
    };
    close(jz.column(3), full.column(3).into_owned());
    close(jz.column(4), full.column(5).into_owned());
    close(jz.column(5), full.column(6) * theta[6]);
    close(jz.column(6), full.column(7) * theta[7]);
}
