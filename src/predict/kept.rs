//! A large model reduced onto a few of its physical DOFs plus generalised coordinates,
//! so that the dense forward models of small systems (the diagnosis's `D(s)` solve) run
//! on it and extensions still attach to physical DOFs.
//!
//! # The basis (Craig and Bampton 1968, with a Ritz interior)
//! With `k` the kept DOFs (sensors, impacts) and `i` the others, the reduction
//! `x = T q`, `T = [Psi  Q]`:
//! - `Psi` are the static constraint modes of the stiffness at the anchor,
//!   `K_a = K(alpha_a)`: a unit displacement of one kept DOF, the others held,
//!   `Psi_i = -K_a,ii^-1 K_a,ik`, `Psi_k = I`. They carry the static (residual)
//!   flexibility of the whole model at the kept DOFs exactly at the anchor. (Built from
//!   `K0` instead, they left 2.4e-3 of receptance error at a re-anchored point 0.15 from
//!   the nominal one on the bridge, against 1.2e-4 at the nominal anchor.)
//! - `Q` spans the model's lowest exact modes at the anchor (whole) and at snapshot
//!   points around it (their POD, as in [`super::reduced`]) less their static
//!   interpolation from the kept DOFs, `V - Psi V_k`: zero at every kept DOF, and
//!   `span T` contains `V`. `Q` is orthonormalised in the `K_a` norm, nearly dependent
//!   directions dropped.
//!
//! So the first `k` reduced coordinates *are* the kept DOFs' displacements (a force or a
//! sensor there maps one to one), and `K(alpha) = T^T K0 T + sum_r alpha_r T^T K_r T`
//! keeps paper Eq. (20)'s affine form (Eq. 21 for `M`). The basis is fixed: its error
//! grows away from the snapshots and is measured against the full solve
//! ([`compare_frf_with_full`]), never assumed.

use faer::Mat;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use rayon::prelude::*;

use super::reduced::{pod_basis, principal_directions, project, BasisOptions};
use crate::error::{Error, Result};
use crate::modal::condensed::lowest_modes_condensed;
use crate::modal::dense::{cholesky_in_place, matmul, solve_lower, solve_lower_transpose};
use crate::model::StructuralModel;

/// A model reduced onto kept physical DOFs (see the module docs).
#[derive(Debug, Clone)]
pub struct KeptDofModel {
    /// The reduced model: DOF `j < kept.len()` is the full model's DOF `kept[j]`, the
    /// rest generalised coordinates. Same groups and parameter names as the full one.
    pub model: StructuralModel,
    /// 0-based DOFs of the full model kept physical, ascending.
    pub kept: Vec<usize>,
    /// `T` (n x (kept + generalised)).
    pub basis: DMatrix<f64>,
}

impl KeptDofModel {
    /// Number of generalised (modal) coordinates.
    pub fn n_generalised(&self) -> usize {
        self.basis.ncols() - self.kept.len()
    }
}

fn to_nalgebra(a: &Mat<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)])
}

/// The static constraint modes `Psi` (n x k) of `k0` for the kept DOFs.
fn constraint_modes(k0: &DMatrix<f64>, kept: &[usize]) -> Result<Mat<f64>> {
    let n = k0.nrows();
    let interior: Vec<usize> = (0..n).filter(|d| kept.binary_search(d).is_err()).collect();
    let mut kii = Mat::from_fn(interior.len(), interior.len(), |i, j| {
        k0[(interior[i], interior[j])]
    });
    cholesky_in_place(&mut kii).ok_or_else(|| {
        Error::Model(format!(
            "K0 is not positive definite with the {} kept DOFs held; \
             the model cannot be reduced onto them",
            kept.len()
        ))
    })?;
    let mut x = Mat::from_fn(interior.len(), kept.len(), |i, j| {
        -k0[(interior[i], kept[j])]
    });
    solve_lower(kii.as_ref(), x.as_mut());
    solve_lower_transpose(kii.as_ref(), x.as_mut());
    let mut psi = Mat::<f64>::zeros(n, kept.len());
    for (j, _) in kept.iter().enumerate() {
        psi[(kept[j], j)] = 1.0;
    }
    for (r, &d) in interior.iter().enumerate() {
        for j in 0..kept.len() {
            psi[(d, j)] = x[(r, j)];
        }
    }
    Ok(psi)
}

/// `V - Psi V_k`, orthonormalised in the `K0` norm; directions whose Gram eigenvalue is
/// below `1e-10` of the largest are dropped.
fn interior_vectors(
    v: &Mat<f64>,
    psi: &Mat<f64>,
    kept: &[usize],
    k0: &DMatrix<f64>,
) -> Result<Mat<f64>> {
    let vk = Mat::from_fn(kept.len(), v.ncols(), |i, j| v[(kept[i], j)]);
    let mut r = v.clone();
    matmul(r.as_mut(), true, psi.as_ref(), vk.as_ref(), -1.0);
    principal_directions(&r, k0, 1e-10, usize::MAX)
}

