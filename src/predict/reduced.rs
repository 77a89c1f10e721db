//! Mode solvers for large models: the exact condensed solve ([`CondensedModes`]) and a
//! Ritz reduced basis built from it ([`ReducedModes`]).
//!
//! The reduced basis `V` (n x b) spans the exact modes of the model at snapshot points
//! of the parameter box (a proper orthogonal decomposition of the snapshots, in the
//! energy norm `W = M0 + K0 / lambda_ref`). Every evaluation then solves the projected
//! pencil `V^T K(alpha) V y = lambda V^T M(beta) V y`, with
//! `V^T K(alpha) V = V^T K0 V + sum_r alpha_r V^T K_r V` (paper Eq. 20, and Eq. 21 for
//! `M`) assembled from precomputed b x b matrices: `O(b^3)` per evaluation instead of
//! `O(n^3)`. By the Rayleigh-Ritz principle its eigenvalues are upper bounds of the exact
//! ones; how close they are is measured against [`CondensedModes`] across the box
//! ([`compare_with_full`]), never assumed.
//!
//! The projected pencil is solved as `L^-1 (V^T M V) L^-T u = mu u` with
//! `V^T K V = L L^T` (`K` is positive definite inside the box, while `V^T M V` may be
//! singular when the basis carries massless motion): the lowest modes are the largest
//! `mu = 1 / lambda`, and directions without mass get `mu = 0`, never a spurious mode.

use std::sync::Arc;

use faer::Mat;
use nalgebra::DMatrix;
use rayon::prelude::*;

use super::modal::ModeSolver;
use crate::error::{Error, Result};
use crate::modal::condensed::lowest_modes_condensed;
use crate::modal::dense::{
    cholesky_in_place, matmul, solve_lower, solve_lower_transpose, symmetric_eigen, symmetrise,
};
use crate::model::StructuralModel;

/// The exact lowest modes by static condensation and a dense solve (slow, exact).
#[derive(Debug, Clone)]
pub struct CondensedModes {
    model: Arc<StructuralModel>,
}

impl CondensedModes {
    pub fn new(model: Arc<StructuralModel>) -> Self {
        CondensedModes { model }
    }
}

impl ModeSolver for CondensedModes {
    type Workspace = ();
    fn n_dof(&self) -> usize {
        self.model.n_dof()
    }
    fn workspace(&self) {}
    fn lowest_modes(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        _ws: &mut (),
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
    ) -> Result<()> {
        let (k, m) = (self.model.stiffness(alpha), self.model.mass(beta));
        let full = lowest_modes_condensed(&k, &m, eigenvalues.len())?;
        eigenvalues.copy_from_slice(&full.eigenvalues);
        for (i, col) in shapes.chunks_mut(dofs.len()).enumerate() {
            for (s, &d) in col.iter_mut().zip(dofs) {
                *s = full.shapes[(d, i)];
            }
        }
        Ok(())
    }
}

/// How a reduced basis is built.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BasisOptions {
    /// Exact modes kept from each snapshot.
    pub modes_per_snapshot: usize,
    /// Directions whose energy-norm singular value squared is below this fraction of
    /// the largest are dropped.
    pub rel_tol: f64,
    /// At most this many basis vectors (the most energetic).
    pub max_size: usize,
}

impl Default for BasisOptions {
    fn default() -> Self {
        BasisOptions {
            modes_per_snapshot: 10,
            rel_tol: 1e-12,
            max_size: 60,
        }
    }
}

/// A Ritz reduced basis of a model (see the module docs).
#[derive(Debug, Clone)]
pub struct ReducedModes {
    /// `V`, n x b.
    basis: DMatrix<f64>,
    k0: Mat<f64>,
    k_r: Vec<Mat<f64>>,
    m0: Mat<f64>,
    m_r: Vec<Mat<f64>>,
}

