//! Residual map: where measured and predicted FRFs differ, per segment x channel (rows) and
//! resonance band (columns, plus one column for everything off the bands).
//!
//! Inputs are plain: for each row the frequencies, measured and predicted complex FRFs
//! and the noise `sigma_i` of each measured value (standard deviation of its real and of
//! its imaginary part, complex circular noise as in the diagnosis model:
//! `sigma_i^2 = (eps_i^2 + eta^2) |H_meas,i|^2`).
//!
//! Standardised residuals per point, to first order in `sigma / |H|`:
//! - log magnitude `z_mag = (ln|H_meas| - ln|H_pred|) |H_meas| / sigma`,
//! - phase `z_phase = wrap(arg H_meas - arg H_pred) |H_meas| / sigma`,
//!
//! each standard normal when the prediction is right. A cell reports the RMS and the mean
//! of each over its points, and `chi2_per_point = sum |H_meas - H_pred|^2 / sigma^2 / (2 n)`
//! (per real datum: 1 when the prediction is right).

use crate::error::{Error, Result};
use crate::io::write_atomic;
use crate::plot::{heatmap, HeatmapSpec};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

/// One row's data: a channel of a segment.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualRow {
    /// Segment label (test or `test#impactN`).
    pub segment: String,
    pub channel: String,
    pub freq_hz: Vec<f64>,
    pub measured: Vec<Complex64>,
    pub predicted: Vec<Complex64>,
    /// Standard deviation of the real (and of the imaginary) part of each measured value.
    pub sigma: Vec<f64>,
}

/// One cell of the map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ResidualCell {
    pub n_points: usize,
    /// RMS of `z_mag` (NaN without points).
    pub rms_log_mag: f64,
    /// RMS of `z_phase`.
    pub rms_phase: f64,
    /// Mean `z_mag` (signed: positive where the measurement exceeds the prediction).
    pub mean_log_mag: f64,
    /// Mean `z_phase` (signed: positive where the measurement leads).
    pub mean_phase: f64,
    pub chi2_per_point: f64,
}

/// Which cell value to draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapValue {
    RmsLogMag,
    RmsPhase,
    MeanLogMag,
    MeanPhase,
    Chi2PerPoint,
}

impl MapValue {
    fn label(self) -> &'static str {
        match self {
            MapValue::RmsLogMag => "RMS standardised residual of ln|H|",
            MapValue::RmsPhase => "RMS standardised residual of phase",
            MapValue::MeanLogMag => "Mean standardised residual of ln|H|",
            MapValue::MeanPhase => "Mean standardised residual of phase",
            MapValue::Chi2PerPoint => "chi^2 per real datum",
        }
    }

    fn of(self, c: &ResidualCell) -> f64 {
        match self {
            MapValue::RmsLogMag => c.rms_log_mag,
            MapValue::RmsPhase => c.rms_phase,
            MapValue::MeanLogMag => c.mean_log_mag,
            MapValue::MeanPhase => c.mean_phase,
            MapValue::Chi2PerPoint => c.chi2_per_point,
        }
    }
}

/// Residual map (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualMap {
    /// `segment / channel` per row.
    pub rows: Vec<(String, String)>,
    /// Band edges, Hz; the last column (`off-band`) has none.
    pub bands_hz: Vec<(f64, f64)>,
    /// `cells[row][column]`, `bands_hz.len() + 1` columns.
    pub cells: Vec<Vec<ResidualCell>>,
}

fn wrap_pi(x: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    x - two_pi * ((x + std::f64::consts::PI) / two_pi).floor()
}

