//! Category labels under or beside a panel (bar charts, heatmaps): horizontal when they
//! fit their slot, otherwise turned to read upwards; thinned when even that overlaps.

use super::panel::Chart;
use super::render::{put_text, text_width, DResult};
use super::style::text;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::prelude::DrawingBackend;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::FontTransform;

/// Gap between the plot edge and category labels, pixels.
pub(crate) const GAP_PX: i32 = 8;

/// How category labels along x are laid out.
#[derive(Clone, Copy, Debug)]
pub(crate) struct XLayout {
    pub rotated: bool,
    /// Every `stride`-th label is drawn.
    pub stride: usize,
    /// Height the labels need below the plot, pixels.
    pub height_px: u32,
    pub font: f64,
}

/// Chooses horizontal or rotated labels for `n` slots of `slot_px` pixels.
pub(crate) fn x_layout<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    labels: &[String],
    slot_px: f64,
    font: f64,
) -> XLayout {
    let widest = labels
        .iter()
        .map(|l| text_width(l, font))
        .max()
        .unwrap_or(0) as f64;
    let line_px = font * 1.25;
    if widest <= slot_px * 0.92 {
        return XLayout {
            rotated: false,
            stride: 1,
            height_px: GAP_PX as u32 + line_px as u32,
            font,
        };
    }
    // Rotated labels need about one line height per slot; longer labels are capped at
    // 45% of the figure (they are then cut off, which is better than covering the plot).
    let stride = (line_px / slot_px.max(1.0)).ceil().max(1.0) as usize;
    let (_, h) = area.dim_in_pixel();
    let height = widest.min(0.45 * h as f64);
    XLayout {
        rotated: true,
        stride,
        height_px: GAP_PX as u32 + height as u32 + 4,
        font,
    }
}

/// Draws category `i`'s label under x = i of the chart's plotting area.
pub(crate) fn draw_x<DB: DrawingBackend>(
    chart: &Chart<DB>,
    labels: &[String],
    layout: XLayout,
) -> DResult<(), DB> {
    let area = chart.plotting_area().strip_coord_spec();
    let base = area.get_base_pixel();
    let (_, h) = area.dim_in_pixel();
    let y_lo = chart.as_coord_spec().y_spec().lo_hi().0;
    for (i, label) in labels.iter().enumerate().step_by(layout.stride) {
        let (px, _) = chart.backend_coord(&(i as f64, y_lo));
        let x = px - base.0;
        let y = h as i32 + GAP_PX;
        if layout.rotated {
            let style = text(layout.font).transform(FontTransform::Rotate270);
            put_text(&area, label, &style, (x, y), (HPos::Right, VPos::Center))?;
        } else {
            put_text(
                &area,
                label,
                &text(layout.font),
                (x, y),
                (HPos::Center, VPos::Top),
            )?;
        }
    }
    Ok(())
}

/// Width needed left of the plot for row labels.
pub(crate) fn y_width(labels: &[String], font: f64) -> u32 {
    labels
        .iter()
        .map(|l| text_width(l, font))
        .max()
        .unwrap_or(0)
        + GAP_PX as u32
}

/// Draws row labels right-aligned left of the plot; `labels[r]` goes at y = `n - 1 - r`
/// (first row on top). Labels are thinned when rows are lower than the text.
pub(crate) fn draw_y<DB: DrawingBackend>(
    chart: &Chart<DB>,
    labels: &[String],
    font: f64,
) -> DResult<(), DB> {
    let area = chart.plotting_area().strip_coord_spec();
    let base = area.get_base_pixel();
    let (_, h) = area.dim_in_pixel();
    let n = labels.len();
    let row_px = h as f64 / n.max(1) as f64;
    let stride = ((font * 1.1) / row_px.max(1.0)).ceil().max(1.0) as usize;
    let x_lo = chart.as_coord_spec().x_spec().lo_hi().0;
    for (r, label) in labels.iter().enumerate().step_by(stride) {
        let (_, py) = chart.backend_coord(&(x_lo, (n - 1 - r) as f64));
        put_text(
            &area,
            label,
            &text(font),
            (-GAP_PX, py - base.1),
            (HPos::Right, VPos::Center),
        )?;
    }
    Ok(())
}
