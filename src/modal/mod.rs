//! Modal analysis: the generalised symmetric eigenproblem `K phi = omega^2 M phi`
//! (paper Eq. 22b), mass-normalised modes (`Phi^T M Phi = I`), ascending order, and the
//! modal assurance criterion.

pub mod condensed;
pub mod dense;
pub mod partial;
mod tridiagonal;

pub use partial::{PartialEigen, PartialOptions, PartialSolver, PartialWorkspace};

use crate::error::{Error, Result};
use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DVector, DefaultAllocator, DimDiff, DimSub, OMatrix, OVector, U1};

/// Undamped modes of a model, ascending in frequency, mass-normalised.
#[derive(Debug, Clone)]
pub struct Modes {
    /// Natural frequencies `omega_n,i` in rad/s.
    pub omega_rad_s: Vec<f64>,
    /// Mode shapes as columns (n_dof x n_modes); `Phi^T M Phi = I`. Each mode's
    /// largest-magnitude entry is positive, so signs are reproducible.
    pub phi: DMatrix<f64>,
    /// Ground-excitation participation `Gamma_i = phi_i^T M iota` (Eq. 15:
    /// `sum_e m_e phi_e,i` for a lumped-mass shear frame).
    pub participation: Vec<f64>,
}

impl Modes {
    /// Solves `K phi = omega^2 M phi` and keeps the first `n_modes` modes (all when `None`).
    /// `ground_influence` is the rigid-body vector `iota` of ground motion.
    ///
    /// `M = L L^T` (Cholesky), `A = L^-1 K L^-T` is symmetric with eigenpairs
    /// `(omega^2, v)`, and `phi = L^-T v`. Models of up to six DOFs (the paper's frame has
    /// four) use nalgebra's stack-allocated matrices, the same algorithm without heap
    /// allocation in the decomposition (the sampler solves this once per likelihood
    /// evaluation); larger ones use dynamic matrices. When, in addition, `M` is diagonal
    /// and `K` tridiagonal (a shear frame), `L = M^1/2` and `A` is tridiagonal, and a
    /// symmetric tridiagonal QL solver takes the place of the general one (several
    /// times faster; the same eigenpairs to rounding).
    pub fn solve(
        k: &DMatrix<f64>,
        m: &DMatrix<f64>,
        ground_influence: &DVector<f64>,
        n_modes: Option<usize>,
    ) -> Result<Self> {
        let mut modes = Modes {
            omega_rad_s: Vec::new(),
            phi: DMatrix::zeros(0, 0),
            participation: Vec::new(),
        };
        modes.solve_into(k, m, ground_influence, n_modes)?;
        Ok(modes)
    }

    /// [`Self::solve`] into `self`, reusing its memory: for models of up to six DOFs
    /// nothing is allocated once `self` has the right shape (the likelihood's inner
    /// loop). The results are those of [`Self::solve`], bit for bit. On error `self` is
    /// left in an unspecified (but valid) state.
    pub fn solve_into(
        &mut self,
        k: &DMatrix<f64>,
        m: &DMatrix<f64>,
        ground_influence: &DVector<f64>,
        n_modes: Option<usize>,
    ) -> Result<()> {
        let n = k.nrows();
        let n_modes = n_modes.unwrap_or(n).min(n);
        macro_rules! fixed {
            ($n:literal) => {{
                if let Some((eigenvalues, shapes)) = shear_frame_eigen::<$n>(k, m) {
                    return self.assemble(
                        &eigenvalues,
                        |r, i| shapes[i][r],
                        m,
                        ground_influence,
                        n_modes,
                    );
                }
                type Sq = nalgebra::SMatrix<f64, $n, $n>;
                let (eigenvalues, shapes) = generalised_eigen(
                    Sq::from_fn(|i, j| k[(i, j)]),
                    Sq::from_fn(|i, j| m[(i, j)]),
                )?;
                self.assemble(
                    eigenvalues.as_slice(),
                    |r, i| shapes[(r, i)],
                    m,
                    ground_influence,
                    n_modes,
                )
            }};
        }
        match n {
            1 => fixed!(1),
            2 => fixed!(2),
            3 => fixed!(3),
            4 => fixed!(4),
            5 => fixed!(5),
            6 => fixed!(6),
            _ => {
                let (eigenvalues, shapes) = generalised_eigen(k.clone(), m.clone())?;
                self.assemble(
                    eigenvalues.as_slice(),
                    |r, i| shapes[(r, i)],
                    m,
                    ground_influence,
                    n_modes,
                )
            }
        }
    }

