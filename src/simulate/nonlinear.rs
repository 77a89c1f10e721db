//! Time stepping with cubic story springs: `M x'' + C x' + K x + sum_s p_s k3_s d_s^3 =
//! f(t) - M iota a_g(t)`, with `d_s = p_s^T x` the drift across spring s and
//! `p_s = e_upper - e_lower` its load pattern.
//!
//! The linear part is stepped exactly as in [`super::discrete`]: the spring forces
//! `q_s = -k3_s d_s^3` are extra inputs (drives [`Drive::Pair`]). Over each step the
//! external input is the straight line between its pre-emphasised samples (as for the
//! linear simulation, [`super::discrete::pre_emphasised`], so `k3 = 0` reproduces it),
//! and each spring force is the cubic Hermite
//! interpolant of its end values and end derivatives `q' = -3 k3 d^2 v` (`v = d'`):
//!
//! `q(t_k + tau h) = c0 + c1 tau + c2 tau^2 + c3 tau^3`, `c0 = q_k`, `c1 = h q'_k`,
//! `c2 = 3 (q_{k+1} - q_k) - h (2 q'_k + q'_{k+1})`, `c3 = 2 (q_k - q_{k+1}) + h (q'_k + q'_{k+1})`,
//!
//! stepped exactly with the degree-3 polynomial hold ([`polynomial_hold`]). The end values
//! depend on the new state, so each step solves for the new drifts and drift velocities
//! `(d_s, v_s)` by Newton's method (a 2 x 2 system per spring, to rounding). The Hermite
//! interpolant is in error by `O(h^4)` within a step, so the scheme is fourth order
//! globally (checked on a Duffing oscillator against the exact `cn` solution and by step
//! halving), and exact for `k3 = 0`.

use super::discrete::{dot, polynomial_hold, pre_emphasised, Drive, OutputMap, StateSpace};
use super::system::LinearSystem;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// A cubic spring: force `k3 d^3` (N) between `upper_dof` and `lower_dof` (none: the
/// rigid ground), `d = x_upper - x_lower`; hardening for `k3 > 0`, softening for `k3 < 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubicSpring {
    pub upper_dof: usize,
    pub lower_dof: Option<usize>,
    pub k3_n_per_m3: f64,
    /// The linear stiffness in parallel (of the story), N/m: a softening spring whose
    /// tangent `k + 3 k3 d^2` reaches zero has lost stability and stops the simulation.
    pub linear_stiffness_n_per_m: f64,
}

/// Most Newton iterations per step before giving up.
const MAX_NEWTON: usize = 50;
/// Newton stops when every update is below this fraction of the size of its terms.
const NEWTON_RTOL: f64 = 1e-14;

/// The stepping matrices of a system with cubic springs (module docs).
#[derive(Debug, Clone)]
pub struct NonlinearFoh {
    /// State space with the external drives first, then one [`Drive::Pair`] per spring.
    pub state_space: StateSpace,
    phi: DMatrix<f64>,
    /// `G_0..G_3` of the degree-3 polynomial hold, all inputs.
    g: Vec<DMatrix<f64>>,
    springs: Vec<CubicSpring>,
    n_external: usize,
    step_s: f64,
}

impl NonlinearFoh {
    /// Discretises `system` driven by `drives` with `springs` at step `step_s`.
    pub fn new(
        system: &LinearSystem,
        drives: &[Drive],
        springs: &[CubicSpring],
        step_s: f64,
    ) -> Result<Self> {
        let mut all = drives.to_vec();
        all.extend(springs.iter().map(|s| Drive::Pair {
            plus_dof: s.upper_dof,
            minus_dof: s.lower_dof,
        }));
        for s in springs {
            if !(s.k3_n_per_m3.is_finite() && s.linear_stiffness_n_per_m.is_finite()) {
                return Err(Error::Usage(format!("cubic spring {s:?} is not finite")));
            }
        }
        let state_space = StateSpace::new(system, &all)?;
        let (phi, g) = polynomial_hold(&state_space, step_s, 3)?;
        Ok(NonlinearFoh {
            state_space,
            phi,
            g,
            springs: springs.to_vec(),
            n_external: drives.len(),
            step_s,
        })
    }

