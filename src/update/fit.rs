//! Multistart updating of a [`Problem`] (the paper's MATLAB `MultiStart` +
//! `lsqnonlin`), reported in physical variables.

use super::lsq::{self, multistart_from, Active, MultistartOptions, Termination};
use super::problem::Problem;
use crate::error::Result;

/// One local fit in physical variables.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fit {
    /// `theta` (full layout; fixed variables at their values).
    pub theta: Vec<f64>,
    /// Physical values for the tables: k (N/m), m (kg), damping as is.
    pub physical: Vec<f64>,
    /// `0.5 ||r||^2` of the problem's residuals.
    pub cost: f64,
    /// Per variable of `theta`: which bound it ends on (`Free` for fixed variables).
    pub active: Vec<Active>,
    pub termination: Termination,
    pub n_evaluations: usize,
    pub n_jacobians: usize,
    pub n_iterations: usize,
}

/// One start of a multistart run.
#[derive(Debug)]
pub struct StartFit {
    /// Start point `theta`.
    pub start: Vec<f64>,
    pub fit: Result<Fit>,
}

/// The result of [`update`].
#[derive(Debug)]
pub struct UpdateResult {
    /// Variable names in `theta` order.
    pub names: Vec<String>,
    /// Units of [`Fit::physical`].
    pub units: Vec<String>,
    /// Index of the best start.
    pub best_index: usize,
    /// The best fit.
    pub best: Fit,
    /// Starts that reached the best minimum (see [`MultistartOptions::best_cost_rtol`]).
    pub n_at_best: usize,
    /// Every start, in order (the first from the variables' start values).
    pub starts: Vec<StartFit>,
}

impl UpdateResult {
    /// Names of the variables the best fit ends on a bound, with the side.
    pub fn on_bounds(&self) -> Vec<(&str, Active)> {
        self.names
            .iter()
            .zip(&self.best.active)
            .filter(|(_, a)| **a != Active::Free)
            .map(|(n, a)| (n.as_str(), *a))
            .collect()
    }
}

/// An [`UpdateResult`] as data (failed starts as their messages), e.g. to travel
/// between the ranks of an MPI run; converts back with the same `Display` of every
/// failure.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct UpdateRecord {
    names: Vec<String>,
    units: Vec<String>,
    best_index: usize,
    best: Fit,
    n_at_best: usize,
    starts: Vec<(Vec<f64>, std::result::Result<Fit, String>)>,
}

impl From<&UpdateResult> for UpdateRecord {
    fn from(r: &UpdateResult) -> Self {
        UpdateRecord {
            names: r.names.clone(),
            units: r.units.clone(),
            best_index: r.best_index,
            best: r.best.clone(),
            n_at_best: r.n_at_best,
            starts: r
                .starts
                .iter()
                .map(|s| {
                    (
                        s.start.clone(),
                        s.fit.as_ref().map(Fit::clone).map_err(|e| e.to_string()),
                    )
                })
                .collect(),
        }
    }
}

impl From<UpdateRecord> for UpdateResult {
    fn from(r: UpdateRecord) -> Self {
        UpdateResult {
            names: r.names,
            units: r.units,
            best_index: r.best_index,
            best: r.best,
            n_at_best: r.n_at_best,
            starts: r
                .starts
                .into_iter()
                .map(|(start, fit)| StartFit {
                    start,
                    fit: fit.map_err(crate::error::Error::Usage),
                })
                .collect(),
        }
    }
}

/// Updates the model: `options.n_starts` bounded least-squares solves, the first from
/// the variables' start values, the others from a seeded Latin hypercube over the box
/// (damping on its log scale), in parallel; deterministic for a given seed.
pub fn update(problem: &Problem, options: &MultistartOptions) -> Result<UpdateResult> {
    let vars = problem.variables();
    let starts = internal_start_points(problem, options)?;
    let ms = multistart_from(problem, &vars.internal_bounds(), starts, options)?;
    let to_fit = |s: &super::lsq::Solution| {
        let theta = vars.theta(&s.x);
        let mut active = vec![Active::Free; vars.len()];
        for (&i, &a) in vars.free().iter().zip(&s.active) {
            active[i] = a;
        }
        Fit {
            physical: vars.physical(problem.model(), &theta),
            theta,
            cost: s.cost,
            active,
            termination: s.termination,
            n_evaluations: s.n_evaluations,
            n_jacobians: s.n_jacobians,
            n_iterations: s.n_iterations,
        }
    };
    let best = to_fit(&ms.best);
    let starts = ms
        .starts
        .into_iter()
        .map(|s| StartFit {
            start: vars.theta(&s.start),
            fit: s.solution.map(|sol| to_fit(&sol)),
        })
        .collect();
    Ok(UpdateResult {
        names: vars.names().iter().map(|s| s.to_string()).collect(),
        units: vars.physical_units(problem.model()),
        best_index: ms.best_index,
        best,
        n_at_best: ms.n_at_best,
        starts,
    })
}

/// The start points [`update`] uses for `options` (`n_starts` and `seed`), in the
/// solver's internal coordinates `z` (free variables only, damping on its log scale
/// by default; see [`crate::update::Variables`]): the variables' start values, then a
/// seeded Latin hypercube over the internal box.
pub fn internal_start_points(
    problem: &Problem,
    options: &MultistartOptions,
) -> Result<Vec<Vec<f64>>> {
    let vars = problem.variables();
    let z0 = vars.to_internal(&vars.initial());
    lsq::start_points(&vars.internal_bounds(), Some(&z0), options)
}

/// The start points [`update`] uses for `options`, as full physical `theta` (fixed
/// variables at their values), so another solver can start from the very same points.
///
/// # Example
/// ```
/// # use frfbayes::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
/// # use frfbayes::model::StructuralModel;
/// # use frfbayes::update::*;
/// let model = StructuralModel::shear_frame(&[1.0], &[100.0])?;
/// let pair = FrfPair { response: 0, excitation: Excitation::Dof(0), kind: FrfKind::Receptance };
/// let blocks = vec![FrfBlock { omega_rad_s: vec![5.0, 10.0, 15.0], pairs: vec![pair] }];
/// let data = Measurements { blocks, magnitude: vec![0.01, 0.05, 0.01], sigma: None };
/// let problem = Problem::new(model, data, DampingModel::Caughey,
///     &VariablesConfig::default(), ObjectiveOptions::default())?;
/// let options = MultistartOptions { n_starts: 4, seed: 7, ..Default::default() };
/// let starts = start_points(&problem, &options)?;
/// assert_eq!(starts.len(), 4);
/// // The first start is the variables' start values (up to the log-scale round trip).
/// for (s, t) in starts[0].iter().zip(problem.variables().initial()) {
///     assert!((s - t).abs() <= 1e-15 * t.abs());
/// }
/// # Ok::<(), frfbayes::Error>(())
/// ```
pub fn start_points(problem: &Problem, options: &MultistartOptions) -> Result<Vec<Vec<f64>>> {
    let vars = problem.variables();
    Ok(internal_start_points(problem, options)?
        .iter()
        .map(|z| vars.theta(z))
        .collect())
}
