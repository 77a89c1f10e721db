//! Time stepping with cubic story springs: `M x'' + C x' + K x + sum_s p_s k3_s d_s^3 =
//! f(t) - M iota a_g(t)`, with `d_s = p_s^T x` the drift across spring s and
//! `p_s = e_upper - e_lower` its load pattern.
//!
//! The linear part is stepped exactly as in [`super::discrete`]: the spring forces
//! `q_s = -k3_s d_s^3` are extra inputs (drives [`Drive::Pair`]). Over each step the
//! external input is the straight line between its samples (as for the linear
//! simulation, so `k3 = 0` reproduces it), and each spring force is the cubic Hermite
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

use super::discrete::{dot, polynomial_hold, Drive, OutputMap, StateSpace};
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
        let h = self.step_s;
        let row_major = |m: &DMatrix<f64>| -> Vec<f64> { m.transpose().as_slice().to_vec() };
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
        struct Cols {
            // z_{k+1} gains kq q_k + kp q'_k + uq q_{k+1} + up q'_{k+1}.
            kq: Vec<f64>,
            kp: Vec<f64>,
            uq: Vec<f64>,
            up: Vec<f64>,
        }
        let lin = |a: &[(f64, &DMatrix<f64>)], s: usize| -> Vec<f64> {
            let mut out = vec![0.0; ns];
            for (w, m) in a {
                for (o, v) in out.iter_mut().zip(col(m, s)) {
                    *o += w * v;
                }
            }
            out
        };
        let cols: Vec<Cols> = (0..self.springs.len())
            .map(|s| Cols {
                kq: lin(&[(1.0, g0), (-3.0, g2), (2.0, g3)], s),
                kp: lin(&[(h, g1), (-2.0 * h, g2), (h, g3)], s),
                uq: lin(&[(3.0, g2), (-2.0, g3)], s),
                up: lin(&[(-h, g2), (h, g3)], s),
            })
            .collect();
        // Drift and drift velocity read-outs of each spring.
        let drift = |s: &CubicSpring, z: &[f64]| -> (f64, f64) {
            let (lo_d, lo_v) = s.lower_dof.map_or((0.0, 0.0), |l| (z[l], z[n + l]));
            (z[s.upper_dof] - lo_d, z[n + s.upper_dof] - lo_v)
        };
        let m = self.springs.len();
        // B: sensitivity of (d_j, v_j) of the new state to (q_i, q'_i) at the step end.
        let mut b = vec![0.0; 4 * m * m];
        for (j, sj) in self.springs.iter().enumerate() {
            for (i, ci) in cols.iter().enumerate() {
                let (dq, vq) = drift(sj, &ci.uq);
                let (dp, vp) = drift(sj, &ci.up);
                let r = 2 * j;
                b[r * 2 * m + 2 * i] = dq;
                b[r * 2 * m + 2 * i + 1] = dp;
                b[(r + 1) * 2 * m + 2 * i] = vq;
                b[(r + 1) * 2 * m + 2 * i + 1] = vp;
            }
        }
        let oc = row_major(&outputs.c);
        let od = row_major(&outputs.d);
        let mut z = match z0 {
            Some(z0) if z0.len() == ns => z0.as_slice().to_vec(),
            Some(z0) => {
                return Err(Error::Usage(format!(
                    "initial state has {} entries, expected {ns}",
                    z0.len()
                )))
            }
            None => vec![0.0; ns],
        };
        // Force and its derivative of each spring at the current state.
        let force = |s: &CubicSpring, (d, v): (f64, f64)| -> (f64, f64) {
            (-s.k3_n_per_m3 * d * d * d, -3.0 * s.k3_n_per_m3 * d * d * v)
        };
        let mut qk: Vec<(f64, f64)> = self
            .springs
            .iter()
            .map(|s| force(s, drift(s, &z)))
            .collect();
        let mut z_star = vec![0.0; ns];
        let mut u = vec![0.0; ni];
        let mut y_out: Vec<Vec<f64>> = (0..no).map(|_| Vec::with_capacity(n_steps)).collect();
        let mut newton = Newton::new(2 * m);
        const CHUNK: usize = 1 << 14;
        let mut reported = 0;
        for k in 0..n_steps {
            for (j, uj) in u.iter_mut().take(ne).enumerate() {
                *uj = inputs[j][k];
            }
            for (s, q) in qk.iter().enumerate() {
                u[ne + s] = q.0;
            }
            for (r, yr) in y_out.iter_mut().enumerate() {
                yr.push(dot(&oc[r * ns..(r + 1) * ns], &z) + dot(&od[r * ni..(r + 1) * ni], &u));
            }
            if k + 1 == n_steps {
                break;
            }
            // Known part of the new state.
            for (i, zi) in z_star.iter_mut().enumerate() {
                let mut v = dot(&phi[i * ns..(i + 1) * ns], &z);
                for j in 0..ne {
                    v += gamma0[i * ne + j] * inputs[j][k] + gamma1[i * ne + j] * inputs[j][k + 1];
                }
                for (c, q) in cols.iter().zip(&qk) {
                    v += c.kq[i] * q.0 + c.kp[i] * q.1;
                }
                *zi = v;
            }
            let a: Vec<(f64, f64)> = self.springs.iter().map(|s| drift(s, &z_star)).collect();
            newton
                .solve(&self.springs, &a, &b, &qk, &force)
                .map_err(|what| {
                    Error::Numerical(format!(
                        "cubic spring step at t = {:.6} s: {what}",
                        (k + 1) as f64 * h
                    ))
                })?;
            for (s, c) in cols.iter().enumerate() {
                let (q, p) = newton.forces[s];
                for (zi, (cq, cp)) in z_star.iter_mut().zip(c.uq.iter().zip(&c.up)) {
                    *zi += cq * q + cp * p;
                }
            }
            std::mem::swap(&mut z, &mut z_star);
            qk.copy_from_slice(&newton.forces);
            for (s, &(d, _)) in self.springs.iter().zip(&newton.y) {
                if s.linear_stiffness_n_per_m + 3.0 * s.k3_n_per_m3 * d * d <= 0.0 {
                    return Err(Error::Numerical(format!(
                        "softening spring at DOF {} lost its stiffness (drift {d:.3e} m at t = {:.3} s); lower |k3| or the excitation",
                        s.upper_dof,
                        (k + 1) as f64 * h
                    )));
                }
            }
            if (k + 1) % CHUNK == 0 {
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
}

/// Newton's method for the spring unknowns `y = (d_1, v_1, ..., d_m, v_m)` of the new
/// state: `y = a + B g(y)` with `g = (q_1, q'_1, ...)` the spring forces of `y`.
struct Newton {
    /// Converged `(d, v)` per spring.
    y: Vec<(f64, f64)>,
    /// Converged `(q, q')` per spring.
    forces: Vec<(f64, f64)>,
    jac: Vec<f64>,
    res: Vec<f64>,
}

impl Newton {
    fn new(dim: usize) -> Self {
        Newton {
            y: vec![(0.0, 0.0); dim / 2],
            forces: vec![(0.0, 0.0); dim / 2],
            jac: vec![0.0; dim * dim],
            res: vec![0.0; dim],
        }
    }

    fn solve(
        &mut self,
        springs: &[CubicSpring],
        a: &[(f64, f64)],
        b: &[f64],
        q_prev: &[(f64, f64)],
        force: &dyn Fn(&CubicSpring, (f64, f64)) -> (f64, f64),
    ) -> std::result::Result<(), String> {
        let m = springs.len();
        let dim = 2 * m;
        // Predictor: the spring forces held at their last values.
        let flat = |v: &[(f64, f64)], i: usize| if i % 2 == 0 { v[i / 2].0 } else { v[i / 2].1 };
        for j in 0..dim {
            let bg: f64 = (0..dim).map(|i| b[j * dim + i] * flat(q_prev, i)).sum();
            let v = flat(a, j) + bg;
            if j % 2 == 0 {
                self.y[j / 2].0 = v;
            } else {
                self.y[j / 2].1 = v;
            }
        }
        for _ in 0..MAX_NEWTON {
            for (s, sp) in springs.iter().enumerate() {
                self.forces[s] = force(sp, self.y[s]);
            }
            // Residual r = y - a - B g and Jacobian I - B Dg.
            let mut scale = vec![0.0; dim];
            for j in 0..dim {
                let mut bg = 0.0;
                let mut bg_abs = 0.0;
                for i in 0..dim {
                    let t = b[j * dim + i] * flat(&self.forces, i);
                    bg += t;
                    bg_abs += t.abs();
                }
                let (yj, aj) = (flat(&self.y, j), flat(a, j));
                self.res[j] = yj - aj - bg;
                scale[j] = yj.abs() + aj.abs() + bg_abs;
            }
            for j in 0..dim {
                for i in 0..dim {
                    self.jac[j * dim + i] = f64::from(i == j);
                }
                for (s, sp) in springs.iter().enumerate() {
                    let (d, v) = self.y[s];
                    let k3 = sp.k3_n_per_m3;
                    // Dg: dq/dd = -3 k3 d^2, dq'/dd = -6 k3 d v, dq'/dv = -3 k3 d^2.
                    let (bq, bp) = (b[j * dim + 2 * s], b[j * dim + 2 * s + 1]);
                    self.jac[j * dim + 2 * s] -=
                        bq * (-3.0 * k3 * d * d) + bp * (-6.0 * k3 * d * v);
                    self.jac[j * dim + 2 * s + 1] -= bp * (-3.0 * k3 * d * d);
                }
            }
            solve_in_place(&mut self.jac, &mut self.res, dim)?;
            let mut done = true;
            for j in 0..dim {
                let step = self.res[j];
                done &= step.abs() <= NEWTON_RTOL * scale[j];
                if j % 2 == 0 {
                    self.y[j / 2].0 -= step;
                } else {
                    self.y[j / 2].1 -= step;
                }
            }
            if done {
                for (s, sp) in springs.iter().enumerate() {
                    self.forces[s] = force(sp, self.y[s]);
                }
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
        if !(a[p * dim + c].abs() > 0.0) {
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
