//! The growing `M`-orthonormal search space of the partial eigen-solver, with its images
//! under `M` and the shift-invert operator `Op`, and the projected operator
//! `V^T M Op V` (Rayleigh-Ritz).

use crate::model::sparse::SparsePencil;
use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};
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

/// A column-major `rows x cols` slice as a faer view.
fn view(s: &[f64], rows: usize, cols: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(&s[..rows * cols], rows, cols)
}

/// `dst = a^T b` (`a`: `n x p`, `b`: `n x q`, `dst`: `p x q`, column-major).
fn tr_mul(dst: &mut [f64], a: MatRef<'_, f64>, b: MatRef<'_, f64>) {
    let (p, q) = (a.ncols(), b.ncols());
    let dst = MatMut::from_column_major_slice_mut(&mut dst[..p * q], p, q);
    matmul(dst, Accum::Replace, a.transpose(), b, 1.0, Par::Seq);
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

    /// `M`-orthogonalises the `b` columns of `w` (column-major) against the basis
    /// (block classical Gram-Schmidt, twice) and against each other (modified
    /// Gram-Schmidt, twice), normalises them and appends the independent ones as pending
    /// columns; returns how many. A column is dependent when less than `DROP_RTOL` of
    /// its `M`-norm survives.
    pub fn push_block(&mut self, w: &mut [f64], b: usize, pencil: &Pencil) -> usize {
        let n = self.n;
        let d = self.dim;
        let norm0: Vec<f64> = (0..b)
            .map(|j| {
                pencil.m_mul(&w[j * n..(j + 1) * n], &mut self.scratch);
                dot(&w[j * n..(j + 1) * n], &self.scratch).max(0.0).sqrt()
            })
            .collect();
        if d > 0 {
            let mut c = vec![0.0; d * b];
            for _ in 0..2 {
                tr_mul(&mut c, view(&self.mv, n, d), view(w, n, b));
                let wm = MatMut::from_column_major_slice_mut(&mut w[..n * b], n, b);
                matmul(
                    wm,
                    Accum::Add,
                    view(&self.v, n, d),
                    view(&c, d, b),
                    -1.0,
                    Par::Seq,
                );
            }
        }
        let mut added = 0;
        for j in 0..b {
            let col = &mut w[j * n..(j + 1) * n];
            for _ in 0..2 {
                for k in d..d + added {
                    let c = dot(Self::col(&self.mv, n, k), col);
                    axpy(-c, Self::col(&self.v, n, k), col);
                }
            }
            pencil.m_mul(col, &mut self.scratch);
            let norm = dot(col, &self.scratch).max(0.0).sqrt();
            if !(norm0[j] > 0.0 && norm0[j].is_finite() && norm > DROP_RTOL * norm0[j]) {
                continue;
            }
            col.iter_mut().for_each(|x| *x /= norm);
            self.v.extend_from_slice(col);
            self.mv.extend(self.scratch.iter().map(|x| x / norm));
            added += 1;
        }
        added
    }

    /// Attaches `Op v` (column-major, one column per pending column) to the pending
    /// columns and extends `H = V^T M Op V`.
    pub fn attach_op(&mut self, op: &[f64]) {
        let n = self.n;
        let new = op.len() / n;
        self.opv.extend_from_slice(op);
        let d = self.dim + new;
        let mut c = vec![0.0; d * new];
        tr_mul(
            &mut c,
            view(&self.mv, n, d),
            view(&self.opv[self.dim * n..], n, new),
        );
        for (k, j) in (self.dim..d).enumerate() {
            for i in 0..d {
                let x = c[k * d + i];
                if i >= self.dim && i > j {
                    continue;
                }
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
        let (n, d) = (self.n, self.dim);
        let y = coords.view((0, 0), (d, p));
        let y = MatRef::from_column_major_slice(y.clone_owned().as_slice(), d, p).to_owned();
        for (src, dst) in [&self.v, &self.opv, &self.mv].into_iter().zip(out) {
            dst.clear();
            dst.resize(n * p, 0.0);
            let dm = MatMut::from_column_major_slice_mut(&mut dst[..], n, p);
            matmul(
                dm,
                Accum::Replace,
                view(src, n, d),
                y.as_ref(),
                1.0,
                Par::Seq,
            );
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
