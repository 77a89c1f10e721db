//! A labelled matrix on a diverging colour scale with a colour bar (residual z-score
//! maps: rows test x channel, columns frequency bands).

use super::axis::NiceAxis;
use super::labels;
use super::panel::{self, Chart, Panel};
use super::render::{put_text, render, text_width, title_area, DResult, Figure};
use super::style::{self, text, text_colored, NORMAL};
use super::{same_len, Scale};
use crate::error::{Error, Result};
use plotters::chart::ChartBuilder;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::element::Rectangle;
use plotters::prelude::DrawingBackend;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::Color;
use std::path::Path;

/// A matrix `values[row][col]` coloured from blue (-limit) through white (0) to red
/// (+limit); values beyond the limit take the end colours; NaN cells are grey.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeatmapSpec {
    pub title: String,
    /// Text under the column labels, e.g. "Frequency band".
    pub x_label: String,
    /// Text left of the row labels, e.g. "Test / channel".
    pub y_label: String,
    pub row_labels: Vec<String>,
    pub col_labels: Vec<String>,
    pub values: Vec<Vec<f64>>,
    /// Colour bar text, e.g. "Residual z-score".
    pub colour_label: String,
    /// Half-width of the colour scale; `None`: the largest finite |value| (1 if none).
    pub limit: Option<f64>,
    /// Print each value in its cell (where the text fits).
    pub show_values: bool,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`HeatmapSpec`].
pub fn heatmap(spec: &HeatmapSpec, stem: &Path) -> Result<()> {
    let what = format!("heatmap \"{}\"", spec.title);
    same_len(
        &what,
        "row_labels",
        spec.row_labels.len(),
        "values (rows)",
        spec.values.len(),
    )?;
    for (r, row) in spec.values.iter().enumerate() {
        same_len(
            &what,
            "col_labels",
            spec.col_labels.len(),
            &format!("values row {r}"),
            row.len(),
        )?;
    }
    if let Some(l) = spec.limit {
        if !(l.is_finite() && l > 0.0) {
            return Err(Error::Usage(format!(
                "{what}: colour limit {l} must be a positive finite number"
            )));
        }
    }
    render(spec, spec.size_px, stem)
}

impl HeatmapSpec {
    fn colour_limit(&self) -> f64 {
        self.limit.unwrap_or_else(|| {
            let m = self
                .values
                .iter()
                .flatten()
                .filter(|v| v.is_finite())
                .fold(0.0f64, |a, v| a.max(v.abs()));
            if m > 0.0 {
                m
            } else {
                1.0
            }
        })
    }
}

