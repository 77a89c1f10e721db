//! Oracle tests of the one posterior: on a linear-Gaussian model every face has a closed
//! form (least squares, posterior moments, evidence), and each must reproduce it.

use nalgebra::{DMatrix, DVector};

use super::likelihood::Transform;
use super::*;
use crate::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
use crate::mcmc::{Ball, LogDensity, Start};
use crate::model::StructuralModel;
use crate::predict::{
    Coordinate, DenseModes, FrfDamping, FrfOptions, FrfOutput, FrfPredictor, Parametrisation,
    Predict, Scale, Variable,
};
use std::f64::consts::PI;
use std::sync::Arc;

/// `y = A theta`, 3 parameters, 8 outputs.
#[derive(Clone)]
struct Linear {
    a: DMatrix<f64>,
}

impl Predict for Linear {
    type Workspace = ();
    fn n_params(&self) -> usize {
        self.a.ncols()
    }
    fn n_outputs(&self) -> usize {
        self.a.nrows()
    }
    fn param_names(&self) -> Vec<String> {
        (0..self.a.ncols()).map(|i| format!("t{i}")).collect()
    }
    fn workspace(&self) {}
    fn predict(&self, theta: &[f64], _: &mut (), out: &mut [f64]) -> crate::Result<()> {
        let y = &self.a * DVector::from_column_slice(theta);
        out.copy_from_slice(y.as_slice());
        Ok(())
    }
}

const SD: [f64; 8] = [0.1, 0.2, 0.15, 0.1, 0.3, 0.25, 0.1, 0.2];

fn problem(scale: NoiseScale) -> (Posterior<Linear>, DVector<f64>, DMatrix<f64>) {
    let a = DMatrix::from_fn(8, 3, |i, j| {
        ((i + 1) as f64 * 0.7 + j as f64 * 1.3).sin() + 0.1 * j as f64
    });
    let y: Vec<f64> = (0..8).map(|i| 1.0 + 0.3 * (i as f64 * 2.1).cos()).collect();
    // Weighted least squares: precision P = A^T W A, mean = P^-1 A^T W y.
    let w = DMatrix::from_diagonal(&DVector::from_iterator(8, SD.iter().map(|s| 1.0 / (s * s))));
    let precision = a.transpose() * &w * &a;
    let mean = precision
        .clone()
        .cholesky()
        .unwrap()
        .solve(&(a.transpose() * &w * DVector::from_column_slice(&y)));
    let blocks = vec![
        Block::values("first", 0..5, &y[..5], &SD[..5], Transform::Identity, scale).unwrap(),
        Block::values("rest", 5..8, &y[5..], &SD[5..], Transform::Identity, scale).unwrap(),
    ];
    let scales: Vec<(String, (f64, f64))> = match scale {
        NoiseScale::Sampled(_) => vec![("ln s".into(), (-3.0, 3.0))],
        NoiseScale::Fixed(_) => vec![],
    };
    let post = Posterior::new(Linear { a }, &[(-20.0, 20.0); 3], &scales, blocks).unwrap();
    (post, mean, precision)
}

/// The MAP fit is the weighted least-squares solution, and its cost is
/// `0.5 chi2` (the block residuals are whitened).
#[test]
fn fit_is_weighted_least_squares() {
    let (post, mean, _) = problem(NoiseScale::Fixed(1.0));
    let fit = fit_multistart(
        &post,
        &[],
        None,
        &FitOptions {
            n_starts: 4,
            ..Default::default()
        },
    )
    .unwrap();
    for i in 0..3 {
        assert!(
            (fit.best.x[i] - mean[i]).abs() < 1e-7,
            "{:?} {mean}",
            fit.best.x
        );
    }
    assert_eq!(fit.n_at_best, 4);
    let r = post.residuals(&fit.best.x).unwrap();
    let chi2: f64 = r.iter().map(|v| v * v).sum();
    assert!((fit.best.cost - 0.5 * chi2).abs() < 1e-12 * chi2.max(1.0));
}

