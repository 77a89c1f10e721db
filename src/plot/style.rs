//! Look of every figure: the bundled font, text sizes, the colour-blind-safe palette and
//! the colour maps. One place, so all figures look alike.

use ab_glyph::{Font, FontRef};
use plotters::style::{Color, FontStyle, RGBAColor, RGBColor, TextStyle};
use std::sync::{Once, OnceLock};

/// The bundled DejaVu Sans (licence beside it in `src/plot/fonts/`).
pub(crate) const FONT_BYTES: &[u8] = include_bytes!("fonts/DejaVuSans.ttf");

/// The bundled font's family name: written into every SVG, and the only font the PNG
/// rasteriser knows (`raster.rs`).
pub(crate) const FONT: &str = "DejaVu Sans";

/// plotters' SVG backend writes `font-size = size / 1.24` for a text style of size `size`.
const EM_PER_SIZE: f32 = 1.0 / 1.24;

static FONT_ONCE: Once = Once::new();

/// Registers the bundled font with plotters under [`FONT`], exactly once per process.
/// plotters has no system font lookup here (no fontconfig) and measures tick labels with
/// it, so every figure calls this before drawing text.
pub(crate) fn ensure_font() {
    FONT_ONCE.call_once(|| {
        // The font is compiled in; failing to parse it is a build defect, caught by the
        // tests (every figure then fails with a font error rather than panicking).
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

/// Width in pixels of `s` set at text size `size` as the SVG shows it (advances and
/// kerning of the bundled font at an em of `size / 1.24` px). Zero if the font fails to
/// parse (a build defect the tests catch).
pub(crate) fn text_width(s: &str, size: f64) -> f64 {
    static PARSED: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    let Some(font) = PARSED.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).ok()) else {
        return 0.0;
    };
    let units = font.units_per_em().unwrap_or(2048.0);
    let em = size as f32 * EM_PER_SIZE;
    let (mut caret, mut prev) = (0.0f32, None);
    for c in s.chars() {
        let id = font.glyph_id(c);
        if let Some(p) = prev {
            caret += font.kern_unscaled(p, id);
        }
        caret += font.h_advance_unscaled(id);
        prev = Some(id);
    }
    (caret * em / units) as f64
}

/// Text sizes for a figure of about 1000 x 700 px (the em is `size / 1.24` pixels).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sizes {
    pub title: f64,
    pub panel_title: f64,
    pub axis_desc: f64,
    pub tick: f64,
    pub legend: f64,
}

pub(crate) const NORMAL: Sizes = Sizes {
    title: 28.0,
    panel_title: 22.0,
    axis_desc: 21.0,
    tick: 18.0,
    legend: 18.0,
};

/// Smaller text for figures made of many small panels (corner plots, traces).
pub(crate) const SMALL: Sizes = Sizes {
    title: 26.0,
    panel_title: 18.0,
    axis_desc: 18.0,
    tick: 15.0,
    legend: 16.0,
};

pub(crate) fn text(size: f64) -> TextStyle<'static> {
    TextStyle::from((FONT, size))
}

pub(crate) fn text_colored(size: f64, color: RGBColor) -> TextStyle<'static> {
    let mut style = TextStyle::from((FONT, size));
    style.color = color.to_backend_color();
    style
}

pub(crate) const BLACK: RGBColor = RGBColor(0, 0, 0);
pub(crate) const WHITE: RGBColor = RGBColor(255, 255, 255);
pub(crate) const AXIS_GREY: RGBColor = RGBColor(90, 90, 90);
pub(crate) const GRID_BOLD: RGBColor = RGBColor(218, 218, 218);
pub(crate) const GRID_LIGHT: RGBColor = RGBColor(240, 240, 240);
pub(crate) const MISSING_GREY: RGBColor = RGBColor(205, 205, 205);

/// Okabe-Ito colours (Okabe & Ito 2008), safe for the common colour-vision deficiencies.
pub(crate) const OI_BLUE: RGBColor = RGBColor(0, 114, 178);
pub(crate) const OI_VERMILLION: RGBColor = RGBColor(213, 94, 0);
pub(crate) const OI_GREEN: RGBColor = RGBColor(0, 158, 115);
pub(crate) const OI_PURPLE: RGBColor = RGBColor(204, 121, 167);
pub(crate) const OI_ORANGE: RGBColor = RGBColor(230, 159, 0);
pub(crate) const OI_SKY: RGBColor = RGBColor(86, 180, 233);
pub(crate) const OI_YELLOW: RGBColor = RGBColor(240, 228, 66);

/// Line colours in order of use. Okabe-Ito without yellow (too faint on white).
const PALETTE: [RGBColor; 7] = [
    OI_BLUE,
    OI_VERMILLION,
    OI_GREEN,
    OI_PURPLE,
    OI_ORANGE,
    OI_SKY,
    BLACK,
];

