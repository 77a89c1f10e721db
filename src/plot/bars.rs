//! Labelled bars, optionally grouped by variant (e.g. the coefficient of variation of
//! every parameter, one bar per damping model).

use super::axis::{data_range, limits, valid, NiceAxis};
use super::labels;
use super::panel::{self, Chart, Entry, Occupied, Panel, Swatch};
use super::render::{put_text, render, text_width, title_area, DResult, Figure};
use super::style::{self, text, NORMAL};
use super::{same_len, Scale};
use crate::error::Result;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::element::Rectangle;
use plotters::prelude::DrawingBackend;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::Color;
use std::path::Path;

/// One variant's bar heights, one per category.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BarGroup {
    /// Legend text; a single group with an empty label gets no legend.
    pub label: String,
    pub values: Vec<f64>,
}

/// Bars per category, side by side per group. Missing values (NaN, and zeros or
/// negatives on a log scale) leave a gap.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BarChartSpec {
    pub title: String,
    pub x_label: String,
    /// Value axis text with unit.
    pub y_label: String,
    pub categories: Vec<String>,
    pub groups: Vec<BarGroup>,
    pub y_scale: Scale,
    /// Print each value above its bar (when the text fits the bar's width).
    pub show_values: bool,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`BarChartSpec`].
pub fn bar_chart(spec: &BarChartSpec, stem: &Path) -> Result<()> {
    for g in &spec.groups {
        same_len(
            &format!("bar chart \"{}\", group \"{}\"", spec.title, g.label),
            "categories",
            spec.categories.len(),
            "values",
            g.values.len(),
        )?;
    }
    render(spec, spec.size_px, stem)
}

/// Share of a category's slot covered by its bars.
const GROUP_WIDTH: f64 = 0.8;

