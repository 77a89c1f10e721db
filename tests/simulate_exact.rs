//! The FOH discretisation against closed-form modal solutions: step, impulse (initial
//! velocity), triangle pulse (piecewise linear after pre-emphasis, so FOH is exact) and
//! ground steps, for a
//! proportionally damped 3-DOF shear frame. Displacement, velocity and absolute
//! acceleration must agree to 1e-10 relative to their peaks.

use frfbayes::modal::Modes;
use frfbayes::simulate::{
    DampingSpec, Drive, Foh, LinearSystem, Response, StateSpace, StructureSpec,
};
use nalgebra::DVector;

/// Required agreement, relative to the peak of each response. The recursion multiplies
/// by Phi once per step, so rounding grows at most like (steps x eps x a few); for the
/// 250 000 steps used here that is ~1e-10 at worst, and in practice far less.
const EXACT_RTOL: f64 = 1e-10;

const RATE_HZ: f64 = 5000.0;

fn system() -> LinearSystem {
    LinearSystem::from_spec(
        &StructureSpec::ShearFrame {
            floor_mass_kg: vec![5.2, 4.9, 5.1],
            story_stiffness_n_per_m: vec![1100.0, 1300.0, 2600.0],
        },
        &DampingSpec::Modal {
            xi: vec![0.02, 0.012, 0.005],
        },
    )
    .unwrap()
}

/// Unit-force modal responses of `q'' + 2 xi w q' + w^2 q = p(t)`: (q, q', q'').
trait Sdof {
    fn eval(&self, w: f64, xi: f64, t: f64) -> (f64, f64, f64);
}

/// Unit step `p = 1` for t >= 0.
struct Step;
impl Sdof for Step {
    fn eval(&self, w: f64, xi: f64, t: f64) -> (f64, f64, f64) {
        if t < 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let wd = w * (1.0 - xi * xi).sqrt();
        let e = (-xi * w * t).exp();
        let q = (1.0 - e * ((wd * t).cos() + xi * w / wd * (wd * t).sin())) / (w * w);
        let qd = e * (wd * t).sin() / wd;
        (q, qd, 1.0 - 2.0 * xi * w * qd - w * w * q)
    }
}

/// Unit ramp `p = t` for t >= 0.
struct Ramp;
impl Sdof for Ramp {
    fn eval(&self, w: f64, xi: f64, t: f64) -> (f64, f64, f64) {
        if t < 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let wd = w * (1.0 - xi * xi).sqrt();
        let e = (-xi * w * t).exp();
        let (c, s) = ((wd * t).cos(), (wd * t).sin());
        // q = (t - 2 xi / w + e (2 xi / w cos + (2 xi^2 - 1) / wd sin)) / w^2
        let q =
            (t - 2.0 * xi / w + e * (2.0 * xi / w * c + (2.0 * xi * xi - 1.0) / wd * s)) / (w * w);
        // q' is the unit step response.
        let qd = Step.eval(w, xi, t).0;
        (q, qd, t - 2.0 * xi * w * qd - w * w * q)
    }
}

/// A piecewise-linear pulse `p = sum_j a_j ramp(t - t_j)` that is zero from `end` on
/// (`kinks`: `(t_j, a_j)`, the slopes summing to zero). Past `end` the growing ramp
/// responses would cancel to a small remainder and lose digits, so the response there
/// is the free vibration from the state at `end`.
struct PiecewiseLinear {
    kinks: Vec<(f64, f64)>,
    end: f64,
}
impl Sdof for PiecewiseLinear {
    fn eval(&self, w: f64, xi: f64, t: f64) -> (f64, f64, f64) {
        let during = |t: f64| {
            self.kinks.iter().fold((0.0, 0.0, 0.0), |acc, (tj, a)| {
                let r = Ramp.eval(w, xi, t - tj);
                (acc.0 + a * r.0, acc.1 + a * r.1, acc.2 + a * r.2)
            })
        };
        if t <= self.end {
            return during(t);
        }
        let (q0, v0, _) = during(self.end);
        let wd = w * (1.0 - xi * xi).sqrt();
        let tau = t - self.end;
        let e = (-xi * w * tau).exp();
        let (c, s) = ((wd * tau).cos(), (wd * tau).sin());
        let b = (v0 + xi * w * q0) / wd;
        let q = e * (q0 * c + b * s);
        let qd = e * (-xi * w * (q0 * c + b * s) + wd * (-q0 * s + b * c));
        (q, qd, -2.0 * xi * w * qd - w * w * q)
    }
}

