//! MATLAB v5 `.mat` files: numeric variables of every class (double, single, int8..int64,
//! uint8..uint64, logical, sparse), with errors that name the file and the variable.
//!
//! The bytes are decoded by [`decode`] (the `matfile` crate refuses a whole file when one
//! variable is `int32`, which the bridge model of `../shared/data/real/bridge-fe` has).

mod decode;
#[cfg(test)]
mod tests;

pub use decode::{scan, Values, Variable, VariableInfo};

use std::path::{Path, PathBuf};

use num_complex::Complex64;

use super::sparse::Triplets;
use crate::error::{Error, Result};

/// A 2-D array, column-major as MATLAB stores it.
#[derive(Debug, Clone, PartialEq)]
pub struct MatArray<T> {
    pub rows: usize,
    pub cols: usize,
    /// `data[r + rows * c]`.
    pub data: Vec<T>,
}

impl<T: Copy> MatArray<T> {
    /// Element `(r, c)`, 0-based.
    pub fn get(&self, r: usize, c: usize) -> T {
        self.data[r + self.rows * c]
    }
    /// Column `c` as a slice.
    pub fn column(&self, c: usize) -> &[T] {
        &self.data[c * self.rows..(c + 1) * self.rows]
    }
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

/// A decoded `.mat` file and its path (for error messages).
#[derive(Debug)]
pub struct MatData {
    path: PathBuf,
    vars: Vec<Variable>,
}

impl MatData {
    /// Reads and decodes `path`.
    pub fn open(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::from_bytes(path, &bytes)
    }

