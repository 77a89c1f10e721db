//! The bridge study's computations: a reduced basis checked against the exact solve,
//! SMU's multistart with both weightings, the pull of the bounds at the optimum, and the
//! posterior with its predictive checks. Everything the report shows is computed here.

use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::bridge::{smu_bounds, smu_posterior, BridgeData, Weighting, SMU_PUBLISHED_ALPHA};
use super::bridge_posterior::{sample_posterior, BridgePosterior};
use super::posterior::Sampling;
use crate::error::Result;
use crate::infer::{fit_multistart, FitOptions, Posterior};
use crate::modal::PartialOptions;
use crate::predict::choice::{axis_snapshots, uniform_box_points};
use crate::predict::modal::PartialModes;
use crate::predict::reduced::{
    compare_with_full, BasisOptions, CondensedModes, PointError, ReducedModes,
};
use crate::update::lsq::TrfOptions;

/// Study settings (defaults are what `frfbayes real bridge-fe` runs).
#[derive(Debug, Clone, serde::Serialize)]
pub struct BridgeSettings {
    pub seed: u64,
    /// Random snapshot points of the reduced basis (beside the nominal model, the
    /// published optimum and every alpha at each of its bounds).
    pub n_random_snapshots: usize,
    pub basis: BasisOptions,
    /// Random points of the box where the basis is checked against the exact solve.
    pub n_check_points: usize,
    /// Starts of each multistart (SMU: 100).
    pub n_starts: usize,
    /// Residual evaluations per start (SMU's fmincon: 3000).
    pub max_evaluations: usize,
    /// Walkers per ensemble (4 ensembles).
    pub n_walkers: usize,
    /// Posterior draws pushed through the predictive check.
    pub n_predictive: usize,
    /// Step cap of the sampler (the study stops there, converged or not, and says which).
    pub max_steps: u64,
    /// Distinct multistart end points polished with the exact solver, and the residual
    /// evaluations of each polish.
    pub n_polished: usize,
    pub polish_evaluations: usize,
}

impl Default for BridgeSettings {
    fn default() -> Self {
        BridgeSettings {
            seed: 1,
            n_random_snapshots: 24,
            basis: BasisOptions {
                modes_per_snapshot: 8,
                rel_tol: 1e-12,
                max_size: 48,
            },
            n_check_points: 40,
            n_starts: 100,
            max_evaluations: 3000,
            n_walkers: 48,
            n_predictive: 400,
            max_steps: 9000,
            n_polished: 5,
            polish_evaluations: 200,
        }
    }
}

impl BridgeSettings {
    /// `frfbayes real bridge-fe --quick`: every stage of the study on a small scale (4
    /// random snapshots, 2 check points, 4 starts of 200 evaluations, one end point
    /// polished with 40 exact evaluations, 20 predictive draws, 100 sampler steps), for
    /// tests of the command; its numbers are not the study's.
    pub fn quick(seed: u64) -> Self {
        BridgeSettings {
            seed,
            n_random_snapshots: 4,
            n_check_points: 2,
            n_starts: 4,
            max_evaluations: 200,
            n_predictive: 20,
            max_steps: 100,
            n_polished: 1,
            polish_evaluations: 40,
            ..Default::default()
        }
    }
}

/// The reduced basis and its measured error.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BasisCheck {
    pub size: usize,
    pub n_snapshots: usize,
    pub build_s: f64,
    /// Per check point, lowest 5 modes.
    pub points: Vec<PointError>,
    pub max_eigenvalue_rel: f64,
    pub median_eigenvalue_rel: f64,
    pub max_one_minus_mac: f64,
    /// Seconds per evaluation of the 5 lowest modes: reduced, exact.
    pub reduced_eval_s: f64,
    pub exact_eval_s: f64,
}

/// One weighting's multistart and polish.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SmuFit {
    pub weighting: Weighting,
    /// Polished with the exact solver, SMU's order.
    pub alpha: Vec<f64>,
    /// SMU's `f = sum r^2` at `alpha`, exact solver.
    pub objective: f64,
    /// `f` at the multistart's best, reduced basis.
    pub objective_reduced: f64,
    pub n_starts: usize,
    /// Starts within 1e-6 (relative) of the best `f` (reduced basis).
    pub n_reached: usize,
    /// `f` at every start's end point (reduced basis), in start order.
    pub start_objectives: Vec<f64>,
    /// Wall-clock seconds of the multistart (all starts, all threads) and the polish.
    pub wall_s: f64,
    pub polish_s: f64,
    pub threads: usize,
    /// Residual evaluations of all starts.
    pub n_evaluations: usize,
    /// Per alpha: -1 at the lower bound, +1 at the upper, 0 inside (1e-6 of the width).
    pub on_bound: Vec<i8>,
    /// `d f / d alpha_j` at `alpha` (exact solver, central differences).
    pub gradient: Vec<f64>,
}

