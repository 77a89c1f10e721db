//! Unison Tower with a hybrid mass damper (`tower-hmd`): records, the damper force, and
//! Welch H1 estimates from that force to the floor accelerations.
//!
//! The force the damper exerts on the building is `F = -m_d a_d` (Newton's law for the
//! damper mass `m_d` with absolute acceleration `a_d`), applied at floor 5, so the
//! building model excludes the damper mass and takes `F` as its input.
//!
//! Spectra: Hann-windowed segments with 50% overlap, accumulated over every record;
//! `H1 = G_fy / G_ff`, `gamma^2 = |G_fy|^2 / (G_ff G_yy)`. With `n_d` segments the H1
//! estimate has `E|dH|^2 = |H|^2 (1 - gamma^2) / (n_d gamma^2)` (Bendat & Piersol; the
//! effective `n_d` of 50%-overlapped Hann segments is a little smaller, which the
//! likelihood's noise scale absorbs).

use std::path::{Path, PathBuf};

use num_complex::Complex64;

use crate::error::{Error, Result};
use crate::signal::spectra::Fft;
use crate::signal::windows::hann;

/// Record files.
pub const FILES: [&str; 3] = ["wn_01.dat", "wn_02.dat", "wn_03.dat"];
/// Columns per row.
pub const N_COLUMNS: usize = 8;
/// Sampling rate (Hz).
pub const SAMPLE_RATE_HZ: f64 = 100.0;
/// The author's calibration of columns 1-8 (V to m/s^2; cm for column 8), unverified.
pub const AUTHOR_GAINS: [f64; 8] = [1.0, 9.8, -9.8, 2.0, 2.0, 1.0, 1.0, 2.25 / 9.0];
/// Damper mass (kg), the author's 1.5 tf.
pub const DAMPER_MASS_KG: f64 = 1500.0;
/// Floor mass (kg), the author's (64.8 + 32.0275) / 5 tf.
pub const FLOOR_MASS_KG: f64 = (64.8 + 32.0275) / 5.0 * 1000.0;
/// Column (0-based) of the floor-f acceleration, f = 1..5.
pub const FLOOR_COLUMN: [usize; 5] = [4, 5, 6, 3, 2];
/// Column of the damper acceleration.
pub const DAMPER_COLUMN: usize = 1;

/// One record: columns of raw volts.
#[derive(Debug, Clone)]
pub struct Record {
    pub path: PathBuf,
    /// `columns[j][n]`.
    pub columns: Vec<Vec<f64>>,
}

/// Reads one whitespace-separated record of [`N_COLUMNS`] columns; errors name the file,
/// line and column.
pub fn read_record(path: &Path) -> Result<Record> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut columns = vec![Vec::new(); N_COLUMNS];
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let mut n = 0;
        for (j, cell) in line.split_whitespace().enumerate() {
            if j >= N_COLUMNS {
                return Err(Error::Cell {
                    path: path.into(),
                    line: i + 1,
                    column: j + 1,
                    what: format!("more than {N_COLUMNS} columns"),
                });
            }
            let v: f64 = cell.parse().map_err(|_| Error::Cell {
                path: path.into(),
                line: i + 1,
                column: j + 1,
                what: format!("`{cell}` is not a number"),
            })?;
            if !v.is_finite() {
                return Err(Error::Cell {
                    path: path.into(),
                    line: i + 1,
                    column: j + 1,
                    what: format!("`{cell}` is not finite"),
                });
            }
            columns[j].push(v);
            n += 1;
        }
        if n != N_COLUMNS {
            return Err(Error::Cell {
                path: path.into(),
                line: i + 1,
                column: n + 1,
                what: format!("{n} columns; expected {N_COLUMNS}"),
            });
        }
    }
    if columns[0].len() < 1024 {
        return Err(Error::invalid(
            path,
            format!(
                "{} rows; expected a long record (at least 1024)",
                columns[0].len()
            ),
        ));
    }
    Ok(Record {
        path: path.into(),
        columns,
    })
}

/// Reads the three records of the dataset folder.
pub fn load(dir: &Path) -> Result<Vec<Record>> {
    FILES.iter().map(|f| read_record(&dir.join(f))).collect()
}

/// Welch H1 FRFs from the damper force to the five floor accelerations, with the
/// author's calibration applied (so a gain of 1 means "the author's calibration").
#[derive(Debug, Clone)]
pub struct TowerFrf {
    pub freq_hz: Vec<f64>,
    /// `h1[f][k]`: floor f+1 acceleration per damper force, (m/s^2)/N.
    pub h1: Vec<Vec<Complex64>>,
    /// `coherence[f][k]`.
    pub coherence: Vec<Vec<f64>>,
    /// Segments averaged.
    pub n_segments: usize,
    pub segment_len: usize,
}

