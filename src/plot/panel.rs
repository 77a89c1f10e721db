//! One x-y panel and what every figure draws on it: lines broken at invalid points,
//! filled intervals, shaded frequency bands, reference lines and a frame (the legend is
//! in `legend.rs`).

use super::axis::{valid, NiceAxis};
use super::render::{put_text, text_width, DResult};
use super::style::{self, text, text_colored, Dash, Sizes};
use super::{FreqBand, Scale};
use plotters::chart::{ChartBuilder, ChartContext};
use plotters::coord::cartesian::Cartesian2d;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::element::{Circle, DashedPathElement, PathElement, Polygon, Rectangle};
use plotters::prelude::DrawingBackend;
use plotters::style::text_anchor::{HPos, VPos};
use plotters::style::{Color, RGBAColor, RGBColor, ShapeStyle};

pub(crate) use super::legend::{legend, Entry, Swatch};

/// A chart with [`NiceAxis`] on both axes.
pub(crate) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<NiceAxis, NiceAxis>>;

/// Distance from the axis to its tick labels (plotters: twice the tick size).
const TICK_PX: i32 = 5;
const LABEL_DIST_PX: u32 = 2 * TICK_PX as u32;

/// What a panel shows around its data.
pub(crate) struct Panel<'s> {
    pub title: &'s str,
    pub x: NiceAxis,
    pub y: NiceAxis,
    pub x_desc: &'s str,
    pub y_desc: &'s str,
    pub sizes: Sizes,
    /// Height of the label area under the plot; see [`x_area`].
    pub x_area: u32,
    /// Width of the label area left of the plot; see [`y_area`].
    pub y_area: u32,
    pub margin_right: u32,
}

/// Width the left label area needs for `axis`'s tick labels and `desc`.
pub(crate) fn y_area(axis: &NiceAxis, desc: &str, sizes: Sizes) -> u32 {
    let widest = axis
        .labels()
        .iter()
        .map(|l| text_width(l, sizes.tick))
        .max()
        .unwrap_or(0);
    let desc_px = if desc.is_empty() {
        0
    } else {
        (sizes.axis_desc * 1.3) as u32 + 6
    };
    LABEL_DIST_PX + widest + 6 + desc_px
}

/// Height the bottom label area needs: tick labels (if shown) and `desc`.
pub(crate) fn x_area(tick_labels: bool, desc: &str, sizes: Sizes) -> u32 {
    let labels = if tick_labels {
        LABEL_DIST_PX + (sizes.tick * 1.3) as u32
    } else {
        TICK_PX as u32 + 2
    };
    labels + desc_height(desc, sizes)
}

/// Labelled ticks for an axis `px` pixels long: about one per `spacing` pixels, at
/// least 2 and at most `max`.
pub(crate) fn ticks_for(px: u32, spacing: u32, max: usize) -> usize {
    ((px / spacing.max(1)) as usize).clamp(2, max.max(2))
}

/// Height of an x axis description with its gap (0 when empty).
pub(crate) fn desc_height(desc: &str, sizes: Sizes) -> u32 {
    if desc.is_empty() {
        0
    } else {
        6 + (sizes.axis_desc * 1.15) as u32
    }
}

/// Builds the chart and draws its grid, axes, tick labels and axis descriptions.
pub(crate) fn build<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    p: Panel,
) -> DResult<Chart<'a, DB>, DB> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin_top(8)
        .margin_left(4)
        .margin_bottom(4)
        .margin_right(p.margin_right)
        .x_label_area_size(p.x_area)
        .y_label_area_size(p.y_area);
    if !p.title.is_empty() {
        builder.caption(p.title, text(p.sizes.panel_title));
    }
    let mut chart = builder.build_cartesian_2d(p.x, p.y)?;
    let mut mesh = chart.configure_mesh();
    mesh.x_labels(10)
        .y_labels(10)
        .bold_line_style(style::GRID_BOLD.stroke_width(1))
        .light_line_style(style::GRID_LIGHT.stroke_width(1))
        .axis_style(style::AXIS_GREY.stroke_width(1))
        .set_all_tick_mark_size(TICK_PX)
        .x_label_style(text(p.sizes.tick))
        .y_label_style(text(p.sizes.tick))
        .axis_desc_style(text(p.sizes.axis_desc));
    if !p.x_desc.is_empty() {
        mesh.x_desc(p.x_desc);
    }
    if !p.y_desc.is_empty() {
        mesh.y_desc(p.y_desc);
    }
    mesh.draw()?;
    Ok(chart)
}