/// Colour and dash of the `i`-th series: the 7 palette colours solid, then dashed, then
/// dotted-dashed (short dashes), so up to 21 series stay distinguishable.
pub(crate) fn series_look(i: usize) -> (RGBColor, Dash) {
    let dash = match (i / PALETTE.len()) % 3 {
        0 => Dash::Solid,
        1 => Dash::Dashed,
        _ => Dash::Short,
    };
    (PALETTE[i % PALETTE.len()], dash)
}

/// Line pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Dash {
    Solid,
    Dashed,
    Short,
}

impl Dash {
    /// (dash length, gap) in pixels, `None` for solid.
    pub(crate) fn pattern(self) -> Option<(u32, u32)> {
        match self {
            Dash::Solid => None,
            Dash::Dashed => Some((9, 5)),
            Dash::Short => Some((3, 4)),
        }
    }
}

/// Shade of the selected frequency bands.
pub(crate) fn band_shade() -> RGBAColor {
    OI_YELLOW.mix(0.28)
}

/// ColorBrewer RdBu (11 classes), blue for negative, red for positive; colour-blind safe.
const RDBU: [(u8, u8, u8); 11] = [
    (5, 48, 97),
    (33, 102, 172),
    (67, 147, 195),
    (146, 197, 222),
    (209, 229, 240),
    (247, 247, 247),
    (253, 219, 199),
    (244, 165, 130),
    (214, 96, 77),
    (178, 24, 43),
    (103, 0, 31),
];

/// ColorBrewer Blues (9 classes), for densities.
const BLUES: [(u8, u8, u8); 9] = [
    (247, 251, 255),
    (222, 235, 247),
    (198, 219, 239),
    (158, 202, 225),
    (107, 174, 214),
    (66, 146, 198),
    (33, 113, 181),
    (8, 81, 156),
    (8, 48, 107),
];

fn interpolate(stops: &[(u8, u8, u8)], t: f64) -> RGBColor {
    let t = if t.is_nan() { 0.5 } else { t.clamp(0.0, 1.0) };
    let pos = t * (stops.len() - 1) as f64;
    let i = (pos.floor() as usize).min(stops.len() - 2);
    let f = pos - i as f64;
    let lerp = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * f).round() as u8;
    let (a, b) = (stops[i], stops[i + 1]);
    RGBColor(lerp(a.0, b.0), lerp(a.1, b.1), lerp(a.2, b.2))
}

/// Diverging colour for `t` in [-1, 1] (clamped): -1 dark blue, 0 near-white, 1 dark red.
pub(crate) fn diverging(t: f64) -> RGBColor {
    interpolate(&RDBU, 0.5 * (t + 1.0))
}

/// Sequential colour for `t` in [0, 1]: near-white to dark blue.
pub(crate) fn sequential(t: f64) -> RGBColor {
    interpolate(&BLUES, t)
}

/// Black or white, whichever reads better on `bg` (relative luminance threshold).
pub(crate) fn text_on(bg: RGBColor) -> RGBColor {
    let l = 0.2126 * bg.0 as f64 + 0.7152 * bg.1 as f64 + 0.0722 * bg.2 as f64;
    if l < 120.0 {
        WHITE
    } else {
        BLACK
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diverging_ends_and_centre() {
        assert_eq!(diverging(-1.0), RGBColor(5, 48, 97));
        assert_eq!(diverging(0.0), RGBColor(247, 247, 247));
        assert_eq!(diverging(1.0), RGBColor(103, 0, 31));
        assert_eq!(diverging(7.0), RGBColor(103, 0, 31));
        assert_eq!(diverging(f64::NAN), RGBColor(247, 247, 247));
        // halfway between stops 0 and 1 of the 11: t = -1 + 0.1 = -0.9
        assert_eq!(diverging(-0.9), RGBColor(19, 75, 135));
    }

    #[test]
    fn series_looks_are_distinct_for_21() {
        let looks: Vec<_> = (0..21).map(series_look).collect();
        for i in 0..21 {
            for j in 0..i {
                assert_ne!(looks[i], looks[j], "{i} {j}");
            }
        }
    }

    #[test]
    fn text_width_matches_the_svg_em() {
        // DejaVu Sans: "H" advances 1540/2048 em (hmtx, read with fontTools); em = size / 1.24 px.
        let w = text_width("H", 24.8);
        assert!((w - 20.0 * 1540.0 / 2048.0).abs() < 1e-4, "{w}");
        assert!((text_width("HzHz", 24.8) - 2.0 * text_width("Hz", 24.8)).abs() < 1e-6);
        assert_eq!(text_width("", 24.8), 0.0);
    }

    #[test]
    fn readable_text_colour() {
        assert_eq!(text_on(RGBColor(5, 48, 97)), WHITE);
        assert_eq!(text_on(RGBColor(247, 247, 247)), BLACK);
    }
}