    /// Runs from state `z0` (rest when `None`) over the external input samples
    /// `inputs[j][k]` (at `t = k h`), returning the outputs `y[r][k]` of `outputs` (from
    /// [`StateSpace::output_map`] of [`Self::state_space`]; accelerations include the
    /// spring forces). `progress` gets the number of steps done since its last call.
    pub fn simulate(
        &self,
        outputs: &OutputMap,
        inputs: &[Vec<f64>],
        z0: Option<&DVector<f64>>,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Vec<f64>>> {
        let ns = self.phi.nrows();
        let n = ns / 2;
        let ne = self.n_external;
        let ni = ne + self.springs.len();
        let no = outputs.c.nrows();
        let n_steps = self.check_input_shapes(outputs, inputs)?;
        let h = self.step_s;
        let ops = self.step_operators();
        let oc = row_major(&outputs.c);
        let od = row_major(&outputs.d);
        let mut z = initial_state(z0, ns)?;
        let m = self.springs.len();
        // Forces and their derivatives (q_s, q'_s) at the current state, flat.
        let mut qk = vec![0.0; 2 * m];
        for (s, sp) in self.springs.iter().enumerate() {
            let (d, v) = spring_drift(sp, &z, n);
            (qk[2 * s], qk[2 * s + 1]) = sp.force(d, v);
        }
        let drive: Vec<Vec<f64>> = inputs.iter().map(|u| pre_emphasised(u)).collect();
        let mut z_star = vec![0.0; ns];
        let mut a = vec![0.0; 2 * m];
        let mut u = vec![0.0; ni];
        let mut y_out: Vec<Vec<f64>> = (0..no).map(|_| Vec::with_capacity(n_steps)).collect();
        let mut newton = Newton::new(m);
        const CHUNK: usize = 1 << 14;
        let mut reported = 0;
        for k in 0..n_steps {
            for (uj, series) in u.iter_mut().take(ne).zip(inputs) {
                *uj = series[k];
            }
            for s in 0..m {
                u[ne + s] = qk[2 * s];
            }
            for (r, yr) in y_out.iter_mut().enumerate() {
                yr.push(dot(&oc[r * ns..(r + 1) * ns], &z) + dot(&od[r * ni..(r + 1) * ni], &u));
            }
            if k + 1 == n_steps {
                break;
            }
            ops.known_state(&z, &drive, k, &qk, &mut z_star);
            for (s, sp) in self.springs.iter().enumerate() {
                (a[2 * s], a[2 * s + 1]) = spring_drift(sp, &z_star, n);
            }
            let t_s = (k + 1) as f64 * h;
            newton
                .solve(&self.springs, &a, &ops.b, &qk)
                .map_err(|what| {
                    Error::Numerical(format!("cubic spring step at t = {t_s:.6} s: {what}"))
                })?;
            for (s, c) in ops.cols.iter().enumerate() {
                let (q, p) = (newton.forces[2 * s], newton.forces[2 * s + 1]);
                for (zi, (cq, cp)) in z_star.iter_mut().zip(c.uq.iter().zip(&c.up)) {
                    *zi += cq * q + cp * p;
                }
            }
            std::mem::swap(&mut z, &mut z_star);
            qk.copy_from_slice(&newton.forces);
            check_tangent_stiffness(&self.springs, &newton.y, t_s)?;
            if (k + 1).is_multiple_of(CHUNK) {
                progress(CHUNK as u64);
                reported += CHUNK;
            }
        }
        progress((n_steps - reported) as u64);
        if y_out.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::Numerical("simulated response is not finite".into()));
        }
        Ok(y_out)
    }

    /// Checks that there is one input series per external input, all of one length, and
    /// that `outputs` reads this state space; returns the number of samples.
    fn check_input_shapes(&self, outputs: &OutputMap, inputs: &[Vec<f64>]) -> Result<usize> {
        let ns = self.phi.nrows();
        let ne = self.n_external;
        let ni = ne + self.springs.len();
        if inputs.len() != ne || outputs.c.ncols() != ns || outputs.d.ncols() != ni {
            return Err(Error::Usage(format!(
                "simulation with {} input series for {ne} inputs, or read-out of the wrong shape",
                inputs.len()
            )));
        }
        let n_steps = inputs.first().map_or(0, Vec::len);
        if inputs.iter().any(|u| u.len() != n_steps) {
            return Err(Error::Usage("input series of different lengths".into()));
        }
        Ok(n_steps)
    }

    /// The flat, row-major stepping operators: `Phi`, the external inputs' first-order
    /// hold, each spring's Hermite-hold columns and the Newton sensitivity `B`.
    fn step_operators(&self) -> StepOperators {
        let ns = self.phi.nrows();
        let n = ns / 2;
        let ne = self.n_external;
        let h = self.step_s;
        let phi = row_major(&self.phi);
        // External inputs (first-order hold): z += Gamma0 u_k + Gamma1 u_{k+1}.
        let ext = |m: &DMatrix<f64>| row_major(&m.columns(0, ne).into_owned());
        let gamma1 = ext(&self.g[1]);
        let gamma0 = ext(&(&self.g[0] - &self.g[1]));
        // Spring force columns: known part from (q_k, q'_k), unknown from (q_{k+1}, q'_{k+1}).
        let col = |m: &DMatrix<f64>, s: usize| -> Vec<f64> {
            m.column(ne + s).iter().copied().collect::<Vec<f64>>()
        };
        let [g0, g1, g2, g3] = [&self.g[0], &self.g[1], &self.g[2], &self.g[3]];
        let lin = |a: &[(f64, &DMatrix<f64>)], s: usize| -> Vec<f64> {
            let mut out = vec![0.0; ns];
            for (w, m) in a {
                for (o, v) in out.iter_mut().zip(col(m, s)) {
                    *o += w * v;
                }
            }
            out
        };
        let cols: Vec<SpringCols> = (0..self.springs.len())
            .map(|s| SpringCols {
                kq: lin(&[(1.0, g0), (-3.0, g2), (2.0, g3)], s),
                kp: lin(&[(h, g1), (-2.0 * h, g2), (h, g3)], s),
                uq: lin(&[(3.0, g2), (-2.0, g3)], s),
                up: lin(&[(-h, g2), (h, g3)], s),
            })
            .collect();
        let m = self.springs.len();
        // B: sensitivity of (d_j, v_j) of the new state to (q_i, q'_i) at the step end.
        let mut b = vec![0.0; 4 * m * m];
        for (j, sj) in self.springs.iter().enumerate() {
            for (i, ci) in cols.iter().enumerate() {
                let (dq, vq) = spring_drift(sj, &ci.uq, n);
                let (dp, vp) = spring_drift(sj, &ci.up, n);
                let r = 2 * j;
                b[r * 2 * m + 2 * i] = dq;
                b[r * 2 * m + 2 * i + 1] = dp;
                b[(r + 1) * 2 * m + 2 * i] = vq;
                b[(r + 1) * 2 * m + 2 * i + 1] = vp;
            }
        }
        StepOperators {
            ns,
            ne,
            phi,
            gamma0,
            gamma1,
            cols,
            b,
        }
    }
}

