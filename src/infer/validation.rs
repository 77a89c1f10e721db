//! Nested linear-Gaussian problems with known Bayes factors, for validating evidence
//! estimators where the diagnosis decides (issue 14, item 3).
//!
//! ## The model
//! `y = A theta + B e + noise`, `noise ~ N(0, sigma^2 I)` with `n` points. The base model
//! has `theta` (`n_b` coordinates, uniform box prior); the extension adds the effect `e`
//! (`k` coordinates) through a sampled coordinate `phi` with a uniform box prior:
//! `e = phi` ([`EffectScale::Linear`]) or `e = exp(phi)` ([`EffectScale::Log`], a
//! log-uniform prior, as the diagnosis samples `ln c`). The base model is the extension
//! at `e = 0`: at a corner of the box (`[0, hi]`), inside it, or at `phi -> -inf`.
//!
//! ## The reference evidence
//! With `G = A^T A`, `Q = I - A G^-1 A^T` and the box of `theta` holding its posterior
//! (checked: the conditional mean at least [`MIN_INSIDE_SD`] posterior sd from every
//! face, truncation below 1e-30),
//! `ln Z_base = -n/2 ln(2 pi sigma^2) - |Q y|^2 / (2 sigma^2) + n_b/2 ln 2 pi
//! - 1/2 ln det(G / sigma^2) - ln V_theta`
//! (the Gaussian integral; `V` a box volume). Integrating `theta` out at fixed `e` leaves
//! a Gaussian in `e` (`S = (QB)^T QB / sigma^2`, `e_hat = S^-1 (QB)^T Q y / sigma^2`),
//! so the Bayes factor is
//! `ln Z_ext - ln Z_base = g + ln (1/V_phi) int_box exp(-q(phi) / 2) d phi` with
//! `q(phi) = (e(phi) - e_hat)^T S (e(phi) - e_hat)` and `g = e_hat^T S e_hat / 2`,
//! the gain in maximum log-likelihood (over all `e`). The integral is analytic when the
//! box holds the Gaussian (every problem with `k > 2`), otherwise by composite
//! Gauss-Legendre quadrature on the window `e_hat +- 14 sd` cut to the box (`k <= 2`;
//! relative error below 1e-9, checked against the analytic value in the tests).
//! Since `Z(e) / Z(0) = exp(Delta ln L_max(e))` exactly here, `ln Z_ext - ln Z_base <= g`:
//! the bound [`super::nested::gain_bound`] rests on.
//!
//! ## The problems
//! Designs are correlated (every pair of columns at correlation ~0.9, scales over a
//! decade, as FE sensitivities are) and `sigma` makes the widest base posterior sd
//! [`BASE_SD`] of a box of width 2, about 7 nats of information per coordinate. The data
//! are made, not drawn, along `QB`: `y = A theta_0 + sigma (xi - P_QB xi) + QB e*`,
//! so that the best fit of the extension gains exactly the chosen `g` (a null
//! realisation whose noise happens to look like the effect; `e* = 0` gains nothing).

use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::evidence::TemperedTarget;
use crate::error::{Error, Result};

const LN_2PI: f64 = 1.837_877_066_409_345_5;
/// Widest posterior sd of a base coordinate (box width 2).
pub const BASE_SD: f64 = 2e-3;
/// The base box must hold the conditional posterior mean this many sd from every face.
pub const MIN_INSIDE_SD: f64 = 12.0;
/// Half-width, in posterior sd, of the quadrature window around `e_hat`.
const WINDOW_SD: f64 = 14.0;

/// How the sampled effect coordinate `phi` gives the effect `e`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectScale {
    /// `e = phi`.
    Linear,
    /// `e = exp(phi)` (log-uniform prior on `e`).
    Log,
}

impl EffectScale {
    fn effect(self, phi: f64) -> f64 {
        match self {
            EffectScale::Linear => phi,
            EffectScale::Log => phi.exp(),
        }
    }
}

