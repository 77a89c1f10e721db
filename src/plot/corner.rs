//! Corner plot of posterior samples: 1-D histograms on the diagonal, 2-D densities below,
//! optional reference (truth) lines.

use super::axis::{data_range, limits, NiceAxis};
use super::panel::{self, Occupied, Panel, Stroke};
use super::render::{put_text, render, title_area, DResult, Figure};
use super::style::{self, text, SMALL};
use super::Scale;
use crate::error::{Error, Result};
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::element::{Circle, PathElement, Rectangle};
use plotters::prelude::DrawingBackend;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::Color;
use std::path::Path;

/// One parameter's samples; all parameters of a corner plot hold the same draws in the
/// same order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CornerParam {
    pub name: String,
    /// Unit shown on the axes; empty for dimensionless.
    pub unit: String,
    pub values: Vec<f64>,
    /// Truth or reference value drawn as a line.
    pub reference: Option<f64>,
}

/// How pairs are shown below the diagonal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Density2d {
    /// Counts on a bins x bins grid, white to dark blue.
    #[default]
    Binned,
    /// Translucent points (at most 3000, evenly strided).
    Scatter,
}

/// Corner plot. Draws with a NaN in either coordinate are skipped per pair.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CornerSpec {
    pub title: String,
    pub params: Vec<CornerParam>,
    /// Histogram bins per axis; 0 means 30.
    pub bins: usize,
    pub density: Density2d,
    /// Legend text of the reference lines; empty: "Reference".
    pub reference_label: String,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`CornerSpec`].
pub fn corner(spec: &CornerSpec, stem: &Path) -> Result<()> {
    if let Some(first) = spec.params.first() {
        for p in &spec.params {
            if p.values.len() != first.values.len() {
                return Err(Error::Usage(format!(
                    "corner plot \"{}\": parameter {} has {} samples but {} has {}; all \
                     parameters must hold the same draws",
                    spec.title,
                    p.name,
                    p.values.len(),
                    first.name,
                    first.values.len()
                )));
            }
        }
    }
    render(spec, spec.size_px, stem)
}

const SCATTER_MAX: usize = 3000;
const DEFAULT_BINS: usize = 30;

fn axis_text(p: &CornerParam) -> String {
    if p.unit.is_empty() {
        p.name.clone()
    } else {
        format!("{} ({})", p.name, p.unit)
    }
}

/// Bin of `v` among `bins` equal bins over `lo..hi`, `None` outside or non-finite.
fn bin_of(v: f64, (lo, hi): (f64, f64), bins: usize) -> Option<usize> {
    if !v.is_finite() || v < lo || v > hi || hi <= lo {
        return None;
    }
    Some((((v - lo) / (hi - lo) * bins as f64) as usize).min(bins - 1))
}

impl Figure for CornerSpec {
    fn default_size(&self) -> (u32, u32) {
        let side = (210 * self.params.len() as u32 + 140).clamp(700, 2600);
        (side, side)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, SMALL)?;
        let n = self.params.len();
        if n == 0 {
            let (w, h) = body.dim_in_pixel();
            let grey = super::style::text_colored(SMALL.legend, style::AXIS_GREY);
            return put_text(
                &body,
                "no parameters",
                &grey,
                (w as i32 / 2, h as i32 / 2),
                (HPos::Center, VPos::Center),
            );
        }
        let bins = if self.bins == 0 {
            DEFAULT_BINS
        } else {
            self.bins
        };
        let grid = self.layout(&body);
        let xs: Vec<i32> = (1..n)
            .map(|j| (grid.left as f64 + j as f64 * grid.cell_w) as i32)
            .collect();
        let ys: Vec<i32> = (1..n).map(|i| (i as f64 * grid.cell_h) as i32).collect();
        let cells = body.split_by_breakpoints(xs, ys);
        for i in 0..n {
            for j in 0..=i {
                self.draw_cell(&cells[i * n + j], &grid, i, j, bins)?;
            }
        }

        // Upper right corner: sample count and the reference legend.
        if n < 2 {
            return Ok(());
        }
        self.draw_corner_note(&cells[n - 1])
    }
}

/// Geometry of a corner grid: one axis and axis text per parameter, label areas and
/// cell sizes in px.
struct GridLayout {
    axes: Vec<NiceAxis>,
    texts: Vec<String>,
    /// Width of the y label area of the first column.
    left: u32,
    /// Height of the x label area of the last row.
    bottom: u32,
    cell_w: f64,
    cell_h: f64,
    /// Right margin that the last column also holds.
    extra_right: u32,
}

