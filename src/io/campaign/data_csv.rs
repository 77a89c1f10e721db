//! `tests/<name>/data.csv`: header `time_s,<channel names in any order>`, then one row
//! per sample. Parsed with the `csv` crate (`ByteRecord`, no per-cell allocation) and
//! `str::parse::<f64>`.

use crate::error::{Error, Result};
use crate::io::Channel;
use std::collections::HashMap;
use std::path::Path;

/// Allowed deviation of `time_s` from `i / sample_rate_hz`, as a fraction of the sample
/// period, on top of half the resolution the time is printed with. A dropped or repeated
/// sample moves the time by a whole period, far beyond this.
const TIME_SLACK_PER_PERIOD: f64 = 0.01;

/// Largest rounding of `time_s` accepted, as a fraction of the sample period: below one
/// half, so that neighbouring samples stay distinguishable.
const MAX_ROUNDING_PER_PERIOD: f64 = 0.45;

/// A bad cell: 1-based column and what to fix. The line is worked out only when needed.
struct Problem {
    column: usize,
    what: String,
}

/// Reads the samples of `path`, returned per channel in the order of `channels`.
pub(super) fn read_data(
    path: &Path,
    channels: &[Channel],
    sample_rate_hz: f64,
) -> Result<Vec<Vec<f64>>> {
    // The whole file in memory (a few MB): fast, and lets errors count lines exactly.
    let bytes = std::fs::read(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::invalid(
            path,
            "file not found; each test folder needs data.csv (header time_s,<channel names>, \
             then one row per sample)",
        ),
        _ => Error::io(path, e),
    })?;
    // Rough row count for the initial allocation: about 12 bytes per cell.
    let rows_guess = (bytes.len() / (12 * (channels.len() + 1))).min(1 << 24);

    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes.as_slice());
    let mut record = csv::ByteRecord::new();
    let csv_err = |e: csv::Error| Error::io(path, e.into());
    let at = |record: &csv::ByteRecord, p: Problem| Error::Cell {
        path: path.to_path_buf(),
        line: line_of(&bytes, record),
        column: p.column,
        what: p.what,
    };

    if !reader.read_byte_record(&mut record).map_err(csv_err)? {
        return Err(Error::invalid(
            path,
            "empty file; the first line must be the header time_s,<channel names>",
        ));
    }
    let column_channel = map_header(&record, channels).map_err(|p| at(&record, p))?;
    for (ch, c) in channels.iter().enumerate() {
        if !column_channel.contains(&ch) {
            return Err(Error::invalid(
                path,
                format!(
                    "the header has no column `{}`, which test.toml lists as a channel; add the \
                     column or remove that [[channel]] from test.toml",
                    c.name
                ),
            ));
        }
    }
    let n_columns = record.len();

    let period_s = 1.0 / sample_rate_hz;
    let mut data: Vec<Vec<f64>> = channels
        .iter()
        .map(|_| Vec::with_capacity(rows_guess))
        .collect();
    let mut i_sample: usize = 0;
    while reader.read_byte_record(&mut record).map_err(csv_err)? {
        read_row(
            &record,
            n_columns,
            &column_channel,
            i_sample,
            period_s,
            &mut data,
        )
        .map_err(|p| at(&record, p))?;
        i_sample += 1;
    }
    if i_sample == 0 {
        return Err(Error::invalid(
            path,
            "no samples after the header; add one row per sample",
        ));
    }
    Ok(data)
}

/// Parses one data row into `data` (per channel).
fn read_row(
    record: &csv::ByteRecord,
    n_columns: usize,
    column_channel: &[usize],
    i_sample: usize,
    period_s: f64,
    data: &mut [Vec<f64>],
) -> Result<(), Problem> {
    if record.len() != n_columns {
        let hint = if record.len() < n_columns {
            "every row needs one cell per header column"
        } else {
            "remove the extra cells or name their columns in the header"
        };
        return Err(Problem {
            column: record.len().min(n_columns) + 1,
            what: format!(
                "row has {} cells but the header has {n_columns}; {hint}",
                record.len()
            ),
        });
    }
    let time_s = parse_cell(1, &record[0])?;
    check_time(&record[0], time_s, i_sample, period_s)?;
    for (j, &ch) in column_channel.iter().enumerate() {
        data[ch].push(parse_cell(j + 2, &record[j + 1])?);
    }
    Ok(())
}

