//! Where the walkers start: the maximum-likelihood point of the posterior's own model
//! (multistart trust-region least squares, [`crate::update::lsq`], on the standardised
//! residuals `(y_k - |H^A_k|) / sigma_k`, windows included; on general models whose data
//! have shared force noise or correlated bins, then polished on the likelihood that is
//! sampled, [`plug_in_start`]), plus a ball of about the Gauss-Newton posterior width,
//! truncated to the prior box.

use super::data::LoadingMagnitude;
use super::posterior::FrfPosterior;
use crate::error::{Error, Result};
use crate::mcmc::LogDensity;
use crate::predict::choice::ModelModesWorkspace;
use crate::predict::{FrfWorkspace, Predict};
use crate::update::lsq::{
    fd_jacobian, multistart, Bounds, FdScheme, LeastSquaresProblem, MultistartOptions,
    MultistartResult,
};
use crate::update::ResidualForm;
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::Serialize;

/// The optimum the sampler starts from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StartPoint {
    /// Sampled vector at the optimum; the noise scale is its maximum-likelihood value
    /// `sqrt(sum r_k^2 / N)` given the structural optimum (clamped to its prior box).
    pub z: Vec<f64>,
    /// `0.5 sum r_k^2` at the optimum (standardised residuals, noise scale 1).
    pub cost: f64,
    /// Local solves run and how many reached the best cost.
    pub n_starts: usize,
    pub n_at_best: usize,
    /// Gauss-Newton standard deviation of each sampled coordinate at the optimum
    /// (infinite, written as `null`, along an exact ridge such as the mass-stiffness
    /// scale of shake-table data).
    pub sd: Vec<f64>,
    /// Principal axes of the Gauss-Newton covariance in range-scaled coordinates
    /// (`z_j / range_j`, range of the prior box), unit vectors ...
    #[serde(skip)]
    pub axes: Vec<Vec<f64>>,
    /// ... and the standard deviation along each (range-scaled; may be infinite).
    #[serde(skip)]
    pub axis_sd: Vec<f64>,
    /// Residual evaluations of all local solves (finite-difference Jacobians included).
    pub n_evaluations: usize,
    /// The noise scale was moved to the full likelihood's optimum ([`refine_noise_scale`]).
    pub noise_scale_refined: bool,
}

/// Least gain of log-likelihood (nats) for which [`refine_noise_scale`] moves the start.
pub const NOISE_START_GAIN: f64 = 20.0;

/// With noise shared by a test's points, `sqrt(sum r_k^2 / N)` from the per-point
/// residuals is not the likelihood's optimum in `s`: the shared term explains part of
/// the residual. This maximises the full log-likelihood over `ln s` at the structural
/// optimum (golden section on the prior box, 60 steps) and moves `z`'s last coordinate
/// there when that gains more than [`NOISE_START_GAIN`] nats (many posterior sd: the
/// sd of `ln s` is about `1/sqrt(2N)`). Returns whether it moved. Why: on the six-DOF
/// campaign (`experiments/models/six-dof-hammer.toml`) the per-point start was s = 2.55
/// against a posterior of 1.12 +- 0.02, and the walkers' drift from it made the
/// autocorrelation-time rule run 10,800 steps (tau of s 214 steps, others 11-51); from
/// the refined start, 2,700 steps (every tau 10-12). [`find_start`] applies it to
/// models without nominal values only (general manifests): the shear-frame runs keep
/// their start, and so their draws, bit for bit (the four-story hammer start would move
/// from s = 1.67 to 0.82; those runs converge in 1,400 steps as they are).
pub fn refine_noise_scale(post: &FrfPosterior, z: &mut [f64]) -> Result<bool> {
    let (best, gain) = noise_scale_optimum(post, z)?;
    let moved = gain > NOISE_START_GAIN;
    if moved {
        z[z.len() - 1] = best;
    }
    Ok(moved)
}

