//! Text layout and rasterisation with the bundled font.
//!
//! plotters 0.3.7 places ab_glyph glyphs without their left side bearing, so PNG text
//! came out with uneven letter spacing ("Frequ ency"). Here text is laid out with
//! advances, kerning and bearings at sub-pixel positions. Sizes follow plotters' SVG
//! backend: a text style of size `s` has an em of `s / 1.24` pixels, so PNG and SVG
//! text match.

use ab_glyph::{point, Font, FontRef, GlyphId, PxScale, ScaleFont};
use plotters_backend::text_anchor::{HPos, Pos, VPos};
use plotters_backend::FontTransform;
use std::sync::OnceLock;

/// The bundled DejaVu Sans (licence beside it in `src/plot/fonts/`).
pub(crate) const FONT_BYTES: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// plotters' SVG backend writes `font-size = size / 1.24`.
const EM_PER_SIZE: f32 = 1.0 / 1.24;

pub(crate) fn font() -> Option<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).ok())
        .as_ref()
}

/// Glyphs of one line of text, positioned from x = 0 on the baseline.
pub(crate) struct Layout {
    scale: PxScale,
    glyphs: Vec<(GlyphId, f32)>,
    pub width: f32,
    pub ascent: f32,
    pub descent: f32,
}

pub(crate) fn layout(font: &FontRef<'static>, text: &str, size: f64) -> Layout {
    let em = size as f32 * EM_PER_SIZE;
    let units = font.units_per_em().unwrap_or(2048.0);
    let scale = PxScale::from(em * font.height_unscaled() / units);
    let sf = font.as_scaled(scale);
    let mut caret = 0.0f32;
    let mut prev: Option<GlyphId> = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(p) = prev {
            caret += sf.kern(p, id);
        }
        glyphs.push((id, caret));
        caret += sf.h_advance(id);
        prev = Some(id);
    }
    Layout {
        scale,
        glyphs,
        width: caret,
        ascent: sf.ascent(),
        descent: sf.descent(),
    }
}

/// Coverage (0..1] of the pixels of `text` anchored at the origin, after `trans`.
pub(crate) fn coverage(
    font: &FontRef<'static>,
    text: &str,
    size: f64,
    anchor: Pos,
    trans: FontTransform,
) -> Vec<(i32, i32, f32)> {
    let l = layout(font, text, size);
    let dx = match anchor.h_pos {
        HPos::Left => 0.0,
        HPos::Center => -l.width / 2.0,
        HPos::Right => -l.width,
    };
    let height = l.ascent - l.descent;
    let top = match anchor.v_pos {
        VPos::Top => 0.0,
        VPos::Center => -height / 2.0,
        VPos::Bottom => -height,
    };
    let baseline = top + l.ascent;
    let mut pixels = Vec::new();
    for &(id, x) in &l.glyphs {
        let glyph = id.with_scale_and_position(l.scale, point(dx + x, baseline));
        if let Some(outlined) = font.outline_glyph(glyph) {
            let b = outlined.px_bounds();
            outlined.draw(|gx, gy, cov| {
                if cov > 0.004 {
                    let (x, y) = (b.min.x as i32 + gx as i32, b.min.y as i32 + gy as i32);
                    let (tx, ty) = trans.transform(x, y);
                    pixels.push((tx, ty, cov.min(1.0)));
                }
            });
        }
    }
    pixels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_width_grows_with_text_and_size() {
        let f = font().expect("bundled font parses");
        let a = layout(f, "Hz", 20.0);
        let b = layout(f, "Hz Hz", 20.0);
        let c = layout(f, "Hz", 40.0);
        assert!(a.width > 10.0 && b.width > 2.0 * a.width);
        assert!((c.width / a.width - 2.0).abs() < 1e-3);
        // DejaVu Sans: ascent - descent is 1.164 em; em = size / 1.24
        let em = 20.0 / 1.24;
        assert!(((a.ascent - a.descent) / em - 1.164).abs() < 0.01);
    }

    #[test]
    fn anchored_text_sits_on_its_anchor() {
        let f = font().expect("bundled font parses");
        let px = coverage(
            f,
            "HH",
            30.0,
            Pos::new(HPos::Right, VPos::Center),
            FontTransform::None,
        );
        let max_x = px.iter().map(|p| p.0).max().unwrap();
        let (min_y, max_y) = (
            px.iter().map(|p| p.1).min().unwrap(),
            px.iter().map(|p| p.1).max().unwrap(),
        );
        // Right-anchored: ends just left of x = 0 (H's right bearing is ~1.6 px here).
        assert!((-4..=0).contains(&max_x), "{max_x}");
        // Capitals (cap height 0.73 em = 17.6 px) are centred on the anchor within 2 px:
        // the ascent-descent box is centred and DejaVu's caps sit in its middle.
        assert!(
            max_y - min_y >= 17 && (min_y + max_y).abs() <= 2,
            "{min_y} {max_y}"
        );
    }
}
