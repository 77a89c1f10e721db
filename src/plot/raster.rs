//! PNG figures are the SVG figures rasterised by resvg: the two files show the same
//! drawing, and the PNG is anti-aliased (lines, fills and text alike).
//!
//! Text renders with the bundled DejaVu Sans only: the font database holds that one
//! font and no system fonts, so a PNG comes out the same on every machine.

use super::style::{FONT, FONT_BYTES};
use crate::error::{Error, Result};
use resvg::tiny_skia::{Pixmap, Transform};
use resvg::usvg::{fontdb, Options, Tree};
use std::sync::{Arc, OnceLock};

/// The font database: the bundled font, also standing in for the generic families.
fn font_db() -> Arc<fontdb::Database> {
    static DB: OnceLock<Arc<fontdb::Database>> = OnceLock::new();
    DB.get_or_init(|| {
        let mut db = fontdb::Database::new();
        db.load_font_data(FONT_BYTES.to_vec());
        db.set_sans_serif_family(FONT);
        db.set_serif_family(FONT);
        db.set_monospace_family(FONT);
        Arc::new(db)
    })
    .clone()
}

fn raster_error(what: impl std::fmt::Display) -> Error {
    Error::Usage(format!("rasterising the SVG figure failed: {what}"))
}

/// Rasterises an SVG document at its own size (1 SVG unit = 1 pixel) into PNG bytes.
pub fn svg_to_png(svg: &str) -> Result<Vec<u8>> {
    let opt = Options {
        font_family: FONT.to_owned(),
        fontdb: font_db(),
        ..Options::default()
    };
    let tree = Tree::from_str(svg, &opt).map_err(raster_error)?;
    let size = tree.size().to_int_size();
    let mut pixmap = Pixmap::new(size.width(), size.height())
        .ok_or_else(|| raster_error(format!("empty size {size:?}")))?;
    resvg::render(&tree, Transform::identity(), &mut pixmap.as_mut());
    pixmap.encode_png().map_err(raster_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RGBA pixels of a PNG and its width.
    fn decode(png: &[u8]) -> (Vec<u8>, usize) {
        let p = Pixmap::decode_png(png).expect("our PNG decodes");
        (p.data().to_vec(), p.width() as usize)
    }

    #[test]
    fn diagonal_line_is_anti_aliased() {
        let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="60" height="60">
            <rect width="60" height="60" fill="white"/>
            <line x1="5" y1="10" x2="55" y2="40" stroke="black" stroke-width="1"/></svg>"#;
        let (px, _) = decode(&svg_to_png(svg).unwrap());
        // Aliased drawing gives only 0 and 255; anti-aliasing leaves partly covered
        // pixels along both edges of the line (about 2 per column over 50 columns).
        let between: Vec<u8> = px
            .chunks(4)
            .map(|p| p[0])
            .filter(|&g| g > 10 && g < 245)
            .collect();
        let levels: std::collections::BTreeSet<u8> = between.iter().copied().collect();
        assert!(
            between.len() >= 50 && levels.len() >= 3,
            "{} partly covered pixels, {} levels",
            between.len(),
            levels.len()
        );
        assert!(px.chunks(4).any(|p| p[0] < 60), "the line's core is dark");
    }

    #[test]
    fn text_renders_with_the_bundled_font() {
        // "sans-serif" and the font's own name both resolve to the bundled font; a family
        // the database lacks falls back to it too (usvg's default family is ours).
        for family in ["DejaVu Sans", "sans-serif", "No Such Font"] {
            let svg = format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" width="200" height="60">
                <rect width="200" height="60" fill="white"/>
                <text x="10" y="40" font-family="{family}" font-size="24">Hz label</text></svg>"#
            );
            let (px, w) = decode(&svg_to_png(&svg).unwrap());
            // Ink inside the label's box (x 10..130, baseline 40, cap height ~18 px) and
            // none far right of it.
            let ink = |x0: usize, x1: usize| {
                (20..44)
                    .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                    .filter(|&(x, y)| px[4 * (y * w + x)] < 128)
                    .count()
            };
            assert!(ink(10, 130) > 150, "{family}: {} dark pixels", ink(10, 130));
            assert_eq!(ink(150, 200), 0, "{family}");
        }
    }

    #[test]
    fn same_svg_same_png_and_bad_svg_is_an_error() {
        let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="30" height="20">
            <circle cx="10" cy="10" r="6" fill="blue"/></svg>"#;
        assert_eq!(svg_to_png(svg).unwrap(), svg_to_png(svg).unwrap());
        let err = svg_to_png("<svg").unwrap_err().to_string();
        assert!(err.contains("rasterising the SVG figure failed"), "{err}");
    }
}