/// A nested pair of linear-Gaussian models (module docs), serialisable for other tools.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct NestedProblem {
    pub name: String,
    /// Base design, `n x n_b`, rows.
    pub a: Vec<Vec<f64>>,
    /// Effect design, `n x k`, rows.
    pub b: Vec<Vec<f64>>,
    pub y: Vec<f64>,
    pub sigma: f64,
    pub base_bounds: Vec<(f64, f64)>,
    /// Box of the sampled effect coordinates `phi`.
    pub effect_bounds: Vec<(f64, f64)>,
    pub effect_scale: EffectScale,
    /// Reference `ln Z` of the base model.
    pub ln_z_base: f64,
    /// Reference `ln Z` of the extension.
    pub ln_z_extension: f64,
    /// Gain in maximum `ln L` of the extension over all `e` (`>= ln_z_extension -
    /// ln_z_base`).
    pub gain: f64,
}

/// The parts of the reference computation.
struct Reduced {
    ln_z_base: f64,
    /// `S` and `e_hat`.
    s: DMatrix<f64>,
    e_hat: DVector<f64>,
}

impl NestedProblem {
    /// Base design matrix.
    pub fn a_matrix(&self) -> DMatrix<f64> {
        rows_to_matrix(&self.a)
    }
    /// Effect design matrix.
    pub fn b_matrix(&self) -> DMatrix<f64> {
        rows_to_matrix(&self.b)
    }
    /// Reference `ln Z_ext - ln Z_base`.
    pub fn ln_bayes_factor(&self) -> f64 {
        self.ln_z_extension - self.ln_z_base
    }
    /// The base model as a target (`z = theta`).
    pub fn base(&self) -> NestedModel<'_> {
        NestedModel::new(self, false)
    }
    /// The extension as a target (`z = [theta, phi]`).
    pub fn extension(&self) -> NestedModel<'_> {
        NestedModel::new(self, true)
    }

    /// A start near the best fit, in the model's coordinates: the least-squares effect
    /// clamped to its box (`phi`), then the least-squares `theta` given it. (The MAP of a
    /// real study comes from its fit; this stands in for it.)
    pub fn best_fit(&self, extended: bool) -> Result<Vec<f64>> {
        let r = self.reduce()?;
        let (a, b) = (self.a_matrix(), self.b_matrix());
        let phi: Vec<f64> = (0..r.e_hat.len())
            .map(|i| {
                let (lo, hi) = self.effect_bounds[i];
                let (l, h) = (self.effect_scale.effect(lo), self.effect_scale.effect(hi));
                let e = r.e_hat[i].clamp(l, h);
                match self.effect_scale {
                    EffectScale::Linear => e,
                    EffectScale::Log => e.ln(),
                }
            })
            .collect();
        let mut y = DVector::from_column_slice(&self.y);
        if extended {
            let e = phi.iter().map(|p| self.effect_scale.effect(*p));
            y -= &b * DVector::from_iterator(phi.len(), e);
        }
        let g = a.transpose() * &a;
        let theta = g
            .cholesky()
            .ok_or_else(|| Error::Numerical("validation: A^T A is singular".into()))?
            .solve(&(a.transpose() * y));
        let mut z: Vec<f64> = theta.iter().copied().collect();
        if extended {
            z.extend(phi);
        }
        Ok(z)
    }

    /// A problem from its designs and data, with the reference values computed.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: &str,
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        y: &DVector<f64>,
        sigma: f64,
        base_bounds: Vec<(f64, f64)>,
        effect_bounds: Vec<(f64, f64)>,
        effect_scale: EffectScale,
    ) -> Result<Self> {
        let mut p = NestedProblem {
            name: name.to_string(),
            a: matrix_to_rows(a),
            b: matrix_to_rows(b),
            y: y.iter().copied().collect(),
            sigma,
            base_bounds,
            effect_bounds,
            effect_scale,
            ln_z_base: f64::NAN,
            ln_z_extension: f64::NAN,
            gain: f64::NAN,
        };
        let r = p.reduce()?;
        p.gain = 0.5 * r.e_hat.dot(&(&r.s * &r.e_hat));
        p.ln_z_base = r.ln_z_base;
        p.ln_z_extension = r.ln_z_base + p.gain + p.ln_window_integral(&r)?;
        Ok(p)
    }

    /// `ln Z_base`, `S` and `e_hat` (module docs), with the base box checked.
    fn reduce(&self) -> Result<Reduced> {
        let (a, b) = (self.a_matrix(), self.b_matrix());
        let y = DVector::from_column_slice(&self.y);
        let (n, nb) = (a.nrows(), a.ncols());
        let s2 = self.sigma * self.sigma;
        let g = a.transpose() * &a;
        let chol = nalgebra::Cholesky::new(g.clone())
            .ok_or_else(|| Error::Numerical("validation: A^T A is singular".into()))?;
        let project = |v: &DMatrix<f64>| v - &a * chol.solve(&(a.transpose() * v));
        let qy = project(&DMatrix::from_column_slice(n, 1, y.as_slice()));
        let qb = project(&b);
        let s = qb.transpose() * &qb / s2;
        let s_chol = nalgebra::Cholesky::new(s.clone())
            .ok_or_else(|| Error::Numerical("validation: (QB)^T QB is singular".into()))?;
        let e_hat = s_chol
            .solve(&(qb.transpose() * &qy / s2))
            .column(0)
            .into_owned();
        // Conditional posterior of theta at e = e_hat clamped to the box: inside it?
        let e_c: Vec<f64> = (0..e_hat.len())
            .map(|i| {
                let (lo, hi) = self.effect_bounds[i];
                let (lo, hi) = (self.effect_scale.effect(lo), self.effect_scale.effect(hi));
                e_hat[i].clamp(lo, hi)
            })
            .collect();
        let r = &y - &b * DVector::from_vec(e_c);
        let theta = chol.solve(&(a.transpose() * &r));
        let g_inv = chol.inverse();
        for i in 0..nb {
            let sd = (s2 * g_inv[(i, i)]).sqrt();
            let (lo, hi) = self.base_bounds[i];
            if theta[i] - lo < MIN_INSIDE_SD * sd || hi - theta[i] < MIN_INSIDE_SD * sd {
                return Err(Error::Usage(format!(
                    "validation `{}`: base coordinate {i} at {:.4} +- {sd:.2e} is within \
                     {MIN_INSIDE_SD} sd of its box [{lo}, {hi}]",
                    self.name, theta[i]
                )));
            }
        }
        let ln_det = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
        let ln_v: f64 = self.base_bounds.iter().map(|(l, u)| (u - l).ln()).sum();
        let ln_z_base = -0.5 * n as f64 * (LN_2PI + s2.ln()) - qy.norm_squared() / (2.0 * s2)
            + 0.5 * nb as f64 * LN_2PI
            - 0.5 * (ln_det - nb as f64 * s2.ln())
            - ln_v;
        Ok(Reduced {
            ln_z_base,
            s,
            e_hat,
        })
    }

    /// `ln (1/V_phi) int_box exp(-(e - e_hat)^T S (e - e_hat) / 2) d phi`.
    fn ln_window_integral(&self, r: &Reduced) -> Result<f64> {
        let k = r.e_hat.len();
        let s_inv =
            r.s.clone()
                .try_inverse()
                .ok_or_else(|| Error::Numerical("validation: S is singular".into()))?;
        let ln_v: f64 = self.effect_bounds.iter().map(|(l, u)| (u - l).ln()).sum();
        let mut windows = Vec::with_capacity(k);
        let mut inside = true;
        for i in 0..k {
            let sd = s_inv[(i, i)].sqrt();
            let (lo, hi) = self.effect_bounds[i];
            let (e_lo, e_hi) = (r.e_hat[i] - WINDOW_SD * sd, r.e_hat[i] + WINDOW_SD * sd);
            let w = match self.effect_scale {
                EffectScale::Linear => (e_lo.max(lo), e_hi.min(hi)),
                EffectScale::Log => {
                    let l = if e_lo <= lo.exp() { lo } else { e_lo.ln() };
                    (l, if e_hi <= 0.0 { lo } else { e_hi.ln().min(hi) })
                }
            };
            inside &= self.effect_scale == EffectScale::Linear && e_lo > lo && e_hi < hi;
            if w.1 <= w.0 {
                return Err(Error::Usage(format!(
                    "validation `{}`: effect {i} has no prior mass near its best fit",
                    self.name
                )));
            }
            windows.push(w);
        }
        if inside {
            let ln_det_s = r.s.clone().cholesky().map_or(f64::NAN, |c| {
                2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>()
            });
            return Ok(0.5 * k as f64 * LN_2PI - 0.5 * ln_det_s - ln_v);
        }
        if k > 2 {
            return Err(Error::Usage(format!(
                "validation `{}`: {k} effects reaching the box need quadrature in {k} \
                 dimensions (at most 2 here)",
                self.name
            )));
        }
        let panels = if k == 1 { 4000 } else { 200 };
        let scale = self.effect_scale;
        let f = |phi: &[f64]| {
            let d = DVector::from_iterator(
                k,
                phi.iter()
                    .zip(r.e_hat.iter())
                    .map(|(p, e)| scale.effect(*p) - e),
            );
            -0.5 * d.dot(&(&r.s * &d))
        };
        Ok(ln_gauss_legendre(&windows, panels, f) - ln_v)
    }
}