/// The full log-likelihood's maximum over `ln s` at `z`'s structural coordinates
/// (golden section on the prior box, 60 steps) and what it gains over `z`'s own `ln s`.
fn noise_scale_optimum(post: &FrfPosterior, z: &[f64]) -> Result<(f64, f64)> {
    let j = z.len() - 1;
    let (lo, hi) = (post.prior().lower()[j], post.prior().upper()[j]);
    let mut y = z.to_vec();
    let mut ll = |t: f64| -> Result<f64> {
        y[j] = t;
        post.ln_likelihood(&y, &mut [])
    };
    let before = ll(z[j])?;
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (lo, hi);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (ll(c)?, ll(d)?);
    for _ in 0..60 {
        if fc > fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = ll(c)?;
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = ll(d)?;
        }
    }
    let (best, f_best) = if fc > fd { (c, fc) } else { (d, fd) };
    Ok((best, f_best - before))
}

/// Standardised residuals of a posterior, noise scale 1, in the free structural
/// coordinates; central finite-difference Jacobian ([`fd_jacobian`]) inside the prior box.
struct Residuals<'a> {
    post: &'a FrfPosterior,
    bounds: &'a Bounds,
}

struct Scratch {
    ws: FrfWorkspace<ModelModesWorkspace>,
}

impl LeastSquaresProblem for Residuals<'_> {
    type Workspace = Scratch;

    fn n_params(&self) -> usize {
        self.post.n_free()
    }
    fn n_residuals(&self) -> usize {
        self.post.data().len()
    }
    fn workspace(&self) -> Scratch {
        Scratch {
            ws: self.post.predictor().workspace(),
        }
    }
    fn residuals(&self, x: &[f64], ws: &mut Scratch, r: &mut [f64]) -> Result<()> {
        self.post.predictor().predict(x, &mut ws.ws, r)?;
        let data = self.post.data();
        let log = data.residual == ResidualForm::LogMagnitude;
        for ((v, y), s) in r.iter_mut().zip(&data.magnitude).zip(&data.sigma) {
            *v = if log {
                (v.ln() - y.ln()) / s
            } else {
                (*v - y) / s
            };
        }
        Ok(())
    }
    fn jacobian(&self, x: &[f64], ws: &mut Scratch, jac: &mut DMatrix<f64>) -> Result<()> {
        let residuals = |x: &[f64], r: &mut [f64]| self.residuals(x, ws, r);
        fd_jacobian(FdScheme::Central, x, self.bounds, residuals, jac).map(|_| ())
    }
}

/// Multistart maximum likelihood (noise scale 1 in the residuals, then its optimum):
/// the first start at the variables' start values, the others from a Latin hypercube
/// over the box ([`multistart`]); deterministic for `options.seed`.
pub fn find_start(post: &FrfPosterior, options: &MultistartOptions) -> Result<StartPoint> {
    let ms = structural_optimum(post, options)?;
    start_at(post, &ms, None)
}