/// The stepping operators of [`NonlinearFoh::simulate`], flat and row-major.
struct StepOperators {
    /// State size.
    ns: usize,
    /// Number of external inputs.
    ne: usize,
    phi: Vec<f64>,
    gamma0: Vec<f64>,
    gamma1: Vec<f64>,
    /// Per spring.
    cols: Vec<SpringCols>,
    /// Sensitivity of the new drifts and drift velocities to the end forces (`2m x 2m`).
    b: Vec<f64>,
}

/// One spring's columns of the Hermite hold: z_{k+1} gains
/// `kq q_k + kp q'_k + uq q_{k+1} + up q'_{k+1}`.
struct SpringCols {
    kq: Vec<f64>,
    kp: Vec<f64>,
    uq: Vec<f64>,
    up: Vec<f64>,
}

impl StepOperators {
    /// The known part of the new state (`z_star`): `Phi z_k`, the external inputs'
    /// first-order hold over step `k` and the springs' start forces `(q_k, q'_k)`.
    fn known_state(
        &self,
        z: &[f64],
        inputs: &[Vec<f64>],
        k: usize,
        qk: &[f64],
        z_star: &mut [f64],
    ) {
        let (ns, ne) = (self.ns, self.ne);
        for (i, zi) in z_star.iter_mut().enumerate() {
            let mut v = dot(&self.phi[i * ns..(i + 1) * ns], z);
            for (j, u) in inputs.iter().enumerate().take(ne) {
                v += self.gamma0[i * ne + j] * u[k] + self.gamma1[i * ne + j] * u[k + 1];
            }
            for (s, c) in self.cols.iter().enumerate() {
                v += c.kq[i] * qk[2 * s] + c.kp[i] * qk[2 * s + 1];
            }
            *zi = v;
        }
    }
}

