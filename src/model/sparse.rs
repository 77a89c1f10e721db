//! Sparse matrices of the model layer: triplets as read from files, and the sparse
//! pencil `(K(alpha), M(beta))` of a [`StructuralModel`] (paper Eqs. 20-21) on fixed
//! compressed-column patterns, so that every evaluation is a linear combination of value
//! arrays and a sparse factorisation can reuse one symbolic analysis.

use super::StructuralModel;
use nalgebra::DMatrix;

/// The entries `(row, col, value)` (0-based) of a `rows x cols` matrix; repeated
/// positions add up, as in Matrix Market and MATLAB's `sparse`.
#[derive(Debug, Clone, PartialEq)]
pub struct Triplets {
    pub rows: usize,
    pub cols: usize,
    pub entries: Vec<(usize, usize, f64)>,
}

impl Triplets {
    /// The dense matrix.
    pub fn to_dense(&self) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(self.rows, self.cols);
        for &(i, j, v) in &self.entries {
            m[(i, j)] += v;
        }
        m
    }
}

/// A square compressed-sparse-column pattern (0-based): the rows of column `j` are
/// `row_idx[col_ptr[j]..col_ptr[j + 1]]`, strictly ascending. Values live in separate
/// arrays of length [`CscPattern::nnz`], one per matrix on the pattern.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CscPattern {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
}

impl CscPattern {
    /// The union of the non-zero (exactly: `!= 0.0`) entries of square matrices of size
    /// `n`.
    pub fn union_of_dense(n: usize, mats: &[&DMatrix<f64>]) -> Self {
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for j in 0..n {
            for i in 0..n {
                if mats.iter().any(|m| m[(i, j)] != 0.0) {
                    row_idx.push(i);
                }
            }
            col_ptr.push(row_idx.len());
        }
        CscPattern {
            n,
            col_ptr,
            row_idx,
        }
    }

    /// Rows (= columns).
    pub fn n(&self) -> usize {
        self.n
    }
    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }
    /// Column pointers (`n + 1` entries).
    pub fn col_ptr(&self) -> &[usize] {
        &self.col_ptr
    }
    /// Row index of each stored entry.
    pub fn row_idx(&self) -> &[usize] {
        &self.row_idx
    }

    /// Index of entry `(i, j)` in the value arrays, `None` when it is not stored.
    pub fn position(&self, i: usize, j: usize) -> Option<usize> {
        let (a, b) = (self.col_ptr[j], self.col_ptr[j + 1]);
        self.row_idx[a..b].binary_search(&i).ok().map(|k| a + k)
    }

    /// The values of `m` at the stored entries that are non-zero in `m`: `(positions,
    /// values)`. Panics if `m` has a non-zero outside the pattern (a bug of the caller).
    fn values_of(&self, m: &DMatrix<f64>) -> PatternValues {
        let mut v = PatternValues::default();
        for j in 0..self.n {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let x = m[(self.row_idx[p], j)];
                if x != 0.0 {
                    v.pos.push(p);
                    v.val.push(x);
                }
            }
        }
        v
    }

    /// `y += A x` for the matrix with `values` on this pattern.
    pub fn mul_add(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        for (j, &xj) in x.iter().enumerate().take(self.n) {
            if xj == 0.0 {
                continue;
            }
            let range = self.col_ptr[j]..self.col_ptr[j + 1];
            for (&i, &a) in self.row_idx[range.clone()].iter().zip(&values[range]) {
                y[i] += a * xj;
            }
        }
    }

    /// `y = A x` for the matrix with `values` on this pattern.
    pub fn mul(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        self.mul_add(values, x, y);
    }

    /// The dense matrix with `values` on this pattern.
    pub fn to_dense(&self, values: &[f64]) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(self.n, self.n);
        for j in 0..self.n {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                m[(self.row_idx[p], j)] = values[p];
            }
        }
        m
    }
}

/// One constant matrix stored by its non-zeros on a shared pattern: entry `pos[k]` of the
/// pattern's value array has value `val[k]`; the others are zero.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PatternValues {
    pub pos: Vec<usize>,
    pub val: Vec<f64>,
}

impl PatternValues {
    /// `out[pos] += factor * val`.
    fn add_scaled(&self, factor: f64, out: &mut [f64]) {
        if factor == 0.0 {
            return;
        }
        for (&p, &v) in self.pos.iter().zip(&self.val) {
            out[p] += factor * v;
        }
    }
}

