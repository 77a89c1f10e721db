//! Reading datasets 58 and 58b from a file's bytes.

use super::binary::{binary_block, BinaryHeader};
use super::{
    Abscissa, Axis, Encoding, Function58, FunctionType, Location, NodeDof, Ordinate, Precision,
    UffFile,
};
use crate::error::{Error, Result};
use num_complex::Complex64;
use std::path::Path;

/// Reads every dataset 58/58b of `path` (other datasets are skipped).
pub fn read_uff(path: &Path) -> Result<UffFile> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_uff_bytes(path, &bytes)
}

/// [`read_uff`] of bytes already in memory; `path` names them in errors.
pub fn read_uff_bytes(path: &Path, bytes: &[u8]) -> Result<UffFile> {
    let mut cur = Cursor::new(path, bytes);
    let mut file = UffFile {
        functions: Vec::new(),
        skipped: Vec::new(),
    };
    while let Some(start) = cur.find_marker()? {
        let (head, line) = cur
            .next_line()
            .ok_or_else(|| cur.cell(start.line, 1, "the file ends after a `-1` marker"))?;
        let head = String::from_utf8_lossy(head);
        let number = head.get(..6.min(head.len())).unwrap_or("").trim();
        let binary = head
            .as_bytes()
            .get(6)
            .is_some_and(|c| c.eq_ignore_ascii_case(&b'b'));
        if number != "58" {
            let name = if number.is_empty() {
                head.trim().to_string()
            } else {
                format!("{number}{}", if binary { "b" } else { "" })
            };
            file.skipped.push((name, start));
            cur.skip_dataset(start)?;
            continue;
        }
        let (function, encoding) = if binary {
            let bh = BinaryHeader::parse(&cur, &head, line)?;
            let header = cur.header(start)?;
            let n_values = header.n_values(&cur)?;
            let data = binary_block(&mut cur, &bh, &header, n_values)?;
            (header.assemble(&cur, data)?, bh.encoding())
        } else {
            let header = cur.header(start)?;
            let n_values = header.n_values(&cur)?;
            let data = cur.ascii_values(start, n_values)?;
            (header.assemble(&cur, data)?, Encoding::Ascii)
        };
        file.functions.push((function, start, encoding));
    }
    Ok(file)
}

/// A position in the file's bytes with its 1-based line number.
pub(super) struct Cursor<'a> {
    pub path: &'a Path,
    pub bytes: &'a [u8],
    pub pos: usize,
    /// Line number of the next line.
    pub line: usize,
}

impl<'a> Cursor<'a> {
    fn new(path: &'a Path, bytes: &'a [u8]) -> Self {
        Cursor {
            path,
            bytes,
            pos: 0,
            line: 1,
        }
    }

    /// The next line without its `\n` / `\r\n`, and its line number.
    pub fn next_line(&mut self) -> Option<(&'a [u8], usize)> {
        if self.pos >= self.bytes.len() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        let end = rest.iter().position(|&b| b == b'\n');
        let (text, used) = match end {
            Some(e) => (&rest[..e], e + 1),
            None => (rest, rest.len()),
        };
        let text = text.strip_suffix(b"\r").unwrap_or(text);
        self.pos += used;
        let line = self.line;
        self.line += 1;
        Some((text, line))
    }

    /// An error at `line`, `column` of this file.
    pub fn cell(&self, line: usize, column: usize, what: impl Into<String>) -> Error {
        Error::Cell {
            path: self.path.to_path_buf(),
            line,
            column,
            what: what.into(),
        }
    }

    /// Skips blank lines up to the next `-1` marker line; `None` at the end of the file.
    fn find_marker(&mut self) -> Result<Option<Location>> {
        loop {
            let byte = self.pos;
            let Some((text, line)) = self.next_line() else {
                return Ok(None);
            };
            if is_marker(text) {
                return Ok(Some(Location { line, byte }));
            }
            if !text.iter().all(u8::is_ascii_whitespace) {
                return Err(self.cell(
                    line,
                    1,
                    format!(
                        "expected `    -1`, the line that starts a dataset, found {:?}",
                        short(text)
                    ),
                ));
            }
        }
    }

    /// Skips to the line after the `-1` that closes the dataset started at `start`.
    fn skip_dataset(&mut self, start: Location) -> Result<()> {
        while let Some((text, _)) = self.next_line() {
            if is_marker(text) {
                return Ok(());
            }
        }
        Err(self.cell(
            start.line,
            1,
            "the dataset starting here has no closing `-1` line (is the file truncated?)",
        ))
    }