/// [`find_start`], and the posterior whose shared force-noise loadings are scaled by the
/// model's magnitudes at the start (`magnitude` [`LoadingMagnitude::Model`]; `post`
/// itself for [`LoadingMagnitude::Measured`] or without magnitude-scaled loadings).
///
/// Two-stage plug-in: the structural optimum is the weighted least-squares point of the
/// per-point residuals `(y_k - |H^A_k|) / sigma_k`, which does not involve the loadings;
/// the loadings `|H_k| a_k` then take `|H_k| = |H^A_k(theta_ML)|`
/// ([`super::FrfData::with_loading_magnitudes`]), a function of all `n` points, each with
/// weight `O(1/n)`, so no longer correlated with point `k`'s own residual as the
/// measured `|H^E_k|` is. The noise scale of the start is then found on the new
/// posterior. Exact would be `|H^A_k(theta)|` at every evaluation (a new Woodbury
/// factor per evaluation: a cost on the hot path); the plug-in differs from it by the
/// posterior spread of `|H^A_k|`, a fraction of a percent, in a term that is itself a
/// correction. Deterministic for `options.seed`.
pub fn plug_in_start(
    post: FrfPosterior,
    magnitude: LoadingMagnitude,
    options: &MultistartOptions,
) -> Result<(FrfPosterior, StartPoint)> {
    let (post, ms) = anchored_optimum(post, options)?;
    let scaled = post
        .data()
        .correlated
        .iter()
        .any(|c| !c.magnitude.is_empty());
    let post = if magnitude == LoadingMagnitude::Model && scaled {
        let mut z = ms.best.x.clone();
        z.push(0.0);
        let h = post.magnitudes(&z)?;
        let plugged = post.with_data(post.data().with_loading_magnitudes(&h)?)?;
        if plugged.prior() != post.prior() || plugged.names() != post.names() {
            return Err(Error::Numerical(
                "plug-in loadings: the rebuilt posterior has other variables or bounds".into(),
            ));
        }
        plugged
    } else {
        post
    };
    if !samples_another_likelihood(&post) {
        let start = start_at(&post, &ms, None)?;
        return Ok((post, start));
    }
    let (post, ms, ln_s) = sampled_optimum(post, ms, options)?;
    let start = start_at(&post, &ms, Some(ln_s))?;
    Ok((post, start))
}

/// Whether the likelihood that is sampled is not the per-point one the multistart fits
/// (noise shared by a test's points, or bins correlated along a chain) on a general
/// model (no nominal values). The shear frames keep their per-point start, and so
/// their draws, bit for bit, as with [`refine_noise_scale`].
fn samples_another_likelihood(post: &FrfPosterior) -> bool {
    let data = post.data();
    let correlated = !data.correlated.is_empty() || data.bin_correlation.iter().any(|r| *r != 0.0);
    is_general(post) && correlated
}

/// Whether the model is a general one: no updating variable has a nominal value.
fn is_general(post: &FrfPosterior) -> bool {
    let model = post.model();
    (model.alpha_parameters().iter())
        .chain(model.beta_parameters())
        .all(|p| p.nominal.is_none())
}

/// Rounds of [`sampled_optimum`].
const SAMPLED_ROUNDS: usize = 3;

/// The maximum of the likelihood that is sampled, from the per-point optimum `ms`:
/// [`SAMPLED_ROUNDS`] times the noise scale's optimum ([`noise_scale_optimum`]), then a
/// local trust-region solve of the layer's least squares at that scale (shared noise
/// and correlated bins whitened: [`crate::infer::Posterior::least_squares`]); on a
/// reduced basis, anchored again at each new point over `+- BASIS_SPREAD_SD`
/// Gauss-Newton sd. Returns the posterior, the record with the new best, and `ln s`.
/// Why: on the bridge's FRF campaign the per-point start sat 106 nats below the
/// sampled likelihood's value at the truth, and the four ensembles drifted from it
/// together along the flat deck directions, where R-hat cannot see a shared drift.
fn sampled_optimum(
    mut post: FrfPosterior,
    mut ms: MultistartResult,
    options: &MultistartOptions,
) -> Result<(FrfPosterior, MultistartResult, f64)> {
    let polish = MultistartOptions {
        n_starts: 1,
        ..options.clone()
    };
    let n_free = post.n_free();
    let mut z = ms.best.x.clone();
    z.push(0.0);
    for round in 0..SAMPLED_ROUNDS {
        z[n_free] = noise_scale_optimum(&post, &z)?.0;
        let ls = post.layer().least_squares(&[z[n_free].exp()])?;
        ms.best = multistart(&ls, ls.bounds(), Some(&z[..n_free]), &polish)?.best;
        z[..n_free].copy_from_slice(&ms.best.x);
        if post.has_reduced_basis() && round + 1 < SAMPLED_ROUNDS {
            let sd = start_at(&post, &ms, Some(z[n_free]))?.sd;
            let spread = basis_spread(&post, &sd)?;
            post = post.with_basis_anchored_at(&z[..n_free], Some(&spread))?;
        }
    }
    let ln_s = noise_scale_optimum(&post, &z)?.0;
    Ok((post, ms, ln_s))
}

