//! The binary form 58b: its extra header line and its block of raw numbers.

use super::read::{is_marker, Cursor, Header};
use super::{Encoding, Precision};
use crate::error::{Error, Result};

/// Fields of the line `    58b     1     2          11        1600 ...`.
pub(super) struct BinaryHeader {
    little_endian: bool,
    /// Bytes of data the header announces.
    n_bytes: usize,
}

impl BinaryHeader {
    /// Parses the fields after `58b`: byte order, floating-point format, number of ASCII
    /// lines, number of bytes.
    pub fn parse(cur: &Cursor, head: &str, line: usize) -> Result<Self> {
        let fields: Vec<&str> = head.get(7..).unwrap_or("").split_whitespace().collect();
        let int = |k: usize, what: &str| -> Result<i64> {
            fields
                .get(k)
                .and_then(|f| f.parse::<i64>().ok())
                .ok_or_else(|| {
                    cur.cell(
                        line,
                        8,
                        format!(
                            "58b header: the {what} is missing or not an integer (format \
                             I6,A1,I6,I6,I12,I12: byte order, floating-point format, ASCII \
                             lines, bytes)"
                        ),
                    )
                })
        };
        let little_endian = match int(0, "byte order")? {
            1 => true,
            2 => false,
            v => {
                return Err(cur.cell(
                    line,
                    8,
                    format!(
                        "58b header: byte order {v}; expected 1 (little-endian) or 2 (big-endian)"
                    ),
                ))
            }
        };
        let fp = int(1, "floating-point format")?;
        if fp != 2 {
            return Err(cur.cell(
                line,
                14,
                format!(
                    "58b header: floating-point format {fp}; only 2 (IEEE 754) is supported \
                     (1 is DEC VMS, 3 IBM 370)"
                ),
            ));
        }
        let n_lines = int(2, "number of ASCII lines")?;
        if n_lines != 11 {
            return Err(cur.cell(
                line,
                20,
                format!(
                    "58b header: {n_lines} ASCII lines announced; dataset 58 has 11 (records 1-11)"
                ),
            ));
        }
        let n_bytes = int(3, "number of bytes")?;
        let n_bytes = usize::try_from(n_bytes).map_err(|_| {
            cur.cell(
                line,
                32,
                format!("58b header: number of bytes {n_bytes} is negative"),
            )
        })?;
        Ok(BinaryHeader {
            little_endian,
            n_bytes,
        })
    }

    pub fn encoding(&self) -> Encoding {
        Encoding::Binary {
            little_endian: self.little_endian,
        }
    }
}

/// Reads the binary block of `n_values` numbers that follows the header and the closing
/// `-1`, leaving the cursor after it. The block's length comes from record 7; the
/// header's byte count may differ only if the end marker is where record 7 says.
pub(super) fn binary_block(
    cur: &mut Cursor,
    bh: &BinaryHeader,
    header: &Header,
    n_values: usize,
) -> Result<Vec<f64>> {
    let width = match header.form.precision {
        Precision::Single => 4,
        Precision::Double => 8,
    };
    let start = cur.pos;
    let invalid = |what: String| Error::invalid(cur.path, what);
    let expected = n_values
        .checked_mul(width)
        .filter(|&n| n <= cur.bytes.len() - start);
    let Some(expected) = expected else {
        return Err(invalid(format!(
            "byte offset {start}: dataset 58b (line {}) needs {} x {width} bytes of data for \
             record 7's {} points; only {} bytes are left (is the file truncated?)",
            header.start.line,
            n_values,
            header.form.n_points,
            cur.bytes.len() - start
        )));
    };
    let end_at = |len: usize| marker_after(cur.bytes, start + len);
    let Some(next) = end_at(expected) else {
        let hint = if bh.n_bytes != expected && end_at(bh.n_bytes).is_some() {
            format!(
                "; the header's {} bytes end at a marker, so record 7's number of points or \
                 data type is wrong",
                bh.n_bytes
            )
        } else {
            String::new()
        };
        return Err(invalid(format!(
            "byte offset {}: dataset 58b (line {}) has no closing `-1` after its {expected} \
             bytes of data (record 7: {} points; header: {} bytes){hint}",
            start + expected,
            header.start.line,
            header.form.n_points,
            bh.n_bytes
        )));
    };
    let block = &cur.bytes[start..start + expected];
    let mut values = Vec::with_capacity(n_values);
    for (k, chunk) in block.chunks_exact(width).enumerate() {
        let v = match (width, bh.little_endian) {
            (4, true) => f32::from_le_bytes(chunk.try_into().unwrap_or([0; 4])) as f64,
            (4, false) => f32::from_be_bytes(chunk.try_into().unwrap_or([0; 4])) as f64,
            (_, true) => f64::from_le_bytes(chunk.try_into().unwrap_or([0; 8])),
            (_, false) => f64::from_be_bytes(chunk.try_into().unwrap_or([0; 8])),
        };
        if !v.is_finite() {
            return Err(invalid(format!(
                "byte offset {}: value {} of dataset 58b (line {}) is {v}; values must be finite",
                start + k * width,
                k + 1,
                header.start.line
            )));
        }
        values.push(v);
    }
    cur.line += block.iter().filter(|&&b| b == b'\n').count();
    cur.line += cur.bytes[start + expected..next]
        .iter()
        .filter(|&&b| b == b'\n')
        .count();
    cur.pos = next;
    Ok(values)
}

/// If a `-1` line starts at `at` (after an optional line end), the position after it.
fn marker_after(bytes: &[u8], at: usize) -> Option<usize> {
    let mut p = at;
    for nl in [&b"\r\n"[..], b"\n"] {
        if bytes.get(p..)?.starts_with(nl) {
            p += nl.len();
            break;
        }
    }
    let rest = bytes.get(p..)?;
    let end = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
    let line = rest[..end].strip_suffix(b"\r").unwrap_or(&rest[..end]);
    is_marker(line).then_some(p + (end + 1).min(rest.len()))
}