/// Pixels covered by data, for placing the legend where it hides least.
#[derive(Default)]
pub(crate) struct Occupied(pub(crate) Vec<(i32, i32)>);

impl Occupied {
    pub(crate) fn add<DB: DrawingBackend>(&mut self, chart: &Chart<DB>, pts: &[(f64, f64)]) {
        self.0.extend(pts.iter().map(|p| chart.backend_coord(p)));
    }

    /// Marks a filled rectangle (data corners) as covered, sampled on a 6 x 6 grid.
    pub(crate) fn add_rect<DB: DrawingBackend>(
        &mut self,
        chart: &Chart<DB>,
        a: (f64, f64),
        b: (f64, f64),
    ) {
        let (p, q) = (chart.backend_coord(&a), chart.backend_coord(&b));
        for i in 0..6 {
            for j in 0..6 {
                self.0
                    .push((p.0 + (q.0 - p.0) * i / 5, p.1 + (q.1 - p.1) * j / 5));
            }
        }
    }

    /// True when nothing was drawn.
    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Line look.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stroke {
    pub color: RGBAColor,
    pub width: u32,
    pub dash: Dash,
}

impl Stroke {
    pub(crate) fn solid(color: RGBColor, width: u32) -> Self {
        Stroke {
            color: color.to_rgba(),
            width,
            dash: Dash::Solid,
        }
    }