/// How far a reduced basis anchored at the optimum extends along each structural
/// coordinate: `BASIS_SPREAD_SD` Gauss-Newton sd, the whole box where `sd` is infinite.
fn basis_spread(post: &FrfPosterior, sd: &[f64]) -> Result<Vec<f64>> {
    let bounds = structural_bounds(post)?;
    Ok((0..post.n_free())
        .map(|j| match sd[j].is_finite() {
            true => BASIS_SPREAD_SD * sd[j],
            false => bounds.upper()[j] - bounds.lower()[j],
        })
        .collect())
}

/// The multistart weighted least-squares optimum of the structural coordinates
/// (standardised per-point residuals, noise scale 1; the shared noise is not involved).
/// The prior box of the free updating variables (the noise scale left out).
fn structural_bounds(post: &FrfPosterior) -> Result<Bounds> {
    let (n_free, prior) = (post.n_free(), post.prior());
    Bounds::new(
        prior.lower()[..n_free].to_vec(),
        prior.upper()[..n_free].to_vec(),
    )
}

fn structural_optimum(
    post: &FrfPosterior,
    options: &MultistartOptions,
) -> Result<MultistartResult> {
    let vars = post.variables();
    let z0 = vars.to_internal(&vars.initial());
    let bounds = structural_bounds(post)?;
    let problem = Residuals {
        post,
        bounds: &bounds,
    };
    multistart(&problem, &bounds, Some(&z0), options)
}

/// Gauss-Newton standard deviations by which the reduced basis's region around the
/// maximum-likelihood point extends ([`anchored_optimum`]).
const BASIS_SPREAD_SD: f64 = 4.0;

/// [`structural_optimum`]; on a reduced basis, then twice: the basis anchored at the
/// optimum ([`FrfPosterior::with_basis_anchored_at`]: exact there; the first time over
/// the box, then over `+- BASIS_SPREAD_SD` Gauss-Newton sd around it) and the optimum
/// polished on it from there (one local solve). The start, its Gauss-Newton axes and
/// the sampling then use a basis exact at the maximum likelihood and accurate over the
/// posterior's region. The multistart's record (starts, how many reached the best) is
/// kept, its best replaced by the polished one.
fn anchored_optimum(
    post: FrfPosterior,
    options: &MultistartOptions,
) -> Result<(FrfPosterior, MultistartResult)> {
    let mut ms = structural_optimum(&post, options)?;
    if !post.has_reduced_basis() {
        return Ok((post, ms));
    }
    let mut post = post.with_basis_anchored_at(&ms.best.x, None)?;
    let polish = MultistartOptions {
        n_starts: 1,
        ..options.clone()
    };
    for round in 0..3 {
        let bounds = structural_bounds(&post)?;
        let problem = Residuals {
            post: &post,
            bounds: &bounds,
        };
        ms.best = multistart(&problem, &bounds, Some(&ms.best.x), &polish)?.best;
        if round == 2 {
            break;
        }
        let sd = start_at(&post, &ms, None)?.sd;
        let spread = basis_spread(&post, &sd)?;
        post = post.with_basis_anchored_at(&ms.best.x, Some(&spread))?;
    }
    Ok((post, ms))
}