/// The pencil `K(alpha) = K0 + sum_r alpha_r K0_r` (Eq. 20), `M(beta) = M0 + sum_r beta_r
/// M0_r` (Eq. 21) of a [`StructuralModel`] in sparse form.
///
/// `K` lives on the union pattern of `K0`, every `K0_r`, `M0` and every `M0_r` (so that
/// `K - sigma M` of a shift-invert eigen-solver has the same pattern for every
/// evaluation); `M` lives on the (usually much smaller: diagonal for lumped masses)
/// union pattern of `M0` and the `M0_r`. Both patterns are full (both triangles).
/// Each constant matrix keeps only its own exact non-zeros, so assembling `K(alpha)`
/// costs `nnz(K0) + sum_r nnz(K0_r)` multiply-adds.
#[derive(Debug, Clone)]
pub struct SparsePencil {
    stiffness_pattern: CscPattern,
    mass_pattern: CscPattern,
    /// Position in the stiffness pattern of each mass-pattern entry.
    mass_in_stiffness: Vec<usize>,
    k0: PatternValues,
    k_influence: Vec<PatternValues>,
    m0: PatternValues,
    m_influence: Vec<PatternValues>,
}

impl SparsePencil {
    /// The sparse pencil of `model`, dropping its exact zeros.
    pub fn from_model(model: &StructuralModel) -> Self {
        let n = model.n_dof();
        let masses: Vec<&DMatrix<f64>> = std::iter::once(&model.m0)
            .chain(model.m_influence.iter())
            .collect();
        let all: Vec<&DMatrix<f64>> = std::iter::once(&model.k0)
            .chain(model.k_influence.iter())
            .chain(masses.iter().copied())
            .collect();
        let stiffness_pattern = CscPattern::union_of_dense(n, &all);
        let mass_pattern = CscPattern::union_of_dense(n, &masses);
        let mass_in_stiffness = (0..n)
            .flat_map(|j| {
                let mp = &mass_pattern;
                (mp.col_ptr[j]..mp.col_ptr[j + 1]).map(move |p| (mp.row_idx[p], j))
            })
            .map(|(i, j)| {
                stiffness_pattern
                    .position(i, j)
                    .expect("the stiffness pattern contains the mass pattern")
            })
            .collect();
        SparsePencil {
            k0: stiffness_pattern.values_of(&model.k0),
            k_influence: model
                .k_influence
                .iter()
                .map(|m| stiffness_pattern.values_of(m))
                .collect(),
            m0: mass_pattern.values_of(&model.m0),
            m_influence: model
                .m_influence
                .iter()
                .map(|m| mass_pattern.values_of(m))
                .collect(),
            stiffness_pattern,
            mass_pattern,
            mass_in_stiffness,
        }
    }

    /// Number of degrees of freedom.
    pub fn n_dof(&self) -> usize {
        self.stiffness_pattern.n
    }
    /// Number of stiffness multipliers alpha.
    pub fn n_alpha(&self) -> usize {
        self.k_influence.len()
    }
    /// Number of mass multipliers beta.
    pub fn n_beta(&self) -> usize {
        self.m_influence.len()
    }
    /// Pattern of `K` (and of `K - sigma M`).
    pub fn stiffness_pattern(&self) -> &CscPattern {
        &self.stiffness_pattern
    }
    /// Pattern of `M`.
    pub fn mass_pattern(&self) -> &CscPattern {
        &self.mass_pattern
    }

