//! Walker traces: one small panel per parameter, one thin translucent line per walker.

use super::axis::{data_range, limits, union, NiceAxis};
use super::panel::{self, Occupied, Panel, Stroke};
use super::render::{render, title_area, DResult, Figure};
use super::style::{self, Dash, SMALL};
use super::Scale;
use crate::error::Result;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::element::Rectangle;
use plotters::prelude::DrawingBackend;
use plotters::style::{Color, RGBColor};
use std::path::Path;

/// One parameter's chains: `walkers[w][step]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraceParam {
    pub name: String,
    /// Unit shown on the axis; empty for dimensionless.
    pub unit: String,
    pub walkers: Vec<Vec<f64>>,
    /// Truth or reference value drawn as a horizontal line.
    pub reference: Option<f64>,
}

/// Walker traces per parameter; the burn-in, if given, is shaded grey.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TracesSpec {
    pub title: String,
    pub params: Vec<TraceParam>,
    /// Steps discarded as burn-in, shaded from step 0.
    pub burn_in: Option<usize>,
    /// Step axis text; empty: "Step".
    pub x_label: String,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`TracesSpec`].
pub fn traces(spec: &TracesSpec, stem: &Path) -> Result<()> {
    render(spec, spec.size_px, stem)
}

fn columns(n: usize) -> usize {
    if n <= 4 {
        1
    } else {
        2
    }
}

const BURN_GREY: RGBColor = RGBColor(120, 120, 120);
/// Okabe-Ito blue lightened towards white: opaque, so overlapping walkers do not show
/// the dotted joints of translucent bitmap lines.
const WALKER_BLUE: RGBColor = RGBColor(102, 160, 204);

impl Figure for TracesSpec {
    fn default_size(&self) -> (u32, u32) {
        let n = self.params.len().max(1);
        let rows = n.div_ceil(columns(n)) as u32;
        (1000, (110 + 165 * rows).clamp(500, 3000))
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, SMALL)?;
        let n = self.params.len();
        if n == 0 {
            return Ok(());
        }
        let cols = columns(n);
        let rows = n.div_ceil(cols);
        let x_desc = if self.x_label.is_empty() {
            "Step"
        } else {
            &self.x_label
        };
        let steps = self
            .params
            .iter()
            .flat_map(|p| p.walkers.iter().map(Vec::len))
            .max()
            .unwrap_or(0);
        let x_lim = limits(
            Some((0.0, steps.saturating_sub(1) as f64)),
            Scale::Linear,
            0.0,
        );
        let (bw, bh) = body.dim_in_pixel();
        let x = NiceAxis::new(
            Scale::Linear,
            x_lim,
            panel::ticks_for(bw / cols as u32, 95, 8),
        );
        let y_ticks = panel::ticks_for(bh / rows as u32, 40, 4);
        let texts: Vec<String> = self.params.iter().map(axis_text).collect();
        let y_axes: Vec<NiceAxis> = self.params.iter().map(|p| y_axis(p, y_ticks)).collect();
        let y_area = (0..n)
            .map(|i| panel::y_area(&y_axes[i], &texts[i], SMALL))
            .max()
            .unwrap_or(0);
        // Only the bottom row carries the step axis text; it gets that much more height
        // so all plots have the same size.
        let desc_px = panel::desc_height(x_desc, SMALL);
        let (w, h) = body.dim_in_pixel();
        let row_h = h.saturating_sub(desc_px) as f64 / rows as f64;
        let xs: Vec<i32> = (1..cols)
            .map(|c| (c as f64 * w as f64 / cols as f64) as i32)
            .collect();
        let ys: Vec<i32> = (1..rows).map(|r| (r as f64 * row_h) as i32).collect();
        let cells = body.split_by_breakpoints(xs, ys);
        for (i, p) in self.params.iter().enumerate() {
            // Column-major order, so parameters read down the first column first.
            let (r, c) = (i % rows, i / rows);
            let last_row = r == rows - 1;
            let layout = Panel {
                title: "",
                x: x.clone(),
                y: y_axes[i].clone(),
                x_desc: if last_row { x_desc } else { "" },
                y_desc: &texts[i],
                sizes: SMALL,
                x_area: panel::x_area(true, if last_row { x_desc } else { "" }, SMALL),
                y_area,
                margin_right: 14,
            };
            self.draw_param(&cells[r * cols + c], layout, p, x_lim.0)?;
        }
        Ok(())
    }
}

/// Axis text of one parameter: its name, with the unit in parentheses when it has one.
fn axis_text(p: &TraceParam) -> String {
    if p.unit.is_empty() {
        p.name.clone()
    } else {
        format!("{} ({})", p.name, p.unit)
    }
}

/// Value axis of one parameter over all its walkers and its reference.
fn y_axis(p: &TraceParam, ticks: usize) -> NiceAxis {
    let r = p.walkers.iter().fold(None, |acc, w| {
        union(acc, data_range(w.iter().copied(), Scale::Linear))
    });
    let r = union(r, data_range(p.reference, Scale::Linear));
    NiceAxis::new(Scale::Linear, limits(r, Scale::Linear, 0.05), ticks)
}

impl TracesSpec {
    /// One parameter's panel in `cell`: the burn-in shaded from `x_lo` with its edge
    /// dashed, every walker's trace and the reference line.
    fn draw_param<DB: DrawingBackend>(
        &self,
        cell: &DrawingArea<DB, Shift>,
        layout: Panel,
        p: &TraceParam,
        x_lo: f64,
    ) -> DResult<(), DB> {
        let walker = Stroke::solid(WALKER_BLUE, 1);
        let burn = Stroke {
            color: BURN_GREY.to_rgba(),
            width: 1,
            dash: Dash::Dashed,
        };
        let reference = Stroke {
            color: style::OI_VERMILLION.to_rgba(),
            width: 2,
            dash: Dash::Dashed,
        };
        let (y0, y1) = layout.y.lo_hi();
        let mut chart = panel::build(cell, layout)?;
        if let Some(b) = self.burn_in.filter(|&b| b > 0) {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(x_lo, y0), (b as f64, y1)],
                BURN_GREY.mix(0.12).filled(),
            )))?;
            panel::ref_line(&mut chart, Some(b as f64), None, burn)?;
        }
        let mut occ = Occupied::default();
        let buckets = (panel::plot_width(&chart) / 2).max(100);
        for w in &p.walkers {
            let steps: Vec<f64> = (0..w.len()).map(|s| s as f64).collect();
            panel::line(&mut chart, &steps, w, walker, Some(buckets), &mut occ)?;
        }
        panel::ref_line(&mut chart, None, p.reference, reference)?;
        panel::frame(&mut chart)?;
        if occ.is_empty() {
            panel::note(&chart, "no data", SMALL)?;
        }
        Ok(())
    }
}