    pub(crate) fn shape(&self) -> ShapeStyle {
        ShapeStyle {
            color: self.color,
            filled: false,
            stroke_width: self.width,
        }
    }
}

/// Runs of consecutive points drawable on the chart's axes (finite, positive on log
/// axes); an invalid point breaks the line.
pub(crate) fn runs<DB: DrawingBackend>(
    chart: &Chart<DB>,
    x: &[f64],
    y: &[f64],
) -> Vec<Vec<(f64, f64)>> {
    let (sx, sy) = scales(chart);
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for (&a, &b) in x.iter().zip(y) {
        if valid(a, sx) && valid(b, sy) {
            cur.push((a, b));
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

fn scales<DB: DrawingBackend>(chart: &Chart<DB>) -> (Scale, Scale) {
    let spec = chart.as_coord_spec();
    let s = |a: &NiceAxis| {
        if a.is_log() {
            Scale::Log
        } else {
            Scale::Linear
        }
    };
    (s(spec.x_spec()), s(spec.y_spec()))
}

/// Plot width in pixels.
pub(crate) fn plot_width<DB: DrawingBackend>(chart: &Chart<DB>) -> usize {
    let (xr, _) = chart.plotting_area().get_pixel_range();
    (xr.end - xr.start).max(1) as usize
}

/// At most `2 * buckets` points keeping each bucket's minimum and maximum in order, so
/// spikes survive (the drawn envelope equals the full line's at one bucket per pixel).
pub(crate) fn decimate(run: &[(f64, f64)], buckets: usize) -> Vec<(f64, f64)> {
    let n = run.len();
    let buckets = buckets.max(1);
    if n <= 2 * buckets {
        return run.to_vec();
    }
    let mut out = Vec::with_capacity(2 * buckets + 2);
    for b in 0..buckets {
        let s = b * n / buckets;
        let e = ((b + 1) * n / buckets).min(n);
        if s >= e {
            continue;
        }
        let (mut imin, mut imax) = (s, s);
        for i in s..e {
            if run[i].1 < run[imin].1 {
                imin = i;
            }
            if run[i].1 > run[imax].1 {
                imax = i;
            }
        }
        let (a, b) = (imin.min(imax), imin.max(imax));
        out.push(run[a]);
        if b != a {
            out.push(run[b]);
        }
    }
    if out.last() != run.last() {
        out.push(run[n - 1]);
    }
    if out.first() != run.first() {
        out.insert(0, run[0]);
    }
    out
}

/// Draws `y(x)` as a line; invalid points break it, isolated points become dots.
/// `buckets` limits the points per run (see [`decimate`]); `None`: one per pixel.
pub(crate) fn line<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    x: &[f64],
    y: &[f64],
    stroke: Stroke,
    buckets: Option<usize>,
    occ: &mut Occupied,
) -> DResult<(), DB> {
    let buckets = buckets.unwrap_or_else(|| plot_width(chart));
    for run in runs(chart, x, y) {
        let pts = decimate(&run, buckets);
        occ.add(chart, &pts);
        if pts.len() == 1 {
            let r = stroke.width + 2;
            chart.draw_series(std::iter::once(Circle::new(
                pts[0],
                r,
                stroke.color.filled(),
            )))?;
            continue;
        }
        match stroke.dash.pattern() {
            None => {
                chart.draw_series(std::iter::once(PathElement::new(pts, stroke.shape())))?;
            }
            Some((on, off)) => {
                chart.draw_series(std::iter::once(DashedPathElement::new(
                    pts,
                    on,
                    off,
                    stroke.shape(),
                )))?;
            }
        }
    }
    Ok(())
}

/// Draws points as small filled circles (invalid points skipped).
pub(crate) fn points<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    x: &[f64],
    y: &[f64],
    color: RGBAColor,
    radius: u32,
    occ: &mut Occupied,
) -> DResult<(), DB> {
    let pts: Vec<(f64, f64)> = runs(chart, x, y).into_iter().flatten().collect();
    occ.add(chart, &pts);
    chart.draw_series(
        pts.into_iter()
            .map(|p| Circle::new(p, radius, color.filled())),
    )?;
    Ok(())
}

/// Fills between `lo(x)` and `hi(x)`; points where either is invalid break the fill.
/// Long runs are reduced to a per-bucket envelope (min of `lo`, max of `hi`).
pub(crate) fn fill_between<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    x: &[f64],
    lo: &[f64],
    hi: &[f64],
    color: RGBAColor,
    occ: &mut Occupied,
) -> DResult<(), DB> {
    let (sx, sy) = scales(chart);
    let buckets = plot_width(chart);
    let mut run: Vec<(f64, f64, f64)> = Vec::new();
    let n = x.len().min(lo.len()).min(hi.len());
    for i in 0..=n {
        let ok = i < n && valid(x[i], sx) && valid(lo[i], sy) && valid(hi[i], sy);
        if ok {
            run.push((x[i], lo[i], hi[i]));
            continue;
        }
        if run.len() >= 2 {
            let env = envelope(&run, buckets);
            let mut poly: Vec<(f64, f64)> = env.iter().map(|&(a, l, _)| (a, l)).collect();
            poly.extend(env.iter().rev().map(|&(a, _, h)| (a, h)));
            occ.add(chart, &poly);
            chart.draw_series(std::iter::once(Polygon::new(poly, color.filled())))?;
        }
        run.clear();
    }
    Ok(())
}

fn envelope(run: &[(f64, f64, f64)], buckets: usize) -> Vec<(f64, f64, f64)> {
    let n = run.len();
    if n <= 2 * buckets {
        return run.to_vec();
    }
    (0..buckets)
        .filter_map(|b| {
            let part = &run[b * n / buckets..((b + 1) * n / buckets).min(n)];
            let first = part.first()?;
            let lo = part.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
            let hi = part.iter().map(|p| p.2).fold(f64::NEG_INFINITY, f64::max);
            Some((first.0, lo, hi))
        })
        .chain(run.last().copied())
        .collect()
}

/// Shades each band over the full height of the panel (bands outside the x range and
/// non-finite bounds are skipped; reversed bounds are accepted).
pub(crate) fn shade_bands<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    bands: &[FreqBand],
) -> DResult<(), DB> {
    let spec = chart.as_coord_spec();
    let (x0, x1) = spec.x_spec().lo_hi();
    let (y0, y1) = spec.y_spec().lo_hi();
    let rects: Vec<_> = bands
        .iter()
        .filter(|b| b.lo_hz.is_finite() && b.hi_hz.is_finite())
        .map(|b| (b.lo_hz.min(b.hi_hz), b.lo_hz.max(b.hi_hz)))
        .filter(|&(a, b)| b >= x0 && a <= x1)
        .map(|(a, b)| {
            Rectangle::new(
                [(a.max(x0), y0), (b.min(x1), y1)],
                style::band_shade().filled(),
            )
        })
        .collect();
    chart.draw_series(rects)?;
    Ok(())
}

