use super::*;
use crate::simulate::config::{DampingSpec, StructureSpec};
use crate::simulate::discrete::{Foh, Response};

/// Jacobi `cn(u | m)` for `0 <= m < 1` by the arithmetic-geometric mean (descending
/// Landen transformation, Abramowitz & Stegun 16.4), accurate to rounding.
fn jacobi_cn(u: f64, m: f64) -> f64 {
    let (mut a, mut b) = (1.0_f64, (1.0 - m).sqrt());
    let mut c = vec![m.sqrt()];
    let mut aa = vec![a];
    while c.last().is_some_and(|c| c.abs() > 1e-17) && c.len() < 40 {
        let (an, bn) = (0.5 * (a + b), (a * b).sqrt());
        c.push(0.5 * (a - b));
        a = an;
        b = bn;
        aa.push(a);
    }
    let n = c.len() - 1;
    let mut phi = 2f64.powi(n as i32) * aa[n] * u;
    for k in (1..=n).rev() {
        phi = 0.5 * (phi + (c[k] / aa[k] * phi.sin()).asin());
    }
    phi.cos()
}

#[test]
fn jacobi_cn_limits() {
    // m = 0: cos; m -> 1: sech. And cn(K(m)) = 0 with K(1/2) = 1.854074677301372.
    for u in [0.0, 0.3, 1.7, 5.0] {
        assert!((jacobi_cn(u, 0.0) - u.cos()).abs() < 1e-15);
        assert!((jacobi_cn(u, 1.0 - 1e-15) - 1.0 / u.cosh()).abs() < 1e-6);
    }
    assert!(jacobi_cn(1.854_074_677_301_372, 0.5).abs() < 1e-14);
}

/// One floor of mass `M` on a story of stiffness `K`, undamped unless told.
fn sdof(xi: f64) -> LinearSystem {
    LinearSystem::from_spec(
        &StructureSpec::ShearFrame {
            floor_mass_kg: vec![M],
            story_stiffness_n_per_m: vec![K],
        },
        &DampingSpec::Modal { xi: vec![xi] },
    )
    .unwrap()
}

const M: f64 = 2.0;
const K: f64 = 800.0;
/// Free-vibration amplitude; `K3 A^2 = K / 2`: strongly nonlinear (frequency up 22%).
const A: f64 = 0.01;
const K3: f64 = 4e6;

fn spring() -> CubicSpring {
    CubicSpring {
        upper_dof: 0,
        lower_dof: None,
        k3_n_per_m3: K3,
        linear_stiffness_n_per_m: K,
    }
}

/// Displacement and acceleration from rest at `A` over `duration_s` at `rate_hz`.
fn free_duffing(sys: &LinearSystem, rate_hz: f64, duration_s: f64) -> Vec<Vec<f64>> {
    let nl =
        NonlinearFoh::new(sys, &[Drive::Force { dof: 0 }], &[spring()], 1.0 / rate_hz).unwrap();
    let out = nl
        .state_space
        .output_map(&[
            Response::Displacement { dof: 0 },
            Response::Acceleration { dof: 0 },
        ])
        .unwrap();
    let n = (duration_s * rate_hz).round() as usize + 1;
    let z0 = DVector::from_row_slice(&[A, 0.0]);
    nl.simulate(&out, &[vec![0.0; n]], Some(&z0), &|_| {})
        .unwrap()
}

#[test]
fn undamped_duffing_matches_the_exact_cn_solution_to_fourth_order() {
    // m x'' + k x + k3 x^3 = 0, x(0) = A, x'(0) = 0 has x = A cn(W t | mu) with
    // W^2 = (k + k3 A^2) / m, mu = k3 A^2 / (2 (k + k3 A^2)); x'' from the equation.
    let w = ((K + K3 * A * A) / M).sqrt();
    let mu = K3 * A * A / (2.0 * (K + K3 * A * A));
    let duration_s = 3.0; // ~11 periods
    let mut errors = Vec::new();
    for rate_hz in [1000.0, 2000.0, 4000.0] {
        let y = free_duffing(&sdof(0.0), rate_hz, duration_s);
        let mut worst: f64 = 0.0;
        for (k, (x, acc)) in y[0].iter().zip(&y[1]).enumerate() {
            let t = k as f64 / rate_hz;
            let xe = A * jacobi_cn(w * t, mu);
            let ae = -(K * xe + K3 * xe.powi(3)) / M;
            worst = worst
                .max((x - xe).abs() / A)
                .max((acc - ae).abs() / (w * w * A));
        }
        errors.push(worst);
    }
    println!("Duffing vs cn: relative errors {errors:?}");
    // Fourth order: halving the step divides the error by 16. The leading term dominates
    // once (w h)^2 << 1 (w h = 0.025 at 1000 Hz, so the next term is ~1e-3 of it); the
    // ratio is allowed 16 +- 25% for the phase error's accumulation over the cycles.
    for pair in errors.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!((12.0..20.0).contains(&ratio), "ratio {ratio}: {errors:?}");
    }
    // Absolute level: the Hermite interpolant of the force is off by at most
    // h^4 max|q''''| / 384 within a step, q'''' ~ (3 W)^4 k3 A^3 (third harmonic), i.e.
    // ~4e-6 of the force k3 A^3 at 1000 Hz; that error drives the displacement off
    // resonance (gain ~ 1 / (8 W^2 m)) and accumulates in phase over ~11 periods: a bound
    // of 1e-6 of A is generous (measured: 1.1e-9).
    assert!(errors[0] < 1e-6, "{errors:?}");
}