/// `m` row-major, flat.
fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

/// The state to start from: `z0` (checked to be of size `ns`) or rest.
fn initial_state(z0: Option<&DVector<f64>>, ns: usize) -> Result<Vec<f64>> {
    match z0 {
        Some(z0) if z0.len() == ns => Ok(z0.as_slice().to_vec()),
        Some(z0) => Err(Error::Usage(format!(
            "initial state has {} entries, expected {ns}",
            z0.len()
        ))),
        None => Ok(vec![0.0; ns]),
    }
}

/// Drift (m) and drift velocity (m/s) of spring `s` read from the state `z`
/// (`n` displacements, then `n` velocities).
fn spring_drift(s: &CubicSpring, z: &[f64], n: usize) -> (f64, f64) {
    let (lo_d, lo_v) = s.lower_dof.map_or((0.0, 0.0), |l| (z[l], z[n + l]));
    (z[s.upper_dof] - lo_d, z[n + s.upper_dof] - lo_v)
}

/// Stops when a softening spring's tangent stiffness `k + 3 k3 d^2` (N/m) at the new
/// drifts `y = (d_1, v_1, ...)` has reached zero (time `t_s` for the message).
fn check_tangent_stiffness(springs: &[CubicSpring], y: &[f64], t_s: f64) -> Result<()> {
    for (s, sp) in springs.iter().enumerate() {
        let d = y[2 * s];
        if sp.linear_stiffness_n_per_m + 3.0 * sp.k3_n_per_m3 * d * d <= 0.0 {
            return Err(Error::Numerical(format!(
                "softening spring at DOF {} lost its stiffness (drift {d:.3e} m at t = {t_s:.3} s); lower |k3| or the excitation",
                sp.upper_dof,
            )));
        }
    }
    Ok(())
}

impl CubicSpring {
    /// Force on the upper DOF, `q = -k3 d^3`, and its rate `q' = -3 k3 d^2 v`, for the
    /// drift `d` and drift velocity `v`.
    pub fn force(&self, d: f64, v: f64) -> (f64, f64) {
        let k3 = self.k3_n_per_m3;
        (-k3 * d * d * d, -3.0 * k3 * d * d * v)
    }
}

/// Newton's method for the spring unknowns of the new state, flat as
/// `y = (d_1, v_1, ..., d_m, v_m)`: `y = a + B g(y)` with `g = (q_1, q'_1, ...)` the
/// spring forces of `y` and `B` (`2m x 2m`, row-major) their effect on `y`.
struct Newton {
    /// Converged `y`.
    y: Vec<f64>,
    /// Converged `g(y)`.
    forces: Vec<f64>,
    jac: Vec<f64>,
    res: Vec<f64>,
    scale: Vec<f64>,
}

impl Newton {
    fn new(n_springs: usize) -> Self {
        let dim = 2 * n_springs;
        Newton {
            y: vec![0.0; dim],
            forces: vec![0.0; dim],
            jac: vec![0.0; dim * dim],
            res: vec![0.0; dim],
            scale: vec![0.0; dim],
        }
    }