/// 1-based line of `record` in `bytes`. The csv crate's position can stop short of the
/// record (after a `\r` of CRLF, or before blank lines it skips), so the line breaks
/// between that position and the record's first byte are counted here.
fn line_of(bytes: &[u8], record: &csv::ByteRecord) -> usize {
    let Some(pos) = record.position() else {
        return 0;
    };
    let start = (pos.byte() as usize).min(bytes.len());
    let skipped = bytes[start..]
        .iter()
        .take_while(|&&b| b == b'\n' || b == b'\r')
        .filter(|&&b| b == b'\n')
        .count();
    pos.line() as usize + skipped
}

/// For each data column (after `time_s`), the index of its channel. Checks that every
/// header column is a channel of test.toml, once.
fn map_header(header: &csv::ByteRecord, channels: &[Channel]) -> Result<Vec<usize>, Problem> {
    let by_name: HashMap<&str, usize> = channels
        .iter()
        .enumerate()
        .map(|(i, c)| (c.name.as_str(), i))
        .collect();
    let mut names: Vec<&str> = Vec::with_capacity(header.len());
    for (j, cell) in header.iter().enumerate() {
        let Ok(name) = std::str::from_utf8(cell) else {
            return Err(Problem {
                column: j + 1,
                what: "header cell is not valid UTF-8; use plain column names".into(),
            });
        };
        let name = name.trim();
        // A byte-order mark some spreadsheet programs put at the start of the file.
        let name = if j == 0 {
            name.trim_start_matches('\u{feff}')
        } else {
            name
        };
        names.push(name);
    }
    let first = names.first().copied().unwrap_or_default();
    if first != "time_s" {
        return Err(Problem {
            column: 1,
            what: format!("the first header column is `{first}`; it must be `time_s`"),
        });
    }
    let mut column_channel = Vec::with_capacity(names.len() - 1);
    let mut first_column: HashMap<&str, usize> = HashMap::new();
    for (j, &name) in names.iter().enumerate().skip(1) {
        if let Some(&earlier) = first_column.get(name) {
            return Err(Problem {
                column: j + 1,
                what: format!(
                    "column `{name}` appears twice in the header (also column {}); \
                     every column needs its own name",
                    earlier + 1
                ),
            });
        }
        first_column.insert(name, j);
        let Some(&ch) = by_name.get(name) else {
            return Err(Problem {
                column: j + 1,
                what: format!(
                    "column `{name}` is not a channel of test.toml; add a [[channel]] with \
                     name = \"{name}\" or remove the column"
                ),
            });
        };
        column_channel.push(ch);
    }
    Ok(column_channel)
}

/// One number; empty, non-numeric and non-finite cells are errors.
fn parse_cell(column: usize, cell: &[u8]) -> Result<f64, Problem> {
    let cell = cell.trim_ascii();
    if cell.is_empty() {
        return Err(Problem {
            column,
            what: "empty cell; every cell needs a number".into(),
        });
    }
    let parsed = std::str::from_utf8(cell)
        .ok()
        .and_then(|s| s.parse::<f64>().ok());
    match parsed {
        Some(v) if v.is_finite() => Ok(v),
        Some(_) => Err(Problem {
            column,
            what: format!(
                "`{}` is NaN or infinite; only finite numbers are allowed (repair or cut the \
                 record)",
                String::from_utf8_lossy(cell)
            ),
        }),
        None => Err(Problem {
            column,
            what: format!(
                "`{}` is not a number; use decimal numbers with `.` (e.g. 1.25e-3)",
                String::from_utf8_lossy(cell)
            ),
        }),
    }
}

