//! FRF estimates as CSV: `freq_hz`, then for every response channel (in the estimate's
//! order) `<name>_re,<name>_im,<name>_coherence` of H1. Numbers are written in Rust's
//! shortest round-trip form, so reading back gives the same `f64`s. Metadata (input, kinds,
//! bands, window) is not part of this table.

use crate::error::{Error, Result};
use crate::io::write_atomic_with;
use crate::signal::TestFrf;
use num_complex::Complex64;
use std::path::Path;

/// One response's columns read back.
#[derive(Debug, Clone, PartialEq)]
pub struct FrfColumn {
    /// Channel name (the column prefix).
    pub name: String,
    pub h1: Vec<Complex64>,
    pub coherence: Vec<f64>,
}

/// A whole FRF table read back.
#[derive(Debug, Clone, PartialEq)]
pub struct FrfTable {
    pub freq_hz: Vec<f64>,
    pub columns: Vec<FrfColumn>,
}

/// Writes the H1 estimates and coherences of `frf` to `path` atomically.
pub fn write_frf_csv(path: &Path, frf: &TestFrf) -> Result<()> {
    for r in &frf.responses {
        if r.h1.len() != frf.freq_hz.len() || r.coherence.len() != frf.freq_hz.len() {
            return Err(Error::Usage(format!(
                "response {} has {} values for {} frequencies",
                r.channel.name,
                r.h1.len(),
                frf.freq_hz.len()
            )));
        }
        if r.channel.name.contains([',', '"', '\n', '\r']) {
            return Err(Error::Usage(format!(
                "channel name {:?} cannot be a CSV column prefix",
                r.channel.name
            )));
        }
    }
    write_atomic_with(path, |w| {
        write!(w, "freq_hz")?;
        for r in &frf.responses {
            let n = &r.channel.name;
            write!(w, ",{n}_re,{n}_im,{n}_coherence")?;
        }
        writeln!(w)?;
        for (k, f) in frf.freq_hz.iter().enumerate() {
            write!(w, "{f:e}")?;
            for r in &frf.responses {
                write!(w, ",{:e},{:e},{:e}", r.h1[k].re, r.h1[k].im, r.coherence[k])?;
            }
            writeln!(w)?;
        }
        Ok(())
    })
}