    /// Records 1-11 of the dataset started at `start`.
    fn header(&mut self, start: Location) -> Result<Header> {
        const NAMES: [&str; 11] = [
            "1 (ID line 1)",
            "2 (ID line 2)",
            "3 (ID line 3)",
            "4 (ID line 4)",
            "5 (ID line 5)",
            "6 (DOF identification)",
            "7 (data form)",
            "8 (abscissa)",
            "9 (ordinate)",
            "10 (ordinate denominator)",
            "11 (z axis)",
        ];
        let mut lines: Vec<(&[u8], usize)> = Vec::with_capacity(11);
        for name in NAMES {
            match self.next_line() {
                Some((text, line)) if !is_marker(text) => lines.push((text, line)),
                _ => {
                    return Err(self.cell(
                        start.line,
                        1,
                        format!("dataset 58 starting here ends before record {name}"),
                    ))
                }
            }
        }
        let id_lines =
            std::array::from_fn(|k| String::from_utf8_lossy(lines[k].0).trim_end().to_string());
        let (function_type, ids, response, reference) = self.record6(lines[5])?;
        let form = self.record7(lines[6])?;
        let mut axes: [Axis; 4] = Default::default();
        for (k, axis) in axes.iter_mut().enumerate() {
            *axis = self.axis_record(lines[7 + k])?;
        }
        Ok(Header {
            id_lines,
            function_type,
            ids,
            response,
            reference,
            form,
            axes,
            start,
        })
    }

    /// Record 6, Format(2(I5,I10),2(1X,10A1,I10,I4)).
    #[allow(clippy::type_complexity)]
    fn record6(
        &self,
        (text, line): (&[u8], usize),
    ) -> Result<(FunctionType, [i32; 3], NodeDof, NodeDof)> {
        let int = |from: usize, to: usize, what: &str| -> Result<i64> {
            let s = column_text(text, from, to);
            let s = s.trim();
            if s.is_empty() {
                return Ok(0);
            }
            s.parse::<i64>().map_err(|_| {
                self.cell(
                    line,
                    from + 1,
                    format!(
                        "record 6: {what} (columns {}-{to}) is {s:?}, not an integer",
                        from + 1
                    ),
                )
            })
        };
        let small = |v: i64, from: usize, what: &str| -> Result<i32> {
            i32::try_from(v).map_err(|_| {
                self.cell(
                    line,
                    from + 1,
                    format!("record 6: {what} {v} is out of range"),
                )
            })
        };
        let function_type = small(int(0, 5, "the function type")?, 0, "the function type")?;
        let ids = [
            small(int(5, 15, "the function id")?, 5, "the function id")?,
            small(int(15, 20, "the version number")?, 15, "the version number")?,
            small(int(20, 30, "the load case")?, 20, "the load case")?,
        ];
        let dof = |e: usize, n: usize, d: usize, which: &str| -> Result<NodeDof> {
            let direction = small(
                int(d, d + 4, &format!("the {which} direction"))?,
                d,
                "direction",
            )?;
            if !(-6..=6).contains(&direction) {
                return Err(self.cell(
                    line,
                    d + 1,
                    format!("record 6: {which} direction {direction}; expected -6..6 (1 = +X, -3 = -Z, ...)"),
                ));
            }
            Ok(NodeDof {
                entity: column_text(text, e, e + 10).trim().to_string(),
                node: int(n, n + 10, &format!("the {which} node"))?,
                direction,
            })
        };
        let response = dof(31, 41, 51, "response")?;
        let reference = dof(56, 66, 76, "reference")?;
        Ok((
            FunctionType::from_code(function_type),
            ids,
            response,
            reference,
        ))
    }