/// Free vibration after a unit initial modal velocity (the impulse response).
struct Impulse;
impl Sdof for Impulse {
    fn eval(&self, w: f64, xi: f64, t: f64) -> (f64, f64, f64) {
        let wd = w * (1.0 - xi * xi).sqrt();
        let e = (-xi * w * t).exp();
        let q = e * (wd * t).sin() / wd;
        let qd = e * ((wd * t).cos() - xi * w / wd * (wd * t).sin());
        (q, qd, -2.0 * xi * w * qd - w * w * q)
    }
}

/// Modal superposition: response at DOF r = sum_i phi_ri f_i q_i, with modal force
/// amplitudes `f_i`.
fn modal_response(
    modes: &Modes,
    xi: &[f64],
    f: &[f64],
    shape: &dyn Sdof,
    r: usize,
    t: f64,
) -> (f64, f64, f64) {
    let mut out = (0.0, 0.0, 0.0);
    for i in 0..modes.n_modes() {
        let (q, qd, qdd) = shape.eval(modes.omega_rad_s[i], xi[i], t);
        let a = modes.phi[(r, i)] * f[i];
        out.0 += a * q;
        out.1 += a * qd;
        out.2 += a * qdd;
    }
    out
}

/// Simulates and compares every DOF's displacement, velocity and acceleration;
/// `extra_acc(dof, t)` is added to the modal solution's acceleration (the ground's own,
/// or a feedthrough the read-out takes from other samples than the state).
fn check(
    drive: Drive,
    input: &dyn Fn(f64) -> f64,
    z0: Option<DVector<f64>>,
    shape: &dyn Sdof,
    modal_force: &[f64],
    extra_acc: &dyn Fn(usize, f64) -> f64,
    n_steps: usize,
) -> f64 {
    let sys = system();
    let modes = sys.modes().unwrap();
    let xi = sys.modal_damping_ratios().unwrap();
    let ss = StateSpace::new(&sys, &[drive]).unwrap();
    let mut responses = Vec::new();
    for dof in 0..3 {
        responses.push(Response::Displacement { dof });
        responses.push(Response::Velocity { dof });
        responses.push(Response::Acceleration { dof });
    }
    let out = ss.output_map(&responses).unwrap();
    let foh = Foh::new(&ss, 1.0 / RATE_HZ).unwrap();
    let u: Vec<f64> = (0..n_steps).map(|k| input(k as f64 / RATE_HZ)).collect();
    let y = foh.simulate(&out, &[u], z0.as_ref(), &|_| {}).unwrap();
    let mut worst: f64 = 0.0;
    for dof in 0..3 {
        let exact: Vec<(f64, f64, f64)> = (0..n_steps)
            .map(|k| {
                let t = k as f64 / RATE_HZ;
                let (x, v, a) = modal_response(&modes, &xi, modal_force, shape, dof, t);
                (x, v, a + extra_acc(dof, t))
            })
            .collect();
        for (c, get) in [
            |e: &(f64, f64, f64)| e.0,
            |e: &(f64, f64, f64)| e.1,
            |e: &(f64, f64, f64)| e.2,
        ]
        .iter()
        .enumerate()
        {
            let sim = &y[3 * dof + c];
            let peak = exact.iter().map(|e| get(e).abs()).fold(0.0, f64::max);
            let err = sim
                .iter()
                .zip(&exact)
                .map(|(s, e)| (s - get(e)).abs())
                .fold(0.0, f64::max);
            worst = worst.max(err / peak);
            assert!(
                err <= EXACT_RTOL * peak,
                "dof {dof} quantity {c}: max error {err:e} vs peak {peak:e}"
            );
        }
    }
    worst
}

