//! One mode solver for any model, chosen by its size: [`ModelModes`].
//!
//! Small models (up to [`DENSE_MAX_DOF`] DOFs, every DOF with mass: the shear frames, the
//! six-DOF and ten-story manifests) use the dense solver of every mode ([`DenseModes`],
//! with the shear frame's tridiagonal fast path); large ones, or any with massless DOFs
//! (an FE model's rotations), a Ritz reduced basis ([`ReducedModes`]) built from exact
//! condensed solves at snapshots of the prior box ([`box_snapshots`]) and anchored at a
//! point where it must be exact (the maximum-likelihood point of a posterior:
//! [`ReducedModes::from_snapshots_anchored`]). [`CondensedModes`] (exact, slow) is there
//! to check the basis against.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Uniform};
use serde::{Deserialize, Serialize};

use super::modal::{DenseModes, DenseWorkspace, ModeSolver};
use super::reduced::{CondensedModes, ReducedModes, ReducedWorkspace};
use crate::error::{Error, Result};
use crate::modal::Modes;
use crate::model::condense::massless_dofs;
use crate::model::StructuralModel;

/// Models of up to this many DOFs (all with mass) are solved densely by
/// [`ModeSolverChoice::Auto`].
pub const DENSE_MAX_DOF: usize = 200;

/// Which mode solver a posterior uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModeSolverChoice {
    /// Dense for small models with mass on every DOF, else reduced.
    #[default]
    Auto,
    /// Every mode by the dense solver ([`DenseModes`]).
    Dense,
    /// The exact lowest modes by static condensation ([`CondensedModes`]; slow).
    Exact,
    /// A Ritz reduced basis ([`ReducedModes`]).
    Reduced,
}

impl ModeSolverChoice {
    /// `Auto` resolved for `model`; the others as they are.
    pub fn resolve(self, model: &StructuralModel) -> ModeSolverChoice {
        match self {
            ModeSolverChoice::Auto => {
                let m = model.mass(&model.beta_zero());
                if model.n_dof() <= DENSE_MAX_DOF && massless_dofs(&m).is_empty() {
                    ModeSolverChoice::Dense
                } else {
                    ModeSolverChoice::Reduced
                }
            }
            c => c,
        }
    }
}

/// The mode solver of a model (see the module docs).
#[derive(Debug, Clone)]
pub enum ModelModes {
    Dense(DenseModes),
    Exact(CondensedModes),
    Reduced(ReducedModes),
}

/// Scratch memory of a [`ModelModes`].
pub enum ModelModesWorkspace {
    Dense(DenseWorkspace),
    Exact,
    Reduced(ReducedWorkspace),
}

fn mismatch() -> Error {
    Error::Numerical("mode solver and workspace of different kinds".into())
}

impl ModeSolver for ModelModes {
    type Workspace = ModelModesWorkspace;

    fn n_dof(&self) -> usize {
        match self {
            ModelModes::Dense(s) => s.n_dof(),
            ModelModes::Exact(s) => s.n_dof(),
            ModelModes::Reduced(s) => s.n_dof(),
        }
    }

    fn workspace(&self) -> ModelModesWorkspace {
        match self {
            ModelModes::Dense(s) => ModelModesWorkspace::Dense(s.workspace()),
            ModelModes::Exact(_) => ModelModesWorkspace::Exact,
            ModelModes::Reduced(s) => ModelModesWorkspace::Reduced(s.workspace()),
        }
    }

    fn lowest_modes(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut ModelModesWorkspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
    ) -> Result<()> {
        match (self, ws) {
            (ModelModes::Dense(s), ModelModesWorkspace::Dense(w)) => {
                s.lowest_modes(alpha, beta, dofs, w, eigenvalues, shapes)
            }
            (ModelModes::Exact(s), ModelModesWorkspace::Exact) => {
                s.lowest_modes(alpha, beta, dofs, &mut (), eigenvalues, shapes)
            }
            (ModelModes::Reduced(s), ModelModesWorkspace::Reduced(w)) => {
                s.lowest_modes(alpha, beta, dofs, w, eigenvalues, shapes)
            }
            _ => Err(mismatch()),
        }
    }

    fn modes<'w>(
        &self,
        alpha: &[f64],
        beta: &[f64],
        n_modes: usize,
        ws: &'w mut ModelModesWorkspace,
    ) -> Result<Option<&'w mut Modes>> {
        match (self, ws) {
            (ModelModes::Dense(s), ModelModesWorkspace::Dense(w)) => {
                s.modes(alpha, beta, n_modes, w)
            }
            (ModelModes::Dense(_), _) => Err(mismatch()),
            _ => Ok(None),
        }
    }
}

