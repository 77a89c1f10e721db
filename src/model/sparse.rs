//! Sparse matrices of the model layer.

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