/// H1 and coherence from `-m_d a_d` to each floor, segments of `segment_len` samples.
pub fn estimate_frf(records: &[Record], segment_len: usize) -> Result<TowerFrf> {
    if segment_len < 16 || !segment_len.is_power_of_two() {
        return Err(Error::Usage(format!(
            "segment length {segment_len}: use a power of two of at least 16"
        )));
    }
    let window = hann(segment_len);
    let mut fft = Fft::new();
    let nb = segment_len / 2 + 1;
    let mut gff = vec![0.0; nb];
    let mut gfy = vec![vec![Complex64::new(0.0, 0.0); nb]; 5];
    let mut gyy = vec![vec![0.0; nb]; 5];
    let mut n_segments = 0;
    for rec in records {
        let n = rec.columns[0].len();
        let force: Vec<f64> = rec.columns[DAMPER_COLUMN]
            .iter()
            .map(|v| -DAMPER_MASS_KG * AUTHOR_GAINS[DAMPER_COLUMN] * v)
            .collect();
        let floors: Vec<Vec<f64>> = FLOOR_COLUMN
            .iter()
            .map(|&c| rec.columns[c].iter().map(|v| AUTHOR_GAINS[c] * v).collect())
            .collect();
        let mut start = 0;
        while start + segment_len <= n {
            let seg = |x: &[f64]| -> Vec<f64> {
                let s = &x[start..start + segment_len];
                let m = s.iter().sum::<f64>() / segment_len as f64;
                s.iter().map(|v| v - m).collect()
            };
            let fk = fft.forward(&seg(&force), Some(&window), segment_len)?;
            for k in 0..nb {
                gff[k] += fk[k].norm_sqr();
            }
            for (f, y) in floors.iter().enumerate() {
                let yk = fft.forward(&seg(y), Some(&window), segment_len)?;
                for k in 0..nb {
                    gfy[f][k] += fk[k].conj() * yk[k];
                    gyy[f][k] += yk[k].norm_sqr();
                }
            }
            n_segments += 1;
            start += segment_len / 2;
        }
    }
    if n_segments < 2 {
        return Err(Error::Usage(format!(
            "records too short for segments of {segment_len} samples"
        )));
    }
    let freq_hz = (0..nb)
        .map(|k| k as f64 * SAMPLE_RATE_HZ / segment_len as f64)
        .collect();
    let h1 = gfy
        .iter()
        .map(|g| g.iter().zip(&gff).map(|(a, b)| a / b).collect())
        .collect();
    let coherence = gfy
        .iter()
        .zip(&gyy)
        .map(|(g, yy)| {
            g.iter()
                .zip(yy)
                .zip(&gff)
                .map(|((a, y), f)| (a.norm_sqr() / (f * y)).min(1.0))
                .collect()
        })
        .collect();
    Ok(TowerFrf {
        freq_hz,
        h1,
        coherence,
        n_segments,
        segment_len,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_records_name_file_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.dat");
        std::fs::write(&p, "1 2 3 4 5 6 7 8\n1 2 3 x 5 6 7 8\n").unwrap();
        let e = read_record(&p).unwrap_err().to_string();
        assert!(e.contains("bad.dat:2:4") && e.contains("`x`"), "{e}");
        std::fs::write(&p, "1 2 3 4 5 6 7\n").unwrap();
        let e = read_record(&p).unwrap_err().to_string();
        assert!(e.contains("bad.dat:1:8") && e.contains("7 columns"), "{e}");
        std::fs::write(&p, "1 2 3 4 5 6 7 8\n").unwrap();
        let e = read_record(&p).unwrap_err().to_string();
        assert!(e.contains("1 rows"), "{e}");
    }

    /// The real records (skipped without ../shared): three records of 40960 rows, and
    /// the first mode near 0.53 Hz in the top-floor FRF with good coherence.
    #[test]
    fn reads_the_real_records() {
        let Some(dir) = crate::real::shared_dataset(crate::real::Dataset::TowerHmd) else {
            return;
        };
        let recs = load(&dir).unwrap();
        assert!(recs.iter().all(|r| r.columns[0].len() == 40960));
        let est = estimate_frf(&recs, 4096).unwrap();
        let band: Vec<usize> = (0..est.freq_hz.len())
            .filter(|&k| est.freq_hz[k] > 0.4 && est.freq_hz[k] < 0.8)
            .collect();
        let k = *band
            .iter()
            .max_by(|&&a, &&b| est.h1[4][a].norm().total_cmp(&est.h1[4][b].norm()))
            .unwrap();
        assert!((est.freq_hz[k] - 0.53).abs() < 0.06, "{}", est.freq_hz[k]);
    }

    /// H1 of a known FIR relation y = 2 x[n] - 0.5 x[n-1] from white noise: the exact
    /// FRF is 2 - 0.5 exp(-j w dt), and coherence is near 1 (leakage of the one-sample
    /// delay over a 256-sample Hann window is ~1e-3 relative).
    #[test]
    fn welch_h1_recovers_a_known_filter() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let n = 8192;
        let x: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
        let mut columns = vec![vec![0.0; n]; N_COLUMNS];
        // Force column holds x scaled so that -m_d g_d a = x.
        columns[DAMPER_COLUMN] = x
            .iter()
            .map(|v| -v / (DAMPER_MASS_KG * AUTHOR_GAINS[DAMPER_COLUMN]))
            .collect();
        for (f, &c) in FLOOR_COLUMN.iter().enumerate() {
            let a = (f + 1) as f64;
            columns[c] = (0..n)
                .map(|i| {
                    (2.0 * a * x[i] - 0.5 * if i > 0 { x[i - 1] } else { 0.0 }) / AUTHOR_GAINS[c]
                })
                .collect();
        }
        let rec = Record {
            path: "synthetic".into(),
            columns,
        };
        let est = estimate_frf(&[rec], 256).unwrap();
        for f in 0..5 {
            let a = (f + 1) as f64;
            for k in [10usize, 40, 100] {
                let w = 2.0 * std::f64::consts::PI * est.freq_hz[k] / SAMPLE_RATE_HZ;
                let exact = Complex64::new(2.0 * a, 0.0) - 0.5 * Complex64::from_polar(1.0, -w);
                assert!(
                    (est.h1[f][k] - exact).norm() / exact.norm() < 0.01,
                    "floor {f} bin {k}"
                );
                assert!(est.coherence[f][k] > 0.99);
            }
        }
    }
}