/// The start at the structural optimum `ms` and the Gauss-Newton axes of the initial
/// ball. With `sampled` (`ln s` of [`sampled_optimum`]), the noise scale is that and the
/// axes come from the layer's whitened least squares at it (shared noise and correlated
/// bins included); without, the noise scale comes from the per-point cost (refined on
/// the full likelihood for general models with shared noise, [`refine_noise_scale`])
/// and the axes from the per-point residuals.
fn start_at(
    post: &FrfPosterior,
    ms: &MultistartResult,
    sampled: Option<f64>,
) -> Result<StartPoint> {
    let (n_free, prior) = (post.n_free(), post.prior());
    let bounds = structural_bounds(post)?;
    let problem = Residuals {
        post,
        bounds: &bounds,
    };
    let n_evaluations = ms
        .starts
        .iter()
        .filter_map(|s| s.solution.as_ref().ok())
        .map(|s| s.n_evaluations + 2 * n_free * s.n_jacobians)
        .sum();
    let n = post.data().len();
    let mut z = ms.best.x.clone();
    let mut ws = problem.workspace();
    let mut jac = DMatrix::zeros(n, n_free);
    let (cost, noise_scale_refined, s_ball) = match sampled {
        Some(ln_s) => {
            let mut r = vec![0.0; n];
            problem.residuals(&ms.best.x, &mut ws, &mut r)?;
            z.push(ln_s);
            let ls = post.layer().least_squares(&[ln_s.exp()])?;
            ls.jacobian(&ms.best.x, &mut ls.workspace(), &mut jac)?;
            (0.5 * r.iter().map(|v| v * v).sum::<f64>(), true, 1.0)
        }
        None => {
            let s2 = (2.0 * ms.best.cost / n as f64).max(f64::MIN_POSITIVE);
            let (s_lo, s_hi) = (prior.lower()[n_free], prior.upper()[n_free]);
            z.push((0.5 * s2.ln()).clamp(s_lo, s_hi));
            let refined = is_general(post)
                && !post.data().correlated.is_empty()
                && refine_noise_scale(post, &mut z)?;
            problem.jacobian(&ms.best.x, &mut ws, &mut jac)?;
            // the structural widths at the start's noise scale
            let s_ball = if refined { z[n_free].exp() } else { s2.sqrt() };
            (ms.best.cost, refined, s_ball)
        }
    };
    let (axes, axis_sd, sd) = gauss_newton_axes(post, jac, s_ball);
    Ok(StartPoint {
        z,
        cost,
        n_starts: ms.starts.len(),
        n_at_best: ms.n_at_best,
        sd,
        axes,
        axis_sd,
        n_evaluations,
        noise_scale_refined,
    })
}

/// Principal axes, their sd (range-scaled) and each coordinate's sd.
type Axes = (Vec<Vec<f64>>, Vec<f64>, Vec<f64>);

/// Gauss-Newton posterior of the structural coordinates from the SVD of the residual
/// Jacobian `jac` (noise scale 1; the widths are `s_ball` times its) in range-scaled
/// coordinates `u_j = z_j / range_j`: `J D = U S V^T`, so the covariance of `u` is
/// `s^2 V S^-2 V^T`, principal axes `V` with standard deviations `s / S_k` (infinite
/// along an exact ridge). Taken from the SVD, not from the covariance, so
/// well-determined directions are not lost to rounding next to a ridge. `ln s` of N
/// Gaussian residuals: sd `1/sqrt(2N)`, uncorrelated with the rest at the optimum.
/// Returns the axes, their sd (range-scaled) and each coordinate's sd.
fn gauss_newton_axes(post: &FrfPosterior, mut jac: DMatrix<f64>, s_ball: f64) -> Axes {
    let (n_free, prior, n) = (post.n_free(), post.prior(), post.data().len() as f64);
    let dim = n_free + 1;
    let range: Vec<f64> = (0..dim)
        .map(|i| prior.upper()[i] - prior.lower()[i])
        .collect();
    for (j, r) in range.iter().take(n_free).enumerate() {
        jac.column_mut(j).scale_mut(*r);
    }
    let svd = jac.svd(false, true);
    let mut axes = vec![vec![0.0; dim]; dim];
    let mut axis_sd = vec![f64::INFINITY; dim];
    if let Some(v_t) = &svd.v_t {
        for k in 0..n_free.min(v_t.nrows()) {
            axes[k][..n_free].copy_from_slice(&v_t.row(k).transpose().as_slice()[..n_free]);
            axis_sd[k] = s_ball / svd.singular_values[k];
        }
    }
    axes[n_free][n_free] = 1.0;
    axis_sd[n_free] = 1.0 / (2.0 * n).sqrt() / range[n_free];
    let sd = (0..dim)
        .map(|i| {
            let var: f64 = (0..dim).map(|k| (axes[k][i] * axis_sd[k]).powi(2)).sum();
            var.sqrt() * range[i]
        })
        .collect();
    (axes, axis_sd, sd)
}

