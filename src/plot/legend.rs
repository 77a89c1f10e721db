//! Legends: inside a plotting area where they hide the fewest data pixels, or as a strip
//! shared by several panels.

use super::panel::{Chart, Occupied, Stroke};
use super::render::{put_text, text_width, DResult};
use super::style::{self, text, Sizes};
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::element::{Circle, DashedPathElement, PathElement, Rectangle};
use plotters::prelude::DrawingBackend;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::{Color, RGBAColor, RGBColor};

/// How a legend entry is drawn.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Swatch {
    Line(Stroke),
    LineDot(Stroke),
    Patch(RGBAColor),
    Dot(RGBAColor),
}

/// One legend row.
#[derive(Clone, Debug)]
pub(crate) struct Entry {
    pub label: String,
    pub swatch: Swatch,
}

/// Width of an entry's swatch, pixels.
const SWATCH_PX: i32 = 28;

/// Draws one entry, its swatch starting at `x` and centred on `cy`, the label after it.
fn draw_entry<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    e: &Entry,
    (x, cy): (i32, i32),
    font: f64,
) -> DResult<(), DB> {
    let swatch = SWATCH_PX;
    match e.swatch {
        Swatch::Line(s) | Swatch::LineDot(s) => {
            let pts = vec![(x, cy), (x + swatch - 4, cy)];
            if let Swatch::LineDot(_) = e.swatch {
                area.draw(&Circle::new((x + swatch / 2 - 2, cy), 4, s.color.filled()))?;
            }
            match s.dash.pattern() {
                None => area.draw(&PathElement::new(pts, s.shape()))?,
                Some((on, off)) => area.draw(&DashedPathElement::new(pts, on, off, s.shape()))?,
            }
        }
        Swatch::Patch(color) => area.draw(&Rectangle::new(
            [
                (x, cy - font as i32 / 2 + 1),
                (x + swatch - 4, cy + font as i32 / 2 - 1),
            ],
            color.filled(),
        ))?,
        Swatch::Dot(color) => {
            area.draw(&Circle::new((x + swatch / 2 - 2, cy), 4, color.filled()))?
        }
    }
    put_text(
        area,
        &e.label,
        &text(font),
        (x + swatch + 4, cy),
        (HPos::Left, VPos::Center),
    )
}

/// Draws `entries` in centred rows across the top of `area` (a legend shared by several
/// panels) and returns the area below them.
pub(crate) fn legend_strip<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[Entry],
    sizes: Sizes,
) -> DResult<DrawingArea<DB, Shift>, DB> {
    let entries: Vec<&Entry> = entries.iter().filter(|e| !e.label.is_empty()).collect();
    if entries.is_empty() {
        return Ok(area.clone());
    }
    let font = sizes.legend;
    let gap = 26;
    let (w, _) = area.dim_in_pixel();
    let widths: Vec<i32> = entries
        .iter()
        .map(|e| SWATCH_PX + 4 + text_width(&e.label, font) as i32)
        .collect();
    // Greedy rows that fit the width.
    let mut rows: Vec<Vec<usize>> = vec![Vec::new()];
    let mut used = 0;
    for (i, &ew) in widths.iter().enumerate() {
        let need = if used == 0 { ew } else { used + gap + ew };
        if need > w as i32 - 20 && used > 0 {
            rows.push(vec![i]);
            used = ew;
        } else {
            if let Some(r) = rows.last_mut() {
                r.push(i);
            }
            used = need;
        }
    }
    let row_h = (font * 1.5) as i32;
    for (r, row) in rows.iter().enumerate() {
        let total: i32 = row.iter().map(|&i| widths[i]).sum::<i32>() + gap * (row.len() as i32 - 1);
        let mut x = (w as i32 - total) / 2;
        let cy = 4 + r as i32 * row_h + row_h / 2;
        for &i in row {
            draw_entry(area, entries[i], (x, cy), font)?;
            x += widths[i] + gap;
        }
    }
    let (_, below) = area.split_vertically(4 + rows.len() as i32 * row_h + 4);
    Ok(below)
}

/// Draws the legend inside the plotting area, in the corner (or top/bottom centre) where
/// it covers the fewest data pixels; columns are added when it would be too tall.
pub(crate) fn legend<DB: DrawingBackend>(
    chart: &Chart<DB>,
    entries: &[Entry],
    occ: &Occupied,
    sizes: Sizes,
) -> DResult<(), DB> {
    let entries: Vec<&Entry> = entries.iter().filter(|e| !e.label.is_empty()).collect();
    if entries.is_empty() {
        return Ok(());
    }
    let area = chart.plotting_area().strip_coord_spec();
    let base = area.get_base_pixel();
    let (w, h) = area.dim_in_pixel();
    let (w, h) = (w as i32, h as i32);
    let font = sizes.legend;
    let row = (font * 1.45) as i32;
    let pad = 8;
    let swatch = SWATCH_PX;
    let max_rows = ((h - 2 * pad - 16) / row).max(1) as usize;
    let cols = entries.len().div_ceil(max_rows);
    let rows = entries.len().div_ceil(cols);
    let col_w: Vec<i32> = (0..cols)
        .map(|c| {
            entries
                .iter()
                .skip(c * rows)
                .take(rows)
                .map(|e| text_width(&e.label, font) as i32)
                .max()
                .unwrap_or(0)
                + swatch
                + 8
        })
        .collect();
    let box_w = col_w.iter().sum::<i32>() + 2 * pad + 12 * (cols as i32 - 1);
    let box_h = rows as i32 * row + 2 * pad - (row - font as i32) / 2;
    if box_w > w || box_h > h {
        // Larger than the plot itself (tiny figure): leave the data visible instead.
        return Ok(());
    }
    let m = 10;
    let candidates = [
        (w - box_w - m, m),
        (m, m),
        (w - box_w - m, h - box_h - m),
        (m, h - box_h - m),
        ((w - box_w) / 2, m),
        ((w - box_w) / 2, h - box_h - m),
    ];
    let covered = |(x, y): (i32, i32)| {
        occ.0
            .iter()
            .filter(|p| {
                let (px, py) = (p.0 - base.0, p.1 - base.1);
                px >= x - 4 && px <= x + box_w + 4 && py >= y - 4 && py <= y + box_h + 4
            })
            .count()
    };
    let (bx, by) = candidates
        .iter()
        .copied()
        .min_by_key(|&c| covered(c))
        .unwrap_or(candidates[0]);
    area.draw(&Rectangle::new(
        [(bx, by), (bx + box_w, by + box_h)],
        style::WHITE.mix(0.88).filled(),
    ))?;
    area.draw(&Rectangle::new(
        [(bx, by), (bx + box_w, by + box_h)],
        RGBColor(170, 170, 170).stroke_width(1),
    ))?;
    let mut x = bx + pad;
    for (c, cw) in col_w.iter().enumerate() {
        for (r, e) in entries.iter().skip(c * rows).take(rows).enumerate() {
            let cy = by + pad + r as i32 * row + font as i32 / 2;
            draw_entry(&area, e, (x, cy), font)?;
        }
        x += cw + 12;
    }
    Ok(())
}