/// Reads a table written by [`write_frf_csv`]; errors name the file, line and column.
pub fn read_frf_csv(path: &Path) -> Result<FrfTable> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(std::io::BufReader::new(file));
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| Error::invalid(path, format!("cannot read the header: {e}")))?
        .iter()
        .map(|s| s.trim().to_string())
        .collect();
    if header.first().map(String::as_str) != Some("freq_hz")
        || !(header.len() - 1).is_multiple_of(3)
    {
        return Err(Error::invalid(
            path,
            "header must be freq_hz followed by <name>_re,<name>_im,<name>_coherence triples",
        ));
    }
    let mut columns = Vec::new();
    for (t, triple) in header[1..].chunks(3).enumerate() {
        let name = triple[0].strip_suffix("_re").unwrap_or("");
        if name.is_empty()
            || triple[1] != format!("{name}_im")
            || triple[2] != format!("{name}_coherence")
        {
            return Err(Error::Cell {
                path: path.into(),
                line: 1,
                column: 2 + 3 * t,
                what: format!(
                    "expected <name>_re,<name>_im,<name>_coherence, found {}",
                    triple.join(",")
                ),
            });
        }
        columns.push(FrfColumn {
            name: name.to_string(),
            h1: Vec::new(),
            coherence: Vec::new(),
        });
    }
    let mut freq_hz = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let line = i + 2;
        let rec = rec.map_err(|e| Error::Cell {
            path: path.into(),
            line,
            column: 1,
            what: e.to_string(),
        })?;
        if rec.len() != header.len() {
            return Err(Error::Cell {
                path: path.into(),
                line,
                column: rec.len().min(header.len()) + 1,
                what: format!("{} cells, the header has {}", rec.len(), header.len()),
            });
        }
        let cell = |c: usize| -> Result<f64> {
            let s = rec[c].trim();
            match s.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(Error::Cell {
                    path: path.into(),
                    line,
                    column: c + 1,
                    what: format!("{s:?} is not a finite number"),
                }),
            }
        };
        freq_hz.push(cell(0)?);
        for (t, col) in columns.iter_mut().enumerate() {
            let c = 1 + 3 * t;
            col.h1.push(Complex64::new(cell(c)?, cell(c + 1)?));
            col.coherence.push(cell(c + 2)?);
        }
    }
    Ok(FrfTable { freq_hz, columns })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::FrfKind;
    use crate::io::{Channel, Quantity};
    use crate::signal::{InputKind, ResponseFrf};

    fn sample() -> TestFrf {
        let freq_hz: Vec<f64> = (0..5).map(|k| k as f64 * 0.1).collect();
        let resp = |name: &str, q: Quantity, kind, s: f64| ResponseFrf {
            channel: Channel {
                name: name.into(),
                quantity: q,
                floor: 1,
                unit: q.unit().into(),
            },
            kind,
            h1: (0..5)
                .map(|k| Complex64::new(s / (k as f64 + 0.3), -1e-7 * k as f64))
                .collect(),
            h2: vec![Complex64::new(0.0, 0.0); 5],
            coherence: (0..5).map(|k| 1.0 - 0.1 * k as f64 / 3.0).collect(),
            output_coherence: (0..5).map(|k| 1.0 - 0.1 * k as f64 / 3.0).collect(),
        };
        TestFrf {
            test: "t".into(),
            freq_hz,
            input: InputKind::Ground {
                channel: "ground_acc".into(),
            },
            responses: vec![
                resp("acc1", Quantity::Acceleration, FrfKind::Accelerance, 1.0),
                resp("disp1", Quantity::Displacement, FrfKind::Receptance, 3.3e-5),
            ],
            n_averages: 1,
            coherence_dof: 5,
            exp_window_tau_s: None,
            block_s: 10.0,
            impacts_s: vec![],
            input_power: vec![1.0; 5],
            input_spectra: vec![],
            bands: vec![],
            selected: vec![],
            input_noise: None,
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("frf.csv");
        let frf = sample();
        write_frf_csv(&p, &frf).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(
            text.lines().next().unwrap(),
            "freq_hz,acc1_re,acc1_im,acc1_coherence,disp1_re,disp1_im,disp1_coherence"
        );
        let back = read_frf_csv(&p).unwrap();
        assert_eq!(back.freq_hz, frf.freq_hz);
        for (c, r) in back.columns.iter().zip(&frf.responses) {
            assert_eq!(c.name, r.channel.name);
            assert_eq!(c.h1, r.h1);
            assert_eq!(c.coherence, r.coherence);
        }
    }

    #[test]
    fn bad_files_name_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.csv");
        std::fs::write(&p, "freq_hz,a_re,a_im,a_coherence\n0,1,2,1\n0.1,1,x,1\n").unwrap();
        match read_frf_csv(&p) {
            Err(Error::Cell { line, column, .. }) => assert_eq!((line, column), (3, 3)),
            other => panic!("{other:?}"),
        }
        std::fs::write(&p, "freq_hz,a_re,b_im,a_coherence\n").unwrap();
        assert!(matches!(
            read_frf_csv(&p),
            Err(Error::Cell {
                line: 1,
                column: 2,
                ..
            })
        ));
        std::fs::write(&p, "f,a_re,a_im,a_coherence\n").unwrap();
        assert!(matches!(read_frf_csv(&p), Err(Error::Invalid { .. })));
        std::fs::write(&p, "freq_hz,a_re,a_im,a_coherence\n0,1,2\n").unwrap();
        assert!(matches!(read_frf_csv(&p), Err(Error::Cell { line: 2, .. })));
        std::fs::write(&p, "freq_hz,a_re,a_im,a_coherence\n0,1,NaN,1\n").unwrap();
        assert!(matches!(
            read_frf_csv(&p),
            Err(Error::Cell {
                line: 2,
                column: 3,
                ..
            })
        ));
        assert!(matches!(
            read_frf_csv(&dir.path().join("missing.csv")),
            Err(Error::Io { .. })
        ));
    }
}