/// `V^T A V` for a dense `A`.
pub(crate) fn project(v: &Mat<f64>, a: &DMatrix<f64>) -> Mat<f64> {
    let af = Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)]);
    let mut av = Mat::<f64>::zeros(a.nrows(), v.ncols());
    matmul(av.as_mut(), false, af.as_ref(), v.as_ref(), 1.0);
    let mut out = Mat::<f64>::zeros(v.ncols(), v.ncols());
    matmul(out.as_mut(), false, v.transpose(), av.as_ref(), 1.0);
    symmetrise(&mut out);
    out
}

/// The POD basis `V` (n x b, `V^T W V = I`) of the snapshots' `modes_per_snapshot`
/// lowest exact modes in the energy norm `W = M0 + K0 / lambda_ref` (`lambda_ref` the
/// median snapshot eigenvalue), and `W`.
pub(crate) fn pod_basis(
    model: &StructuralModel,
    snapshots: &[(Vec<f64>, Vec<f64>)],
    opts: &BasisOptions,
) -> Result<(Mat<f64>, DMatrix<f64>)> {
    if snapshots.is_empty() || opts.modes_per_snapshot == 0 || opts.max_size == 0 {
        return Err(Error::Usage(
            "a reduced basis needs snapshots, modes and a positive size".into(),
        ));
    }
    let solved: Vec<_> = snapshots
        .par_iter()
        .map(|(a, b)| {
            lowest_modes_condensed(&model.stiffness(a), &model.mass(b), opts.modes_per_snapshot)
        })
        .collect::<Result<_>>()?;
    let n = model.n_dof();
    let p = opts.modes_per_snapshot;
    let x = Mat::from_fn(n, p * solved.len(), |i, j| solved[j / p].shapes[(i, j % p)]);
    let mut lambdas: Vec<f64> = solved.iter().flat_map(|s| s.eigenvalues.clone()).collect();
    lambdas.sort_by(f64::total_cmp);
    let lambda_ref = lambdas[lambdas.len() / 2].max(f64::MIN_POSITIVE);
    let (k0, m0) = (
        model.stiffness(&model.alpha_zero()),
        model.mass(&model.beta_zero()),
    );
    let w = &m0 + &k0 / lambda_ref;
    let v = principal_directions(&x, &w, opts.rel_tol, opts.max_size)?;
    Ok((v, w))
}

/// The span of `x`'s columns as `W`-orthonormal directions (`V^T W V = I`), the most
/// energetic first: the eigen-decomposition of the Gram matrix `x^T W x`, directions
/// whose eigenvalue is below `rel_tol` of the largest dropped, at most `max_size` kept.
pub(crate) fn principal_directions(
    x: &Mat<f64>,
    w: &DMatrix<f64>,
    rel_tol: f64,
    max_size: usize,
) -> Result<Mat<f64>> {
    let gram = project(x, w);
    let (s, u) = symmetric_eigen(gram.as_ref())?;
    let s_max = s.last().copied().unwrap_or(0.0);
    let keep: Vec<usize> = (0..s.len())
        .rev()
        .filter(|&i| s[i] > rel_tol * s_max)
        .take(max_size)
        .collect();
    let mut coef = Mat::<f64>::zeros(x.ncols(), keep.len());
    for (c, &i) in keep.iter().enumerate() {
        for r in 0..x.ncols() {
            coef[(r, c)] = u[(r, i)] / s[i].sqrt();
        }
    }
    let mut v = Mat::<f64>::zeros(x.nrows(), keep.len());
    matmul(v.as_mut(), false, x.as_ref(), coef.as_ref(), 1.0);
    Ok(v)
}

impl ReducedModes {
    /// The basis spanning the `modes_per_snapshot` lowest exact modes at every snapshot
    /// `(alpha, beta)`, compressed by a proper orthogonal decomposition in the energy
    /// norm. Snapshots are solved in parallel; the result does not depend on the
    /// number of threads.
    pub fn from_snapshots(
        model: &StructuralModel,
        snapshots: &[(Vec<f64>, Vec<f64>)],
        opts: &BasisOptions,
    ) -> Result<Self> {
        let (v, _) = pod_basis(model, snapshots, opts)?;
        Ok(Self::project_model(model, v))
    }