    /// Orders the eigenpairs ascending, keeps `n_modes`, fixes each shape's sign (largest
    /// entry positive) and computes the participation factors (Eq. 15) into `self`.
    /// `shape(r, i)` is entry `r` (of `m.nrows()`) of eigenvector `i`.
    fn assemble(
        &mut self,
        eigenvalues: &[f64],
        shape: impl Fn(usize, usize) -> f64,
        m: &DMatrix<f64>,
        ground_influence: &DVector<f64>,
        n_modes: usize,
    ) -> Result<()> {
        const STACK: usize = 8;
        // shapes have `n` rows (every DOF); a condensed pencil has fewer eigenvalues
        let (n, n_ev) = (m.nrows(), eigenvalues.len());
        // Ascending order by a stable insertion sort (ties keep their index order).
        let mut order_stack = [0usize; STACK];
        let mut order_heap = Vec::new();
        let order: &mut [usize] = if n_ev <= STACK {
            &mut order_stack[..n_ev]
        } else {
            order_heap.resize(n_ev, 0);
            &mut order_heap
        };
        for i in 0..n_ev {
            let mut j = i;
            while j > 0 && eigenvalues[order[j - 1]].total_cmp(&eigenvalues[i]).is_gt() {
                order[j] = order[j - 1];
                j -= 1;
            }
            order[j] = i;
        }
        if self.phi.nrows() != n || self.phi.ncols() != n_modes {
            self.phi = DMatrix::zeros(n, n_modes);
        }
        self.omega_rad_s.clear();
        for (col, &i) in order.iter().take(n_modes).enumerate() {
            let lam = eigenvalues[i];
            if !lam.is_finite() {
                return Err(Error::Numerical("non-finite eigenvalue".into()));
            }
            self.omega_rad_s.push(lam.max(0.0).sqrt());
            let imax = (0..n)
                .max_by(|&a, &b| {
                    shape(a, i)
                        .abs()
                        .total_cmp(&shape(b, i).abs())
                        .then(b.cmp(&a))
                })
                .unwrap_or(0);
            let sign = if shape(imax, i) < 0.0 { -1.0 } else { 1.0 };
            for r in 0..n {
                self.phi[(r, col)] = shape(r, i) * sign;
            }
        }
        // `M iota`, summed column by column as nalgebra's matrix-vector product does.
        let m_iota = |r: usize| {
            let mut acc = m[(r, 0)] * ground_influence[0];
            for j in 1..n {
                acc += m[(r, j)] * ground_influence[j];
            }
            acc
        };
        let mut m_iota_stack = [0.0; STACK];
        let m_iota_heap: Vec<f64>;
        let m_iota: &[f64] = if n <= STACK {
            for (r, x) in m_iota_stack[..n].iter_mut().enumerate() {
                *x = m_iota(r);
            }
            &m_iota_stack[..n]
        } else {
            m_iota_heap = (0..n).map(m_iota).collect();
            &m_iota_heap
        };
        let m_iota = nalgebra::DVectorView::from_slice(m_iota, n);
        self.participation.clear();
        for i in 0..n_modes {
            self.participation.push(self.phi.column(i).dot(&m_iota));
        }
        Ok(())
    }

