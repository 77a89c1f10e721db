//! Maximum a posteriori fits of a [`ModelPosterior`] (the prior is flat in its box, so
//! the MAP is the box-constrained maximum likelihood).
//!
//! Each start alternates (a) a trust-region reflective least-squares solve
//! ([`crate::update::lsq::Trf`]) of the whitened residuals over every coordinate but
//! `ln eta`, with `eta` fixed, and (b) the exact profile of `eta` for that fit
//! ([`ModelPosterior::profile_eta`]), until `eta` moves by less than 5 % (at most
//! [`MapOptions::max_eta_rounds`] rounds); the first round runs at the profile of the
//! start itself. For fixed
//! `eta` the log-likelihood is `-0.5 ||r||^2` plus a constant, so (a) maximises it
//! exactly; (b) maximises over `eta` given the fit. The Jacobian is by forward
//! differences (step `1e-6` of each coordinate's box width). Starts run in parallel,
//! results are collected in start order: the same starts give the same result whatever
//! the thread count.

use super::posterior::ModelPosterior;
use crate::error::{Error, Result};
use crate::update::lsq::{
    fd_jacobian, fd_jacobian_at, latin_hypercube, Bounds, FdScheme, LeastSquaresProblem, Trf,
    TrfOptions,
};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::time::Instant;

/// Settings of [`fit_map`].
#[derive(Debug, Clone, PartialEq)]
pub struct MapOptions {
    /// Local solver settings.
    pub trf: TrfOptions,
    /// At most this many least-squares / eta-profile rounds per start (default 4).
    pub max_eta_rounds: usize,
    /// Starts within this many nats of the best count as reaching it (default 0.5).
    pub at_best_tol: f64,
}

impl Default for MapOptions {
    fn default() -> Self {
        MapOptions {
            trf: TrfOptions {
                max_evaluations: Some(400),
                ..TrfOptions::default()
            },
            max_eta_rounds: 4,
            at_best_tol: 0.5,
        }
    }
}

/// The result of one start.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StartResult {
    pub start: Vec<f64>,
    /// `None` when the start failed (error message in `error`).
    pub z: Option<Vec<f64>>,
    pub ln_likelihood: f64,
    pub error: Option<String>,
    pub n_evaluations: usize,
}

/// A MAP fit.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MapFit {
    /// The best point.
    pub z: Vec<f64>,
    pub ln_likelihood: f64,
    /// `ln_likelihood + ln_prior`.
    pub ln_posterior: f64,
    /// Error floor at the best point.
    pub eta: f64,
    /// `sum |r|^2 / sigma^2 / (2 N)` at the best point.
    pub chi2_per_dof: f64,
    pub n_points: usize,
    /// Starts within `at_best_tol` of the best.
    pub n_at_best: usize,
    pub starts: Vec<StartResult>,
    /// Wall time, s.
    pub elapsed_s: f64,
}

/// The whitened residuals at a fixed `eta` in the free coordinates; forward-difference
/// Jacobian ([`fd_jacobian`]) inside their box.
struct MapProblem<'a> {
    post: &'a ModelPosterior,
    eta: f64,
    free: Vec<usize>,
    template: Vec<f64>,
    bounds: &'a Bounds,
    n_res: usize,
}

impl MapProblem<'_> {
    fn z_of(&self, x: &[f64], z: &mut Vec<f64>) {
        z.clear();
        z.extend_from_slice(&self.template);
        for (&i, &v) in self.free.iter().zip(x) {
            z[i] = v;
        }
    }
}

impl LeastSquaresProblem for MapProblem<'_> {
    type Workspace = Vec<f64>;

    fn n_params(&self) -> usize {
        self.free.len()
    }

    fn n_residuals(&self) -> usize {
        self.n_res
    }

    fn workspace(&self) -> Self::Workspace {
        Vec::new()
    }

    fn residuals(&self, x: &[f64], z: &mut Self::Workspace, r: &mut [f64]) -> Result<()> {
        self.z_of(x, z);
        self.post.whitened_residuals(z, self.eta, r)
    }

    fn jacobian(&self, x: &[f64], z: &mut Self::Workspace, jac: &mut DMatrix<f64>) -> Result<()> {
        let residuals = |x: &[f64], r: &mut [f64]| self.residuals(x, z, r);
        fd_jacobian(FdScheme::Forward, x, self.bounds, residuals, jac).map(|_| ())
    }

    fn jacobian_at(
        &self,
        x: &[f64],
        f: &[f64],
        z: &mut Self::Workspace,
        jac: &mut DMatrix<f64>,
    ) -> Result<()> {
        let residuals = |x: &[f64], r: &mut [f64]| self.residuals(x, z, r);
        fd_jacobian_at(FdScheme::Forward, x, Some(f), self.bounds, residuals, jac).map(|_| ())
    }
}

