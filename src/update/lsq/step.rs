//! One trust-region reflective step (scipy's `select_step` and helpers): Coleman-Li
//! scaling, strict feasibility, the choice among the interior trust-region step, its
//! reflection and the scaled anti-gradient, and the radius and termination tests.

use super::linalg::{
    evaluate_quadratic, intersect_trust_region, minimize_quadratic_1d, norm, quadratic_1d,
    step_size_to_bound,
};
use super::trf::Termination;
use nalgebra::DMatrix;

/// n-sized scratch vectors.
#[derive(Debug, Clone)]
pub(super) struct Scratch {
    pub(super) v: Vec<f64>,
    pub(super) dv: Vec<f64>,
    pub(super) d: Vec<f64>,
    pub(super) diag_h: Vec<f64>,
    pub(super) g_h: Vec<f64>,
    pub(super) uf: Vec<f64>,
    pub(super) p: Vec<f64>,
    pub(super) p_h: Vec<f64>,
    pub(super) step: Vec<f64>,
    pub(super) step_h: Vec<f64>,
    pub(super) r: Vec<f64>,
    pub(super) r_h: Vec<f64>,
    pub(super) ag: Vec<f64>,
    pub(super) ag_h: Vec<f64>,
    pub(super) x_trial: Vec<f64>,
    pub(super) w1: Vec<f64>,
    pub(super) w2: Vec<f64>,
    pub(super) hits: Vec<i8>,
}

impl Scratch {
    pub(super) fn new(n: usize) -> Self {
        let z = || vec![0.0; n];
        Scratch {
            v: z(),
            dv: z(),
            d: z(),
            diag_h: z(),
            g_h: z(),
            uf: z(),
            p: z(),
            p_h: z(),
            step: z(),
            step_h: z(),
            r: z(),
            r_h: z(),
            ag: z(),
            ag_h: z(),
            x_trial: z(),
            w1: z(),
            w2: z(),
            hits: vec![0; n],
        }
    }
}

/// Coleman-Li scaling: `v_i` is the distance to the bound the negative gradient points
/// at (1 when that bound is infinite), `dv_i` its derivative (0, +1 or -1).
pub(super) fn cl_scaling(
    x: &[f64],
    g: &[f64],
    lower: &[f64],
    upper: &[f64],
    v: &mut [f64],
    dv: &mut [f64],
) {
    for i in 0..x.len() {
        v[i] = 1.0;
        dv[i] = 0.0;
        if g[i] < 0.0 && upper[i].is_finite() {
            v[i] = upper[i] - x[i];
            dv[i] = -1.0;
        }
        if g[i] > 0.0 && lower[i].is_finite() {
            v[i] = x[i] - lower[i];
            dv[i] = 1.0;
        }
    }
}

/// Moves entries on or beyond a bound inside: by `rstep * max(1, |bound|)`, or to the
/// next representable number when `rstep == 0`; to the midpoint when the box is too
/// tight for that.
pub(super) fn make_strictly_feasible(x: &mut [f64], lower: &[f64], upper: &[f64], rstep: f64) {
    for i in 0..x.len() {
        let (l, u) = (lower[i], upper[i]);
        if x[i] <= l {
            x[i] = if rstep == 0.0 {
                l.next_up()
            } else {
                l + rstep * l.abs().max(1.0)
            };
        } else if x[i] >= u {
            x[i] = if rstep == 0.0 {
                u.next_down()
            } else {
                u - rstep * u.abs().max(1.0)
            };
        }
        if !(x[i] > l && x[i] < u) && l.is_finite() && u.is_finite() {
            x[i] = 0.5 * (l + u);
        }
    }
}