fn rows_to_matrix(rows: &[Vec<f64>]) -> DMatrix<f64> {
    let ncols = rows.first().map_or(0, Vec::len);
    DMatrix::from_fn(rows.len(), ncols, |i, j| rows[i][j])
}

fn matrix_to_rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

/// Nodes and weights of the 8-point Gauss-Legendre rule on `[-1, 1]` (Abramowitz &
/// Stegun 25.4.30).
const GL8: [(f64, f64); 4] = [
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
];

/// `ln int_window exp(f)` over a box of 1 or 2 dimensions by composite 8-point
/// Gauss-Legendre with `panels` panels per dimension (log-sum-exp of the terms).
fn ln_gauss_legendre(window: &[(f64, f64)], panels: usize, f: impl Fn(&[f64]) -> f64) -> f64 {
    let nodes_1d = |(lo, hi): (f64, f64)| -> Vec<(f64, f64)> {
        let h = (hi - lo) / panels as f64;
        let mut out = Vec::with_capacity(8 * panels);
        for p in 0..panels {
            let c = lo + (p as f64 + 0.5) * h;
            for &(x, w) in &GL8 {
                out.push((c - 0.5 * h * x, 0.5 * h * w));
                out.push((c + 0.5 * h * x, 0.5 * h * w));
            }
        }
        out
    };
    let axes: Vec<Vec<(f64, f64)>> = window.iter().map(|w| nodes_1d(*w)).collect();
    let mut terms = Vec::new();
    match axes.as_slice() {
        [x] => terms.extend(x.iter().map(|&(p, w)| f(&[p]) + w.ln())),
        [x, y] => {
            for &(p, wp) in x {
                for &(q, wq) in y {
                    terms.push(f(&[p, q]) + (wp * wq).ln());
                }
            }
        }
        _ => return f64::NAN,
    }
    super::tempering::log_sum_exp(&terms)
}