/// A straight reference line across the panel: vertical at `x` or horizontal at `y`.
pub(crate) fn ref_line<DB: DrawingBackend>(
    chart: &mut Chart<DB>,
    vertical_at: Option<f64>,
    horizontal_at: Option<f64>,
    stroke: Stroke,
) -> DResult<(), DB> {
    let spec = chart.as_coord_spec();
    let (x0, x1) = spec.x_spec().lo_hi();
    let (y0, y1) = spec.y_spec().lo_hi();
    let (sx, sy) = scales(chart);
    let mut occ = Occupied::default();
    if let Some(x) = vertical_at.filter(|&x| valid(x, sx) && x >= x0 && x <= x1) {
        line(chart, &[x, x], &[y0, y1], stroke, None, &mut occ)?;
    }
    if let Some(y) = horizontal_at.filter(|&y| valid(y, sy) && y >= y0 && y <= y1) {
        line(chart, &[x0, x1], &[y, y], stroke, None, &mut occ)?;
    }
    Ok(())
}

/// Frame around the plotting area.
pub(crate) fn frame<DB: DrawingBackend>(chart: &mut Chart<DB>) -> DResult<(), DB> {
    let spec = chart.as_coord_spec();
    let (x0, x1) = spec.x_spec().lo_hi();
    let (y0, y1) = spec.y_spec().lo_hi();
    chart.draw_series(std::iter::once(Rectangle::new(
        [(x0, y0), (x1, y1)],
        style::AXIS_GREY.stroke_width(1),
    )))?;
    Ok(())
}

/// Writes `msg` in grey in the middle of the plotting area (empty panels).
pub(crate) fn note<DB: DrawingBackend>(
    chart: &Chart<DB>,
    msg: &str,
    sizes: Sizes,
) -> DResult<(), DB> {
    let area = chart.plotting_area().strip_coord_spec();
    let (w, h) = area.dim_in_pixel();
    put_text(
        &area,
        msg,
        &text_colored(sizes.legend, style::AXIS_GREY),
        (w as i32 / 2, h as i32 / 2),
        (HPos::Center, VPos::Center),
    )
}

/// Rows and columns for `n` panels: side by side up to 3, then a near-square grid.
pub(crate) fn grid_shape(n: usize) -> (usize, usize) {
    let n = n.max(1);
    if n <= 3 {
        return (1, n);
    }
    let cols = (n as f64).sqrt().ceil() as usize;
    (n.div_ceil(cols), cols)
}

/// The first `n` cells of a [`grid_shape`] split of `area`, row by row.
pub(crate) fn grid_cells<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    n: usize,
) -> Vec<DrawingArea<DB, Shift>> {
    let (rows, cols) = grid_shape(n);
    area.split_evenly((rows, cols))
        .into_iter()
        .take(n)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimate_keeps_extremes_and_ends() {
        let run: Vec<(f64, f64)> = (0..1000)
            .map(|i| (i as f64, ((i * 37) % 101) as f64))
            .collect();
        let d = decimate(&run, 10);
        assert!(d.len() <= 22, "{}", d.len());
        assert_eq!(d.first(), run.first());
        assert_eq!(d.last(), run.last());
        let max = d.iter().map(|p| p.1).fold(f64::MIN, f64::max);
        let min = d.iter().map(|p| p.1).fold(f64::MAX, f64::min);
        assert_eq!((min, max), (0.0, 100.0));
        assert!(d.windows(2).all(|w| w[0].0 < w[1].0), "order kept");
        let short = &run[..15];
        assert_eq!(grid_shape(0), (1, 1));
        assert_eq!(grid_shape(2), (1, 2));
        assert_eq!(grid_shape(4), (2, 2));
        assert_eq!(grid_shape(5), (2, 3));
        assert_eq!(grid_shape(10), (3, 4));
        assert_eq!(decimate(short, 10), short.to_vec());
    }
}
