//! MATLAB v5 `.mat` files through the `matfile` crate, with errors that name the file and
//! the variable.
//!
//! `matfile` 0.5 reads numeric arrays only, and it rejects a whole file when one of its
//! variables is stored as `int32` (it checks the data of an `mxINT32_CLASS` array against
//! `miUINT32`). When the crate fails, [`MatData::open`] scans the file's top-level
//! elements itself (header, `miMATRIX`, zlib-compressed `miCOMPRESSED`) to name the
//! variables and their classes, so the error says which variable to convert.

use std::io::Read;
use std::path::{Path, PathBuf};

use num_complex::Complex64;

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

/// A parsed `.mat` file and its path (for error messages).
#[derive(Debug)]
pub struct MatData {
    path: PathBuf,
    file: matfile::MatFile,
}

/// One top-level variable as the header scan sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VariableInfo {
    pub name: String,
    /// MATLAB class, e.g. "double", "int32", "struct".
    pub class: &'static str,
    pub dims: Vec<usize>,
}

impl MatData {
    /// Reads and parses `path`. A file `matfile` cannot parse is scanned to name the
    /// variable at fault (an `int32` variable, typically).
    pub fn open(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::from_bytes(path, &bytes)
    }

    /// Parses `bytes` read from `path`.
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Self> {
        // The crate can panic on some malformed input (it unwraps internally); a file
        // from a user must give an error instead.
        // `matfile` silently drops a truncated last element, so every file is also
        // checked by the header scan.
        let parsed = std::panic::catch_unwind(|| matfile::MatFile::parse(bytes));
        match parsed {
            Ok(Ok(file)) => match scan(bytes) {
                Ok(_) => Ok(MatData {
                    path: path.to_path_buf(),
                    file,
                }),
                Err(why) => Err(Error::invalid(
                    path,
                    format!("malformed MATLAB v5 .mat file: {why}"),
                )),
            },
            Ok(Err(e)) => Err(diagnose(path, bytes, &e.to_string())),
            Err(_) => Err(diagnose(path, bytes, "the parser panicked")),
        }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Names of the numeric variables.
    pub fn names(&self) -> Vec<String> {
        self.file
            .arrays()
            .iter()
            .map(|a| a.name().to_string())
            .collect()
    }

    fn find(&self, name: &str) -> Result<&matfile::Array> {
        let a = self.file.find_by_name(name).ok_or_else(|| {
            Error::invalid(
                &self.path,
                format!(
                    "no numeric variable `{name}` (numeric variables: {})",
                    self.names().join(", ")
                ),
            )
        })?;
        if a.size().len() != 2 {
            return Err(Error::invalid(
                &self.path,
                format!(
                    "variable `{name}` has {} dimensions {:?}; expected a 2-D array",
                    a.size().len(),
                    a.size()
                ),
            ));
        }
        Ok(a)
    }

    /// A real variable as `f64` (integer and single classes are converted). Complex
    /// variables are an error.
    pub fn real(&self, name: &str) -> Result<MatArray<f64>> {
        let a = self.find(name)?;
        let (re, im) = to_f64(a.data());
        if im.is_some() {
            return Err(Error::invalid(
                &self.path,
                format!("variable `{name}` is complex; expected real values"),
            ));
        }
        self.finite(name, &re)?;
        Ok(MatArray {
            rows: a.size()[0],
            cols: a.size()[1],
            data: re,
        })
    }

    /// A variable as complex values (a real variable gets zero imaginary parts).
    pub fn complex(&self, name: &str) -> Result<MatArray<Complex64>> {
        let a = self.find(name)?;
        let (re, im) = to_f64(a.data());
        self.finite(name, &re)?;
        let data: Vec<Complex64> = match im {
            Some(im) => {
                self.finite(name, &im)?;
                re.iter()
                    .zip(&im)
                    .map(|(&r, &i)| Complex64::new(r, i))
                    .collect()
            }
            None => re.iter().map(|&r| Complex64::new(r, 0.0)).collect(),
        };
        Ok(MatArray {
            rows: a.size()[0],
            cols: a.size()[1],
            data,
        })
    }

    /// A real vector (a 1 x n or n x 1 array) of exactly `len` values, when given.
    pub fn vector(&self, name: &str, len: Option<usize>) -> Result<Vec<f64>> {
        let a = self.real(name)?;
        if a.rows != 1 && a.cols != 1 {
            return Err(Error::invalid(
                &self.path,
                format!(
                    "variable `{name}` is {} x {}; expected a vector",
                    a.rows, a.cols
                ),
            ));
        }
        if let Some(n) = len {
            if a.len() != n {
                return Err(Error::invalid(
                    &self.path,
                    format!("variable `{name}` has {} values; expected {n}", a.len()),
                ));
            }
        }
        Ok(a.data)
    }

    fn finite(&self, name: &str, v: &[f64]) -> Result<()> {
        match v.iter().position(|x| !x.is_finite()) {
            None => Ok(()),
            Some(i) => Err(Error::invalid(
                &self.path,
                format!(
                    "variable `{name}`: element {} (column-major, 1-based) is {}",
                    i + 1,
                    v[i]
                ),
            )),
        }
    }
}

fn to_f64(d: &matfile::NumericData) -> (Vec<f64>, Option<Vec<f64>>) {
    use matfile::NumericData as N;
    fn conv<T: Copy + Into<f64>>(re: &[T], im: &Option<Vec<T>>) -> (Vec<f64>, Option<Vec<f64>>) {
        (
            re.iter().map(|&x| x.into()).collect(),
            im.as_ref().map(|v| v.iter().map(|&x| x.into()).collect()),
        )
    }
    match d {
        N::Int8 { real, imag } => conv(real, imag),
        N::UInt8 { real, imag } => conv(real, imag),
        N::Int16 { real, imag } => conv(real, imag),
        N::UInt16 { real, imag } => conv(real, imag),
        N::Int32 { real, imag } => conv(real, imag),
        N::UInt32 { real, imag } => conv(real, imag),
        N::Int64 { real, imag } => (
            real.iter().map(|&x| x as f64).collect(),
            imag.as_ref().map(|v| v.iter().map(|&x| x as f64).collect()),
        ),
        N::UInt64 { real, imag } => (
            real.iter().map(|&x| x as f64).collect(),
            imag.as_ref().map(|v| v.iter().map(|&x| x as f64).collect()),
        ),
        N::Single { real, imag } => conv(real, imag),
        N::Double { real, imag } => conv(real, imag),
    }
}

/// The error for a file the crate could not parse: names `int32` variables when the scan
/// finds any, else lists what the scan found.
fn diagnose(path: &Path, bytes: &[u8], crate_error: &str) -> Error {
    match scan(bytes) {
        Err(why) => Error::invalid(
            path,
            format!("not a readable MATLAB v5 .mat file: {why} (matfile: {crate_error})"),
        ),
        Ok(vars) => {
            let int32: Vec<&VariableInfo> = vars.iter().filter(|v| v.class == "int32").collect();
            if let Some(v) = int32.first() {
                let names: Vec<&str> = int32.iter().map(|v| v.name.as_str()).collect();
                Error::invalid(
                    path,
                    format!(
                        "variable `{}` is stored as int32, which the matfile crate cannot \
                         read (int32 variables: {}); convert it to double and save again, \
                         e.g. in MATLAB `{} = double({});`",
                        v.name,
                        names.join(", "),
                        v.name,
                        v.name
                    ),
                )
            } else {
                let list: Vec<String> = vars
                    .iter()
                    .map(|v| format!("`{}` ({} {:?})", v.name, v.class, v.dims))
                    .collect();
                Error::invalid(
                    path,
                    format!(
                        "could not parse the .mat file (matfile: {crate_error}); its \
                         variables: {}",
                        if list.is_empty() {
                            "none found".to_string()
                        } else {
                            list.join(", ")
                        }
                    ),
                )
            }
        }
    }
}

const MI_INT8: u32 = 1;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;

fn class_name(c: u32) -> &'static str {
    match c {
        1 => "cell",
        2 => "struct",
        3 => "object",
        4 => "char",
        5 => "sparse",
        6 => "double",
        7 => "single",
        8 => "int8",
        9 => "uint8",
        10 => "int16",
        11 => "uint16",
        12 => "int32",
        13 => "uint32",
        14 => "int64",
        15 => "uint64",
        _ => "unknown",
    }
}