/// A cell value with the decimals that resolve a tenth of the colour limit (one decimal
/// for z-scores up to 3), scientific for extreme magnitudes; never "-0.0".
fn cell_text(v: f64, limit: f64) -> String {
    if !(1e-3..1e5).contains(&limit) {
        return format!("{v:.1e}");
    }
    let dec = (1.0 - limit.log10().floor()).max(0.0) as usize;
    let s = format!("{v:.dec$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

const BAR_PX: u32 = 24;
const TOP_MARGIN: u32 = 8;

impl Figure for HeatmapSpec {
    fn default_size(&self) -> (u32, u32) {
        let rows = self.row_labels.len() as u32;
        let cols = self.col_labels.len() as u32;
        (
            (400 + 55 * cols).clamp(900, 2400),
            (200 + 26 * rows).clamp(500, 2400),
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, NORMAL)?;
        let limit = self.colour_limit();
        let (n_rows, n_cols) = (self.row_labels.len(), self.col_labels.len());

        // Colour bar on the right: its axis, then the space it needs.
        let bar_axis = NiceAxis::new(Scale::Linear, (-limit, limit), 6);
        let bar_right = self.colour_bar_right_px(&bar_axis);
        let (w, h) = body.dim_in_pixel();
        let (main, bar) = body.split_horizontally(w.saturating_sub(16 + BAR_PX + bar_right + 8));

        // Main panel: label areas from the labels.
        let desc_px = |s: &str| panel::desc_height(s, NORMAL);
        let mut row_font = NORMAL.tick;
        let y_area = labels::y_width(&self.row_labels, row_font) + desc_px(&self.y_label) + 4;
        let (mw, _) = main.dim_in_pixel();
        let slot = (mw as f64 - y_area as f64 - 14.0) / n_cols.max(1) as f64;
        let layout = labels::x_layout(&main, &self.col_labels, slot, NORMAL.tick);
        let x_area = layout.height_px + desc_px(&self.x_label);
        let plot_h = h as f64 - x_area as f64 - TOP_MARGIN as f64 - 4.0;
        let row_px = plot_h / n_rows.max(1) as f64;
        if row_font > row_px * 0.85 {
            row_font = (row_px * 0.85).max(9.0);
        }
        let mut chart = panel::build(
            &main,
            Panel {
                title: "",
                x: NiceAxis::categorical(n_cols),
                y: NiceAxis::categorical(n_rows),
                x_desc: &self.x_label,
                y_desc: &self.y_label,
                sizes: NORMAL,
                x_area,
                y_area,
                margin_right: 10,
            },
        )?;
        self.draw_cells(&mut chart, limit)?;
        panel::frame(&mut chart)?;
        if n_rows * n_cols == 0 {
            panel::note(&chart, "no data", NORMAL)?;
        }
        labels::draw_x(&chart, &self.col_labels, layout)?;
        labels::draw_y(&chart, &self.row_labels, row_font)?;
        self.draw_colour_bar(&bar, bar_axis, x_area, bar_right, limit)
    }
}

impl HeatmapSpec {
    /// Width in px right of the colour bar: tick labels and the colour label.
    fn colour_bar_right_px(&self, bar_axis: &NiceAxis) -> u32 {
        let bar_labels_px = bar_axis
            .labels()
            .iter()
            .map(|l| text_width(l, NORMAL.tick))
            .max()
            .unwrap_or(0);
        let bar_desc_px = if self.colour_label.is_empty() {
            0
        } else {
            (NORMAL.axis_desc * 1.3) as u32 + 6
        };
        10 + bar_labels_px + 6 + bar_desc_px
    }

    /// The coloured cells, white cell borders when cells are at least 10 px, and the
    /// values written in the cells when `show_values`.
    fn draw_cells<DB: DrawingBackend>(&self, chart: &mut Chart<DB>, limit: f64) -> DResult<(), DB> {
        let (n_rows, n_cols) = (self.row_labels.len(), self.col_labels.len());
        let mut cells = Vec::with_capacity(n_rows * n_cols);
        for (r, row) in self.values.iter().enumerate() {
            let y = (n_rows - 1 - r) as f64;
            for (c, &v) in row.iter().enumerate() {
                let color = if v.is_finite() {
                    style::diverging(v / limit)
                } else {
                    style::MISSING_GREY
                };
                let x = c as f64;
                cells.push(Rectangle::new(
                    [(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)],
                    color.filled(),
                ));
            }
        }
        chart.draw_series(cells)?;
        let cell_w = panel::plot_width(chart) as f64 / n_cols.max(1) as f64;
        let (_, yr) = chart.plotting_area().get_pixel_range();
        let cell_h = (yr.end - yr.start) as f64 / n_rows.max(1) as f64;
        if cell_w >= 10.0 && cell_h >= 10.0 {
            let mut grid = Vec::new();
            for r in 0..n_rows {
                for c in 0..n_cols {
                    let (x, y) = (c as f64, r as f64);
                    grid.push(Rectangle::new(
                        [(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)],
                        style::WHITE.stroke_width(1),
                    ));
                }
            }
            chart.draw_series(grid)?;
        }
        if self.show_values {
            self.draw_values(chart, limit, cell_w, cell_h)?;
        }
        Ok(())
    }

    /// Each finite value written in its cell, in a colour readable on the cell's; values
    /// that do not fit in `cell_w` px, or a font under 7 px, are left out.
    fn draw_values<DB: DrawingBackend>(
        &self,
        chart: &Chart<DB>,
        limit: f64,
        cell_w: f64,
        cell_h: f64,
    ) -> DResult<(), DB> {
        let n_rows = self.row_labels.len();
        let area = chart.plotting_area().strip_coord_spec();
        let origin = area.get_base_pixel();
        let font = (cell_h * 0.5).min(NORMAL.tick - 1.0);
        for (r, row) in self.values.iter().enumerate() {
            let y = (n_rows - 1 - r) as f64;
            for (c, &v) in row.iter().enumerate() {
                if !v.is_finite() || font < 7.0 {
                    continue;
                }
                let s = cell_text(v, limit);
                if text_width(&s, font) as f64 > cell_w - 4.0 {
                    continue;
                }
                let (px, py) = chart.backend_coord(&(c as f64, y));
                let color = style::text_on(style::diverging(v / limit));
                put_text(
                    &area,
                    &s,
                    &text_colored(font, color),
                    (px - origin.0, py - origin.1),
                    (HPos::Center, VPos::Center),
                )?;
            }
        }
        Ok(())
    }

    /// Colour bar from -limit to +limit in `bar`, aligned with the plot's top and bottom.
    fn draw_colour_bar<DB: DrawingBackend>(
        &self,
        bar: &DrawingArea<DB, Shift>,
        bar_axis: NiceAxis,
        x_area: u32,
        bar_right: u32,
        limit: f64,
    ) -> DResult<(), DB> {
        let mut cb = ChartBuilder::on(bar)
            .margin_top(TOP_MARGIN)
            .margin_bottom(4)
            .margin_left(16)
            .margin_right(8)
            .x_label_area_size(x_area)
            .right_y_label_area_size(bar_right)
            .build_cartesian_2d(NiceAxis::new(Scale::Linear, (0.0, 1.0), 2), bar_axis)?;
        let mut mesh = cb.configure_mesh();
        mesh.disable_mesh()
            .disable_x_axis()
            .y_labels(10)
            .axis_style(style::AXIS_GREY.stroke_width(1))
            .set_all_tick_mark_size(5)
            .y_label_style(text(NORMAL.tick))
            .axis_desc_style(text(NORMAL.axis_desc));
        if !self.colour_label.is_empty() {
            mesh.y_desc(self.colour_label.as_str());
        }
        mesh.draw()?;
        let steps = 200;
        cb.draw_series((0..steps).map(|i| {
            let a = -limit + 2.0 * limit * i as f64 / steps as f64;
            let b = -limit + 2.0 * limit * (i + 1) as f64 / steps as f64;
            let color = style::diverging((a + b) / (2.0 * limit));
            Rectangle::new([(0.0, a), (1.0, b)], color.filled())
        }))?;
        cb.draw_series(std::iter::once(Rectangle::new(
            [(0.0, -limit), (1.0, limit)],
            style::AXIS_GREY.stroke_width(1),
        )))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_text_formats() {
        assert_eq!(cell_text(-2.345, 3.0), "-2.3");
        assert_eq!(cell_text(-8.9e-16, 3.0), "0.0");
        assert_eq!(cell_text(0.0, 3.0), "0.0");
        assert_eq!(cell_text(123.4, 300.0), "123");
        assert_eq!(cell_text(0.0123, 0.05), "0.012");
        assert_eq!(cell_text(1234.0, 1e6), "1.2e3");
    }

    #[test]
    fn default_limit_is_largest_magnitude() {
        let spec = HeatmapSpec {
            values: vec![vec![1.0, -3.5], vec![f64::NAN, 2.0]],
            ..Default::default()
        };
        assert_eq!(spec.colour_limit(), 3.5);
        assert_eq!(HeatmapSpec::default().colour_limit(), 1.0);
    }
}