/// Everything the report renders.
#[derive(Debug, Clone)]
pub struct BridgeStudy {
    pub settings: BridgeSettings,
    pub basis: BasisCheck,
    pub smu: SmuFit,
    pub per_entry: SmuFit,
    /// SMU's objective at the published alphas (exact solver), both weightings.
    pub published_objective: f64,
    pub posterior: BridgePosterior,
    pub freq_exp_hz: Vec<f64>,
    pub std_freq_hz: Vec<f64>,
    pub names: Vec<String>,
}

/// Uniform points of the SMU box.
fn box_points(n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    uniform_box_points(&smu_bounds(), n, rng)
}

/// The basis from the nominal model, the published optimum, each alpha at each bound
/// (the others nominal) and random points; checked at fresh random points.
pub fn build_basis(
    data: &BridgeData,
    settings: &BridgeSettings,
) -> Result<(ReducedModes, BasisCheck)> {
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
    let mut snaps = vec![vec![0.0; 17], SMU_PUBLISHED_ALPHA.to_vec()];
    snaps.extend(axis_snapshots(&[0.0; 17], &smu_bounds()));
    snaps.extend(box_points(settings.n_random_snapshots, &mut rng));
    let pairs: Vec<_> = snaps.iter().map(|a| (a.clone(), Vec::new())).collect();
    let t0 = Instant::now();
    let reduced = ReducedModes::from_snapshots(&data.model, &pairs, &settings.basis)?;
    let build_s = t0.elapsed().as_secs_f64();
    let checks = box_points(settings.n_check_points, &mut rng);
    let n_modes = data.n_modes();
    let points = compare_with_full(&data.model, &reduced, &checks, n_modes, &data.meas_dofs)?;
    let mut rel: Vec<f64> = points
        .iter()
        .flat_map(|p| p.eigenvalue_rel.clone())
        .collect();
    rel.sort_by(f64::total_cmp);
    let max_one_minus_mac = points
        .iter()
        .flat_map(|p| p.one_minus_mac.iter().copied())
        .fold(0.0, f64::max);
    let (reduced_eval_s, exact_eval_s) = time_evaluations(data, &reduced)?;
    Ok((
        reduced.clone(),
        BasisCheck {
            size: reduced.size(),
            n_snapshots: snaps.len(),
            build_s,
            max_eigenvalue_rel: rel.iter().fold(0.0, |a, b| a.max(b.abs())),
            median_eigenvalue_rel: rel[rel.len() / 2],
            max_one_minus_mac,
            points,
            reduced_eval_s,
            exact_eval_s,
        },
    ))
}

/// Seconds per evaluation of the 5 lowest modes at the nominal model: reduced basis
/// (mean of 200) and exact (mean of 3), on this thread.
fn time_evaluations(data: &BridgeData, reduced: &ReducedModes) -> Result<(f64, f64)> {
    use crate::predict::modal::ModeSolver;
    let (a, b) = (vec![0.0; 17], Vec::new());
    let n = data.n_modes();
    let (mut ev, mut sh) = (vec![0.0; n], vec![0.0; n * data.meas_dofs.len()]);
    let mut ws = reduced.workspace();
    let t0 = Instant::now();
    for _ in 0..200 {
        reduced.lowest_modes(&a, &b, &data.meas_dofs, &mut ws, &mut ev, &mut sh)?;
    }
    let r = t0.elapsed().as_secs_f64() / 200.0;
    let exact = CondensedModes::new(data.model.clone());
    let t0 = Instant::now();
    for _ in 0..3 {
        exact.lowest_modes(&a, &b, &data.meas_dofs, &mut (), &mut ev, &mut sh)?;
    }
    Ok((r, t0.elapsed().as_secs_f64() / 3.0))
}

fn trf_options(max_evaluations: usize) -> TrfOptions {
    TrfOptions {
        ftol: 1e-10,
        xtol: 1e-10,
        gtol: 1e-10,
        max_evaluations: Some(max_evaluations),
        ..TrfOptions::default()
    }
}

/// SMU's `f = 2 * cost` at `alpha`.
fn objective<P: crate::predict::Predict>(post: &Posterior<P>, alpha: &[f64]) -> Result<f64> {
    Ok(post.residuals(alpha)?.iter().map(|r| r * r).sum())
}

/// The exact sparse partial solver (`src/modal/partial.rs`) of the bridge.
fn partial_modes(data: &BridgeData) -> Result<PartialModes> {
    PartialModes::new(data.model.clone(), PartialOptions::default())
}

