//! Matrix Market (`.mtx`) matrices, the exchange format most FE packages can export.
//! Supported: `matrix coordinate real|integer general|symmetric` and
//! `matrix array real|integer general|symmetric`. Errors name the file and line.

use super::sparse::Triplets;
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use std::path::Path;

/// Reads a real matrix from a Matrix Market file as a dense matrix.
pub fn read_matrix_market(path: &Path) -> Result<DMatrix<f64>> {
    Ok(read_matrix_market_triplets(path)?.to_dense())
}

/// Reads a real matrix from a Matrix Market file as its entries (a symmetric file
/// gives both triangles), naming file and line on error.
pub fn read_matrix_market_triplets(path: &Path) -> Result<Triplets> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    let (_, header) = lines
        .next()
        .ok_or_else(|| Error::invalid(path, "empty file"))?;
    let Header {
        coordinate,
        symmetric,
    } = parse_header(path, header)?;
    let mut data = lines.filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('%'));
    let (size_line, size) = data
        .next()
        .ok_or_else(|| Error::invalid(path, "missing size line"))?;
    let sizes: Vec<&str> = size.split_whitespace().collect();
    let expect = if coordinate { 3 } else { 2 };
    if sizes.len() != expect {
        return Err(cell(
            path,
            size_line,
            format!("size line needs {expect} integers, got '{size}'"),
        ));
    }
    let rows = parse_usize(path, size_line, sizes[0])?;
    let cols = parse_usize(path, size_line, sizes[1])?;
    let entries = if coordinate {
        let nnz = parse_usize(path, size_line, sizes[2])?;
        coordinate_entries(path, data, (rows, cols), nnz, symmetric)?
    } else {
        array_entries(path, data, (rows, cols), symmetric)?
    };
    Ok(Triplets {
        rows,
        cols,
        entries,
    })
}

/// What the header line announces.
struct Header {
    /// `coordinate` (else `array`).
    coordinate: bool,
    /// `symmetric` (else `general`).
    symmetric: bool,
}

/// Parses the header line `%%MatrixMarket matrix <format> <field> <symmetry>` (case
/// insensitive) of a supported file.
fn parse_header(path: &Path, header: &str) -> Result<Header> {
    let h: Vec<String> = header
        .split_whitespace()
        .map(|s| s.to_ascii_lowercase())
        .collect();
    if h.len() != 5 || h[0] != "%%matrixmarket" || h[1] != "matrix" {
        return Err(cell(
            path,
            1,
            format!("expected '%%MatrixMarket matrix <format> <field> <symmetry>', got '{header}'"),
        ));
    }
    let coordinate = match h[2].as_str() {
        "coordinate" => true,
        "array" => false,
        f => {
            return Err(cell(
                path,
                1,
                format!("format '{f}' not supported (use coordinate or array)"),
            ))
        }
    };
    if h[3] != "real" && h[3] != "integer" && h[3] != "double" {
        return Err(cell(
            path,
            1,
            format!("field '{}' not supported (use real)", h[3]),
        ));
    }
    let symmetric = match h[4].as_str() {
        "general" => false,
        "symmetric" => true,
        s => {
            return Err(cell(
                path,
                1,
                format!("symmetry '{s}' not supported (use general or symmetric)"),
            ))
        }
    };
    Ok(Header {
        coordinate,
        symmetric,
    })
}

/// The entries of a `coordinate` file from its data lines `row col value` (1-based
/// indices into a `rows x cols` matrix; `nnz` of them announced).
fn coordinate_entries<'a>(
    path: &Path,
    data: impl Iterator<Item = (usize, &'a str)>,
    (rows, cols): (usize, usize),
    nnz: usize,
    symmetric: bool,
) -> Result<Vec<(usize, usize, f64)>> {
    let mut entries = Vec::new();
    let mut count = 0;
    for (line, l) in data {
        let f: Vec<&str> = l.split_whitespace().collect();
        if f.len() != 3 {
            return Err(cell(
                path,
                line,
                format!("expected 'row col value', got '{l}'"),
            ));
        }
        let (i, j) = (
            parse_usize(path, line, f[0])?,
            parse_usize(path, line, f[1])?,
        );
        if i == 0 || j == 0 || i > rows || j > cols {
            return Err(cell(
                path,
                line,
                format!("index ({i},{j}) outside {rows}x{cols} (indices are 1-based)"),
            ));
        }
        let v = parse_f64(path, line, f[2])?;
        entries.push((i - 1, j - 1, v));
        if symmetric && i != j {
            entries.push((j - 1, i - 1, v));
        }
        count += 1;
    }
    if count != nnz {
        return Err(Error::invalid(
            path,
            format!("size line announces {nnz} entries, file has {count}"),
        ));
    }
    Ok(entries)
}

/// The nonzero entries of an `array` file from its values, column-major; for a
/// symmetric file, the lower triangle column by column.
fn array_entries<'a>(
    path: &Path,
    data: impl Iterator<Item = (usize, &'a str)>,
    (rows, cols): (usize, usize),
    symmetric: bool,
) -> Result<Vec<(usize, usize, f64)>> {
    let mut values = Vec::new();
    for (line, l) in data {
        for tok in l.split_whitespace() {
            values.push(parse_f64(path, line, tok)?);
        }
    }
    let expected = if symmetric {
        rows * (rows + 1) / 2
    } else {
        rows * cols
    };
    if values.len() != expected {
        return Err(Error::invalid(
            path,
            format!("expected {expected} values, file has {}", values.len()),
        ));
    }
    let mut entries = Vec::new();
    let mut it = values.into_iter();
    for j in 0..cols {
        let start = if symmetric { j } else { 0 };
        for i in start..rows {
            let v = it.next().unwrap_or(0.0);
            if v != 0.0 {
                entries.push((i, j, v));
                if symmetric && i != j {
                    entries.push((j, i, v));
                }
            }
        }
    }
    Ok(entries)
}

/// An error at `line` of the file at `path`.
fn cell(path: &Path, line: usize, what: String) -> Error {
    Error::Cell {
        path: path.to_path_buf(),
        line,
        column: 1,
        what,
    }
}

/// A non-negative integer read at `line`.
fn parse_usize(path: &Path, line: usize, s: &str) -> Result<usize> {
    s.parse::<usize>()
        .map_err(|_| cell(path, line, format!("'{s}' is not a non-negative integer")))
}

/// A finite number read at `line`.
fn parse_f64(path: &Path, line: usize, s: &str) -> Result<f64> {
    let v = s
        .parse::<f64>()
        .map_err(|_| cell(path, line, format!("'{s}' is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(cell(path, line, format!("'{s}' is not finite")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn bad_matrix_market_names_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            "K.mtx",
            "%%MatrixMarket matrix coordinate real general\n2 2 1\n3 1 1.0\n",
        );
        let e = read_matrix_market(&p).unwrap_err().to_string();
        assert!(e.contains("K.mtx:3:") && e.contains("outside"), "{e}");
        let p = write(
            dir.path(),
            "K2.mtx",
            "%%MatrixMarket matrix coordinate real general\n2 2 1\n1 1 abc\n",
        );
        let e = read_matrix_market(&p).unwrap_err().to_string();
        assert!(e.contains("K2.mtx:3:") && e.contains("not a number"), "{e}");
    }
}