/// Snapshots of a box for a reduced basis, in the model's variables `v = [alpha, beta]`:
/// `center`, then each variable at each of its bounds (the others at `center`), then
/// `n_random` uniform points of the box drawn from `rng`.
pub fn box_snapshots(
    center: &[f64],
    bounds: &[(f64, f64)],
    n_random: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec<f64>> {
    let mut snaps = vec![center.to_vec()];
    snaps.extend(axis_snapshots(center, bounds));
    snaps.extend(uniform_box_points(bounds, n_random, rng));
    snaps
}

/// `center` with each variable in turn at its lower, then its upper bound.
pub fn axis_snapshots(center: &[f64], bounds: &[(f64, f64)]) -> Vec<Vec<f64>> {
    let mut snaps = Vec::with_capacity(2 * bounds.len());
    for (j, &(lo, hi)) in bounds.iter().enumerate() {
        for v in [lo, hi] {
            let mut a = center.to_vec();
            a[j] = v;
            snaps.push(a);
        }
    }
    snaps
}

/// `n` uniform points of the box `bounds`.
pub fn uniform_box_points(bounds: &[(f64, f64)], n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            bounds
                .iter()
                .map(|&(lo, hi)| Uniform::new(lo, hi).map_or(lo, |u| u.sample(rng)))
                .collect()
        })
        .collect()
}

/// `center` and `center +- step_j e_j` for every variable `j`, clipped into `bounds`:
/// snapshots that hold the modes' first derivatives at `center` (to `O(step^2)`).
pub fn local_snapshots(center: &[f64], steps: &[f64], bounds: &[(f64, f64)]) -> Vec<Vec<f64>> {
    let mut snaps = vec![center.to_vec()];
    for (j, (&h, &(lo, hi))) in steps.iter().zip(bounds).enumerate() {
        for sign in [-1.0, 1.0] {
            let mut a = center.to_vec();
            a[j] = (a[j] + sign * h).clamp(lo, hi);
            if a[j] != center[j] {
                snaps.push(a);
            }
        }
    }
    snaps
}

/// How [`reduced_basis`] builds its basis: random box points (seeded, so the basis is
/// the same run to run), the [`super::reduced::BasisOptions`] beyond the modes per
/// snapshot (`n_modes + extra_modes`), and the local step as a fraction of each box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BasisDesign {
    pub n_random: usize,
    pub seed: u64,
    pub extra_modes: usize,
    pub max_size: usize,
    pub local_step_fraction: f64,
    /// `extra_modes` and `max_size` of a basis over an anchor's spread, which must
    /// hold the modes' variation in every direction (about `n_modes` per variable).
    pub local_extra_modes: usize,
    pub local_max_size: usize,
}

impl Default for BasisDesign {
    fn default() -> Self {
        BasisDesign {
            n_random: 16,
            seed: 20261127,
            extra_modes: 4,
            max_size: 60,
            local_step_fraction: 0.02,
            local_extra_modes: 2,
            local_max_size: 100,
        }
    }
}

/// Where a reduced basis must be exact: `point` (the model's `v = [alpha, beta]`) and,
/// when known, the `spread` of the posterior around it (per variable, e.g. a few
/// Gauss-Newton standard deviations).
#[derive(Debug, Clone, Copy)]
pub struct Anchor<'a> {
    pub point: &'a [f64],
    pub spread: Option<&'a [f64]>,
}

/// The reduced basis of `model` for the `n_modes` lowest modes over the box `bounds` of
/// the variables `v = [alpha, beta]` (fixed ones with equal bounds). Without `anchor`:
/// around `center` ([`box_snapshots`]). With an anchor and no spread: also its
/// [`local_snapshots`] (steps a fraction of the box). With a spread: only the anchor's
/// region, its [`local_snapshots`] at `+- spread` and `n_random` uniform points of
/// `point +- spread` (in the box). With an anchor its exact modes are kept whole
/// ([`ReducedModes::from_snapshots_anchored`]).
pub fn reduced_basis(
    model: &StructuralModel,
    n_modes: usize,
    center: &[f64],
    bounds: &[(f64, f64)],
    anchor: Option<Anchor>,
    design: &BasisDesign,
) -> Result<ReducedModes> {
    let n_alpha = model.n_alpha();
    if center.len() != n_alpha + model.n_beta() || bounds.len() != center.len() {
        return Err(Error::Usage(format!(
            "a reduced basis of {} variables got a center of {} and {} bounds",
            n_alpha + model.n_beta(),
            center.len(),
            bounds.len()
        )));
    }
    let snaps = snapshots_of(center, bounds, anchor, design);
    let split = |v: &[f64]| (v[..n_alpha].to_vec(), v[n_alpha..].to_vec());
    let pairs: Vec<_> = snaps.iter().map(|v| split(v)).collect();
    let local = anchor.is_some_and(|a| a.spread.is_some());
    let options = super::reduced::BasisOptions {
        modes_per_snapshot: n_modes
            + match local {
                true => design.local_extra_modes,
                false => design.extra_modes,
            },
        max_size: match local {
            true => design.local_max_size,
            false => design.max_size,
        },
        ..Default::default()
    };
    match anchor {
        Some(a) => ReducedModes::from_snapshots_anchored(model, &split(a.point), &pairs, &options),
        None => ReducedModes::from_snapshots(model, &pairs, &options),
    }
}