/// One model of a [`NestedProblem`] as a [`TemperedTarget`].
#[derive(Debug, Clone)]
pub struct NestedModel<'a> {
    problem: &'a NestedProblem,
    extended: bool,
    /// `[A B]` (or `A`).
    design: DMatrix<f64>,
    y: DVector<f64>,
    bounds: Vec<(f64, f64)>,
    ln_volume: f64,
}

impl<'a> NestedModel<'a> {
    fn new(problem: &'a NestedProblem, extended: bool) -> Self {
        let mut bounds = problem.base_bounds.clone();
        let design = if extended {
            bounds.extend(&problem.effect_bounds);
            let (a, b) = (problem.a_matrix(), problem.b_matrix());
            let mut d = a.clone().resize_horizontally(a.ncols() + b.ncols(), 0.0);
            d.columns_mut(a.ncols(), b.ncols()).copy_from(&b);
            d
        } else {
            problem.a_matrix()
        };
        NestedModel {
            problem,
            extended,
            design,
            y: DVector::from_column_slice(&problem.y),
            ln_volume: bounds.iter().map(|(l, u)| (u - l).ln()).sum(),
            bounds,
        }
    }

    /// The prior box of `z`.
    pub fn bounds(&self) -> &[(f64, f64)] {
        &self.bounds
    }

    /// Number of base coordinates (the effect coordinates follow them).
    pub fn n_base(&self) -> usize {
        self.problem.base_bounds.len()
    }

    /// [`NestedProblem::best_fit`] of this model.
    pub fn best_fit(&self) -> Result<Vec<f64>> {
        self.problem.best_fit(self.extended)
    }

    /// Reference `ln Z` of this model.
    pub fn reference_ln_z(&self) -> f64 {
        if self.extended {
            self.problem.ln_z_extension
        } else {
            self.problem.ln_z_base
        }
    }
}