/// MAP fit of `post` from each of `starts` (full `z`; its `ln eta` is not used: each
/// start's first round runs at the error floor profiled at the start itself).
pub fn fit_map(post: &ModelPosterior, starts: &[Vec<f64>], options: &MapOptions) -> Result<MapFit> {
    if starts.is_empty() {
        return Err(Error::Usage("a MAP fit needs at least one start".into()));
    }
    let t0 = Instant::now();
    let results: Vec<StartResult> = starts
        .par_iter()
        .map(|s| run_start(post, s, options))
        .collect();
    let best = results
        .iter()
        .enumerate()
        .filter(|(_, r)| r.z.is_some())
        .max_by(|a, b| a.1.ln_likelihood.total_cmp(&b.1.ln_likelihood))
        .map(|(i, _)| i)
        .ok_or_else(|| {
            Error::Numerical(format!(
                "every MAP start failed; the first: {}",
                results[0].error.clone().unwrap_or_default()
            ))
        })?;
    let z = results[best].z.clone().unwrap_or_default();
    let ll = results[best].ln_likelihood;
    let n_at_best = results
        .iter()
        .filter(|r| r.z.is_some() && r.ln_likelihood >= ll - options.at_best_tol)
        .count();
    let pred = post.predict(&z)?;
    let eta = z[post.eta_index()].exp();
    Ok(MapFit {
        chi2_per_dof: post.chi2_per_dof_of(&pred, eta),
        ln_posterior: ll + post.ln_prior(&z),
        eta,
        ln_likelihood: ll,
        n_points: post.n_points(),
        n_at_best,
        z,
        starts: results,
        elapsed_s: t0.elapsed().as_secs_f64(),
    })
}

fn run_start(post: &ModelPosterior, start: &[f64], options: &MapOptions) -> StartResult {
    let fail = |e: Error| StartResult {
        start: start.to_vec(),
        z: None,
        ln_likelihood: f64::NEG_INFINITY,
        error: Some(e.to_string()),
        n_evaluations: 0,
    };
    match solve_start(post, start, options) {
        Ok((z, ll, n)) => StartResult {
            start: start.to_vec(),
            z: Some(z),
            ln_likelihood: ll,
            error: None,
            n_evaluations: n,
        },
        Err(e) => fail(e),
    }
}

fn solve_start(
    post: &ModelPosterior,
    start: &[f64],
    options: &MapOptions,
) -> Result<(Vec<f64>, f64, usize)> {
    let (lo, hi) = post.bounds();
    let ie = post.eta_index();
    let mut z: Vec<f64> = start
        .iter()
        .zip(lo.iter().zip(hi))
        .map(|(v, (l, h))| v.clamp(*l, *h))
        .collect();
    if z.len() != post.dim() {
        return Err(Error::Usage(format!(
            "start of {} entries for {} parameters",
            z.len(),
            post.dim()
        )));
    }
    let free: Vec<usize> = (0..post.dim()).filter(|&i| i != ie).collect();
    let bounds = Bounds::new(
        free.iter().map(|&i| lo[i]).collect(),
        free.iter().map(|&i| hi[i]).collect(),
    )?;
    // The floor the start's own misfit implies, not the one it came with: a start far
    // from the fit it was built from (an effect drawn from its box on top of a model
    // whose floor was profiled at 1e-4) would otherwise be solved against whitened
    // residuals millions of times its noise, where the solver crawls or stops in a
    // false minimum (a second round on the four-story campaign: 30-280 iterations at
    // cost 1.2e7 before the profile freed them). A large floor first, then the exact
    // profile, is a continuation from a smooth objective to the sharp one.
    let mut eta = post.profile_eta(&post.predict(&z)?);
    let trf = Trf::new(options.trf.clone());
    let mut n_eval = 0;
    for _ in 0..options.max_eta_rounds.max(1) {
        let problem = MapProblem {
            post,
            eta,
            free: free.clone(),
            template: z.clone(),
            bounds: &bounds,
            n_res: post.n_whitened_residuals(),
        };
        let mut ws = problem.workspace();
        let x0: Vec<f64> = free.iter().map(|&i| z[i]).collect();
        let sol = trf.minimize(&problem, &mut ws, &x0, &bounds)?;
        n_eval += sol.n_evaluations + sol.n_jacobians * (free.len() + 1);
        for (&i, &v) in free.iter().zip(&sol.x) {
            z[i] = v;
        }
        let new_eta = post.profile_eta(&post.predict(&z)?);
        let moved = (new_eta / eta).ln().abs();
        eta = new_eta;
        if moved < 0.05 {
            break;
        }
    }
    z[ie] = eta.ln();
    let ll = post.ln_likelihood(&z)?;
    Ok((z, ll, n_eval))
}

