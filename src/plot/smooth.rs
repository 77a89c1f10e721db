//! A backend wrapper that gives PNG figures anti-aliased text, lines, filled polygons
//! and circles (plotters' bitmap backend draws them aliased, and its text with uneven
//! letter spacing), and measures text the same way for the SVG backend so both files
//! share one layout.
//!
//! Shapes are turned into closed outlines and rasterised with `ab_glyph_rasterizer`
//! (signed-area coverage): a stroke is one quad per segment plus round joints, all with
//! the same winding, so overlaps clamp to full coverage and a translucent line is blended
//! once per pixel. Rectangles and axis-parallel grid lines stay crisp (inner backend).

use super::glyphs;
use ab_glyph_rasterizer::{point, Rasterizer};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};
use std::f32::consts::TAU;

/// Shapes whose bounding box exceeds this many pixels fall back to the inner backend.
const MAX_RASTER_PX: usize = 1 << 24;
/// Vertices of a full circle.
const CIRCLE_SIDES: usize = 40;

/// Wraps `inner`; `rasterise` is true for bitmaps (draw here), false for SVG (only text
/// measurement is taken over).
pub(crate) struct Smooth<B> {
    pub inner: B,
    pub rasterise: bool,
}

type Poly = Vec<(f32, f32)>;

/// Regular polygon approximating a circle, wound like [`stroke_outline`]'s quads.
fn disk(c: (f32, f32), r: f32, sides: usize) -> Poly {
    (0..sides)
        .map(|i| {
            let t = -TAU * i as f32 / sides as f32;
            (c.0 + r * t.cos(), c.1 + r * t.sin())
        })
        .collect()
}

/// Outline of a polyline of `width` pixels through pixel centres: one quad per segment
/// (all wound the same way) and, from 2 px on, a disk at every vertex (round joins and
/// caps).
fn stroke_outline(pts: &[BackendCoord], width: u32) -> Vec<Poly> {
    let hw = (width.max(1) as f32) / 2.0;
    let c: Vec<(f32, f32)> = pts
        .iter()
        .map(|&(x, y)| (x as f32 + 0.5, y as f32 + 0.5))
        .collect();
    let mut out = Vec::with_capacity(2 * c.len());
    for w in c.windows(2) {
        let (p, q) = (w[0], w[1]);
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        let len = dx.hypot(dy);
        if len < 1e-6 {
            continue;
        }
        let (nx, ny) = (-dy / len * hw, dx / len * hw);
        out.push(vec![
            (p.0 + nx, p.1 + ny),
            (q.0 + nx, q.1 + ny),
            (q.0 - nx, q.1 - ny),
            (p.0 - nx, p.1 - ny),
        ]);
    }
    if width >= 2 {
        let sides = if hw < 2.0 { 12 } else { 24 };
        out.extend(c.iter().map(|&p| disk(p, hw, sides)));
    }
    out
}

/// Signed area (shoelace), to check windings in tests.
#[cfg(test)]
fn signed_area(p: &Poly) -> f32 {
    (0..p.len())
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum::<f32>()
        / 2.0
}

/// Pixel coverage of the union of `shapes` (same winding), offset to the image. `None`
/// when the shapes are too large to rasterise here.
fn coverage(shapes: &[Poly], (w, h): (u32, u32)) -> Option<Vec<(i32, i32, f32)>> {
    let pts = shapes.iter().flatten();
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for &(x, y) in pts {
        if !x.is_finite() || !y.is_finite() {
            return None;
        }
        x0 = x0.min(x);
        y0 = y0.min(y);
        x1 = x1.max(x);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return Some(Vec::new());
    }
    let (ox, oy) = (x0.floor() - 1.0, y0.floor() - 1.0);
    let (bw, bh) = ((x1 - ox).ceil() as usize + 2, (y1 - oy).ceil() as usize + 2);
    if bw.saturating_mul(bh) > MAX_RASTER_PX {
        return None;
    }
    let mut r = Rasterizer::new(bw, bh);
    for poly in shapes {
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            r.draw_line(point(a.0 - ox, a.1 - oy), point(b.0 - ox, b.1 - oy));
        }
    }
    let mut out = Vec::new();
    r.for_each_pixel_2d(|x, y, a| {
        let a = a.min(1.0);
        if a > 1.0 / 512.0 {
            let (px, py) = (x as i32 + ox as i32, y as i32 + oy as i32);
            if px >= 0 && py >= 0 && px < w as i32 && py < h as i32 {
                out.push((px, py, a));
            }
        }
    });
    Some(out)
}

