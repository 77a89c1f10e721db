//! General x-y line chart with optional log axes (autocorrelation, eigenvalue spectra,
//! convergence histories, ...).

use super::axis::{data_range, limits, union, NiceAxis};
use super::panel::{self, Entry, Occupied, Panel, Stroke, Swatch};
use super::render::{render, title_area, DResult, Figure};
use super::style::{self, Dash, NORMAL};
use super::{same_len, Scale};
use crate::error::Result;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::prelude::DrawingBackend;
use plotters::style::{Color, RGBColor};
use std::path::Path;

/// How a series is marked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Mark {
    #[default]
    Line,
    Points,
    LineAndPoints,
}

/// One x-y series (`x.len() == y.len()`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Legend text; empty: not in the legend.
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub mark: Mark,
}

/// A dashed grey reference line at `value` on one axis, labelled in the legend.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RefLine {
    pub value: f64,
    /// Legend text; empty: not in the legend.
    pub label: String,
}

/// Multi-series x-y lines.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LineChartSpec {
    pub title: String,
    /// Axis texts with units.
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub x_scale: Scale,
    pub y_scale: Scale,
    /// Vertical reference lines at x values.
    pub x_refs: Vec<RefLine>,
    /// Horizontal reference lines at y values.
    pub y_refs: Vec<RefLine>,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`LineChartSpec`].
pub fn line_chart(spec: &LineChartSpec, stem: &Path) -> Result<()> {
    for s in &spec.series {
        same_len(
            &format!("line chart \"{}\", series \"{}\"", spec.title, s.label),
            "x",
            s.x.len(),
            "y",
            s.y.len(),
        )?;
    }
    render(spec, spec.size_px, stem)
}

const REF_GREY: RGBColor = RGBColor(110, 110, 110);

impl Figure for LineChartSpec {
    fn default_size(&self) -> (u32, u32) {
        (1000, 700)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, NORMAL)?;
        let xr = self.series.iter().fold(None, |acc, s| {
            union(acc, data_range(s.x.iter().copied(), self.x_scale))
        });
        let yr = self.series.iter().fold(None, |acc, s| {
            union(acc, data_range(s.y.iter().copied(), self.y_scale))
        });
        let refs = |r: &[RefLine], scale| data_range(r.iter().map(|l| l.value), scale);
        let xr = union(xr, refs(&self.x_refs, self.x_scale));
        let yr = union(yr, refs(&self.y_refs, self.y_scale));
        let (bw, bh) = body.dim_in_pixel();
        let x_lim = limits(xr, self.x_scale, 0.02);
        let x = NiceAxis::new(self.x_scale, x_lim, panel::ticks_for(bw, 95, 10));
        let y_lim = limits(yr, self.y_scale, 0.04);
        let y = NiceAxis::new(self.y_scale, y_lim, panel::ticks_for(bh, 60, 8));
        let y_area = panel::y_area(&y, &self.y_label, NORMAL);
        let mut chart = panel::build(
            &body,
            Panel {
                title: "",
                x,
                y,
                x_desc: &self.x_label,
                y_desc: &self.y_label,
                sizes: NORMAL,
                x_area: panel::x_area(true, &self.x_label, NORMAL),
                y_area,
                margin_right: 20,
            },
        )?;
        let mut occ = Occupied::default();
        let mut entries = Vec::new();
        let ref_stroke = Stroke {
            color: REF_GREY.to_rgba(),
            width: 1,
            dash: Dash::Dashed,
        };
        for r in &self.x_refs {
            panel::ref_line(&mut chart, Some(r.value), None, ref_stroke)?;
        }
        for r in &self.y_refs {
            panel::ref_line(&mut chart, None, Some(r.value), ref_stroke)?;
        }
        let width = if self.series.len() <= 5 { 2 } else { 1 };
        for (i, s) in self.series.iter().enumerate() {
            let (color, dash) = style::series_look(i);
            let stroke = Stroke {
                color: color.to_rgba(),
                width,
                dash,
            };
            if matches!(s.mark, Mark::Line | Mark::LineAndPoints) {
                panel::line(&mut chart, &s.x, &s.y, stroke, None, &mut occ)?;
            }
            if matches!(s.mark, Mark::Points | Mark::LineAndPoints) {
                panel::points(&mut chart, &s.x, &s.y, color.to_rgba(), 4, &mut occ)?;
            }
            let swatch = match s.mark {
                Mark::Points => Swatch::Dot(color.to_rgba()),
                Mark::Line => Swatch::Line(stroke),
                Mark::LineAndPoints => Swatch::LineDot(stroke),
            };
            entries.push(Entry {
                label: s.label.clone(),
                swatch,
            });
        }
        for r in self.x_refs.iter().chain(&self.y_refs) {
            entries.push(Entry {
                label: r.label.clone(),
                swatch: Swatch::Line(ref_stroke),
            });
        }
        panel::frame(&mut chart)?;
        if occ.is_empty() {
            panel::note(&chart, "no data", NORMAL)?;
        }
        panel::legend(&chart, &entries, &occ, NORMAL)
    }
}