/// The snapshot points of [`reduced_basis`].
fn snapshots_of(
    center: &[f64],
    bounds: &[(f64, f64)],
    anchor: Option<Anchor>,
    design: &BasisDesign,
) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(design.seed);
    match anchor {
        None => box_snapshots(center, bounds, design.n_random, &mut rng),
        Some(Anchor {
            point,
            spread: None,
        }) => {
            let mut snaps = box_snapshots(center, bounds, design.n_random, &mut rng);
            let steps: Vec<f64> = bounds
                .iter()
                .map(|(lo, hi)| design.local_step_fraction * (hi - lo))
                .collect();
            snaps.extend(local_snapshots(point, &steps, bounds));
            snaps
        }
        Some(Anchor {
            point,
            spread: Some(spread),
        }) => {
            let local: Vec<(f64, f64)> = point
                .iter()
                .zip(spread)
                .zip(bounds)
                .map(|((&x, &s), &(lo, hi))| ((x - s).max(lo), (x + s).min(hi)))
                .collect();
            let mut snaps = local_snapshots(point, spread, bounds);
            snaps.extend(uniform_box_points(&local, design.n_random, &mut rng));
            snaps
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predict::reduced::{compare_with_full, test_models::chain_model};

    /// Oracle: the anchored basis reproduces the exact modes at its anchor (a point that
    /// is no snapshot) to rounding, and stays a Rayleigh-Ritz upper bound near it; the
    /// dispatching solver gives the reduced basis's modes; `Auto` picks the reduced basis
    /// for a model with massless DOFs.
    #[test]
    fn anchored_basis_is_exact_at_its_anchor() {
        let model = chain_model(30);
        let bounds = vec![(-0.3, 0.3); 3];
        let design = BasisDesign {
            n_random: 4,
            max_size: 12,
            ..BasisDesign::default()
        };
        let anchor = [0.13, -0.21, 0.07];
        let at_anchor = Anchor {
            point: &anchor,
            spread: None,
        };
        let red = reduced_basis(&model, 4, &[0.0; 3], &bounds, Some(at_anchor), &design).unwrap();
        let dofs: Vec<usize> = (0..60).step_by(3).collect();
        let at = compare_with_full(&model, &red, &[anchor.to_vec()], 4, &dofs).unwrap();
        for (e, m) in at[0].eigenvalue_rel.iter().zip(&at[0].one_minus_mac) {
            assert!(e.abs() < 1e-10 && *m < 1e-10, "{e} {m}");
        }
        let near = compare_with_full(&model, &red, &[vec![0.15, -0.2, 0.05]], 4, &dofs).unwrap();
        for e in &near[0].eigenvalue_rel {
            assert!(*e > -1e-10 && *e < 1e-4, "{e}");
        }
        let solver = ModelModes::Reduced(red.clone());
        let (mut ev, mut sh) = (vec![0.0; 4], vec![0.0; 4 * dofs.len()]);
        let (mut ev2, mut sh2) = (ev.clone(), sh.clone());
        let mut ws = solver.workspace();
        solver
            .lowest_modes(&anchor, &[], &dofs, &mut ws, &mut ev, &mut sh)
            .unwrap();
        let mut ws2 = red.workspace();
        red.lowest_modes(&anchor, &[], &dofs, &mut ws2, &mut ev2, &mut sh2)
            .unwrap();
        assert_eq!((ev, sh), (ev2, sh2));
        assert_eq!(
            ModeSolverChoice::Auto.resolve(&model),
            ModeSolverChoice::Reduced
        );
        let frame = StructuralModel::shear_frame(&[1.0; 4], &[100.0; 4]).unwrap();
        assert_eq!(
            ModeSolverChoice::Auto.resolve(&frame),
            ModeSolverChoice::Dense
        );
        let wrong = ModelModes::Exact(CondensedModes::new(std::sync::Arc::new(model)));
        let e = wrong.lowest_modes(&anchor, &[], &dofs, &mut ws, &mut [0.0; 4], &mut [0.0; 80]);
        assert!(e.is_err());
    }
}