impl ResidualMap {
    /// Builds the map. A point belongs to the first band `[lo, hi]` containing its
    /// frequency, else to the off-band column. Points with a non-finite or non-positive
    /// sigma or a zero measured value are skipped.
    pub fn new(rows: &[ResidualRow], bands_hz: &[(f64, f64)]) -> Result<ResidualMap> {
        let n_col = bands_hz.len() + 1;
        let mut cells = Vec::with_capacity(rows.len());
        for r in rows {
            let n = r.freq_hz.len();
            if r.measured.len() != n || r.predicted.len() != n || r.sigma.len() != n {
                return Err(Error::Usage(format!(
                    "residual map row {} / {}: {} frequencies, {} measured, {} predicted, {} sigma; they must match",
                    r.segment,
                    r.channel,
                    n,
                    r.measured.len(),
                    r.predicted.len(),
                    r.sigma.len()
                )));
            }
            // accumulators: n, sum zm^2, sum zp^2, sum zm, sum zp, sum chi2
            let mut acc = vec![[0.0f64; 6]; n_col];
            for i in 0..n {
                let (m, p, s) = (r.measured[i], r.predicted[i], r.sigma[i]);
                if !(s.is_finite() && s > 0.0 && m.is_finite() && p.is_finite() && m.norm() > 0.0) {
                    continue;
                }
                let f = r.freq_hz[i];
                let col = bands_hz
                    .iter()
                    .position(|&(lo, hi)| f >= lo && f <= hi)
                    .unwrap_or(n_col - 1);
                let scale = m.norm() / s;
                let zm = if p.norm() > 0.0 {
                    (m.norm() / p.norm()).ln() * scale
                } else {
                    f64::INFINITY
                };
                let zp = wrap_pi(m.arg() - p.arg()) * scale;
                let a = &mut acc[col];
                a[0] += 1.0;
                a[1] += zm * zm;
                a[2] += zp * zp;
                a[3] += zm;
                a[4] += zp;
                a[5] += (m - p).norm_sqr() / (s * s);
            }
            cells.push(
                acc.iter()
                    .map(|a| {
                        let k = a[0];
                        let div = |v: f64| if k > 0.0 { v / k } else { f64::NAN };
                        ResidualCell {
                            n_points: k as usize,
                            rms_log_mag: div(a[1]).sqrt(),
                            rms_phase: div(a[2]).sqrt(),
                            mean_log_mag: div(a[3]),
                            mean_phase: div(a[4]),
                            chi2_per_point: div(a[5] / 2.0),
                        }
                    })
                    .collect(),
            );
        }
        Ok(ResidualMap {
            rows: rows
                .iter()
                .map(|r| (r.segment.clone(), r.channel.clone()))
                .collect(),
            bands_hz: bands_hz.to_vec(),
            cells,
        })
    }

    /// Column labels: `lo-hi Hz` per band, then `off-band`.
    pub fn column_labels(&self) -> Vec<String> {
        self.bands_hz
            .iter()
            .map(|(lo, hi)| format!("{lo:.2}-{hi:.2} Hz"))
            .chain(std::iter::once("off-band".to_string()))
            .collect()
    }

    /// Row labels `segment / channel`.
    pub fn row_labels(&self) -> Vec<String> {
        self.rows
            .iter()
            .map(|(s, c)| format!("{s} / {c}"))
            .collect()
    }