/// Lists the top-level variables of a MAT v5 file (name, class, dimensions) from the
/// element tags alone. Errors say what is wrong with the bytes.
pub fn scan(bytes: &[u8]) -> std::result::Result<Vec<VariableInfo>, String> {
    if bytes.len() < 128 {
        return Err(format!(
            "{} bytes, shorter than the 128-byte MAT v5 header",
            bytes.len()
        ));
    }
    let big = match &bytes[126..128] {
        b"IM" => false,
        b"MI" => true,
        other => {
            return Err(format!(
                "bad endian indicator {:?} at byte 126 (expected \"IM\" or \"MI\"; MAT v7.3 \
                 HDF5 files are not supported)",
                String::from_utf8_lossy(other)
            ))
        }
    };
    let rd = Reader { big };
    let mut out = Vec::new();
    let mut pos = 128;
    while pos + 8 <= bytes.len() {
        let (ty, n, data_at) = rd.tag(bytes, pos)?;
        let end = data_at
            .checked_add(n)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| format!("element at byte {pos} runs past the end of the file"))?;
        let body = &bytes[data_at..end];
        match ty {
            MI_MATRIX => out.push(rd.matrix(body)?),
            MI_COMPRESSED => {
                let mut inner = Vec::new();
                flate2::read::ZlibDecoder::new(body)
                    .read_to_end(&mut inner)
                    .map_err(|e| format!("compressed element at byte {pos}: {e}"))?;
                let (ity, inn, iat) = rd.tag(&inner, 0)?;
                if ity == MI_MATRIX {
                    let iend = (iat + inn).min(inner.len());
                    out.push(rd.matrix(&inner[iat..iend])?);
                }
            }
            _ => {}
        }
        // Compressed elements are not padded; others end on an 8-byte boundary.
        pos = if ty == MI_COMPRESSED {
            end
        } else {
            end.div_ceil(8) * 8
        };
    }
    Ok(out)
}