#[test]
fn damped_forced_duffing_converges_at_fourth_order_by_step_halving() {
    // Damped (5%), forced by a smooth pulse (sin^4, three derivatives continuous, so the
    // pre-emphasised straight-line hold represents it to fourth order at every step
    // size), plus an initial drift.
    // Without an exact solution, the error at step h is estimated by |y_h - y_{h/2}|
    // (Richardson); fourth order makes successive estimates fall 16-fold.
    let sys = sdof(0.05);
    let duration_s = 2.0;
    let run = |rate_hz: f64| -> Vec<f64> {
        let nl = NonlinearFoh::new(&sys, &[Drive::Force { dof: 0 }], &[spring()], 1.0 / rate_hz)
            .unwrap();
        let out = nl
            .state_space
            .output_map(&[Response::Displacement { dof: 0 }])
            .unwrap();
        let n = (duration_s * rate_hz).round() as usize + 1;
        // 0 -> 40 N -> 0 over [0.2, 0.3] s.
        let u: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / rate_hz;
                if (0.2..=0.3).contains(&t) {
                    40.0 * (std::f64::consts::PI * (t - 0.2) / 0.1).sin().powi(4)
                } else {
                    0.0
                }
            })
            .collect();
        let z0 = DVector::from_row_slice(&[0.5 * A, 0.0]);
        let y = nl.simulate(&out, &[u], Some(&z0), &|_| {}).unwrap();
        // Keep the samples on the coarsest grid (1000 Hz).
        let stride = (rate_hz / 1000.0).round() as usize;
        y[0].iter().step_by(stride).copied().collect()
    };
    let ys: Vec<Vec<f64>> = [1000.0, 2000.0, 4000.0, 8000.0].map(run).to_vec();
    let diff = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    let est: Vec<f64> = ys.windows(2).map(|p| diff(&p[0], &p[1])).collect();
    println!("Duffing step halving: differences {est:?}");
    for pair in est.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!((12.0..20.0).contains(&ratio), "ratio {ratio}: {est:?}");
    }
    // The response is really nonlinear: the k3 = 0 response differs by far more.
    let peak = ys[3].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    assert!(peak > 0.5 * A && est[0] < 1e-6 * peak, "{peak} {est:?}");
}

#[test]
fn zero_k3_reproduces_the_linear_recursion() {
    // A 3-floor frame with a zero cubic spring on story 2: the Newton solve returns zero
    // forces and the step is the FOH step (its matrices come from a larger exponential,
    // so equal to rounding, not bit for bit).
    let sys = LinearSystem::from_spec(
        &StructureSpec::ShearFrame {
            floor_mass_kg: vec![5.0, 4.0, 4.5],
            story_stiffness_n_per_m: vec![1200.0, 1300.0, 2500.0],
        },
        &DampingSpec::Modal {
            xi: vec![0.02, 0.01, 0.005],
        },
    )
    .unwrap();
    let rate = 5000.0;
    let drive = [Drive::Force { dof: 2 }];
    let responses: Vec<Response> = (0..3)
        .flat_map(|dof| {
            [
                Response::Displacement { dof },
                Response::Acceleration { dof },
            ]
        })
        .collect();
    let n = 40_000;
    let u: Vec<f64> = (0..n)
        .map(|k| if (100..115).contains(&k) { 50.0 } else { 0.0 })
        .collect();
    let ss = StateSpace::new(&sys, &drive).unwrap();
    let lin = Foh::new(&ss, 1.0 / rate)
        .unwrap()
        .simulate(
            &ss.output_map(&responses).unwrap(),
            std::slice::from_ref(&u),
            None,
            &|_| {},
        )
        .unwrap();
    let zero = CubicSpring {
        upper_dof: 1,
        lower_dof: Some(0),
        k3_n_per_m3: 0.0,
        linear_stiffness_n_per_m: 1300.0,
    };
    let nl = NonlinearFoh::new(&sys, &drive, &[zero], 1.0 / rate).unwrap();
    let got = nl
        .simulate(
            &nl.state_space.output_map(&responses).unwrap(),
            &[u],
            None,
            &|_| {},
        )
        .unwrap();
    for (a, b) in lin.iter().zip(&got) {
        let peak = a.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let err = a
            .iter()
            .zip(b)
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(err <= 1e-12 * peak, "{err} vs peak {peak}");
    }
}

#[test]
fn softening_beyond_the_inflection_is_an_error() {
    // k + 3 k3 d^2 <= 0 at d = A when k3 = -k / (3 A^2): start there.
    let soft = CubicSpring {
        k3_n_per_m3: -K / (3.0 * A * A) * 1.01,
        ..spring()
    };
    let nl = NonlinearFoh::new(&sdof(0.0), &[Drive::Force { dof: 0 }], &[soft], 1e-3).unwrap();
    let out = nl
        .state_space
        .output_map(&[Response::Displacement { dof: 0 }])
        .unwrap();
    let z0 = DVector::from_row_slice(&[1.2 * A, 0.0]);
    let e = nl
        .simulate(&out, &[vec![0.0; 100]], Some(&z0), &|_| {})
        .unwrap_err();
    assert!(e.to_string().contains("lost its stiffness"), "{e}");
}