impl<B: DrawingBackend> Smooth<B> {
    fn paint(
        &mut self,
        pixels: Vec<(i32, i32, f32)>,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<B::ErrorType>> {
        for (x, y, a) in pixels {
            let c = BackendColor {
                alpha: color.alpha * a as f64,
                rgb: color.rgb,
            };
            self.inner.draw_pixel((x, y), c)?;
        }
        Ok(())
    }

    /// Fills `shapes` with anti-aliasing; `false` if they must go to the inner backend.
    fn fill_shapes(
        &mut self,
        shapes: &[Poly],
        color: BackendColor,
    ) -> Result<bool, DrawingErrorKind<B::ErrorType>> {
        match coverage(shapes, self.inner.get_size()) {
            Some(px) => {
                self.paint(px, color)?;
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

impl<B: DrawingBackend> DrawingBackend for Smooth<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        if !self.rasterise {
            return self.inner.draw_path(path, style);
        }
        if style.color().alpha == 0.0 {
            return Ok(());
        }
        let pts: Vec<BackendCoord> = path.into_iter().collect();
        let shapes = stroke_outline(&pts, style.stroke_width());
        if !self.fill_shapes(&shapes, style.color())? {
            return self.inner.draw_path(pts, style);
        }
        Ok(())
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        if !self.rasterise || radius == 0 {
            return self.inner.draw_circle(center, radius, style, fill);
        }
        let c = (center.0 as f32 + 0.5, center.1 as f32 + 0.5);
        let shapes = if fill {
            vec![disk(c, radius as f32, CIRCLE_SIDES)]
        } else {
            let ring: Vec<BackendCoord> = disk(c, radius as f32, CIRCLE_SIDES)
                .into_iter()
                .chain(std::iter::once((c.0 + radius as f32, c.1)))
                .map(|(x, y)| ((x - 0.5).round() as i32, (y - 0.5).round() as i32))
                .collect();
            stroke_outline(&ring, style.stroke_width())
        };
        if !self.fill_shapes(&shapes, style.color())? {
            return self.inner.draw_circle(center, radius, style, fill);
        }
        Ok(())
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        if !self.rasterise {
            return self.inner.fill_polygon(vert, style);
        }
        let pts: Vec<BackendCoord> = vert.into_iter().collect();
        let poly: Poly = pts
            .iter()
            .map(|&(x, y)| (x as f32 + 0.5, y as f32 + 0.5))
            .collect();
        // A fill's winding does not matter: coverage takes the absolute value.
        if !self.fill_shapes(&[poly], style.color())? {
            return self.inner.fill_polygon(pts, style);
        }
        Ok(())
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        (iw, ih): (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.blit_bitmap(pos, (iw, ih), src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        match glyphs::font() {
            Some(f) => {
                let l = glyphs::layout(f, text, style.size());
                Ok((l.width.ceil() as u32, (l.ascent - l.descent).ceil() as u32))
            }
            None => self.inner.estimate_text_size(text, style),
        }
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        let font = match glyphs::font() {
            Some(f) if self.rasterise => f,
            _ => return self.inner.draw_text(text, style, pos),
        };
        let color = style.color();
        if color.alpha == 0.0 || text.is_empty() {
            return Ok(());
        }
        let (w, h) = self.inner.get_size();
        let pixels: Vec<(i32, i32, f32)> =
            glyphs::coverage(font, text, style.size(), style.anchor(), style.transform())
                .into_iter()
                .map(|(x, y, a)| (pos.0 + x, pos.1 + y, a))
                .filter(|&(x, y, _)| x >= 0 && y >= 0 && x < w as i32 && y < h as i32)
                .collect();
        self.paint(pixels, color)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stroke_pieces_share_one_winding() {
        let pts = [(0, 0), (10, 0), (10, 10), (0, 3)];
        let shapes = stroke_outline(&pts, 3);
        assert_eq!(shapes.len(), 3 + 4);
        let signs: Vec<bool> = shapes.iter().map(|s| signed_area(s) > 0.0).collect();
        assert!(signs.iter().all(|&s| s == signs[0]), "{signs:?}");
    }

    #[test]
    fn horizontal_line_coverage_is_its_width() {
        // A 3 px wide horizontal segment, 20 px long (+ round caps): the coverage summed
        // over one interior column equals the width.
        let shapes = stroke_outline(&[(10, 10), (30, 10)], 3);
        let px = coverage(&shapes, (100, 100)).unwrap();
        let column: f32 = px.iter().filter(|p| p.0 == 20).map(|p| p.2).sum();
        assert!((column - 3.0).abs() < 1e-3, "{column}");
        assert!(px.iter().all(|p| p.2 <= 1.0));
        // A filled disk of radius 10 covers about pi r^2 (40-gon: 0.4% less).
        let disk_px: f32 = coverage(&[disk((50.0, 50.0), 10.0, CIRCLE_SIDES)], (100, 100))
            .unwrap()
            .iter()
            .map(|p| p.2)
            .sum();
        let area_40gon = 0.5 * 40.0 * 100.0 * (TAU / 40.0).sin();
        assert!(
            (disk_px - area_40gon).abs() < 0.05,
            "{disk_px} vs {area_40gon}"
        );
    }

    #[test]
    fn huge_or_non_finite_shapes_fall_back() {
        assert!(coverage(&[vec![(0.0, 0.0), (1e6, 0.0), (1e6, 1e6)]], (100, 100)).is_none());
        assert!(coverage(&[vec![(0.0, 0.0), (f32::NAN, 1.0), (2.0, 2.0)]], (100, 100)).is_none());
        assert_eq!(coverage(&[], (100, 100)), Some(Vec::new()));
    }
}