impl TemperedTarget for NestedModel<'_> {
    fn dim(&self) -> usize {
        self.bounds.len()
    }
    fn ln_prior(&self, z: &[f64]) -> f64 {
        let inside = z
            .iter()
            .zip(&self.bounds)
            .all(|(v, (l, u))| v >= l && v <= u);
        if inside {
            -self.ln_volume
        } else {
            f64::NEG_INFINITY
        }
    }
    fn ln_likelihood(&self, z: &[f64]) -> Result<f64> {
        let nb = self.problem.base_bounds.len();
        let coef = DVector::from_iterator(
            z.len(),
            z.iter().enumerate().map(|(i, &v)| {
                if i < nb {
                    v
                } else {
                    self.problem.effect_scale.effect(v)
                }
            }),
        );
        let r = &self.y - &self.design * coef;
        let s2 = self.problem.sigma * self.problem.sigma;
        Ok(-0.5 * r.norm_squared() / s2 - 0.5 * self.y.len() as f64 * (LN_2PI + s2.ln()))
    }
    fn sample_prior(&self, rng: &mut rand_chacha::ChaCha8Rng) -> Result<Vec<f64>> {
        Ok(self
            .bounds
            .iter()
            .map(|&(l, u)| l + (u - l) * rng.random::<f64>())
            .collect())
    }
}

/// Correlated design: column `j` is `scale_j (g_j + 3 h)` with a shared `h`, scales over
/// a decade.
fn design(rng: &mut ChaCha8Rng, n: usize, cols: usize, shared: &DVector<f64>) -> DMatrix<f64> {
    let g = DMatrix::from_fn(n, cols, |_, _| rng.sample::<f64, _>(StandardNormal));
    DMatrix::from_fn(n, cols, |i, j| {
        let scale = 10f64.powf(j as f64 / (cols.max(2) - 1) as f64);
        scale * (g[(i, j)] + 3.0 * shared[i])
    })
}

/// How a validation problem is made (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct ProblemSpec {
    pub name: &'static str,
    pub n: usize,
    pub n_base: usize,
    pub n_effect: usize,
    pub effect_bounds: (f64, f64),
    pub effect_scale: EffectScale,
    /// Posterior sd of the effect (widest; `B` is scaled to it).
    pub effect_sd: f64,
    /// Gain in maximum `ln L` the data are made to show, along `e* = t (1, .., 1)`.
    pub gain: f64,
}

impl ProblemSpec {
    /// The four validation problems: a null near threshold (2 effects at a corner of
    /// `[0, 1]^2`, best fit gains a few nats), the same at the threshold
    /// (`ln B ~ ln 150`), a log-uniform null (1 effect, `e = exp(phi)`, the diagnosis'
    /// plateau), and a decisive 4-effect extension inside its box.
    pub fn all() -> Vec<ProblemSpec> {
        let base = ProblemSpec {
            name: "",
            n: 200,
            n_base: 12,
            n_effect: 2,
            effect_bounds: (0.0, 1.0),
            effect_scale: EffectScale::Linear,
            effect_sd: 5e-3,
            gain: 0.0,
        };
        vec![
            ProblemSpec {
                name: "null_corner",
                gain: 4.0,
                ..base.clone()
            },
            ProblemSpec {
                name: "threshold_corner",
                gain: 16.5,
                ..base.clone()
            },
            ProblemSpec {
                name: "null_log_uniform",
                n_base: 13,
                n_effect: 1,
                effect_bounds: ((1e-6f64).ln(), 0.0),
                effect_scale: EffectScale::Log,
                gain: 3.0,
                ..base.clone()
            },
            ProblemSpec {
                name: "decisive_interior",
                n_base: 15,
                n_effect: 4,
                effect_bounds: (-1.0, 1.0),
                gain: 300.0,
                ..base
            },
        ]
    }