    /// Decodes `bytes` read from `path`.
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Self> {
        let vars = decode::decode(bytes).map_err(|why| {
            Error::invalid(path, format!("not a readable MATLAB v5 .mat file: {why}"))
        })?;
        Ok(MatData {
            path: path.to_path_buf(),
            vars,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Names of the numeric variables, in file order.
    pub fn names(&self) -> Vec<String> {
        self.vars
            .iter()
            .filter(|v| v.values.is_some())
            .map(|v| v.info.name.clone())
            .collect()
    }

    /// Every top-level variable (numeric or not): name, class, dimensions.
    pub fn variables(&self) -> Vec<&VariableInfo> {
        self.vars.iter().map(|v| &v.info).collect()
    }

    fn find(&self, name: &str) -> Result<(&VariableInfo, &Values)> {
        let var = self.vars.iter().find(|v| v.info.name == name);
        let Some(var) = var else {
            return Err(self.error(format!(
                "no numeric variable `{name}` (numeric variables: {})",
                self.names().join(", ")
            )));
        };
        let Some(values) = &var.values else {
            return Err(self.error(format!(
                "variable `{name}` is a {} array, not numeric",
                var.info.class
            )));
        };
        if var.info.dims.len() != 2 {
            return Err(self.error(format!(
                "variable `{name}` has {} dimensions {:?}; expected a 2-D array",
                var.info.dims.len(),
                var.info.dims
            )));
        }
        Ok((&var.info, values))
    }

    fn error(&self, what: String) -> Error {
        Error::invalid(&self.path, what)
    }

    /// The real part (and imaginary part when complex) of a variable, dense.
    #[allow(clippy::type_complexity)]
    fn dense(&self, name: &str) -> Result<(usize, usize, Vec<f64>, Option<Vec<f64>>)> {
        let (info, values) = self.find(name)?;
        let (rows, cols) = (info.dims[0], info.dims[1]);
        let (re, im) = match values {
            Values::Dense { re, im } => (re.clone(), im.clone()),
            Values::Sparse { ir, jc, re, im } => {
                let densify = |v: &[f64]| {
                    let mut d = vec![0.0; rows * cols];
                    for c in 0..cols {
                        for k in jc[c]..jc[c + 1] {
                            d[ir[k] + rows * c] += v[k];
                        }
                    }
                    d
                };
                (densify(re), im.as_deref().map(densify))
            }
        };
        self.finite(name, &re)?;
        if let Some(im) = &im {
            self.finite(name, im)?;
        }
        Ok((rows, cols, re, im))
    }

    /// A real variable as `f64` (integer, single and sparse classes are converted).
    /// Complex variables are an error.
    pub fn real(&self, name: &str) -> Result<MatArray<f64>> {
        let (rows, cols, data, im) = self.dense(name)?;
        if im.is_some() {
            return Err(self.error(format!(
                "variable `{name}` is complex; expected real values"
            )));
        }
        Ok(MatArray { rows, cols, data })
    }

    /// The non-zero entries of a real 2-D variable, without forming a dense array when
    /// the variable is stored sparse.
    pub fn real_triplets(&self, name: &str) -> Result<Triplets> {
        let (info, values) = self.find(name)?;
        let (rows, cols) = (info.dims[0], info.dims[1]);
        let (re, entries) = match values {
            Values::Dense { im: Some(_), .. } | Values::Sparse { im: Some(_), .. } => {
                return Err(self.error(format!(
                    "variable `{name}` is complex; expected real values"
                )))
            }
            Values::Dense { re, .. } => {
                let e = re.iter().enumerate().filter(|(_, v)| **v != 0.0);
                (re, e.map(|(k, &v)| (k % rows, k / rows, v)).collect())
            }
            Values::Sparse { ir, jc, re, .. } => {
                let e = (0..cols).flat_map(|c| (jc[c]..jc[c + 1]).map(move |k| (ir[k], c, k)));
                (re, e.map(|(r, c, k)| (r, c, re[k])).collect())
            }
        };
        self.finite(name, re)?;
        Ok(Triplets {
            rows,
            cols,
            entries,
        })
    }

    /// A variable as complex values (a real variable gets zero imaginary parts).
    pub fn complex(&self, name: &str) -> Result<MatArray<Complex64>> {
        let (rows, cols, re, im) = self.dense(name)?;
        let data = match im {
            Some(im) => re
                .iter()
                .zip(&im)
                .map(|(&r, &i)| Complex64::new(r, i))
                .collect(),
            None => re.iter().map(|&r| Complex64::new(r, 0.0)).collect(),
        };
        Ok(MatArray { rows, cols, data })
    }

    /// A real vector (a 1 x n or n x 1 array) of exactly `len` values, when given.
    pub fn vector(&self, name: &str, len: Option<usize>) -> Result<Vec<f64>> {
        let a = self.real(name)?;
        if a.rows != 1 && a.cols != 1 {
            return Err(self.error(format!(
                "variable `{name}` is {} x {}; expected a vector",
                a.rows, a.cols
            )));
        }
        if let Some(n) = len {
            if a.len() != n {
                return Err(self.error(format!(
                    "variable `{name}` has {} values; expected {n}",
                    a.len()
                )));
            }
        }
        Ok(a.data)
    }

    fn finite(&self, name: &str, v: &[f64]) -> Result<()> {
        match v.iter().position(|x| !x.is_finite()) {
            None => Ok(()),
            Some(i) => Err(self.error(format!(
                "variable `{name}`: element {} (column-major, 1-based) is {}",
                i + 1,
                v[i]
            ))),
        }
    }
}

/// Builds a minimal uncompressed little-endian MAT v5 file with real 2-D variables of
/// the given class (`6` double, `7` single, `8`..`15` int8..uint64), each stored in its
/// own class's data type, for tests.
#[cfg(test)]
pub(crate) fn write_test_mat(vars: &[(&str, u32, usize, usize, &[f64])]) -> Vec<u8> {
    use decode::{MI_INT32, MI_INT8, MI_MATRIX, MI_UINT32};
    fn pad8(v: &mut Vec<u8>) {
        while !v.len().is_multiple_of(8) {
            v.push(0);
        }
    }
    let mut out = vec![b' '; 116];
    out[..20].copy_from_slice(b"MATLAB 5.0 MAT-file ");
    out.extend_from_slice(&[0u8; 8]);
    out.extend_from_slice(&0x0100u16.to_le_bytes());
    out.extend_from_slice(b"IM");
    for &(name, class, rows, cols, values) in vars {
        let mut m = Vec::new();
        m.extend_from_slice(&MI_UINT32.to_le_bytes());
        m.extend_from_slice(&8u32.to_le_bytes());
        m.extend_from_slice(&class.to_le_bytes());
        m.extend_from_slice(&0u32.to_le_bytes());
        m.extend_from_slice(&MI_INT32.to_le_bytes());
        m.extend_from_slice(&8u32.to_le_bytes());
        m.extend_from_slice(&(rows as i32).to_le_bytes());
        m.extend_from_slice(&(cols as i32).to_le_bytes());
        m.extend_from_slice(&MI_INT8.to_le_bytes());
        m.extend_from_slice(&(name.len() as u32).to_le_bytes());
        m.extend_from_slice(name.as_bytes());
        pad8(&mut m);
        let (ty, bytes): (u32, Vec<u8>) = match class {
            7 => (
                7,
                values
                    .iter()
                    .flat_map(|&v| (v as f32).to_le_bytes())
                    .collect(),
            ),
            8 => (
                1,
                values
                    .iter()
                    .flat_map(|&v| (v as i8).to_le_bytes())
                    .collect(),
            ),
            9 => (
                2,
                values
                    .iter()
                    .flat_map(|&v| (v as u8).to_le_bytes())
                    .collect(),
            ),
            10 => (
                3,
                values
                    .iter()
                    .flat_map(|&v| (v as i16).to_le_bytes())
                    .collect(),
            ),
            11 => (
                4,
                values
                    .iter()
                    .flat_map(|&v| (v as u16).to_le_bytes())
                    .collect(),
            ),
            12 => (
                5,
                values
                    .iter()
                    .flat_map(|&v| (v as i32).to_le_bytes())
                    .collect(),
            ),
            13 => (
                6,
                values
                    .iter()
                    .flat_map(|&v| (v as u32).to_le_bytes())
                    .collect(),
            ),
            14 => (
                12,
                values
                    .iter()
                    .flat_map(|&v| (v as i64).to_le_bytes())
                    .collect(),
            ),
            15 => (
                13,
                values
                    .iter()
                    .flat_map(|&v| (v as u64).to_le_bytes())
                    .collect(),
            ),
            _ => (9, values.iter().flat_map(|&v| v.to_le_bytes()).collect()),
        };
        m.extend_from_slice(&ty.to_le_bytes());
        m.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        m.extend_from_slice(&bytes);
        pad8(&mut m);
        out.extend_from_slice(&MI_MATRIX.to_le_bytes());
        out.extend_from_slice(&(m.len() as u32).to_le_bytes());
        out.extend_from_slice(&m);
    }
    out
}