struct Reader {
    big: bool,
}

impl Reader {
    fn u32_at(&self, b: &[u8], at: usize) -> std::result::Result<u32, String> {
        let s: [u8; 4] = b
            .get(at..at + 4)
            .and_then(|s| s.try_into().ok())
            .ok_or_else(|| format!("truncated element at byte {at}"))?;
        Ok(if self.big {
            u32::from_be_bytes(s)
        } else {
            u32::from_le_bytes(s)
        })
    }

    /// (type, byte count, offset of the data) of the element tag at `at`; handles the
    /// small-element format (count in the upper 16 bits of the first word).
    fn tag(&self, b: &[u8], at: usize) -> std::result::Result<(u32, usize, usize), String> {
        let w = self.u32_at(b, at)?;
        if w >> 16 != 0 {
            Ok((w & 0xFFFF, (w >> 16) as usize, at + 4))
        } else {
            Ok((w, self.u32_at(b, at + 4)? as usize, at + 8))
        }
    }

    /// Sub-elements of an `miMATRIX`: array flags, dimensions, name.
    fn matrix(&self, b: &[u8]) -> std::result::Result<VariableInfo, String> {
        let (ty, n, at) = self.tag(b, 0)?;
        if ty != MI_UINT32 || n != 8 {
            return Err("matrix without its array-flags sub-element".into());
        }
        let class = self.u32_at(b, at)? & 0xFF;
        let mut pos = (at + n).div_ceil(8) * 8;
        let (ty, n, at) = self.tag(b, pos)?;
        if ty != MI_INT32 {
            return Err("matrix without its dimensions sub-element".into());
        }
        let dims = (0..n / 4)
            .map(|i| self.u32_at(b, at + 4 * i).map(|d| d as usize))
            .collect::<std::result::Result<Vec<_>, _>>()?;
        pos = (at + n).div_ceil(8) * 8;
        let (ty, n, at) = self.tag(b, pos)?;
        if ty != MI_INT8 {
            return Err("matrix without its name sub-element".into());
        }
        let name = b
            .get(at..at + n)
            .map(|s| String::from_utf8_lossy(s).into_owned())
            .ok_or("truncated variable name")?;
        Ok(VariableInfo {
            name,
            class: class_name(class),
            dims,
        })
    }
}