    fn update_forces(&mut self, springs: &[CubicSpring]) {
        for (s, sp) in springs.iter().enumerate() {
            (self.forces[2 * s], self.forces[2 * s + 1]) =
                sp.force(self.y[2 * s], self.y[2 * s + 1]);
        }
    }

    fn solve(
        &mut self,
        springs: &[CubicSpring],
        a: &[f64],
        b: &[f64],
        g_prev: &[f64],
    ) -> std::result::Result<(), String> {
        let dim = 2 * springs.len();
        // Predictor: the spring forces held at their last values.
        for (j, yj) in self.y.iter_mut().enumerate() {
            *yj = a[j] + dot(&b[j * dim..(j + 1) * dim], g_prev);
        }
        for _ in 0..MAX_NEWTON {
            self.update_forces(springs);
            // Residual r = y - a - B g, the size of its terms, and the Jacobian I - B Dg.
            for j in 0..dim {
                let row = &b[j * dim..(j + 1) * dim];
                let bg = dot(row, &self.forces);
                let bg_abs: f64 = row
                    .iter()
                    .zip(&self.forces)
                    .map(|(x, g)| (x * g).abs())
                    .sum();
                self.res[j] = self.y[j] - a[j] - bg;
                self.scale[j] = self.y[j].abs() + a[j].abs() + bg_abs;
                let jac = &mut self.jac[j * dim..(j + 1) * dim];
                for (i, v) in jac.iter_mut().enumerate() {
                    *v = f64::from(i == j);
                }
                for (s, sp) in springs.iter().enumerate() {
                    let (d, v) = (self.y[2 * s], self.y[2 * s + 1]);
                    let k3 = sp.k3_n_per_m3;
                    // Dg: dq/dd = -3 k3 d^2, dq'/dd = -6 k3 d v, dq'/dv = -3 k3 d^2.
                    let (bq, bp) = (row[2 * s], row[2 * s + 1]);
                    jac[2 * s] -= bq * (-3.0 * k3 * d * d) + bp * (-6.0 * k3 * d * v);
                    jac[2 * s + 1] -= bp * (-3.0 * k3 * d * d);
                }
            }
            solve_in_place(&mut self.jac, &mut self.res, dim)?;
            let mut done = true;
            for ((yj, step), scale) in self.y.iter_mut().zip(&self.res).zip(&self.scale) {
                done &= step.abs() <= NEWTON_RTOL * scale;
                *yj -= step;
            }
            if done {
                self.update_forces(springs);
                return Ok(());
            }
        }
        Err(format!(
            "Newton did not converge in {MAX_NEWTON} iterations"
        ))
    }
}

/// Solves `a x = r` in place (`r` becomes `x`) by Gaussian elimination with partial
/// pivoting; `a` is `dim x dim`, row-major.
fn solve_in_place(a: &mut [f64], r: &mut [f64], dim: usize) -> std::result::Result<(), String> {
    for c in 0..dim {
        let p = (c..dim)
            .max_by(|&i, &j| a[i * dim + c].abs().total_cmp(&a[j * dim + c].abs()))
            .unwrap_or(c);
        let pivot = a[p * dim + c];
        if pivot == 0.0 || !pivot.is_finite() {
            return Err("singular Newton matrix".into());
        }
        if p != c {
            for k in 0..dim {
                a.swap(p * dim + k, c * dim + k);
            }
            r.swap(p, c);
        }
        for i in c + 1..dim {
            let f = a[i * dim + c] / a[c * dim + c];
            for k in c..dim {
                a[i * dim + k] -= f * a[c * dim + k];
            }
            r[i] -= f * r[c];
        }
    }
    for c in (0..dim).rev() {
        let s: f64 = (c + 1..dim).map(|k| a[c * dim + k] * r[k]).sum();
        r[c] = (r[c] - s) / a[c * dim + c];
    }
    Ok(())
}

#[cfg(test)]
mod tests;