    /// The modes of a pencil with massless DOFs (zero rows of `m`): every finite mode by
    /// static condensation ([`condensed::lowest_modes_condensed`]), in the form of
    /// [`Self::solve`] (ascending, mass-normalised, largest entry positive,
    /// participation `phi_i^T M iota`). When `m` has no zero row this is [`Self::solve`].
    pub fn solve_condensed(
        k: &DMatrix<f64>,
        m: &DMatrix<f64>,
        ground_influence: &DVector<f64>,
    ) -> Result<Self> {
        let n_massless = crate::model::condense::massless_dofs(m).len();
        if n_massless == 0 {
            return Self::solve(k, m, ground_influence, None);
        }
        let full = condensed::lowest_modes_condensed(k, m, k.nrows() - n_massless)?;
        let mut modes = Modes {
            omega_rad_s: Vec::new(),
            phi: DMatrix::zeros(0, 0),
            participation: Vec::new(),
        };
        let n = full.eigenvalues.len();
        let shapes = &full.shapes;
        modes.assemble(
            &full.eigenvalues,
            |r, i| shapes[(r, i)],
            m,
            ground_influence,
            n,
        )?;
        Ok(modes)
    }

    /// Number of retained modes.
    pub fn n_modes(&self) -> usize {
        self.omega_rad_s.len()
    }

    /// Natural frequencies in Hz.
    pub fn freq_hz(&self) -> Vec<f64> {
        self.omega_rad_s
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect()
    }
}

/// Eigenvalues `omega^2` (unordered) and `M`-orthonormal shapes (`shapes[i]`, from the
/// eigenvectors `v_i` of `A = M^-1/2 K M^-1/2`: `phi_i = M^-1/2 v_i`) when `M` is
/// diagonal with positive entries and `K` is tridiagonal and symmetric; `None`
/// otherwise, or when the tridiagonal solver fails (the general path then decides).
type TridiagonalPairs<const N: usize> = ([f64; N], [[f64; N]; N]);

fn shear_frame_eigen<const N: usize>(
    k: &DMatrix<f64>,
    m: &DMatrix<f64>,
) -> Option<TridiagonalPairs<N>> {
    for i in 0..N {
        for j in 0..N {
            let tridiagonal = i.abs_diff(j) <= 1;
            if (i != j && m[(i, j)] != 0.0) || (!tridiagonal && k[(i, j)] != 0.0) {
                return None;
            }
        }
        if i + 1 < N && k[(i, i + 1)] != k[(i + 1, i)] {
            return None;
        }
        if m[(i, i)].is_nan() || m[(i, i)] <= 0.0 {
            return None;
        }
    }
    let scale: [f64; N] = std::array::from_fn(|i| m[(i, i)].sqrt());
    let diag = std::array::from_fn(|i| k[(i, i)] / m[(i, i)]);
    let off = std::array::from_fn(|i| {
        if i + 1 < N {
            k[(i, i + 1)] / (scale[i] * scale[i + 1])
        } else {
            0.0
        }
    });
    let (values, vectors) = tridiagonal::symmetric_tridiagonal_eigen(diag, off)?;
    let shapes = vectors.map(|v| std::array::from_fn(|r| v[r] / scale[r]));
    Some((values, shapes))
}

/// Eigenvalues (unordered) and eigenvectors (columns) of a `D x D` problem.
type EigenPairs<D> = (OVector<f64, D>, OMatrix<f64, D, D>);

/// Eigenvalues `omega^2` (unordered) and `M`-orthonormal shapes (columns) of
/// `K phi = omega^2 M phi`, for static or dynamic square matrices.
fn generalised_eigen<D>(k: OMatrix<f64, D, D>, m: OMatrix<f64, D, D>) -> Result<EigenPairs<D>>
where
    D: DimSub<U1>,
    DefaultAllocator:
        Allocator<D, D> + Allocator<D> + Allocator<DimDiff<D, U1>> + Allocator<D, DimDiff<D, U1>>,
{
    let singular = || Error::Numerical("singular Cholesky factor".into());
    let chol = m
        .cholesky()
        .ok_or_else(|| Error::Numerical("mass matrix is not positive definite".into()))?;
    let l = chol.l();
    let y = l.solve_lower_triangular(&k).ok_or_else(singular)?;
    let a = l
        .solve_lower_triangular(&y.transpose())
        .ok_or_else(singular)?;
    let a = (&a + a.transpose()) * 0.5;
    let eig = a.symmetric_eigen();
    let shapes = l
        .transpose()
        .solve_upper_triangular(&eig.eigenvectors)
        .ok_or_else(singular)?;
    Ok((eig.eigenvalues, shapes))
}