    /// [`Self::from_snapshots`] plus the `modes_per_snapshot` exact modes at `anchor`,
    /// kept whole (not subject to `max_size`): the basis is then exact at `anchor` (to
    /// rounding) and, by the Rayleigh-Ritz principle, its eigenvalue errors grow only
    /// quadratically with the distance from it. For a posterior, the anchor is its
    /// maximum-likelihood point (where the box's snapshots alone leave errors of about
    /// 1e-3).
    pub fn from_snapshots_anchored(
        model: &StructuralModel,
        anchor: &(Vec<f64>, Vec<f64>),
        snapshots: &[(Vec<f64>, Vec<f64>)],
        opts: &BasisOptions,
    ) -> Result<Self> {
        let (v, w) = pod_basis(model, snapshots, opts)?;
        let w = &w;
        let (a, b) = anchor;
        let exact =
            lowest_modes_condensed(&model.stiffness(a), &model.mass(b), opts.modes_per_snapshot)?;
        let n = model.n_dof();
        let x = Mat::from_fn(n, opts.modes_per_snapshot, |i, j| exact.shapes[(i, j)]);
        // the anchor's modes less their W-projection on V (V^T W V = I), then
        // W-orthonormalised by the eigen-decomposition of their Gram matrix
        let wf = Mat::from_fn(n, n, |i, j| w[(i, j)]);
        let mut wx = Mat::<f64>::zeros(n, x.ncols());
        matmul(wx.as_mut(), false, wf.as_ref(), x.as_ref(), 1.0);
        let mut c = Mat::<f64>::zeros(v.ncols(), x.ncols());
        matmul(c.as_mut(), false, v.transpose(), wx.as_ref(), 1.0);
        let mut r = x.clone();
        matmul(r.as_mut(), true, v.as_ref(), c.as_ref(), -1.0);
        let gram = project(&r, w);
        let (s, u) = symmetric_eigen(gram.as_ref())?;
        let gx = project(&x, w);
        let s_ref = (0..gx.ncols()).fold(0.0, |m: f64, i| m.max(gx[(i, i)]));
        let keep: Vec<usize> = (0..s.len()).filter(|&i| s[i] > 1e-14 * s_ref).collect();
        let mut coef = Mat::<f64>::zeros(r.ncols(), keep.len());
        for (col, &i) in keep.iter().enumerate() {
            for row in 0..r.ncols() {
                coef[(row, col)] = u[(row, i)] / s[i].sqrt();
            }
        }
        let mut extra = Mat::<f64>::zeros(n, keep.len());
        matmul(extra.as_mut(), false, r.as_ref(), coef.as_ref(), 1.0);
        let full = Mat::from_fn(n, v.ncols() + extra.ncols(), |i, j| {
            if j < v.ncols() {
                v[(i, j)]
            } else {
                extra[(i, j - v.ncols())]
            }
        });
        Ok(Self::project_model(model, full))
    }

    fn project_model(model: &StructuralModel, v: Mat<f64>) -> Self {
        let k0 = project(&v, &model.stiffness(&model.alpha_zero()));
        let m0 = project(&v, &model.mass(&model.beta_zero()));
        let k_r = model
            .stiffness_influence()
            .par_iter()
            .map(|k| project(&v, k))
            .collect();
        let m_r = model
            .mass_influence()
            .par_iter()
            .map(|m| project(&v, m))
            .collect();
        let basis = DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[(i, j)]);
        ReducedModes {
            basis,
            k0,
            k_r,
            m0,
            m_r,
        }
    }

    /// Number of basis vectors `b`.
    pub fn size(&self) -> usize {
        self.basis.ncols()
    }
}

/// Scratch memory of a [`ReducedModes`] evaluation.
pub struct ReducedWorkspace {
    k: Mat<f64>,
    c: Mat<f64>,
}