/// Where a reduction's interior is exact: the point `(alpha, beta)` and how many of its
/// lowest modes are kept whole.
#[derive(Debug, Clone, PartialEq)]
pub struct BasisAnchor {
    pub alpha: Vec<f64>,
    pub beta: Vec<f64>,
    pub n_modes: usize,
}

/// `model` reduced onto the 0-based DOFs `kept` (see the module docs), its interior
/// spanning the `anchor.n_modes` lowest modes at the anchor exactly (the reduction is
/// exact there for those modes) and the POD of the `opts.modes_per_snapshot` lowest
/// modes of every snapshot `(alpha, beta)` (at most `opts.max_size` directions).
pub fn reduce_keeping(
    model: &StructuralModel,
    kept: &[usize],
    anchor: &BasisAnchor,
    snapshots: &[(Vec<f64>, Vec<f64>)],
    opts: &BasisOptions,
) -> Result<KeptDofModel> {
    let n = model.n_dof();
    let mut kept = kept.to_vec();
    kept.sort_unstable();
    kept.dedup();
    if kept.is_empty() || kept.iter().any(|&d| d >= n) {
        return Err(Error::Usage(format!(
            "a reduction keeps 1..{n} DOFs of the model (0-based below {n}); got {kept:?}"
        )));
    }
    let k0 = model.stiffness(&model.alpha_zero());
    // The static part at the anchor's stiffness: exact there, where the interior is.
    let k_anchor = model.stiffness(&anchor.alpha);
    let psi = constraint_modes(&k_anchor, &kept)?;
    let (pod, _) = pod_basis(model, snapshots, opts)?;
    // The anchor's modes whole, then the POD directions.
    let exact = lowest_modes_condensed(&k_anchor, &model.mass(&anchor.beta), anchor.n_modes)?;
    let p = exact.shapes.ncols();
    let v = Mat::from_fn(n, p + pod.ncols(), |i, j| {
        if j < p {
            exact.shapes[(i, j)]
        } else {
            pod[(i, j - p)]
        }
    });
    let q = interior_vectors(&v, &psi, &kept, &k_anchor)?;
    let b = kept.len() + q.ncols();
    let t = Mat::from_fn(n, b, |i, j| {
        if j < kept.len() {
            psi[(i, j)]
        } else {
            q[(i, j - kept.len())]
        }
    });
    let red = |a: &DMatrix<f64>| to_nalgebra(&project(&t, a));
    let m0 = model.mass(&model.beta_zero());
    let k_infl: Vec<_> = model.stiffness_influence().par_iter().map(&red).collect();
    let m_infl: Vec<_> = model.mass_influence().par_iter().map(&red).collect();
    let basis = to_nalgebra(&t);
    let m_red = red(&m0);
    // Ground load `-T^T M0 iota` kept exact: iota_r = (T^T M0 T)^-1 T^T M0 iota.
    let load = basis.transpose() * (&m0 * model.ground_influence());
    let iota = m_red
        .clone()
        .cholesky()
        .ok_or_else(|| Error::Model("the reduced mass matrix is not positive definite".into()))?
        .solve(&load);
    let reduced = StructuralModel::from_matrices(
        red(&k0),
        m_red,
        model
            .alpha_parameters()
            .iter()
            .cloned()
            .zip(k_infl)
            .collect(),
        model
            .beta_parameters()
            .iter()
            .cloned()
            .zip(m_infl)
            .collect(),
        Some(DVector::from_iterator(b, iota.iter().copied())),
    )?;
    let reduced = reduced.with_measured_dofs((0..kept.len()).collect())?;
    Ok(KeptDofModel {
        model: reduced,
        kept,
        basis,
    })
}

/// `H(omega)` at `dofs` (rows) for unit forces at `dofs` (columns) of the pencil with
/// Rayleigh damping `C = a0 M + a1 K`, by a dense complex solve.
pub fn receptance(
    k: &DMatrix<f64>,
    m: &DMatrix<f64>,
    rayleigh: (f64, f64),
    omega_rad_s: f64,
    dofs: &[usize],
) -> Result<DMatrix<Complex64>> {
    let s = Complex64::new(0.0, omega_rad_s);
    let d = DMatrix::from_fn(k.nrows(), k.ncols(), |i, j| {
        let c = rayleigh.0 * m[(i, j)] + rayleigh.1 * k[(i, j)];
        k[(i, j)] + s * c + s * s * m[(i, j)]
    });
    let mut rhs = DMatrix::<Complex64>::zeros(k.nrows(), dofs.len());
    for (j, &f) in dofs.iter().enumerate() {
        rhs[(f, j)] = Complex64::new(1.0, 0.0);
    }
    let x = d
        .lu()
        .solve(&rhs)
        .ok_or_else(|| Error::Numerical(format!("D(s) is singular at {omega_rad_s} rad/s")))?;
    Ok(DMatrix::from_fn(dofs.len(), dofs.len(), |i, j| {
        x[(dofs[i], j)]
    }))
}