/// Modal assurance criterion between two real shapes: `(a.b)^2 / ((a.a)(b.b))`.
pub fn mac(a: &[f64], b: &[f64]) -> f64 {
    let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
    let den = dot(a, a) * dot(b, b);
    if den == 0.0 {
        0.0
    } else {
        dot(a, b).powi(2) / den
    }
}

/// MAC matrix between the columns of two shape matrices (rows: DOFs).
pub fn mac_matrix(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(a.ncols(), b.ncols(), |i, j| {
        mac(a.column(i).as_slice(), b.column(j).as_slice())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::StructuralModel;

    #[test]
    fn two_dof_closed_form_and_normalisation() {
        // m = 1, k = 1 chain: omega^2 = (3 -+ sqrt 5)/2.
        let model = StructuralModel::shear_frame(&[1.0, 1.0], &[1.0, 1.0]).unwrap();
        let (k, m) = (model.stiffness(&[0.0, 0.0]), model.mass(&[0.0, 0.0]));
        let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
        let w2: Vec<f64> = modes.omega_rad_s.iter().map(|w| w * w).collect();
        assert!((w2[0] - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-12);
        assert!((w2[1] - (3.0 + 5f64.sqrt()) / 2.0).abs() < 1e-12);
        let ptmp = modes.phi.transpose() * &m * &modes.phi;
        assert!((ptmp - DMatrix::identity(2, 2)).amax() < 1e-12);
        let ptkp = modes.phi.transpose() * &k * &modes.phi;
        assert!((ptkp - DMatrix::from_diagonal(&DVector::from_vec(w2))).amax() < 1e-12);
        assert!(
            (mac(
                modes.phi.column(0).as_slice(),
                modes.phi.column(0).as_slice()
            ) - 1.0)
                .abs()
                < 1e-14
        );
        assert!(
            mac(
                modes.phi.column(0).as_slice(),
                modes.phi.column(1).as_slice()
            ) < 1.0
        );
        let trunc = Modes::solve(&k, &m, model.ground_influence(), Some(1)).unwrap();
        assert_eq!(trunc.n_modes(), 1);
        assert_eq!(trunc.phi.ncols(), 1);
    }

    #[test]
    fn fixed_size_path_equals_the_dynamic_one() {
        // Non-diagonal SPD mass and stiffness (B B^T + n I), 2 to 7 DOFs: sizes 2-6 take
        // the stack-allocated path, 7 the dynamic one; both must agree with the dynamic
        // decomposition and satisfy the eigen equations.
        for n in 2..=7 {
            let spd = |seed: f64| {
                let b = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) as f64 + seed).sin());
                &b * b.transpose() + DMatrix::identity(n, n) * n as f64
            };
            let (k, m) = (spd(0.3) * 1000.0, spd(1.7));
            let iota = DVector::from_element(n, 1.0);
            let modes = Modes::solve(&k, &m, &iota, None).unwrap();
            let (values, shapes) = generalised_eigen(k.clone(), m.clone()).unwrap();
            let mut dynamic = Modes::solve(&k, &m, &iota, Some(0)).unwrap();
            dynamic
                .assemble(values.as_slice(), |r, i| shapes[(r, i)], &m, &iota, n)
                .unwrap();
            for i in 0..n {
                let (a, b) = (modes.omega_rad_s[i], dynamic.omega_rad_s[i]);
                assert!((a - b).abs() <= 1e-12 * b, "n {n} mode {i}: {a} vs {b}");
                let phi = modes.phi.column(i);
                let resid = &k * phi - &m * phi * (a * a);
                assert!(resid.amax() <= 1e-9 * (&k * phi).amax(), "n {n} mode {i}");
            }
            assert!((&modes.phi - &dynamic.phi).amax() < 1e-10, "n {n}");
            let ptmp = modes.phi.transpose() * &m * &modes.phi;
            assert!((ptmp - DMatrix::identity(n, n)).amax() < 1e-12, "n {n}");
        }
    }

    #[test]
    fn shear_frame_tridiagonal_path_equals_the_general_one() {
        // Shear frames of 1 to 6 DOFs (masses and stiffnesses over two decades) take the
        // tridiagonal path; nalgebra's general decomposition of the same matrices is the
        // oracle: same frequencies and shapes to rounding, eigen equations satisfied.
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        for n in 1..=6 {
            for _ in 0..50 {
                let masses: Vec<f64> = (0..n).map(|_| rng.random_range(0.5..50.0)).collect();
                let stiff: Vec<f64> = (0..n).map(|_| rng.random_range(1e2..1e4)).collect();
                let model = StructuralModel::shear_frame(&masses, &stiff).unwrap();
                let (k, m) = (model.stiffness(&vec![0.0; n]), model.mass(&vec![0.0; n]));
                let iota = model.ground_influence();
                assert!(match n {
                    1 => shear_frame_eigen::<1>(&k, &m).is_some(),
                    2 => shear_frame_eigen::<2>(&k, &m).is_some(),
                    3 => shear_frame_eigen::<3>(&k, &m).is_some(),
                    4 => shear_frame_eigen::<4>(&k, &m).is_some(),
                    5 => shear_frame_eigen::<5>(&k, &m).is_some(),
                    _ => shear_frame_eigen::<6>(&k, &m).is_some(),
                });
                let modes = Modes::solve(&k, &m, iota, None).unwrap();
                let (values, shapes) = generalised_eigen(k.clone(), m.clone()).unwrap();
                let mut general = Modes::solve(&k, &m, iota, Some(0)).unwrap();
                general
                    .assemble(values.as_slice(), |r, i| shapes[(r, i)], &m, iota, n)
                    .unwrap();
                let top = general.omega_rad_s[n - 1];
                for i in 0..n {
                    let (a, b) = (modes.omega_rad_s[i], general.omega_rad_s[i]);
                    assert!((a - b).abs() <= 1e-12 * top, "n {n} mode {i}: {a} vs {b}");
                    let phi = modes.phi.column(i);
                    let resid = &k * phi - &m * phi * (a * a);
                    assert!(resid.amax() <= 1e-10 * (&k * phi).amax(), "n {n} mode {i}");
                }
                assert!((&modes.phi - &general.phi).amax() < 1e-8, "n {n}");
                let ptmp = modes.phi.transpose() * &m * &modes.phi;
                assert!((ptmp - DMatrix::identity(n, n)).amax() < 1e-12, "n {n}");
                for (a, b) in modes.participation.iter().zip(&general.participation) {
                    assert!((a - b).abs() <= 1e-8 * b.abs().max(1.0), "n {n}");
                }
            }
        }
    }

    #[test]
    fn solve_into_reuses_memory_and_equals_solve() {
        // One `Modes` reused across sizes and truncations gives the bits of a fresh solve.
        let mut reused = Modes::solve(
            &DMatrix::identity(3, 3),
            &DMatrix::identity(3, 3),
            &DVector::from_element(3, 1.0),
            None,
        )
        .unwrap();
        for (n, keep) in [(4, None), (2, Some(1)), (7, Some(5)), (4, Some(3))] {
            let masses: Vec<f64> = (0..n).map(|i| 1.0 + 0.3 * i as f64).collect();
            let stiff: Vec<f64> = (0..n).map(|i| 900.0 - 50.0 * i as f64).collect();
            let model = StructuralModel::shear_frame(&masses, &stiff).unwrap();
            let (k, m) = (model.stiffness(&vec![0.1; n]), model.mass(&vec![-0.05; n]));
            let fresh = Modes::solve(&k, &m, model.ground_influence(), keep).unwrap();
            reused
                .solve_into(&k, &m, model.ground_influence(), keep)
                .unwrap();
            assert_eq!(reused.omega_rad_s, fresh.omega_rad_s, "n {n}");
            assert_eq!(reused.phi, fresh.phi, "n {n}");
            assert_eq!(reused.participation, fresh.participation, "n {n}");
        }
    }
}