impl CornerSpec {
    /// Axes from each parameter's samples and reference, and the cell sizes of `body`.
    fn layout<DB: DrawingBackend>(&self, body: &DrawingArea<DB, Shift>) -> GridLayout {
        let n = self.params.len();
        let (bw, _) = body.dim_in_pixel();
        let ticks = panel::ticks_for(bw / n as u32, 70, 3);
        let axes: Vec<NiceAxis> = self
            .params
            .iter()
            .map(|p| {
                let r = data_range(p.values.iter().copied().chain(p.reference), Scale::Linear);
                NiceAxis::new(Scale::Linear, limits(r, Scale::Linear, 0.05), ticks)
            })
            .collect();
        let texts: Vec<String> = self.params.iter().map(axis_text).collect();
        let left = (1..n)
            .map(|i| panel::y_area(&axes[i], &texts[i], SMALL))
            .max()
            .unwrap_or(0)
            .max(panel::x_area(true, "", SMALL));
        let bottom = panel::x_area(true, "x", SMALL);
        let (w, h) = body.dim_in_pixel();
        let cell_w = (w.saturating_sub(left + 12)) as f64 / n as f64;
        let cell_h = (h.saturating_sub(bottom)) as f64 / n as f64;
        // The last column also holds the right margin: widen its chart margin to match.
        let extra_right = (w as f64 - left as f64 - n as f64 * cell_w).max(0.0) as u32;
        GridLayout {
            axes,
            texts,
            left,
            bottom,
            cell_w,
            cell_h,
            extra_right,
        }
    }

    /// Cell (row `i`, column `j <= i`): the histogram of parameter `j` on the diagonal,
    /// the pair density of `(j, i)` below it, with reference lines and a frame.
    fn draw_cell<DB: DrawingBackend>(
        &self,
        cell: &DrawingArea<DB, Shift>,
        grid: &GridLayout,
        i: usize,
        j: usize,
        bins: usize,
    ) -> DResult<(), DB> {
        let n = self.params.len();
        let (axes, texts) = (&grid.axes, &grid.texts);
        let hist_axis = NiceAxis::new(Scale::Linear, (0.0, 1.08), 2).without_ticks();
        let ref_stroke = Stroke::solid(style::OI_VERMILLION, 2);
        let last_row = i == n - 1;
        let x_axis = if last_row {
            axes[j].clone()
        } else {
            axes[j].clone().without_labels()
        };
        let diag = i == j;
        let y_axis = if diag {
            hist_axis
        } else if j == 0 {
            axes[i].clone()
        } else {
            axes[i].clone().without_labels()
        };
        let mut chart = panel::build(
            cell,
            Panel {
                title: "",
                x: x_axis,
                y: y_axis,
                x_desc: if last_row { &texts[j] } else { "" },
                y_desc: if j == 0 && !diag { &texts[i] } else { "" },
                sizes: SMALL,
                x_area: if last_row { grid.bottom } else { 0 },
                y_area: if j == 0 { grid.left } else { 0 },
                margin_right: 4 + if j == n - 1 { grid.extra_right } else { 0 },
            },
        )?;
        let (xr, yr) = (axes[j].lo_hi(), axes[i].lo_hi());
        if diag {
            self.histogram(&mut chart, j, xr, bins)?;
            panel::ref_line(&mut chart, self.params[j].reference, None, ref_stroke)?;
        } else {
            self.pair(&mut chart, j, i, xr, yr, bins)?;
            let (rx, ry) = (self.params[j].reference, self.params[i].reference);
            panel::ref_line(&mut chart, rx, ry, ref_stroke)?;
        }
        panel::frame(&mut chart)
    }

    /// Sample count and, when any parameter has a reference, its legend entry, in the
    /// empty upper right cell.
    fn draw_corner_note<DB: DrawingBackend>(
        &self,
        corner_cell: &DrawingArea<DB, Shift>,
    ) -> DResult<(), DB> {
        let m = self.params[0].values.len();
        let (cw, _) = corner_cell.dim_in_pixel();
        let x = cw as i32 - 10;
        put_text(
            corner_cell,
            &format!("{m} samples"),
            &text(SMALL.legend),
            (x, 14),
            (HPos::Right, VPos::Top),
        )?;
        if self.params.iter().any(|p| p.reference.is_some()) {
            let label = if self.reference_label.is_empty() {
                "Reference"
            } else {
                &self.reference_label
            };
            let y = 14 + (SMALL.legend * 1.6) as i32;
            let tw = super::render::text_width(label, SMALL.legend) as i32;
            corner_cell.draw(&PathElement::new(
                vec![(x - tw - 34, y + 8), (x - tw - 8, y + 8)],
                style::OI_VERMILLION.stroke_width(2),
            ))?;
            put_text(
                corner_cell,
                label,
                &text(SMALL.legend),
                (x, y),
                (HPos::Right, VPos::Top),
            )?;
        }
        Ok(())
    }