/// The default start of the frame: nominal masses and stiffnesses, every damping ratio
/// `xi0`, `eta = 1e-2`, effect coordinates at the middle of their boxes.
pub fn nominal_start(post: &ModelPosterior, xi0: f64) -> Vec<f64> {
    let (lo, hi) = post.bounds();
    let mut z = vec![0.0; post.dim()];
    for v in &mut z[post.frame_layout().xi()] {
        *v = xi0.ln();
    }
    z[post.eta_index()] = 1e-2f64.ln();
    for i in post.eta_index() + 1..post.dim() {
        z[i] = 0.5 * (lo[i] + hi[i]);
    }
    z
}

/// Starts for a hypothesis: `base` (the fit of the model it extends: the frame and error
/// floor, then the coordinates of any effects already accepted, which lead the effect
/// coordinates of [`super::extension::WithEffects`]) with, for the remaining effect
/// coordinates, first the end of the box nearest to no effect (each parameter's
/// [`super::EffectParam::no_effect`]; the middle where it has none), then `n` points of
/// a Latin hypercube over their box (seeded).
pub fn effect_starts(
    post: &ModelPosterior,
    base: &[f64],
    n: usize,
    seed: u64,
) -> Result<Vec<Vec<f64>>> {
    let ie = post.eta_index();
    if base.len() < ie + 1 {
        return Err(Error::Usage(format!(
            "base start of {} entries; the frame has {}",
            base.len(),
            ie + 1
        )));
    }
    if base.len() > post.dim() {
        return Err(Error::Usage(format!(
            "base start of {} entries; the model has {}",
            base.len(),
            post.dim()
        )));
    }
    let (lo, hi) = post.bounds();
    let known = base.len();
    if known == post.dim() {
        return Ok(vec![base.to_vec()]);
    }
    let b = Bounds::new(lo[known..].to_vec(), hi[known..].to_vec())?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut pts = latin_hypercube(&b, n, &mut rng)?;
    let near_nominal: Vec<f64> = post.effect_params()[known - ie - 1..]
        .iter()
        .map(|p| match (p.no_effect, p.coordinate) {
            (Some(v), super::hypothesis::Coordinate::Linear { .. }) => {
                p.coordinate_of(v).clamp(p.lower, p.upper)
            }
            (Some(0.0), _) => p.lower,
            (Some(_), _) => p.upper,
            (None, _) => 0.5 * (p.lower + p.upper),
        })
        .collect();
    pts.insert(0, near_nominal);
    Ok(pts
        .into_iter()
        .map(|p| {
            let mut z = base.to_vec();
            z.extend(p);
            z
        })
        .collect())
}

/// `n` frame starts: the nominal start, then a Latin hypercube over the multipliers
/// within `+-spread` (in `ln`) of nominal and over `ln xi` in its whole box (seeded).
pub fn frame_starts(
    post: &ModelPosterior,
    n: usize,
    spread: f64,
    seed: u64,
) -> Result<Vec<Vec<f64>>> {
    let xi = post.frame_layout().xi();
    let (lo, hi) = post.bounds();
    let mut starts = vec![nominal_start(post, 0.01)];
    if n > 1 {
        let mut l = Vec::new();
        let mut u = Vec::new();
        for i in 0..xi.end {
            if i < xi.start {
                l.push((-spread).max(lo[i]));
                u.push(spread.min(hi[i]));
            } else {
                l.push(1e-3f64.ln());
                u.push(0.05f64.ln());
            }
        }
        let b = Bounds::new(l, u)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for p in latin_hypercube(&b, n - 1, &mut rng)? {
            let mut z = nominal_start(post, 0.01);
            z[..xi.end].copy_from_slice(&p);
            starts.push(z);
        }
    }
    Ok(starts)
}

/// With [`super::data::GainCarrier::ModelAtMap`], `post` with its prediction at `map` as
/// the gain carrier, the MAP refitted from there under it (one local fit), and the
/// carrier reset to the refitted MAP, where the fit's likelihood, posterior and chi2
/// are evaluated again (the two-stage plug-in); otherwise both unchanged. The
/// multistart's record (`starts`, `n_at_best`) is kept.
pub fn refit_at_map(
    post: ModelPosterior,
    map: MapFit,
    opts: &MapOptions,
) -> Result<(ModelPosterior, MapFit)> {
    use super::data::GainCarrier;
    if post.data().options.gain_carrier != GainCarrier::ModelAtMap {
        return Ok((post, map));
    }
    let first = post.at_map(&map.z)?;
    let refit = fit_map(&first, std::slice::from_ref(&map.z), opts)?;
    let pred = first.predict(&refit.z)?;
    let post = first.at_map_predicted(&refit.z, pred.clone())?;
    let ln_likelihood = post.ln_likelihood_of(&pred, refit.eta);
    let out = MapFit {
        ln_posterior: ln_likelihood + post.ln_prior(&refit.z),
        ln_likelihood,
        chi2_per_dof: post.chi2_per_dof_of(&pred, refit.eta),
        elapsed_s: map.elapsed_s + refit.elapsed_s,
        z: refit.z,
        eta: refit.eta,
        ..map
    };
    Ok((post, out))
}