    /// The values of `K(alpha)` (Eq. 20) on [`Self::stiffness_pattern`] into `out`
    /// (resized). Extra or missing alphas count as zero.
    pub fn stiffness_values(&self, alpha: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.stiffness_pattern.nnz(), 0.0);
        self.k0.add_scaled(1.0, out);
        for (a, kr) in alpha.iter().zip(&self.k_influence) {
            kr.add_scaled(*a, out);
        }
    }

    /// The values of `M(beta)` (Eq. 21) on [`Self::mass_pattern`] into `out` (resized).
    /// Extra or missing betas count as zero.
    pub fn mass_values(&self, beta: &[f64], out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.mass_pattern.nnz(), 0.0);
        self.m0.add_scaled(1.0, out);
        for (b, mr) in beta.iter().zip(&self.m_influence) {
            mr.add_scaled(*b, out);
        }
    }

    /// `K - sigma M` on the stiffness pattern into `out` (resized), from the values of
    /// [`Self::stiffness_values`] and [`Self::mass_values`].
    pub fn shifted_values(&self, k: &[f64], m: &[f64], sigma: f64, out: &mut Vec<f64>) {
        out.clear();
        out.extend_from_slice(k);
        for (&p, &v) in self.mass_in_stiffness.iter().zip(m) {
            out[p] -= sigma * v;
        }
    }

    /// The diagonal of the matrix with `values` on the mass pattern (`M_ii`), into `out`.
    pub fn mass_diagonal(&self, m: &[f64], out: &mut Vec<f64>) {
        diagonal(&self.mass_pattern, m, out);
    }

    /// The diagonal of the matrix with `values` on the stiffness pattern (`K_ii`).
    pub fn stiffness_diagonal(&self, k: &[f64], out: &mut Vec<f64>) {
        diagonal(&self.stiffness_pattern, k, out);
    }
}

fn diagonal(pattern: &CscPattern, values: &[f64], out: &mut Vec<f64>) {
    out.clear();
    out.extend((0..pattern.n).map(|i| pattern.position(i, i).map_or(0.0, |p| values[p])));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Parameter;

    /// A 5-DOF model with a non-diagonal mass, one massless DOF and influence matrices
    /// of different patterns: the sparse pencil reproduces the dense one.
    #[test]
    fn sparse_pencil_equals_the_dense_model() {
        let n = 5;
        let spring = |i: usize, j: usize, k: f64| {
            let mut m = DMatrix::zeros(n, n);
            m[(i, i)] += k;
            m[(j, j)] += k;
            m[(i, j)] -= k;
            m[(j, i)] -= k;
            m
        };
        let ground =
            |i: usize, k: f64| DMatrix::from_fn(n, n, |a, b| f64::from(a == i && b == i) * k);
        let k1 = spring(0, 1, 100.0) + spring(1, 2, 80.0);
        let k2 = spring(2, 3, 50.0) + spring(3, 4, 70.0) + spring(1, 4, 5.0);
        let k0 = &k1 + &k2 + ground(0, 300.0);
        let mut m0 =
            DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![1.0, 2.0, 0.0, 1.5, 1.0]));
        m0[(0, 1)] = 0.1;
        m0[(1, 0)] = 0.1;
        let m1 = ground(4, 0.5);
        let p = |s: &str| Parameter {
            name: s.into(),
            unit: "-".into(),
            nominal: None,
        };
        let model = StructuralModel::from_matrices(
            k0,
            m0,
            vec![(p("a"), k1), (p("b"), k2)],
            vec![(p("c"), m1)],
            None,
        )
        .unwrap();
        let s = SparsePencil::from_model(&model);
        assert_eq!(s.n_dof(), n);
        assert_eq!(s.mass_pattern().nnz(), 6);
        let (alpha, beta) = ([0.3, -0.2], [0.7]);
        let (mut k, mut m, mut a) = (Vec::new(), Vec::new(), Vec::new());
        s.stiffness_values(&alpha, &mut k);
        s.mass_values(&beta, &mut m);
        let kd = model.stiffness(&alpha);
        let md = model.mass(&beta);
        assert!((s.stiffness_pattern().to_dense(&k) - &kd).amax() < 1e-12);
        assert!((s.mass_pattern().to_dense(&m) - &md).amax() < 1e-15);
        s.shifted_values(&k, &m, -2.5, &mut a);
        let ad = &kd + &md * 2.5;
        assert!((s.stiffness_pattern().to_dense(&a) - &ad).amax() < 1e-12);
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
        let mut y = vec![0.0; n];
        s.stiffness_pattern().mul(&k, &x, &mut y);
        let yd = &kd * nalgebra::DVector::from_column_slice(&x);
        assert!((nalgebra::DVector::from_vec(y) - yd).amax() < 1e-12);
        let mut d = Vec::new();
        s.mass_diagonal(&m, &mut d);
        assert_eq!(d, vec![1.0, 2.0, 0.0, 1.5, 1.35]);
    }
}