/// Multistart on the reduced basis, then the best polished with the exact solver.
pub fn smu_fit(
    data: &BridgeData,
    reduced: &ReducedModes,
    weighting: Weighting,
    settings: &BridgeSettings,
) -> Result<SmuFit> {
    let post = smu_posterior(data, reduced.clone(), weighting)?;
    let opts = FitOptions {
        n_starts: settings.n_starts,
        seed: settings.seed,
        trf: trf_options(settings.max_evaluations),
        ..FitOptions::default()
    };
    let t0 = Instant::now();
    let res = fit_multistart(&post, &[], None, &opts)?;
    let wall_s = t0.elapsed().as_secs_f64();
    let exact = smu_posterior(data, partial_modes(data)?, weighting)?;
    let t0 = Instant::now();
    let polish = FitOptions {
        n_starts: 1,
        trf: trf_options(settings.polish_evaluations),
        ..FitOptions::default()
    };
    // The reduced basis ranks end points to its own accuracy (eigenvalues within a few
    // 1e-3): polish the best few distinct ones exactly and keep the best.
    let mut ends: Vec<(f64, Vec<f64>)> = res
        .starts
        .iter()
        .filter_map(|s| s.solution.as_ref().ok())
        .map(|s| (s.cost, s.x.clone()))
        .collect();
    ends.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut distinct: Vec<(f64, Vec<f64>)> = Vec::new();
    for e in ends {
        if distinct.len() < settings.n_polished
            && distinct.iter().all(|d| (d.0 - e.0).abs() > 1e-6 * d.0)
        {
            distinct.push(e);
        }
    }
    let mut best: Option<crate::infer::FitResult> = None;
    for (_, x) in &distinct {
        let p = fit_multistart(&exact, &[], Some(x), &polish)?;
        if best.as_ref().is_none_or(|b| p.best.cost < b.best.cost) {
            best = Some(p);
        }
    }
    let polished =
        best.ok_or_else(|| crate::error::Error::Numerical("no start converged".into()))?;
    let polish_s = t0.elapsed().as_secs_f64();
    let alpha = polished.best.x.clone();
    let bounds = smu_bounds();
    let on_bound = alpha
        .iter()
        .zip(&bounds)
        .map(|(&a, &(lo, hi))| {
            let tol = 1e-6 * (hi - lo);
            if a - lo < tol {
                -1
            } else if hi - a < tol {
                1
            } else {
                0
            }
        })
        .collect();
    Ok(SmuFit {
        weighting,
        objective: objective(&exact, &alpha)?,
        objective_reduced: 2.0 * res.best.cost,
        n_starts: settings.n_starts,
        n_reached: res.n_at_best,
        start_objectives: res
            .starts
            .iter()
            .map(|s| s.solution.as_ref().map_or(f64::NAN, |s| 2.0 * s.cost))
            .collect(),
        wall_s,
        polish_s,
        threads: rayon::current_num_threads(),
        n_evaluations: res
            .starts
            .iter()
            .filter_map(|s| s.solution.as_ref().ok())
            .map(|s| s.n_evaluations)
            .sum(),
        on_bound,
        gradient: gradient(&exact, &alpha)?,
        alpha,
    })
}

/// `d f / d alpha_j` by central differences of 1e-4 of the box width (one-sided at a
/// bound, stepping inside the box).
fn gradient<P: crate::predict::Predict>(post: &Posterior<P>, alpha: &[f64]) -> Result<Vec<f64>> {
    let f0 = objective(post, alpha)?;
    smu_bounds()
        .iter()
        .enumerate()
        .map(|(j, &(lo, hi))| {
            let h = 1e-4 * (hi - lo);
            let at = |v: f64| {
                let mut a = alpha.to_vec();
                a[j] = v;
                objective(post, &a)
            };
            if alpha[j] - h < lo {
                Ok((at(alpha[j] + h)? - f0) / h)
            } else if alpha[j] + h > hi {
                Ok((f0 - at(alpha[j] - h)?) / h)
            } else {
                Ok((at(alpha[j] + h)? - at(alpha[j] - h)?) / (2.0 * h))
            }
        })
        .collect()
}

/// The whole study.
pub fn run(
    data: &BridgeData,
    settings: &BridgeSettings,
    sampling: &mut Sampling<'_>,
) -> Result<BridgeStudy> {
    let (reduced, basis) = build_basis(data, settings)?;
    let smu = smu_fit(data, &reduced, Weighting::SmuLinearIndex, settings)?;
    let per_entry = smu_fit(data, &reduced, Weighting::PerEntry, settings)?;
    let exact = smu_posterior(data, partial_modes(data)?, Weighting::SmuLinearIndex)?;
    let published_objective = objective(&exact, &SMU_PUBLISHED_ALPHA)?;
    let posterior = sample_posterior(data, &reduced, &per_entry.alpha, settings, sampling)?;
    let freq_exp_hz = data.freq_exp_hz();
    let std_freq_hz = data
        .std_lambda
        .iter()
        .zip(&freq_exp_hz)
        .map(|(s, f)| s / (8.0 * std::f64::consts::PI.powi(2) * f))
        .collect();
    Ok(BridgeStudy {
        settings: settings.clone(),
        basis,
        smu,
        per_entry,
        published_objective,
        posterior,
        freq_exp_hz,
        std_freq_hz,
        names: data
            .model
            .alpha_parameters()
            .iter()
            .map(|p| p.name.clone())
            .collect(),
    })
}