    /// Overall chi^2 per real datum over all cells.
    pub fn chi2_per_point(&self) -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for c in self.cells.iter().flatten().filter(|c| c.n_points > 0) {
            num += c.chi2_per_point * c.n_points as f64;
            den += c.n_points as f64;
        }
        if den > 0.0 {
            num / den
        } else {
            f64::NAN
        }
    }

    /// The `n` cells with the largest chi^2 per point: (row, column, cell).
    pub fn worst_cells(&self, n: usize) -> Vec<(usize, usize, ResidualCell)> {
        let mut v: Vec<(usize, usize, ResidualCell)> = self
            .cells
            .iter()
            .enumerate()
            .flat_map(|(r, row)| row.iter().enumerate().map(move |(c, cell)| (r, c, *cell)))
            .filter(|(_, _, c)| c.n_points > 0 && c.chi2_per_point.is_finite())
            .collect();
        v.sort_by(|a, b| b.2.chi2_per_point.total_cmp(&a.2.chi2_per_point));
        v.truncate(n);
        v
    }

    /// Markdown table: one row per segment / channel, each cell
    /// `RMS z(ln|H|) / RMS z(phase) (chi^2 per point)`.
    pub fn to_markdown(&self) -> String {
        let cols = self.column_labels();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Cells: RMS standardised residual of ln|H| / of phase (chi^2 per real datum); about 1 / 1 (1) where the prediction is right.\n"
        );
        let _ = writeln!(s, "| segment / channel | {} |", cols.join(" | "));
        let _ = writeln!(s, "|---|{}", "---|".repeat(cols.len()));
        for (label, row) in self.row_labels().iter().zip(&self.cells) {
            let cells: Vec<String> = row
                .iter()
                .map(|c| {
                    if c.n_points == 0 {
                        "-".to_string()
                    } else {
                        format!(
                            "{:.1} / {:.1} ({:.1})",
                            c.rms_log_mag, c.rms_phase, c.chi2_per_point
                        )
                    }
                })
                .collect();
            let _ = writeln!(s, "| {label} | {} |", cells.join(" | "));
        }
        s
    }

    /// CSV, one line per cell.
    pub fn to_csv(&self) -> Result<String> {
        let mut w = csv::Writer::from_writer(Vec::new());
        let csv_err = |e: csv::Error| Error::Usage(format!("residual map CSV: {e}"));
        w.write_record([
            "segment",
            "channel",
            "column",
            "lo_hz",
            "hi_hz",
            "n_points",
            "rms_log_mag_z",
            "rms_phase_z",
            "mean_log_mag_z",
            "mean_phase_z",
            "chi2_per_point",
        ])
        .map_err(csv_err)?;
        let labels = self.column_labels();
        for ((seg, ch), row) in self.rows.iter().zip(&self.cells) {
            for (j, c) in row.iter().enumerate() {
                let (lo, hi) = self
                    .bands_hz
                    .get(j)
                    .map_or((String::new(), String::new()), |(a, b)| {
                        (a.to_string(), b.to_string())
                    });
                w.write_record([
                    seg.clone(),
                    ch.clone(),
                    labels[j].clone(),
                    lo,
                    hi,
                    c.n_points.to_string(),
                    c.rms_log_mag.to_string(),
                    c.rms_phase.to_string(),
                    c.mean_log_mag.to_string(),
                    c.mean_phase.to_string(),
                    c.chi2_per_point.to_string(),
                ])
                .map_err(csv_err)?;
            }
        }
        let bytes = w
            .into_inner()
            .map_err(|e| Error::Usage(format!("residual map CSV: {e}")))?;
        String::from_utf8(bytes).map_err(|e| Error::Usage(format!("residual map CSV: {e}")))
    }

    /// Writes `<stem>.md` and `<stem>.csv` atomically.
    pub fn write_tables(&self, stem: &Path) -> Result<()> {
        write_atomic(&stem.with_extension("md"), self.to_markdown().as_bytes())?;
        write_atomic(&stem.with_extension("csv"), self.to_csv()?.as_bytes())
    }

    /// Heatmap of one cell value (`<stem>.png`, `<stem>.svg`). Signed means use a
    /// symmetric colour scale; RMS and chi^2 are non-negative (white = 0).
    pub fn heatmap(&self, value: MapValue, title: &str, stem: &Path) -> Result<()> {
        let spec = HeatmapSpec {
            title: title.to_string(),
            x_label: "Frequency band".into(),
            y_label: "Segment / channel".into(),
            row_labels: self.row_labels(),
            col_labels: self.column_labels(),
            values: self
                .cells
                .iter()
                .map(|row| row.iter().map(|c| value.of(c)).collect())
                .collect(),
            colour_label: value.label().into(),
            limit: None,
            show_values: true,
            size_px: None,
        };
        heatmap(&spec, stem)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_match_hand_computation() {
        // band [1, 2] Hz holds points 0 and 1; point 2 is off-band
        let m = vec![
            Complex64::new(1.0, 0.0),
            Complex64::from_polar(2.0, 0.1),
            Complex64::new(0.0, 3.0),
        ];
        let p = vec![
            Complex64::new(1.0, 0.0),
            Complex64::from_polar(2.0 * (-0.02f64).exp(), 0.1 - 0.05),
            Complex64::new(0.0, 3.0),
        ];
        let row = ResidualRow {
            segment: "t".into(),
            channel: "acc1".into(),
            freq_hz: vec![1.0, 2.0, 3.0],
            measured: m.clone(),
            predicted: p.clone(),
            sigma: vec![0.1, 0.2, 0.3],
        };
        let map = ResidualMap::new(&[row], &[(1.0, 2.0)]).unwrap();
        let c = map.cells[0][0];
        assert_eq!(c.n_points, 2);
        // point 1: z_mag = 0.02 * 2 / 0.2 = 0.2, z_phase = 0.05 * 10 = 0.5
        assert!((c.rms_log_mag - (0.2f64 * 0.2 / 2.0).sqrt()).abs() < 1e-12);
        assert!((c.mean_phase - 0.25).abs() < 1e-12);
        let chi2 = (m[1] - p[1]).norm_sqr() / 0.04 / 4.0;
        assert!((c.chi2_per_point - chi2).abs() < 1e-12);
        assert_eq!(map.cells[0][1].n_points, 1);
        assert_eq!(map.cells[0][1].chi2_per_point, 0.0);
        assert_eq!(map.column_labels(), vec!["1.00-2.00 Hz", "off-band"]);
        let md = map.to_markdown();
        assert!(
            md.contains("| t / acc1 | 0.1 / 0.4 (") && md.contains("off-band"),
            "{md}"
        );
        let csv = map.to_csv().unwrap();
        assert_eq!(csv.lines().count(), 3);
        assert!(map.worst_cells(1)[0].1 == 0);
    }

    #[test]
    fn phase_wraps_and_lengths_are_checked() {
        assert!((wrap_pi(2.0 * std::f64::consts::PI + 0.1) - 0.1).abs() < 1e-12);
        assert!((wrap_pi(-0.1) + 0.1).abs() < 1e-12);
        let bad = ResidualRow {
            segment: "t".into(),
            channel: "c".into(),
            freq_hz: vec![1.0],
            measured: vec![],
            predicted: vec![],
            sigma: vec![],
        };
        assert!(ResidualMap::new(&[bad], &[]).is_err());
    }
}