    fn histogram<DB: DrawingBackend>(
        &self,
        chart: &mut panel::Chart<DB>,
        p: usize,
        xr: (f64, f64),
        bins: usize,
    ) -> DResult<(), DB> {
        let mut counts = vec![0usize; bins];
        for &v in &self.params[p].values {
            if let Some(b) = bin_of(v, xr, bins) {
                counts[b] += 1;
            }
        }
        let max = counts.iter().copied().max().unwrap_or(0);
        if max == 0 {
            return panel::note(chart, "no data", SMALL);
        }
        let width = (xr.1 - xr.0) / bins as f64;
        let heights: Vec<f64> = counts.iter().map(|&c| c as f64 / max as f64).collect();
        chart.draw_series(heights.iter().enumerate().map(|(b, &hgt)| {
            // Both edges from the bin index, so neighbours share them exactly (no gaps).
            let (x0, x1) = (xr.0 + b as f64 * width, xr.0 + (b + 1) as f64 * width);
            Rectangle::new([(x0, 0.0), (x1, hgt)], style::OI_BLUE.mix(0.25).filled())
        }))?;
        let mut outline = vec![(xr.0, 0.0)];
        for (b, &hgt) in heights.iter().enumerate() {
            outline.push((xr.0 + b as f64 * width, hgt));
            outline.push((xr.0 + (b + 1) as f64 * width, hgt));
        }
        outline.push((xr.1, 0.0));
        chart.draw_series(std::iter::once(PathElement::new(
            outline,
            style::OI_BLUE.stroke_width(2),
        )))?;
        Ok(())
    }

    fn pair<DB: DrawingBackend>(
        &self,
        chart: &mut panel::Chart<DB>,
        px: usize,
        py: usize,
        xr: (f64, f64),
        yr: (f64, f64),
        bins: usize,
    ) -> DResult<(), DB> {
        let (xv, yv) = (&self.params[px].values, &self.params[py].values);
        let finite = || {
            xv.iter()
                .zip(yv)
                .filter(|(a, b)| a.is_finite() && b.is_finite())
                .map(|(&a, &b)| (a, b))
        };
        let count = finite().count();
        if count == 0 {
            return panel::note(chart, "no data", SMALL);
        }
        match self.density {
            Density2d::Scatter => {
                let stride = count.div_ceil(SCATTER_MAX).max(1);
                let mut occ = Occupied::default();
                let pts: Vec<(f64, f64)> = finite().step_by(stride).collect();
                occ.add(chart, &pts);
                chart.draw_series(
                    pts.into_iter()
                        .map(|p| Circle::new(p, 2, style::OI_BLUE.mix(0.3).filled())),
                )?;
            }
            Density2d::Binned => {
                let mut grid = vec![0usize; bins * bins];
                for (a, b) in finite() {
                    if let (Some(i), Some(k)) = (bin_of(a, xr, bins), bin_of(b, yr, bins)) {
                        grid[k * bins + i] += 1;
                    }
                }
                let max = grid.iter().copied().max().unwrap_or(0).max(1) as f64;
                let (wx, wy) = ((xr.1 - xr.0) / bins as f64, (yr.1 - yr.0) / bins as f64);
                chart.draw_series(grid.iter().enumerate().filter(|(_, &c)| c > 0).map(
                    |(idx, &c)| {
                        let (i, k) = (idx % bins, idx / bins);
                        let (x0, y0) = (xr.0 + i as f64 * wx, yr.0 + k as f64 * wy);
                        let (x1, y1) = (xr.0 + (i + 1) as f64 * wx, yr.0 + (k + 1) as f64 * wy);
                        let t = 0.15 + 0.85 * (c as f64 / max).sqrt();
                        Rectangle::new([(x0, y0), (x1, y1)], style::sequential(t).filled())
                    },
                ))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_cover_the_range() {
        assert_eq!(bin_of(0.0, (0.0, 1.0), 10), Some(0));
        assert_eq!(bin_of(0.55, (0.0, 1.0), 10), Some(5));
        assert_eq!(bin_of(1.0, (0.0, 1.0), 10), Some(9));
        assert_eq!(bin_of(1.01, (0.0, 1.0), 10), None);
        assert_eq!(bin_of(f64::NAN, (0.0, 1.0), 10), None);
    }
}