    /// The problem made with `seed` (module docs).
    pub fn build(&self, seed: u64) -> Result<NestedProblem> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let shared = DVector::from_fn(self.n, |_, _| rng.sample::<f64, _>(StandardNormal));
        let a = design(&mut rng, self.n, self.n_base, &shared);
        let mut b = design(&mut rng, self.n, self.n_effect, &shared);
        let chol = nalgebra::Cholesky::new(a.transpose() * &a)
            .ok_or_else(|| Error::Numerical("validation: singular design".into()))?;
        let g_inv = chol.inverse();
        let widest = (0..self.n_base).map(|i| g_inv[(i, i)]).fold(0.0, f64::max);
        let sigma = BASE_SD / widest.sqrt();
        let project = |v: &DMatrix<f64>| v - &a * chol.solve(&(a.transpose() * v));
        // Scale B so that the widest effect sd is `effect_sd`.
        let s_inv = ((project(&b).transpose() * project(&b)) / (sigma * sigma))
            .try_inverse()
            .ok_or_else(|| Error::Numerical("validation: singular effect design".into()))?;
        let widest_e = (0..self.n_effect)
            .map(|i| s_inv[(i, i)])
            .fold(0.0, f64::max);
        b *= widest_e.sqrt() / self.effect_sd;
        let qb = project(&b);
        let theta0 = DVector::from_fn(self.n_base, |_, _| rng.random_range(-0.3..0.3));
        let xi = DMatrix::from_fn(self.n, 1, |_, _| {
            sigma * rng.sample::<f64, _>(StandardNormal)
        });
        let qb_chol = nalgebra::Cholesky::new(qb.transpose() * &qb)
            .ok_or_else(|| Error::Numerical("validation: singular QB".into()))?;
        let xi_off = &xi - &qb * qb_chol.solve(&(qb.transpose() * &xi));
        let ones = DVector::from_element(self.n_effect, 1.0);
        let s_ones = (qb.transpose() * &qb / (sigma * sigma)) * &ones;
        let e_star = ones * (2.0 * self.gain / s_ones.sum()).sqrt();
        let y = &a * theta0 + xi_off.column(0) + &qb * e_star;
        NestedProblem::new(
            &format!("{}_{seed}", self.name),
            &a,
            &b,
            &y,
            sigma,
            vec![(-1.0, 1.0); self.n_base],
            vec![self.effect_bounds; self.n_effect],
            self.effect_scale,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quadrature against the analytic Gaussian integral (a window well inside a
    /// box, 1 and 2 dimensions, correlated): relative error below 1e-9.
    #[test]
    fn quadrature_matches_the_gaussian_integral() {
        let s: DMatrix<f64> = DMatrix::from_row_slice(2, 2, &[4e4, -3e4, -3e4, 9e4]);
        let e_hat = [0.3, 0.4];
        let sd: Vec<f64> = {
            let inv = s.clone().try_inverse().unwrap();
            vec![inv[(0, 0)].sqrt(), inv[(1, 1)].sqrt()]
        };
        let window: Vec<(f64, f64)> = (0..2)
            .map(|i| (e_hat[i] - WINDOW_SD * sd[i], e_hat[i] + WINDOW_SD * sd[i]))
            .collect();
        let f = |e: &[f64]| {
            let d = DVector::from_iterator(2, e.iter().zip(e_hat).map(|(a, b)| a - b));
            -0.5 * d.dot(&(&s * &d))
        };
        let exact = LN_2PI - 0.5 * s.determinant().ln();
        let quad = ln_gauss_legendre(&window, 200, f);
        assert!((quad - exact).abs() < 1e-9, "{quad} vs {exact}");
        let f1 = |e: &[f64]| -0.5 * 4e4 * (e[0] - 0.3).powi(2);
        let exact1 = 0.5 * LN_2PI - 0.5 * 4e4f64.ln();
        let quad1 = ln_gauss_legendre(&window[..1], 4000, f1);
        assert!((quad1 - exact1).abs() < 1e-9, "{quad1} vs {exact1}");
    }

    /// The reference ln Z of both models against brute-force importance sampling would be
    /// slow; instead: the made problems show the gain they were made with, obey the
    /// bound `ln B <= gain`, and `ln L` at the best fit is `max ln L_base + gain`.
    #[test]
    fn problems_are_as_specified() {
        for spec in ProblemSpec::all() {
            let p = spec.build(1).unwrap();
            let lnb = p.ln_bayes_factor();
            assert!(
                lnb <= p.gain + 1e-9,
                "{}: ln B {lnb} > gain {}",
                p.name,
                p.gain
            );
            assert!(p.ln_z_base.is_finite() && lnb.is_finite());
            eprintln!("{}: gain {:.3}, ln B {:.3}", p.name, p.gain, lnb);
        }
    }
}