fn assemble(dst: &mut Mat<f64>, base: &Mat<f64>, terms: &[Mat<f64>], coef: &[f64]) {
    dst.copy_from(base);
    for (t, &a) in terms.iter().zip(coef) {
        if a != 0.0 {
            *dst += t * faer::Scale(a);
        }
    }
}

impl ModeSolver for ReducedModes {
    type Workspace = ReducedWorkspace;

    fn n_dof(&self) -> usize {
        self.basis.nrows()
    }

    fn workspace(&self) -> ReducedWorkspace {
        let b = self.size();
        ReducedWorkspace {
            k: Mat::zeros(b, b),
            c: Mat::zeros(b, b),
        }
    }

    fn lowest_modes(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut ReducedWorkspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
    ) -> Result<()> {
        let n_modes = eigenvalues.len();
        let (mu, z) = self.solve(alpha, beta, ws, n_modes)?;
        self.fill_modes(&mu, &z, dofs, eigenvalues, shapes, alpha)
    }

    /// Derivatives of the reduced eigenpairs (Nelson's problem in the reduced space,
    /// where every mode is available, so the modal expansion is exact): with `z_k`
    /// `A`-normalised eigenvectors of `B z = mu A z` (`A = V^T K V`, `B = V^T M V`) and
    /// `w = (B_j - mu_i A_j) z_i`, `d mu_i = z_i^T w` and
    /// `d z_i = sum_{k != i} z_k (z_k^T w) / (mu_i - mu_k) - z_i (z_i^T A_j z_i) / 2`;
    /// then `lambda = 1 / mu` and `phi = z / sqrt(mu)`.
    fn lowest_modes_with_derivatives(
        &self,
        alpha: &[f64],
        beta: &[f64],
        dofs: &[usize],
        ws: &mut ReducedWorkspace,
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
        d_eigenvalues: &mut [f64],
        d_shapes: &mut [f64],
    ) -> Result<bool> {
        let n_modes = eigenvalues.len();
        let b = self.size();
        let (mu, z) = self.solve(alpha, beta, ws, b)?;
        self.fill_modes(&mu, &z, dofs, eigenvalues, shapes, alpha)?;
        let n_var = self.k_r.len() + self.m_r.len();
        let (mut w, mut c, mut az) = (vec![0.0; b], vec![0.0; b], vec![0.0; b]);
        let mut dphi = vec![0.0; b];
        for i in 0..n_modes {
            let (m, zi) = (mu[i], z.col(i));
            for j in 0..n_var {
                let (a_j, b_j) = if j < self.k_r.len() {
                    (Some(&self.k_r[j]), None)
                } else {
                    (None, Some(&self.m_r[j - self.k_r.len()]))
                };
                for r in 0..b {
                    let row = |mat: &Mat<f64>| (0..b).map(|k| mat[(r, k)] * zi[k]).sum::<f64>();
                    az[r] = a_j.map_or(0.0, row);
                    w[r] = b_j.map_or(0.0, row) - m * az[r];
                }
                let dot = |x: &[f64], col: usize| (0..b).map(|r| x[r] * z[(r, col)]).sum::<f64>();
                let dmu = dot(&w, i);
                for k in 0..b {
                    c[k] = if k == i {
                        -0.5 * dot(&az, i)
                    } else {
                        dot(&w, k) / (m - mu[k])
                    };
                }
                for (r, d) in dphi.iter_mut().enumerate() {
                    let dz = (0..b).map(|k| z[(r, k)] * c[k]).sum::<f64>();
                    *d = dz / m.sqrt() - 0.5 * z[(r, i)] * dmu / (m * m.sqrt());
                }
                d_eigenvalues[i * n_var + j] = -dmu / (m * m);
                for (k, &d) in dofs.iter().enumerate() {
                    let row = self.basis.row(d);
                    d_shapes[(i * dofs.len() + k) * n_var + j] =
                        (0..b).map(|q| row[q] * dphi[q]).sum::<f64>();
                }
            }
        }
        Ok(true)
    }
}