/// Smallest step the cell's text can express: `10^(exponent - decimals)`
/// (`0.0020` -> 1e-4, `2.5e-3` -> 1e-4, `12` -> 1).
fn printed_resolution(cell: &[u8]) -> f64 {
    let cell = cell.trim_ascii();
    let (mantissa, exponent) = match cell.iter().position(|&b| b == b'e' || b == b'E') {
        Some(k) => (
            &cell[..k],
            std::str::from_utf8(&cell[k + 1..])
                .ok()
                .and_then(|s| s.parse::<i32>().ok())
                .unwrap_or(0),
        ),
        None => (cell, 0),
    };
    let decimals = mantissa
        .iter()
        .position(|&b| b == b'.')
        .map_or(0, |k| mantissa.len() - k - 1) as i32;
    10f64.powi(exponent - decimals)
}

/// `time_s` must equal `i / sample_rate_hz` within half its printed resolution (capped
/// at [`MAX_ROUNDING_PER_PERIOD`] of a period) plus [`TIME_SLACK_PER_PERIOD`] of a period.
/// 4 decimals at 500 Hz: 5e-5 s + 2e-5 s, against a period of 2e-3 s. Shortest
/// round-trip printing (`0.1`, `0.102`) is exact and passes whatever its decimals.
fn check_time(cell: &[u8], time_s: f64, i_sample: usize, period_s: f64) -> Result<(), Problem> {
    let half_resolution_s = 0.5 * printed_resolution(cell);
    let tolerance_s = half_resolution_s.min(MAX_ROUNDING_PER_PERIOD * period_s)
        + TIME_SLACK_PER_PERIOD * period_s;
    let expected_s = i_sample as f64 * period_s;
    if (time_s - expected_s).abs() <= tolerance_s {
        return Ok(());
    }
    let mut what = if i_sample == 0 {
        format!("time_s of the first sample is {time_s}; it must start at 0")
    } else {
        format!(
            "time_s is {time_s} but sample {i_sample} should be at {expected_s} s (time_s must \
             step uniformly by 1/sample_rate_hz = {period_s} s from 0; a sample is missing or \
             repeated, or sample_rate_hz in test.toml is wrong)"
        )
    };
    if half_resolution_s > MAX_ROUNDING_PER_PERIOD * period_s {
        what += "; if the time is right, print time_s with more decimals";
    }
    Err(Problem { column: 1, what })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Quantity;

    /// Line reported for the bad cell `x` in `text` (one channel `a`, 10 Hz).
    fn bad_line(text: &str) -> (usize, usize) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("data.csv");
        std::fs::write(&path, text).unwrap();
        let channels = [Channel {
            name: "a".into(),
            quantity: Quantity::Acceleration,
            floor: 1,
            unit: "m/s^2".into(),
        }];
        match read_data(&path, &channels, 10.0) {
            Err(Error::Cell { line, column, .. }) => (line, column),
            other => panic!("expected a cell error, got {other:?}"),
        }
    }

    #[test]
    fn lines_are_counted_across_crlf_and_blank_lines() {
        assert_eq!(bad_line("time_s,a\n0,1\n0.1,x\n"), (3, 2));
        assert_eq!(bad_line("time_s,a\r\n0,1\r\n0.1,x\r\n"), (3, 2));
        assert_eq!(bad_line("time_s,a\n0,1\n\n\n0.1,x\n"), (5, 2));
        assert_eq!(bad_line("time_s,a\r\n\r\n0,1\r\n\r\n0.1,x"), (5, 2));
        assert_eq!(bad_line("\n\ntime,a\n0,1\n"), (3, 1));
        // A quoted cell spanning two lines: the record starts on line 3.
        assert_eq!(bad_line("time_s,a\n0,1\n0.1,\"x\ny\"\n0.2,x\n"), (3, 2));
    }

    #[test]
    fn printed_resolution_counts_decimals_and_exponent() {
        let cases: [(&str, f64); 6] = [
            ("0.0020", 1e-4),
            ("119.9980", 1e-4),
            ("12", 1.0),
            ("2.5e-3", 1e-4),
            (" 0.5E1 ", 1.0),
            ("0.001", 1e-3),
        ];
        for (s, r) in cases {
            let got = printed_resolution(s.as_bytes());
            assert!((got - r).abs() <= 1e-12 * r, "{s}: {got} vs {r}");
        }
    }
}