/// At most three significant digits without trailing zeros, scientific beyond ordinary
/// magnitudes.
fn value_text(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    let dec = if a == 0.0 {
        0
    } else {
        (2 - a.log10().floor() as i64).max(0) as usize
    };
    let s = format!("{v:.dec$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

impl Figure for BarChartSpec {
    fn default_size(&self) -> (u32, u32) {
        (1000, 700)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, NORMAL)?;
        let scale = self.y_scale;
        let y_lim = self.y_limits();
        let (_, body_h) = body.dim_in_pixel();
        let y = NiceAxis::new(scale, y_lim, panel::ticks_for(body_h, 70, 8));
        let y_area = panel::y_area(&y, &self.y_label, NORMAL);
        let n = self.categories.len();
        let (w, _) = body.dim_in_pixel();
        let plot_w = w as f64 - y_area as f64 - 24.0;
        let layout = labels::x_layout(
            &body,
            &self.categories,
            plot_w / n.max(1) as f64,
            NORMAL.tick,
        );
        let desc_px = panel::desc_height(&self.x_label, NORMAL);
        let mut chart = panel::build(
            &body,
            Panel {
                title: "",
                x: NiceAxis::categorical(n),
                y,
                x_desc: &self.x_label,
                y_desc: &self.y_label,
                sizes: NORMAL,
                x_area: layout.height_px + desc_px,
                y_area,
                margin_right: 20,
            },
        )?;
        let base = match scale {
            Scale::Log => y_lim.0,
            Scale::Linear => 0.0,
        };
        let sub = GROUP_WIDTH / self.groups.len().max(1) as f64;
        let (occ, entries, tops) = self.draw_bars(&mut chart, base, sub)?;
        if self.show_values {
            self.draw_values(&chart, &tops, base, sub)?;
        }
        if matches!(scale, Scale::Linear) && y_lim.0 < 0.0 && y_lim.1 > 0.0 {
            let s = panel::Stroke::solid(style::AXIS_GREY, 1);
            panel::ref_line(&mut chart, None, Some(0.0), s)?;
        }
        panel::frame(&mut chart)?;
        labels::draw_x(&chart, &self.categories, layout)?;
        if occ.is_empty() {
            panel::note(&chart, "no data", NORMAL)?;
        }
        panel::legend(&chart, &entries, &occ, NORMAL)
    }
}

/// Bar tops `(x, value)` in data coordinates, in drawing order.
type Tops = Vec<(f64, f64)>;

impl BarChartSpec {
    /// Value axis limits: padded for the value texts when `show_values`; on a linear
    /// axis the bars stand on zero.
    fn y_limits(&self) -> (f64, f64) {
        let scale = self.y_scale;
        let all = || self.groups.iter().flat_map(|g| g.values.iter().copied());
        let data = data_range(all(), scale);
        // Room above the bars for their values.
        let pad = if self.show_values { 0.09 } else { 0.05 };
        match scale {
            Scale::Log => limits(data, scale, pad),
            Scale::Linear => {
                let (lo, hi) = data.unwrap_or((0.0, 1.0));
                let (lo, hi) = limits(Some((lo.min(0.0), hi.max(0.0))), scale, pad);
                // Bars stand on zero: no padding below (above) all-positive (negative) data.
                let lo = if data.is_none_or(|d| d.0 >= 0.0) {
                    0.0
                } else {
                    lo
                };
                let hi = if data.is_some_and(|d| d.1 <= 0.0) {
                    0.0
                } else {
                    hi
                };
                (lo, hi)
            }
        }
    }

    /// Every group's bars from `base`, each `sub` wide within its category; returns
    /// the occupied area, the legend entries and the bar tops.
    fn draw_bars<DB: DrawingBackend>(
        &self,
        chart: &mut Chart<DB>,
        base: f64,
        sub: f64,
    ) -> DResult<(Occupied, Vec<Entry>, Tops), DB> {
        let mut occ = Occupied::default();
        let mut entries = Vec::new();
        let mut tops = Vec::new();
        for (g, group) in self.groups.iter().enumerate() {
            let (color, _) = style::series_look(g);
            let mut rects = Vec::new();
            for (i, &v) in group.values.iter().enumerate() {
                if !valid(v, self.y_scale) {
                    continue;
                }
                let x0 = i as f64 - GROUP_WIDTH / 2.0 + g as f64 * sub + 0.06 * sub;
                let x1 = x0 + 0.88 * sub;
                occ.add_rect(chart, (x0, base), (x1, v));
                rects.push(Rectangle::new([(x0, base), (x1, v)], color.filled()));
                tops.push((0.5 * (x0 + x1), v));
            }
            chart.draw_series(rects)?;
            entries.push(Entry {
                label: group.label.clone(),
                swatch: Swatch::Patch(color.to_rgba()),
            });
        }
        Ok((occ, entries, tops))
    }

    /// The value of each bar above (below, if under `base`) its top, only when every
    /// text fits the bar width.
    fn draw_values<DB: DrawingBackend>(
        &self,
        chart: &Chart<DB>,
        tops: &[(f64, f64)],
        base: f64,
        sub: f64,
    ) -> DResult<(), DB> {
        let n = self.categories.len();
        let area = chart.plotting_area().strip_coord_spec();
        let origin = area.get_base_pixel();
        let font = NORMAL.tick - 2.0;
        let bar_px = sub * panel::plot_width(chart) as f64 / n.max(1) as f64;
        let texts: Vec<String> = tops.iter().map(|t| value_text(t.1)).collect();
        let fits = texts
            .iter()
            .all(|t| text_width(t, font) as f64 <= bar_px + 6.0);
        if fits {
            for (t, s) in tops.iter().zip(&texts) {
                let (px, py) = chart.backend_coord(t);
                let (dy, v) = if t.1 >= base {
                    (-3, VPos::Bottom)
                } else {
                    (3, VPos::Top)
                };
                let pos = (px - origin.0, py - origin.1 + dy);
                put_text(&area, s, &text(font), pos, (HPos::Center, v))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_text_three_digits() {
        assert_eq!(value_text(0.012345), "0.0123");
        assert_eq!(value_text(12.345), "12.3");
        assert_eq!(value_text(-5.2), "-5.2");
        assert_eq!(value_text(9.0), "9");
        assert_eq!(value_text(1234.4), "1234");
        assert_eq!(value_text(0.0), "0");
        assert_eq!(value_text(2.5e-6), "2.50e-6");
    }
}