#[test]
fn step_force_matches_modal_solution() {
    let modes = system().modes().unwrap();
    let (e, p) = (1, 30.0);
    // Modal force of a force P at DOF e: phi_ei P.
    let f: Vec<f64> = (0..3).map(|i| modes.phi[(e, i)] * p).collect();
    let worst = check(
        Drive::Force { dof: e },
        &|_| p,
        None,
        &Step,
        &f,
        &|_, _| 0.0,
        250_000,
    );
    println!("step force: worst relative error {worst:e}");
}

#[test]
fn triangle_pulse_matches_modal_solution() {
    // A triangle with corners on the sample grid (4 ms rise, 4 ms fall, peak 40 N). The
    // state is driven by the straight line through its pre-emphasised samples
    // (`p_k = u_k + (2 u_k - u_{k-1} - u_{k+1}) / 12`): the triangle plus hats of
    // +s h / 6 at the peak and -s h / 12 at the foot (s the slope), piecewise linear, so
    // the step is exact for it. The accelerations' feedthrough reads the raw samples:
    // `M^-1 e (u_k - p_k)` off the modal solution at those two samples.
    let sys = system();
    let modes = sys.modes().unwrap();
    let e = 2;
    let h = 1.0 / RATE_HZ;
    let rise = 20.0 * h;
    let slope = 40.0 / rise;
    let input = move |t: f64| {
        if t <= rise {
            slope * t
        } else if t <= 2.0 * rise {
            slope * (2.0 * rise - t)
        } else {
            0.0
        }
    };
    let (peak, foot) = (1.0 / 6.0, -1.0 / 12.0);
    let pulse = PiecewiseLinear {
        kinks: vec![
            (0.0, 1.0),
            (rise - h, peak),
            (rise, -2.0 - 2.0 * peak),
            (rise + h, peak),
            (2.0 * rise - h, foot),
            (2.0 * rise, 1.0 - 2.0 * foot),
            (2.0 * rise + h, foot),
        ],
        end: 2.0 * rise + h,
    };
    let m_inv = sys.mass_kg.clone().try_inverse().unwrap();
    let hat = move |dof: usize, t: f64| {
        let k = (t * RATE_HZ).round() as i64;
        let c = match k {
            20 => peak,
            40 => foot,
            _ => 0.0,
        };
        -m_inv[(dof, e)] * c * slope * h
    };
    let f: Vec<f64> = (0..3).map(|i| modes.phi[(e, i)] * slope).collect();
    let worst = check(
        Drive::Force { dof: e },
        &input,
        None,
        &pulse,
        &f,
        &hat,
        100_000,
    );
    println!("triangle pulse: worst relative error {worst:e}");
}

#[test]
fn impulse_response_from_initial_velocity_matches_modal_solution() {
    // An impulse I at DOF e gives x'(0+) = M^-1 e I; modal velocities phi_ei I.
    let sys = system();
    let modes = sys.modes().unwrap();
    let (e, impulse) = (0, 0.1);
    let mut load = DVector::zeros(3);
    load[e] = impulse;
    let v0 = sys.mass_kg.clone().cholesky().unwrap().solve(&load);
    let mut z0 = DVector::zeros(6);
    z0.rows_mut(3, 3).copy_from(&v0);
    let f: Vec<f64> = (0..3).map(|i| modes.phi[(e, i)] * impulse).collect();
    let worst = check(
        Drive::Force { dof: e },
        &|_| 0.0,
        Some(z0),
        &Impulse,
        &f,
        &|_, _| 0.0,
        250_000,
    );
    println!("impulse: worst relative error {worst:e}");
}

#[test]
fn ground_ramp_matches_modal_solution_with_absolute_acceleration() {
    // a_g = r t: relative response with modal force -Gamma_i r t; the accelerometers read
    // x'' + a_g.
    let modes = system().modes().unwrap();
    let r = 0.05;
    let f: Vec<f64> = modes.participation.iter().map(|g| -g * r).collect();
    let worst = check(
        Drive::Ground,
        &|t| r * t,
        None,
        &Ramp,
        &f,
        &|_, t| r * t,
        50_000,
    );
    println!("ground ramp: worst relative error {worst:e}");
}