/// The Gaussian posterior's evidence in a box that holds all of its mass:
/// `ln Z = ln L(mode) + (d/2) ln 2 pi - (1/2) ln det P - ln volume`; Laplace must give it
/// to the finite-difference Hessian's accuracy, stepping-stone within 4 standard errors.
#[test]
fn laplace_and_stepping_stone_give_the_analytic_evidence() {
    let (post, mean, precision) = problem(NoiseScale::Fixed(1.0));
    let mode: Vec<f64> = mean.iter().copied().collect();
    let ln_l = post.ln_likelihood(&mode).unwrap();
    let exact = ln_l + 1.5 * (2.0 * std::f64::consts::PI).ln()
        - 0.5 * precision.determinant().ln()
        - 3.0 * 40f64.ln();
    let lap = laplace(&post, &mode).unwrap();
    assert!((lap.ln_z - exact).abs() < 1e-5, "{} {exact}", lap.ln_z);
    let ss = stepping_stone(&post, &EvidenceOptions::new(3, 7), None).unwrap();
    assert!(
        (ss.ln_z - exact).abs() < 4.0 * ss.ln_z_se.max(0.05),
        "{} +- {} against {exact}",
        ss.ln_z,
        ss.ln_z_se
    );
}

/// Sampling the posterior with a sampled noise scale: at the mode of `s` the
/// conditional posterior of theta has covariance `s^2 P^-1`; with 8 points and 3
/// parameters the marginal mean of theta is the least-squares mean. Checked within 5
/// Monte Carlo standard errors (sd / sqrt(ESS)).
#[test]
fn sampling_recovers_the_least_squares_mean() {
    let (post, mean, _) = problem(NoiseScale::Sampled(0));
    assert_eq!(post.dim(), 4);
    assert_eq!(post.n_pointwise(), 2);
    let start = Start::Ball(Ball {
        center: vec![mean[0], mean[1], mean[2], 0.0],
        scale: vec![0.01; 4],
    });
    let s = sample_to_targets(
        &post,
        start,
        32,
        11,
        &Targets::default(),
        "linear",
        &mut Sampling::quiet(),
    )
    .unwrap();
    assert!(s.worst_rhat < 1.01 && s.min_ess > 400.0);
    for p in 0..3 {
        let v: Vec<f64> = s.chains(p, |x| x).into_iter().flatten().collect();
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
        assert!(
            (m - mean[p]).abs() < 5.0 * sd / s.min_ess.sqrt(),
            "{p}: {m} vs {}",
            mean[p]
        );
    }
}

/// Oracle: the analytic Jacobian of the reduced modes, through every block kind of
/// the posterior (values of frequencies, MAC shape, SMU's shape difference), equals
/// central differences of the residuals.
#[test]
fn analytic_jacobian_matches_central_differences() {
    use crate::infer::likelihood::Transform;
    use crate::infer::{Block, NoiseScale, Posterior};
    use crate::predict::modal::ModalPredictor;
    use crate::predict::{Parametrisation, Predict};
    use crate::update::lsq::LeastSquaresProblem;
    let model = Arc::new(crate::predict::reduced::test_models::chain_model(30));
    let snaps: Vec<(Vec<f64>, Vec<f64>)> = vec![(vec![0.0; 3], Vec::new())];
    let red = crate::predict::reduced::ReducedModes::from_snapshots(
        &model,
        &snaps,
        &crate::predict::reduced::BasisOptions::default(),
    )
    .unwrap();
    let params = Parametrisation::all_alphas(&model).unwrap();
    let dofs: Vec<usize> = (0..60).step_by(6).collect();
    let p = ModalPredictor::new(red, params, dofs.clone(), vec![0, 1, 2]).unwrap();
    let shape: Vec<f64> = (0..dofs.len())
        .map(|k| 0.3 + (k as f64 * 0.7).sin())
        .collect();
    let blocks = vec![
        Block::values(
            "f",
            p.freq_range(),
            &[1.0, 2.0, 3.0],
            &[0.1, 0.2, 0.3],
            Transform::EigenvalueOfHz,
            NoiseScale::Fixed(1.0),
        )
        .unwrap(),
        Block::shape_mac("mac", p.shape_range(0), &shape, NoiseScale::Fixed(2.0)).unwrap(),
        Block::shape_difference(
            "diff",
            p.shape_range(1),
            &shape,
            3,
            &vec![1.5; dofs.len()],
            NoiseScale::Fixed(1.0),
        )
        .unwrap(),
    ];
    let post = Posterior::new(p, &[(-0.5, 0.5); 3], &[], blocks).unwrap();
    let ls = post.least_squares(&[]).unwrap();
    let x = [0.1, -0.2, 0.15];
    let mut ws = ls.workspace();
    let (m, n) = (ls.n_residuals(), 3);
    let mut jac = DMatrix::zeros(m, n);
    ls.jacobian(&x, &mut ws, &mut jac).unwrap();
    let pr = post.predictor();
    let mut out = vec![0.0; pr.n_outputs()];
    let mut dpred = DMatrix::zeros(pr.n_outputs(), 3);
    assert!(pr
        .jacobian(&x, &mut pr.workspace(), &mut out, &mut dpred)
        .unwrap());
    let direct = post.predict(&x).unwrap();
    let gap = out
        .iter()
        .zip(&direct)
        .fold(0.0f64, |g, (a, b)| g.max((a - b).abs()));
    assert!(
        gap < 1e-12,
        "jacobian writes the predictions too: gap {gap}"
    );
    let h = 1e-6;
    let (mut rp, mut rm) = (vec![0.0; m], vec![0.0; m]);
    let mut worst: f64 = 0.0;
    for j in 0..n {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[j] += h;
        xm[j] -= h;
        ls.residuals(&xp, &mut ws, &mut rp).unwrap();
        ls.residuals(&xm, &mut ws, &mut rm).unwrap();
        for i in 0..m {
            worst = worst.max((jac[(i, j)] - (rp[i] - rm[i]) / (2.0 * h)).abs());
        }
    }
    assert!(
        worst < 1e-6 * jac.amax(),
        "worst {worst}, max {}",
        jac.amax()
    );
}