/// Builds a minimal uncompressed little-endian MAT v5 file with real 2-D variables of
/// the given class (`6` double, `12` int32), for tests.
#[cfg(test)]
pub(crate) fn write_test_mat(vars: &[(&str, u32, usize, usize, &[f64])]) -> Vec<u8> {
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
        if class == 12 {
            m.extend_from_slice(&MI_INT32.to_le_bytes());
            m.extend_from_slice(&((4 * values.len()) as u32).to_le_bytes());
            for v in values {
                m.extend_from_slice(&(*v as i32).to_le_bytes());
            }
        } else {
            m.extend_from_slice(&9u32.to_le_bytes());
            m.extend_from_slice(&((8 * values.len()) as u32).to_le_bytes());
            for v in values {
                m.extend_from_slice(&v.to_le_bytes());
            }
        }
        pad8(&mut m);
        out.extend_from_slice(&MI_MATRIX.to_le_bytes());
        out.extend_from_slice(&(m.len() as u32).to_le_bytes());
        out.extend_from_slice(&m);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_double_matrix_column_major() {
        let bytes = write_test_mat(&[("a", 6, 2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])]);
        let m = MatData::from_bytes(Path::new("t.mat"), &bytes).unwrap();
        let a = m.real("a").unwrap();
        assert_eq!((a.rows, a.cols), (2, 3));
        assert_eq!(a.get(1, 2), 6.0);
        assert_eq!(a.column(1), &[3.0, 4.0]);
        let err = m.vector("a", None).unwrap_err().to_string();
        assert!(err.contains("`a` is 2 x 3"), "{err}");
        let err = m.real("b").unwrap_err().to_string();
        assert!(
            err.contains("t.mat") && err.contains("no numeric variable `b`"),
            "{err}"
        );
    }

    #[test]
    fn int32_variable_is_named_in_the_error() {
        let bytes = write_test_mat(&[
            ("ok", 6, 1, 2, &[1.0, 2.0]),
            ("K_y1", 12, 1, 2, &[3.0, 4.0]),
        ]);
        let vars = scan(&bytes).unwrap();
        assert_eq!(vars[1].class, "int32");
        assert_eq!(vars[1].dims, vec![1, 2]);
        let err = MatData::from_bytes(Path::new("dir/x.mat"), &bytes)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("dir/x.mat") && err.contains("`K_y1` is stored as int32"),
            "{err}"
        );
    }

    #[test]
    fn malformed_files_give_errors_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        let good = write_test_mat(&[("v", 6, 3, 1, &[1.0, 2.0, 3.0])]);
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("short.mat", b"MATLAB 5.0".to_vec()),
            ("truncated.mat", good[..good.len() - 12].to_vec()),
            ("badendian.mat", {
                let mut b = good.clone();
                b[126] = b'X';
                b
            }),
        ];
        for (name, bytes) in cases {
            let p = dir.path().join(name);
            std::fs::write(&p, &bytes).unwrap();
            let err = MatData::open(&p).unwrap_err().to_string();
            assert!(err.contains(name), "{name}: {err}");
        }
        // A NaN in the data is reported with its position.
        let nan = write_test_mat(&[("v", 6, 3, 1, &[1.0, f64::NAN, 3.0])]);
        let m = MatData::from_bytes(Path::new("n.mat"), &nan).unwrap();
        let err = m.vector("v", Some(3)).unwrap_err().to_string();
        assert!(err.contains("`v`: element 2"), "{err}");
        let err = MatData::open(&dir.path().join("missing.mat"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("missing.mat"), "{err}");
    }
}
