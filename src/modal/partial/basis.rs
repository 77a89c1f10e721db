//! The growing `M`-orthonormal search space of the partial eigen-solver, with its images
//! under `M` and the shift-invert operator `Op`, and the projected operator
//! `V^T M Op V` (Rayleigh-Ritz).

use crate::model::sparse::SparsePencil;
use nalgebra::DMatrix;

/// A column is dropped when orthogonalisation leaves less than this fraction of its
/// `M`-norm (it lies in the span already, to rounding).
const DROP_RTOL: f64 = 1e-8;

/// `V` (n x dim, `V^T M V = I`), `M V`, `Op V` (column-major, `n` rows) and the
/// projected operator `H = V^T M Op V` (symmetric: `M Op = M (K - sigma M)^-1 M`).
/// Columns appended by [`Basis::push`] get their `Op` image by [`Basis::attach_op`].
#[derive(Debug, Default)]
pub(super) struct Basis {
    n: usize,
    dim: usize,
    v: Vec<f64>,
    mv: Vec<f64>,
    opv: Vec<f64>,
    /// `H`, `cap x cap`, leading `dim x dim` block valid.
    h: DMatrix<f64>,
    scratch: Vec<f64>,
}

/// Matrices of one evaluation: the pencil and its values.
pub(super) struct Pencil<'a> {
    pub sparse: &'a SparsePencil,
    pub k: &'a [f64],
    pub m: &'a [f64],
}

impl Pencil<'_> {
    pub fn k_mul(&self, x: &[f64], y: &mut [f64]) {
        self.sparse.stiffness_pattern().mul(self.k, x, y);
    }
    pub fn m_mul(&self, x: &[f64], y: &mut [f64]) {
        self.sparse.mass_pattern().mul(self.m, x, y);
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

impl Basis {
    /// Empties the basis for vectors of length `n` and room for `cap` columns.
    pub fn reset(&mut self, n: usize, cap: usize) {
        self.n = n;
        self.dim = 0;
        for b in [&mut self.v, &mut self.mv, &mut self.opv] {
            b.clear();
            b.reserve(n * cap);
        }
        if self.h.nrows() < cap {
            self.h = DMatrix::zeros(cap, cap);
        }
        self.scratch.resize(n, 0.0);
    }

    /// Columns with their `Op` image.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Columns appended by [`Self::push`] and waiting for [`Self::attach_op`].
    pub fn pending(&self) -> &[f64] {
        &self.v[self.dim * self.n..]
    }

    fn col(buf: &[f64], n: usize, j: usize) -> &[f64] {
        &buf[j * n..(j + 1) * n]
    }

    /// `M`-orthogonalises `w` against the basis, pending columns included (classical
    /// Gram-Schmidt, twice), normalises it and appends it as a pending column; `false`
    /// (nothing appended) when it is dependent.
    pub fn push(&mut self, w: &mut [f64], pencil: &Pencil) -> bool {
        let n = self.n;
        pencil.m_mul(w, &mut self.scratch);
        let norm0 = dot(w, &self.scratch).max(0.0).sqrt();
        if !(norm0 > 0.0 && norm0.is_finite()) {
            return false;
        }
        let cols = self.v.len() / n;
        for _ in 0..2 {
            for j in 0..cols {
                let c = dot(Self::col(&self.mv, n, j), w);
                axpy(-c, Self::col(&self.v, n, j), w);
            }
        }
        pencil.m_mul(w, &mut self.scratch);
        let norm = dot(w, &self.scratch).max(0.0).sqrt();
        if !(norm > DROP_RTOL * norm0) {
            return false;
        }
        w.iter_mut().for_each(|x| *x /= norm);
        self.v.extend_from_slice(w);
        self.mv.extend(self.scratch.iter().map(|x| x / norm));
        true
    }

    /// Attaches `Op v` (column-major, one column per pending column) to the pending
    /// columns and extends `H`.
    pub fn attach_op(&mut self, op: &[f64]) {
        let n = self.n;
        let new = op.len() / n;
        self.opv.extend_from_slice(op);
        let d = self.dim + new;
        for j in self.dim..d {
            for i in 0..=j {
                let x = dot(Self::col(&self.mv, n, i), Self::col(&self.opv, n, j));
                self.h[(i, j)] = x;
                self.h[(j, i)] = x;
            }
        }
        self.dim = d;
    }

    /// Ritz values `theta` (descending: the lowest `lambda = sigma + 1 / theta` first)
    /// and the coordinates of the Ritz vectors (columns, same order) of `H y = theta y`.
    pub fn ritz(&self) -> (Vec<f64>, DMatrix<f64>) {
        let d = self.dim;
        let h = self.h.view((0, 0), (d, d));
        let sym = DMatrix::from_fn(d, d, |i, j| 0.5 * (h[(i, j)] + h[(j, i)]));
        let eig = sym.symmetric_eigen();
        let mut order: Vec<usize> = (0..d).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let values = order.iter().map(|&i| eig.eigenvalues[i]).collect();
        let vectors = DMatrix::from_fn(d, d, |r, c| eig.eigenvectors[(r, order[c])]);
        (values, vectors)
    }

    /// `V y`, `Op V y` and `M V y` for the first `p` columns `y` of `coords`, each
    /// column-major (`n x p`) into the given buffers.
    pub fn combine(&self, coords: &DMatrix<f64>, p: usize, out: [&mut Vec<f64>; 3]) {
        let n = self.n;
        for (src, dst) in [&self.v, &self.opv, &self.mv].into_iter().zip(out) {
            dst.clear();
            dst.resize(n * p, 0.0);
            for c in 0..p {
                let col = &mut dst[c * n..(c + 1) * n];
                for j in 0..self.dim {
                    axpy(coords[(j, c)], Self::col(src, n, j), col);
                }
            }
        }
    }

    /// Replaces the basis by `p` Ritz vectors `x` (with `Op x`, `M x`): a thick restart.
    pub fn restart(&mut self, x: &[f64], opx: &[f64], mx: &[f64], p: usize) {
        let n = self.n;
        self.v.clear();
        self.v.extend_from_slice(&x[..n * p]);
        self.mv.clear();
        self.mv.extend_from_slice(&mx[..n * p]);
        self.opv.clear();
        self.dim = 0;
        self.attach_op(&opx[..n * p]);
    }
}