/// Through the one posterior layer: noise-free log-magnitudes of a known frame, and the
/// MAP fit from Latin hypercube starts returns the truth (stiffnesses at fixed masses,
/// Rayleigh damping).
#[test]
fn map_fit_on_the_posterior_layer_recovers_the_truth() {
    let m = [5.0, 4.8, 4.6, 4.4, 4.0];
    let k = [1200.0, 1100.0, 1000.0, 900.0, 800.0];
    let model = Arc::new(StructuralModel::shear_frame(&m, &k).unwrap());
    let params = Parametrisation::new(
        &model,
        (0..5)
            .map(|r| Coordinate {
                name: format!("ln_k{}", r + 1),
                variable: Variable::Alpha(r),
                scale: Scale::Log { ln_offset: 0.0 },
            })
            .collect(),
    )
    .unwrap();
    let omega: Vec<f64> = (1..200).map(|k| 2.0 * PI * 0.05 * k as f64).collect();
    let blocks = [FrfBlock {
        omega_rad_s: omega,
        pairs: vec![
            FrfPair {
                response: 4,
                excitation: Excitation::Dof(1),
                kind: FrfKind::Accelerance,
            },
            FrfPair {
                response: 0,
                excitation: Excitation::Dof(0),
                kind: FrfKind::Accelerance,
            },
        ],
    }];
    let p = FrfPredictor::new(
        DenseModes::new(model.clone()),
        model.clone(),
        params,
        FrfOptions {
            damping: FrfDamping::Rayleigh,
            output: FrfOutput::LogMagnitude,
            n_modes: 5,
        },
        &blocks,
        &[None],
    )
    .unwrap();
    let truth = [0.05, -0.1, 0.02, 0.0, 0.08, 0.3f64.ln(), 2e-4f64.ln()];
    let mut observed = vec![0.0; p.n_outputs()];
    p.predict(&truth, &mut p.workspace(), &mut observed)
        .unwrap();
    let n = observed.len();
    let block = Block::values(
        "ln|A|",
        0..n,
        &observed,
        &vec![0.01; n],
        Transform::Identity,
        NoiseScale::Fixed(1.0),
    )
    .unwrap();
    let mut bounds = vec![(-0.3, 0.3); 5];
    bounds.extend([(-4.0, 1.0), (-12.0, -6.0)]);
    let post = Posterior::new(p, &bounds, &[], vec![block]).unwrap();
    let fit = fit_multistart(
        &post,
        &[],
        None,
        &FitOptions {
            n_starts: 8,
            ..Default::default()
        },
    )
    .unwrap();
    for (x, t) in fit.best.x.iter().zip(truth) {
        assert!((x - t).abs() < 1e-6, "{:?} vs {truth:?}", fit.best.x);
    }
}

/// [`Linear`] with its analytic Jacobian `A` (the least squares' analytic path).
#[derive(Clone)]
struct LinearWithJacobian(Linear);