    /// Record 7, Format(3I10,3E13.5), read by fields separated by blanks.
    fn record7(&self, (text, line): (&[u8], usize)) -> Result<DataForm> {
        let s = String::from_utf8_lossy(text);
        let fields: Vec<&str> = s.split_whitespace().collect();
        if fields.len() < 3 {
            return Err(self.cell(
                line,
                1,
                format!(
                    "record 7 needs the data type, number of points, spacing, minimum, \
                     increment and z value; found {:?}",
                    s.trim()
                ),
            ));
        }
        let int = |k: usize, what: &str| -> Result<i64> {
            fields[k].parse::<i64>().map_err(|_| {
                self.cell(
                    line,
                    1,
                    format!("record 7: {what} is {:?}, not an integer", fields[k]),
                )
            })
        };
        let real = |k: usize, what: &str| -> Result<f64> {
            let Some(f) = fields.get(k) else {
                return Ok(0.0);
            };
            parse_real(f).filter(|v| v.is_finite()).ok_or_else(|| {
                self.cell(
                    line,
                    1,
                    format!("record 7: {what} is {f:?}, not a finite number"),
                )
            })
        };
        let data_type = int(0, "the ordinate data type")?;
        let (complex, precision) = match data_type {
            2 => (false, Precision::Single),
            4 => (false, Precision::Double),
            5 => (true, Precision::Single),
            6 => (true, Precision::Double),
            t => {
                return Err(self.cell(
                    line,
                    1,
                    format!(
                        "record 7: ordinate data type {t}; expected 2 (real single), 4 (real \
                         double), 5 (complex single) or 6 (complex double)"
                    ),
                ))
            }
        };
        let n_points = int(1, "the number of points")?;
        let n_points = usize::try_from(n_points).map_err(|_| {
            self.cell(
                line,
                1,
                format!("record 7: number of points {n_points} is negative"),
            )
        })?;
        let even = match int(2, "the abscissa spacing")? {
            0 => false,
            1 => true,
            v => {
                return Err(self.cell(
                    line,
                    1,
                    format!("record 7: abscissa spacing {v}; expected 0 (uneven) or 1 (even)"),
                ))
            }
        };
        Ok(DataForm {
            complex,
            precision,
            n_points,
            even,
            min: real(3, "the abscissa minimum")?,
            step: real(4, "the abscissa increment")?,
            z: real(5, "the z-axis value")?,
            line,
        })
    }

    /// Records 8-11, Format(I10,3I5,2(1X,20A1)).
    fn axis_record(&self, (text, line): (&[u8], usize)) -> Result<Axis> {
        let ints = column_text(text, 0, 25);
        let v: Vec<&str> = ints.split_whitespace().collect();
        let parsed: Option<Vec<i32>> = v.iter().map(|s| s.parse::<i32>().ok()).collect();
        let Some(n) = parsed.filter(|p| p.len() == 4) else {
            return Err(self.cell(
                line,
                1,
                format!(
                    "axis record (records 8-11): columns 1-25 must hold the specific data type \
                     and the length, force and temperature unit exponents; found {:?}",
                    ints.trim()
                ),
            ));
        };
        let label = column_text(text, 26, 46).trim().to_string();
        let units = column_text(text, 47, usize::MAX).trim().to_string();
        Ok(Axis {
            data_type: n[0],
            length_exp: n[1],
            force_exp: n[2],
            temperature_exp: n[3],
            label,
            units,
        })
    }

    /// The ASCII numbers of record 12 up to the closing `-1`; exactly `n_values` of them.
    fn ascii_values(&mut self, start: Location, n_values: usize) -> Result<Vec<f64>> {
        let mut values = Vec::new();
        loop {
            let Some((text, line)) = self.next_line() else {
                return Err(self.cell(
                    start.line,
                    1,
                    format!(
                        "dataset 58 starting here has no closing `-1` line after its data \
                         ({} of {n_values} values read; is the file truncated?)",
                        values.len()
                    ),
                ));
            };
            if is_marker(text) {
                break;
            }
            parse_numbers(
                text,
                |column, token| {
                    self.cell(
                        line,
                        column,
                        format!("record 12: {token:?} is not a finite number"),
                    )
                },
                &mut values,
            )?;
            if values.len() > n_values {
                return Err(self.cell(
                    line,
                    1,
                    format!("record 12 holds more than the {n_values} values record 7 announces"),
                ));
            }
        }
        if values.len() != n_values {
            return Err(self.cell(
                start.line,
                1,
                format!(
                    "dataset 58 starting here: record 12 holds {} values, record 7 announces \
                     {n_values} (is the file truncated?)",
                    values.len()
                ),
            ));
        }
        Ok(values)
    }
}

/// Record 7.
pub(super) struct DataForm {
    pub complex: bool,
    pub precision: Precision,
    pub n_points: usize,
    pub even: bool,
    min: f64,
    step: f64,
    z: f64,
    line: usize,
}

/// Records 1-11 of a dataset.
pub(super) struct Header {
    id_lines: [String; 5],
    function_type: FunctionType,
    ids: [i32; 3],
    response: NodeDof,
    reference: NodeDof,
    pub form: DataForm,
    axes: [Axis; 4],
    pub start: Location,
}

impl Header {
    /// Numbers per point: the ordinate (1 or 2) and, uneven, the abscissa.
    pub fn values_per_point(&self) -> usize {
        usize::from(!self.form.even) + if self.form.complex { 2 } else { 1 }
    }