impl ReducedModes {
    /// The `n` largest `mu = 1 / lambda` of the projected pencil, descending, and their
    /// `A`-normalised vectors `z` (columns).
    fn solve(
        &self,
        alpha: &[f64],
        beta: &[f64],
        ws: &mut ReducedWorkspace,
        n: usize,
    ) -> Result<(Vec<f64>, Mat<f64>)> {
        let b = self.size();
        if n > b {
            return Err(Error::Usage(format!(
                "{n} modes requested of a reduced basis of {b}"
            )));
        }
        assemble(&mut ws.k, &self.k0, &self.k_r, alpha);
        assemble(&mut ws.c, &self.m0, &self.m_r, beta);
        cholesky_in_place(&mut ws.k).ok_or_else(|| {
            Error::Model(format!(
                "K(alpha) is not positive definite at alpha {alpha:?}"
            ))
        })?;
        solve_lower(ws.k.as_ref(), ws.c.as_mut());
        let mut c = ws.c.transpose().to_owned();
        solve_lower(ws.k.as_ref(), c.as_mut());
        symmetrise(&mut c);
        let (mu, u) = symmetric_eigen(c.as_ref())?;
        let mut z = u.subcols(b - n, n).reverse_cols().to_owned();
        solve_lower_transpose(ws.k.as_ref(), z.as_mut());
        Ok(((0..n).map(|i| mu[b - 1 - i]).collect(), z))
    }

    /// Eigenvalues and mass-normalised shapes at `dofs` of the first
    /// `eigenvalues.len()` columns of [`Self::solve`].
    fn fill_modes(
        &self,
        mu: &[f64],
        z: &Mat<f64>,
        dofs: &[usize],
        eigenvalues: &mut [f64],
        shapes: &mut [f64],
        alpha: &[f64],
    ) -> Result<()> {
        let b = self.size();
        for i in 0..eigenvalues.len() {
            let m = mu[i];
            if m.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return Err(Error::Model(format!(
                    "mode {} has no mass in the reduced basis at alpha {alpha:?}",
                    i + 1
                )));
            }
            eigenvalues[i] = 1.0 / m;
            let scale = 1.0 / m.sqrt();
            for (s, &d) in shapes[i * dofs.len()..(i + 1) * dofs.len()]
                .iter_mut()
                .zip(dofs)
            {
                let row = self.basis.row(d);
                *s = scale * (0..b).map(|k| row[k] * z[(k, i)]).sum::<f64>();
            }
        }
        Ok(())
    }
}

/// The reduced basis against the exact solve at one point.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PointError {
    pub alpha: Vec<f64>,
    /// `lambda_reduced / lambda_exact - 1` of each mode (non-negative up to rounding).
    pub eigenvalue_rel: Vec<f64>,
    /// `1 - MAC` of each mode's shape at the compared DOFs.
    pub one_minus_mac: Vec<f64>,
}

