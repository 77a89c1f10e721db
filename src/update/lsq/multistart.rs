//! Multistart local optimisation (like MATLAB's `MultiStart` with `lsqnonlin`): Latin
//! hypercube start points over the box, one [`Trf`] solve per start, in parallel.
//!
//! Determinism: all randomness (the Latin hypercube design) is drawn on the calling
//! thread from one `ChaCha8Rng` seeded with [`MultistartOptions::seed`] before any
//! solve starts; the local solver is deterministic; results are collected in start
//! order (`par_iter().map().collect()`) and reduced sequentially. So a given seed gives
//! bit-identical results whatever the number of threads.

use super::{Bounds, LeastSquaresProblem, Solution, Trf, TrfOptions};
use crate::error::{Error, Result};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Multistart settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MultistartOptions {
    /// Local solves in all (the first from the caller's initial point when one is
    /// given, the rest from a Latin hypercube). Default 64.
    pub n_starts: usize,
    /// Seed of the Latin hypercube design. Default 0.
    pub seed: u64,
    /// A start reaches the best minimum when its cost is at most
    /// `best * (1 + best_cost_rtol) + best_cost_atol`. Defaults 1e-6 and 1e-12: the
    /// relative part is far above the solver's `ftol` resolution (1e-8), the absolute
    /// part covers zero-residual fits whose costs are rounding noise.
    pub best_cost_rtol: f64,
    /// See [`Self::best_cost_rtol`].
    pub best_cost_atol: f64,
    /// Local solver settings.
    pub trf: TrfOptions,
}

impl Default for MultistartOptions {
    fn default() -> Self {
        MultistartOptions {
            n_starts: 64,
            seed: 0,
            best_cost_rtol: 1e-6,
            best_cost_atol: 1e-12,
            trf: TrfOptions::default(),
        }
    }
}

/// One local solve.
#[derive(Debug)]
pub struct StartOutcome {
    /// Where it started.
    pub start: Vec<f64>,
    /// Its result, or why it failed (e.g. a start point where the model is not
    /// admissible).
    pub solution: Result<Solution>,
}

/// The outcome of a multistart run.
#[derive(Debug)]
pub struct MultistartResult {
    /// Index (into `starts`) of the lowest cost; the first one on ties.
    pub best_index: usize,
    /// The best local solution (minimiser, cost, active bounds, counts).
    pub best: Solution,
    /// How many starts reached the best minimum (see
    /// [`MultistartOptions::best_cost_rtol`]), the best included.
    pub n_at_best: usize,
    /// Every start, in order.
    pub starts: Vec<StartOutcome>,
}

/// `n` Latin hypercube points in a finite box: each coordinate's range is cut into `n`
/// equal strata and each stratum holds exactly one point, at a uniform position in it.
pub fn latin_hypercube(bounds: &Bounds, n: usize, rng: &mut ChaCha8Rng) -> Result<Vec<Vec<f64>>> {
    if !bounds.is_finite() {
        return Err(Error::Usage(
            "Latin hypercube starts need finite bounds on every variable".into(),
        ));
    }
    let d = bounds.len();
    let mut points = vec![vec![0.0; d]; n];
    let mut strata: Vec<usize> = (0..n).collect();
    for j in 0..d {
        strata.shuffle(rng);
        let (l, u) = (bounds.lower()[j], bounds.upper()[j]);
        for (p, &k) in points.iter_mut().zip(&strata) {
            let t = (k as f64 + rng.random::<f64>()) / n as f64;
            p[j] = l + (u - l) * t;
        }
    }
    Ok(points)
}

/// The start points of [`multistart`]: `initial` (when given) first, then
/// `options.n_starts - 1` (or `n_starts`) Latin hypercube points in `bounds` drawn from
/// `ChaCha8Rng::seed_from_u64(options.seed)`.
pub fn start_points(
    bounds: &Bounds,
    initial: Option<&[f64]>,
    options: &MultistartOptions,
) -> Result<Vec<Vec<f64>>> {
    if options.n_starts == 0 {
        return Err(Error::Usage("multistart needs at least one start".into()));
    }
    if let Some(x) = initial {
        if x.len() != bounds.len() {
            return Err(Error::Usage(format!(
                "initial point has {} entries for {} variables",
                x.len(),
                bounds.len()
            )));
        }
    }
    let n_lhs = options.n_starts - usize::from(initial.is_some());
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut starts: Vec<Vec<f64>> = initial.map(|x| x.to_vec()).into_iter().collect();
    starts.extend(latin_hypercube(bounds, n_lhs, &mut rng)?);
    Ok(starts)
}

/// Runs `options.n_starts` local solves of `problem` in `bounds` in parallel and
/// returns the best. `initial`, when given, is the first start (see [`start_points`]).
pub fn multistart<P: LeastSquaresProblem>(
    problem: &P,
    bounds: &Bounds,
    initial: Option<&[f64]>,
    options: &MultistartOptions,
) -> Result<MultistartResult> {
    let starts = start_points(bounds, initial, options)?;
    multistart_from(problem, bounds, starts, options)
}

/// Runs one local solve from each of `starts` in parallel and returns the best
/// (`options.n_starts` and `options.seed` are not used).
pub fn multistart_from<P: LeastSquaresProblem>(
    problem: &P,
    bounds: &Bounds,
    starts: Vec<Vec<f64>>,
    options: &MultistartOptions,
) -> Result<MultistartResult> {
    if starts.is_empty() {
        return Err(Error::Usage("multistart needs at least one start".into()));
    }
    let trf = Trf::new(options.trf.clone());
    let solutions: Vec<Result<Solution>> = starts
        .par_iter()
        .map(|x0| {
            let mut ws = problem.workspace();
            trf.minimize(problem, &mut ws, x0, bounds)
        })
        .collect();
    let starts: Vec<StartOutcome> = starts
        .into_iter()
        .zip(solutions)
        .map(|(start, solution)| StartOutcome { start, solution })
        .collect();
    let mut best: Option<(usize, f64)> = None;
    for (i, s) in starts.iter().enumerate() {
        if let Ok(sol) = &s.solution {
            if best.is_none_or(|(_, c)| sol.cost < c) {
                best = Some((i, sol.cost));
            }
        }
    }
    let Some((best, cost)) = best else {
        let first = starts
            .iter()
            .find_map(|s| s.solution.as_ref().err().map(|e| e.to_string()))
            .unwrap_or_default();
        return Err(Error::Numerical(format!(
            "all {} starts failed; the first error: {first}",
            starts.len()
        )));
    };
    let threshold = cost * (1.0 + options.best_cost_rtol) + options.best_cost_atol;
    let n_at_best = starts
        .iter()
        .filter(|s| matches!(&s.solution, Ok(sol) if sol.cost <= threshold))
        .count();
    let best_solution = match &starts[best].solution {
        Ok(s) => s.clone(),
        Err(_) => unreachable!("best was chosen among successful starts"),
    };
    Ok(MultistartResult {
        best_index: best,
        best: best_solution,
        n_at_best,
        starts,
    })
}