    /// Numbers record 12 must hold; an error when they cannot fit in the file.
    fn n_values(&self, cur: &Cursor) -> Result<usize> {
        let n = self.form.n_points.checked_mul(self.values_per_point());
        let left = cur.bytes.len() - cur.pos.min(cur.bytes.len());
        // at least 4 bytes (binary) or 2 characters (ASCII) per number
        match n {
            Some(n) if n / 2 <= left => Ok(n),
            _ => Err(cur.cell(
                self.form.line,
                1,
                format!(
                    "record 7 announces {} points, more than the {left} bytes left in the file \
                     can hold (is the file truncated?)",
                    self.form.n_points
                ),
            )),
        }
    }

    /// The dataset from its header and record 12's numbers.
    fn assemble(self, cur: &Cursor, values: Vec<f64>) -> Result<Function58> {
        let per = self.values_per_point();
        let abscissa = if self.form.even {
            if self.form.n_points > 1 && self.form.step <= 0.0 {
                return Err(cur.cell(
                    self.form.line,
                    1,
                    format!(
                        "record 7: even abscissa with increment {}; it must be positive",
                        self.form.step
                    ),
                ));
            }
            Abscissa::Even {
                min: self.form.min,
                step: self.form.step,
            }
        } else {
            Abscissa::Uneven(values.chunks_exact(per).map(|c| c[0]).collect())
        };
        let skip = usize::from(!self.form.even);
        let ordinate = if self.form.complex {
            Ordinate::Complex(
                values
                    .chunks_exact(per)
                    .map(|c| Complex64::new(c[skip], c[skip + 1]))
                    .collect(),
            )
        } else {
            Ordinate::Real(values.chunks_exact(per).map(|c| c[skip]).collect())
        };
        Ok(Function58 {
            id_lines: self.id_lines,
            function_type: self.function_type,
            function_id: self.ids[0],
            version: self.ids[1],
            load_case: self.ids[2],
            response: self.response,
            reference: self.reference,
            abscissa,
            z_axis_value: self.form.z,
            axes: self.axes,
            ordinate,
            precision: self.form.precision,
        })
    }
}

/// A line holding only `-1` (blanks around it allowed).
pub(super) fn is_marker(text: &[u8]) -> bool {
    text.trim_ascii() == b"-1"
}

/// Columns `from..to` (0-based, `to` exclusive, clipped to the line) as text.
fn column_text(text: &[u8], from: usize, to: usize) -> String {
    let from = from.min(text.len());
    let to = to.min(text.len());
    String::from_utf8_lossy(&text[from..to]).into_owned()
}

/// The first 60 characters of a line, for messages.
fn short(text: &[u8]) -> String {
    String::from_utf8_lossy(text).chars().take(60).collect()
}

/// A Fortran real: `1.5E+00`, `1.5e-03`, `1.5D+00`, `-1.47553E-102`.
fn parse_real(token: &str) -> Option<f64> {
    let t = token.replace(['D', 'd'], "E");
    t.parse::<f64>().ok()
}

/// Appends the numbers of one data line to `out`. Blank-separated tokens; a token that
/// is not one number may be Fortran numbers that touch (`-1.0E+00-2.0E+00`): it is
/// split before every sign that follows a digit, if every part has an exponent.
pub(super) fn parse_numbers(
    text: &[u8],
    error: impl Fn(usize, &str) -> Error,
    out: &mut Vec<f64>,
) -> Result<()> {
    let s = String::from_utf8_lossy(text);
    let mut offset = 0;
    for token in s.split_ascii_whitespace() {
        let column = s[offset..].find(token).map_or(offset, |p| offset + p) + 1;
        offset = column - 1 + token.len();
        if let Some(v) = parse_real(token).filter(|v| v.is_finite()) {
            out.push(v);
            continue;
        }
        let b = token.as_bytes();
        let cuts: Vec<usize> = (1..b.len())
            .filter(|&i| {
                matches!(b[i], b'+' | b'-') && (b[i - 1].is_ascii_digit() || b[i - 1] == b'.')
            })
            .collect();
        let bounds: Vec<usize> = std::iter::once(0).chain(cuts).chain([b.len()]).collect();
        let parts: Vec<&str> = bounds.windows(2).map(|w| &token[w[0]..w[1]]).collect();
        let ok = parts.len() > 1 && parts.iter().all(|p| p.contains(['E', 'e', 'D', 'd']));
        let values: Option<Vec<f64>> = ok
            .then(|| {
                parts
                    .iter()
                    .map(|p| parse_real(p).filter(|v| v.is_finite()))
                    .collect()
            })
            .flatten();
        match values {
            Some(v) => out.extend(v),
            None => return Err(error(column, token)),
        }
    }
    Ok(())
}