/// Largest standard deviation of the initial ball along any direction, as a fraction of
/// the box (coordinates scaled by their prior range).
pub const BALL_MAX_SD: f64 = 0.05;

/// `n` starting positions `z + f N(0, S)` inside the prior box: `S` is the start's
/// Gauss-Newton covariance with every principal standard deviation capped at
/// [`BALL_MAX_SD`] of the box (coordinates scaled by their ranges), so a ridge (e.g.
/// the mass-stiffness scale of shake-table data) is followed while well-determined
/// directions stay tight; when the start carries no usable axes, independent
/// coordinates with sd 1e-3 of their ranges. Positions outside the box are redrawn whole (a center on a bound gives a
/// half-normal spread inward). Deterministic for `seed`.
pub fn ball_positions(
    post: &FrfPosterior,
    start: &StartPoint,
    n: usize,
    factor: f64,
    seed: u64,
) -> Result<Vec<Vec<f64>>> {
    const MAX_TRIES: usize = 100_000;
    let (lo, hi) = (post.prior().lower(), post.prior().upper());
    let dim = post.dim();
    if start.z.len() != dim {
        return Err(Error::Usage(format!(
            "start point has {} coordinates, the posterior {dim}",
            start.z.len()
        )));
    }
    if !(factor.is_finite() && factor > 0.0) {
        return Err(Error::Usage(format!(
            "ball factor must be positive, got {factor}"
        )));
    }
    let range: Vec<f64> = (0..dim).map(|i| hi[i] - lo[i]).collect();
    // Square root of the capped covariance: axis k contributes `axes[k] min(sd_k, cap)`.
    let mut root = DMatrix::zeros(dim, dim);
    let usable = start.axes.len() == dim
        && start.axis_sd.len() == dim
        && start.axes.iter().flatten().all(|v| v.is_finite())
        && start.axis_sd.iter().all(|s| !s.is_nan() && *s > 0.0);
    for k in 0..dim {
        for i in 0..dim {
            root[(i, k)] = if usable {
                start.axes[k][i] * start.axis_sd[k].min(BALL_MAX_SD) * range[i]
            } else if i == k {
                1e-3 * range[i]
            } else {
                0.0
            };
        }
    }
    let center: Vec<f64> = (0..dim).map(|i| start.z[i].clamp(lo[i], hi[i])).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(0xBA11);
    let mut out = Vec::with_capacity(n);
    let mut e = vec![0.0; dim];
    for _ in 0..n {
        let mut placed = None;
        for _ in 0..MAX_TRIES {
            e.iter_mut().for_each(|v| *v = rng.sample(StandardNormal));
            let z: Vec<f64> = (0..dim)
                .map(|i| center[i] + factor * (0..dim).map(|k| root[(i, k)] * e[k]).sum::<f64>())
                .collect();
            if z.iter()
                .zip(lo.iter().zip(hi))
                .all(|(x, (l, h))| x > l && x < h)
            {
                placed = Some(z);
                break;
            }
        }
        out.push(placed.ok_or_else(|| {
            Error::Numerical(format!(
                "could not place a walker inside the prior box in {MAX_TRIES} draws around the start"
            ))
        })?);
    }
    Ok(out)
}