impl Predict for LinearWithJacobian {
    type Workspace = ();
    fn n_params(&self) -> usize {
        self.0.n_params()
    }
    fn n_outputs(&self) -> usize {
        self.0.n_outputs()
    }
    fn param_names(&self) -> Vec<String> {
        self.0.param_names()
    }
    fn workspace(&self) {}
    fn predict(&self, theta: &[f64], ws: &mut (), out: &mut [f64]) -> crate::Result<()> {
        self.0.predict(theta, ws, out)
    }
    fn jacobian(
        &self,
        theta: &[f64],
        ws: &mut (),
        out: &mut [f64],
        jac: &mut DMatrix<f64>,
    ) -> crate::Result<bool> {
        self.0.predict(theta, ws, out)?;
        jac.copy_from(&self.0.a);
        Ok(true)
    }
}

/// Oracle: with noise shared by a block's values (and its bins correlated along a
/// chain), the least-squares view's minimiser is the generalised least-squares solution
/// `(A^T C^-1 A)^-1 A^T C^-1 y` of the dense covariance `C = sigma^2 D^(1/2) R D^(1/2) +
/// L L^T`, and its cost differences are the log-likelihood's, with the finite-difference
/// Jacobian and the analytic one alike.
#[test]
fn least_squares_with_shared_noise_is_generalised_least_squares() {
    use crate::update::lsq::LeastSquaresProblem;
    let (n, sigma) = (8, 0.7);
    let a = DMatrix::from_fn(n, 3, |i, j| {
        ((i + 1) as f64 * 0.7 + j as f64 * 1.3).sin() + 0.1 * j as f64
    });
    let y: Vec<f64> = (0..n).map(|i| 1.0 + 0.3 * (i as f64 * 2.1).cos()).collect();
    let loadings: Vec<f64> = (0..n * 2)
        .map(|i| 0.12 * ((i as f64 * 0.9).sin() + 0.5))
        .collect();
    let rho: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { 0.4 }).collect();
    let correlation = likelihood::Correlation {
        shared: Some((&loadings, 2)),
        chain: &rho,
    };
    let scale = NoiseScale::Sampled(0);
    let block = Block::correlated_values(
        "all",
        0..n,
        &y,
        &SD,
        Transform::Identity,
        correlation,
        scale,
    )
    .unwrap();
    let corr = |i: usize, j: usize| 0.4f64.powi((i as i32 - j as i32).abs());
    let cov = DMatrix::from_fn(n, n, |i, j| {
        sigma * sigma * SD[i] * SD[j] * corr(i, j)
            + (0..2)
                .map(|c| loadings[i * 2 + c] * loadings[j * 2 + c])
                .sum::<f64>()
    });
    let c_inv = cov.cholesky().unwrap().inverse();
    let precision = a.transpose() * &c_inv * &a;
    let gls = precision
        .cholesky()
        .unwrap()
        .solve(&(a.transpose() * &c_inv * DVector::from_column_slice(&y)));
    let bounds = [(-20.0, 20.0); 3];
    let scales = [("ln s".to_string(), (-3.0, 3.0))];
    let linear = Linear { a: a.clone() };
    let plain = Posterior::new(linear.clone(), &bounds, &scales, vec![block.clone()]).unwrap();
    let analytic =
        Posterior::new(LinearWithJacobian(linear), &bounds, &scales, vec![block]).unwrap();
    let options = FitOptions {
        n_starts: 3,
        ..Default::default()
    };
    let fits = [
        fit_multistart(&plain, &[sigma], None, &options).unwrap(),
        fit_multistart(&analytic, &[sigma], None, &options).unwrap(),
    ];
    for fit in &fits {
        for i in 0..3 {
            assert!(
                (fit.best.x[i] - gls[i]).abs() < 1e-7 * gls.amax(),
                "{:?} against {gls}",
                fit.best.x
            );
        }
    }
    let ls = plain.least_squares(&[sigma]).unwrap();
    let (x1, x2) = ([0.3, -0.2, 0.5], [0.1, 0.4, -0.3]);
    let cost = |x: &[f64]| {
        let mut r = vec![0.0; n];
        ls.residuals(x, &mut ls.workspace(), &mut r).unwrap();
        0.5 * r.iter().map(|v| v * v).sum::<f64>()
    };
    let ln_l = |x: &[f64]| {
        let mut z = x.to_vec();
        z.push(sigma.ln());
        plain.ln_likelihood(&z).unwrap()
    };
    let (d_cost, d_ln_l) = (cost(&x1) - cost(&x2), ln_l(&x1) - ln_l(&x2));
    assert!(
        (d_cost + d_ln_l).abs() < 1e-10 * d_ln_l.abs(),
        "{d_cost} against {d_ln_l}"
    );
}