/// Chooses among the trust-region step `p` (cut back strictly inside), its reflection
/// and the scaled anti-gradient step, by the quadratic model; writes the winner into
/// `s.step` / `s.step_h` and returns its predicted reduction.
pub(super) fn select_step(
    x: &[f64],
    lower: &[f64],
    upper: &[f64],
    r_h: &DMatrix<f64>,
    delta: f64,
    theta: f64,
    s: &mut Scratch,
) -> f64 {
    let n = x.len();
    let inside = (0..n).all(|i| {
        let v = x[i] + s.p[i];
        v >= lower[i] && v <= upper[i]
    });
    if inside {
        s.step.copy_from_slice(&s.p);
        s.step_h.copy_from_slice(&s.p_h);
        return -evaluate_quadratic(r_h, &s.g_h, &s.p_h, &s.diag_h, &mut s.w1);
    }
    let p_stride = step_size_to_bound(x, &s.p, lower, upper, &mut s.hits);
    // Reflected direction.
    for (i, &xi) in x.iter().enumerate() {
        s.r_h[i] = if s.hits[i] != 0 { -s.p_h[i] } else { s.p_h[i] };
        s.r[i] = s.d[i] * s.r_h[i];
        s.p[i] *= p_stride;
        s.p_h[i] *= p_stride;
        s.x_trial[i] = xi + s.p[i];
    }
    let (_, to_tr) = intersect_trust_region(&s.p_h, &s.r_h, delta);
    let to_bound = step_size_to_bound(&s.x_trial, &s.r, lower, upper, &mut s.hits);
    let r_stride = to_bound.min(to_tr);
    let (r_lo, r_hi) = if r_stride > 0.0 {
        let lo = (1.0 - theta) * p_stride / r_stride;
        let hi = if r_stride == to_bound {
            theta * to_bound
        } else {
            to_tr
        };
        (lo, hi)
    } else {
        (0.0, -1.0)
    };
    let r_value = if r_lo <= r_hi {
        let (a, b, c) = quadratic_1d(
            r_h,
            &s.g_h,
            &s.r_h,
            Some(&s.p_h),
            &s.diag_h,
            &mut s.w1,
            &mut s.w2,
        );
        let (t, val) = minimize_quadratic_1d(a, b, c, r_lo, r_hi);
        for i in 0..n {
            s.r_h[i] = s.p_h[i] + t * s.r_h[i];
            s.r[i] = s.d[i] * s.r_h[i];
        }
        val
    } else {
        f64::INFINITY
    };
    // The trust-region step cut back strictly inside.
    for i in 0..n {
        s.p[i] *= theta;
        s.p_h[i] *= theta;
    }
    let p_value = evaluate_quadratic(r_h, &s.g_h, &s.p_h, &s.diag_h, &mut s.w1);
    // Scaled anti-gradient.
    for i in 0..n {
        s.ag_h[i] = -s.g_h[i];
        s.ag[i] = s.d[i] * s.ag_h[i];
    }
    let to_tr = delta / norm(&s.ag_h);
    let to_bound = step_size_to_bound(x, &s.ag, lower, upper, &mut s.hits);
    let ag_max = if to_bound < to_tr {
        theta * to_bound
    } else {
        to_tr
    };
    let (a, b, _) = quadratic_1d(r_h, &s.g_h, &s.ag_h, None, &s.diag_h, &mut s.w1, &mut s.w2);
    let (t, ag_value) = minimize_quadratic_1d(a, b, 0.0, 0.0, ag_max);
    for i in 0..n {
        s.ag_h[i] *= t;
        s.ag[i] *= t;
    }
    if p_value < r_value && p_value < ag_value {
        s.step.copy_from_slice(&s.p);
        s.step_h.copy_from_slice(&s.p_h);
        -p_value
    } else if r_value < p_value && r_value < ag_value {
        s.step.copy_from_slice(&s.r);
        s.step_h.copy_from_slice(&s.r_h);
        -r_value
    } else {
        s.step.copy_from_slice(&s.ag);
        s.step_h.copy_from_slice(&s.ag_h);
        -ag_value
    }
}

/// Trust-region radius update from the agreement ratio; returns `(delta, ratio)`.
pub(super) fn update_radius(
    delta: f64,
    actual: f64,
    predicted: f64,
    step_norm: f64,
    bound_hit: bool,
) -> (f64, f64) {
    let ratio = if predicted > 0.0 {
        actual / predicted
    } else if predicted == actual && actual == 0.0 {
        1.0
    } else {
        0.0
    };
    let delta = if ratio < 0.25 {
        0.25 * step_norm
    } else if ratio > 0.75 && bound_hit {
        2.0 * delta
    } else {
        delta
    };
    (delta, ratio)
}

/// scipy's `check_termination`.
pub(super) fn check_termination(
    reduction: f64,
    cost: f64,
    step_norm: f64,
    x_norm: f64,
    ratio: f64,
    ftol: f64,
    xtol: f64,
) -> Option<Termination> {
    let f_ok = reduction < ftol * cost && ratio > 0.25;
    let x_ok = step_norm < xtol * (xtol + x_norm);
    match (f_ok, x_ok) {
        (true, true) => Some(Termination::FtolAndXtol),
        (true, false) => Some(Termination::Ftol),
        (false, true) => Some(Termination::Xtol),
        (false, false) => None,
    }
}