/// Compares `reduced` with the exact condensed solve of `model` at each `alpha` (beta
/// nominal), for the lowest `n_modes` modes at `dofs`.
pub fn compare_with_full(
    model: &StructuralModel,
    reduced: &ReducedModes,
    alphas: &[Vec<f64>],
    n_modes: usize,
    dofs: &[usize],
) -> Result<Vec<PointError>> {
    alphas
        .par_iter()
        .map(|alpha| {
            let beta = model.beta_zero();
            let mut ev = vec![0.0; n_modes];
            let mut sh = vec![0.0; n_modes * dofs.len()];
            let mut ws = reduced.workspace();
            reduced.lowest_modes(alpha, &beta, dofs, &mut ws, &mut ev, &mut sh)?;
            let exact =
                lowest_modes_condensed(&model.stiffness(alpha), &model.mass(&beta), n_modes)?;
            let nd = dofs.len();
            let one_minus_mac = (0..n_modes)
                .map(|i| {
                    let e: Vec<f64> = dofs.iter().map(|&d| exact.shapes[(d, i)]).collect();
                    1.0 - crate::modal::mac(&e, &sh[i * nd..(i + 1) * nd])
                })
                .collect();
            Ok(PointError {
                alpha: alpha.clone(),
                eigenvalue_rel: (0..n_modes)
                    .map(|i| ev[i] / exact.eigenvalues[i] - 1.0)
                    .collect(),
                one_minus_mac,
            })
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod test_models {
    use crate::model::{Parameter, StructuralModel};
    use nalgebra::DMatrix;

    /// A chain with massless rotational DOFs between its masses: every second DOF has no
    /// mass; three stiffness groups.
    pub(crate) fn chain_model(n_mass: usize) -> StructuralModel {
        let n = 2 * n_mass;
        let mut groups = vec![DMatrix::zeros(n, n); 3];
        for i in 0..n - 1 {
            let g = &mut groups[i % 3];
            let s = 1000.0 * (1.0 + 0.05 * i as f64);
            g[(i, i)] += s;
            g[(i + 1, i + 1)] += s;
            g[(i, i + 1)] -= 0.6 * s;
            g[(i + 1, i)] -= 0.6 * s;
        }
        groups[0][(0, 0)] += 500.0;
        let k0 = groups.iter().fold(DMatrix::zeros(n, n), |a, g| a + g);
        let mut m0 = DMatrix::zeros(n, n);
        for i in (0..n).step_by(2) {
            m0[(i, i)] = 1.0 + 0.01 * i as f64;
        }
        let infl = groups
            .into_iter()
            .enumerate()
            .map(|(r, g)| {
                let p = Parameter {
                    name: format!("g{r}"),
                    unit: "-".into(),
                    nominal: None,
                };
                (p, g)
            })
            .collect();
        StructuralModel::from_matrices(k0, m0, infl, Vec::new(), None).unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::test_models::chain_model;

    /// Oracle: a basis holding the exact modes at a point reproduces them there to
    /// rounding; elsewhere its eigenvalues are upper bounds (Rayleigh-Ritz) and close.
    #[test]
    fn reduced_basis_is_exact_at_its_snapshots_and_bounds_elsewhere() {
        let model = chain_model(40);
        let snaps: Vec<(Vec<f64>, Vec<f64>)> =
            [[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [-0.3, 0.2, 0.5]]
                .iter()
                .map(|a| (a.to_vec(), Vec::new()))
                .collect();
        let opts = BasisOptions {
            modes_per_snapshot: 8,
            ..BasisOptions::default()
        };
        let red = ReducedModes::from_snapshots(&model, &snaps, &opts).unwrap();
        assert!(red.size() <= 24 && red.size() >= 8, "{}", red.size());
        let dofs: Vec<usize> = (0..80).step_by(4).collect();
        let at_snap = compare_with_full(&model, &red, &[snaps[1].0.clone()], 6, &dofs).unwrap();
        for (e, m) in at_snap[0]
            .eigenvalue_rel
            .iter()
            .zip(&at_snap[0].one_minus_mac)
        {
            assert!(e.abs() < 1e-10 && *m < 1e-10, "{e} {m}");
        }
        let other = compare_with_full(&model, &red, &[vec![0.1, 0.1, 0.3]], 6, &dofs).unwrap();
        for e in &other[0].eigenvalue_rel {
            assert!(*e > -1e-10 && *e < 1e-2, "{e}");
        }
        let condensed = CondensedModes::new(Arc::new(model));
        let (mut ev, mut sh) = (vec![0.0; 2], vec![0.0; 2 * dofs.len()]);
        condensed
            .lowest_modes(&[1.0; 3], &[], &dofs, &mut (), &mut ev, &mut sh)
            .unwrap();
        assert!(ev[0] > 0.0 && ev[0] < ev[1]);
    }
}