/// The largest relative error `max |H_red - H_full| / max |H_full|` over the kept DOFs'
/// receptance matrix at each frequency, at `(alpha, beta)` with Rayleigh damping: the
/// reduced model against the full one by direct solves (the oracle of the reduction).
pub fn compare_frf_with_full(
    full: &StructuralModel,
    reduced: &KeptDofModel,
    alpha: &[f64],
    beta: &[f64],
    rayleigh: (f64, f64),
    freq_hz: &[f64],
) -> Result<Vec<f64>> {
    let (kf, mf) = (full.stiffness(alpha), full.mass(beta));
    let (kr, mr) = (reduced.model.stiffness(alpha), reduced.model.mass(beta));
    let local: Vec<usize> = (0..reduced.kept.len()).collect();
    freq_hz
        .par_iter()
        .map(|&f| {
            let w = 2.0 * std::f64::consts::PI * f;
            let hf = receptance(&kf, &mf, rayleigh, w, &reduced.kept)?;
            let hr = receptance(&kr, &mr, rayleigh, w, &local)?;
            let scale = hf.iter().map(|z| z.norm()).fold(0.0, f64::max);
            let err = (&hr - &hf).iter().map(|z| z.norm()).fold(0.0, f64::max);
            Ok(err / scale)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predict::reduced::test_models::chain_model;

    fn snapshots(model: &StructuralModel) -> Vec<(Vec<f64>, Vec<f64>)> {
        let mut s = vec![(model.alpha_zero(), model.beta_zero())];
        for j in 0..model.n_alpha() {
            for v in [-0.3, 0.3] {
                let mut a = model.alpha_zero();
                a[j] = v;
                s.push((a, model.beta_zero()));
            }
        }
        s
    }

    /// Oracle: kept DOFs map one to one, and with the anchor's modes in the basis the
    /// reduced model's lowest eigenvalues at the anchor are the full model's (the
    /// Rayleigh-Ritz projection of a space that contains them), away from it upper
    /// bounds.
    #[test]
    fn anchor_modes_are_exact_and_kept_dofs_physical() {
        let model = chain_model(8);
        let opts = BasisOptions {
            modes_per_snapshot: 2,
            max_size: 1,
            ..Default::default()
        };
        let kept = [0, 6, 14];
        let alpha = vec![0.2, -0.25, 0.1];
        let anchor = BasisAnchor {
            alpha: alpha.clone(),
            beta: model.beta_zero(),
            n_modes: 4,
        };
        let red = reduce_keeping(&model, &kept, &anchor, &snapshots(&model), &opts).unwrap();
        assert_eq!(red.kept, kept);
        for (j, &d) in kept.iter().enumerate() {
            for c in 0..red.basis.ncols() {
                let want = if c == j { 1.0 } else { 0.0 };
                assert!((red.basis[(d, c)] - want).abs() < 1e-12);
            }
        }
        let eig = |m: &StructuralModel, a: &[f64]| {
            lowest_modes_condensed(&m.stiffness(a), &m.mass(&m.beta_zero()), 4)
                .unwrap()
                .eigenvalues
        };
        for (r, e) in eig(&red.model, &alpha).iter().zip(eig(&model, &alpha)) {
            assert!((r / e - 1.0).abs() < 1e-10, "{r} {e}");
        }
        let other = vec![-0.2, 0.3, 0.0];
        for (r, e) in eig(&red.model, &other).iter().zip(eig(&model, &other)) {
            assert!(r / e - 1.0 > -1e-10, "{r} {e}");
        }
    }

    /// With only the lowest modes in the interior, the static constraint modes keep the
    /// kept DOFs' low-frequency response close: the error at the nominal point is small
    /// below the first omitted mode, and grows above it.
    #[test]
    fn truncated_interior_is_accurate_below_its_modes() {
        let model = chain_model(12);
        let opts = BasisOptions {
            modes_per_snapshot: 4,
            ..Default::default()
        };
        let anchor = BasisAnchor {
            alpha: model.alpha_zero(),
            beta: model.beta_zero(),
            n_modes: 4,
        };
        let snaps = [(model.alpha_zero(), model.beta_zero())];
        let red = reduce_keeping(&model, &[2, 22], &anchor, &snaps, &opts).unwrap();
        assert_eq!(red.n_generalised(), 4);
        let exact = crate::modal::condensed::lowest_modes_condensed(
            &model.stiffness(&model.alpha_zero()),
            &model.mass(&model.beta_zero()),
            6,
        )
        .unwrap();
        let f4 = exact.eigenvalues[3].sqrt() / (2.0 * std::f64::consts::PI);
        let low: Vec<f64> = (1..10).map(|i| f4 * i as f64 / 10.0).collect();
        let a0 = model.alpha_zero();
        let err = compare_frf_with_full(&model, &red, &a0, &[], (0.3, 1e-4), &low).unwrap();
        let worst = err.iter().copied().fold(0.0, f64::max);
        assert!(worst < 1e-2, "{worst:e}"); // 5.4e-3 measured
    }
}
