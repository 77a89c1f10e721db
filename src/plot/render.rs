//! Rendering a figure: plotters draws it once, as SVG, in memory; the PNG is that SVG
//! rasterised by resvg (`raster.rs`), so the two files show the same drawing. Odd-width
//! strokes are first put on pixel centres (`crisp.rs`) so thin lines stay sharp. Both are
//! written with [`crate::io::write_atomic`]: a failed run leaves any previous figure
//! untouched and no temporary file behind.

use super::style::{self, text, Sizes};
use crate::error::{Error, Result};
use plotters::backend::{DrawingBackend, SVGBackend};
use plotters::coord::Shift;
use plotters::drawing::{DrawingArea, DrawingAreaErrorKind, IntoDrawingArea};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::TextStyle;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// Result of drawing on backend `DB`.
pub(crate) type DResult<T, DB> =
    std::result::Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A figure that can draw itself on any plotters backend.
pub(crate) trait Figure {
    /// Size in pixels when the caller gives none.
    fn default_size(&self) -> (u32, u32);
    /// Draws on a white root area of the figure's size.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB>;
}

/// Smallest and largest accepted figure sides in pixels.
const MIN_SIDE_PX: u32 = 200;
const MAX_SIDE_PX: u32 = 10_000;

/// `stem` with `.ext` appended (not replacing an extension: `fig.v2` -> `fig.v2.png`).
pub(crate) fn with_suffix(stem: &Path, ext: &str) -> PathBuf {
    let mut s: OsString = stem.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

fn drawing_error(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::io(
        path,
        std::io::Error::other(format!("drawing the figure failed: {what}")),
    )
}

/// Draws `fig` to `<stem>.svg` and `<stem>.png`.
pub(crate) fn render(fig: &impl Figure, size_px: Option<(u32, u32)>, stem: &Path) -> Result<()> {
    let (w, h) = size_px.unwrap_or_else(|| fig.default_size());
    if !(MIN_SIDE_PX..=MAX_SIDE_PX).contains(&w) || !(MIN_SIDE_PX..=MAX_SIDE_PX).contains(&h) {
        return Err(Error::Usage(format!(
            "figure size {w} x {h} px: each side must be between {MIN_SIDE_PX} and {MAX_SIDE_PX}"
        )));
    }
    if stem.file_name().is_none() || stem.as_os_str().to_string_lossy().ends_with('/') {
        return Err(Error::Usage(format!(
            "figure path {}: give a file stem such as out/frf (\".png\" and \".svg\" are added)",
            stem.display()
        )));
    }
    style::ensure_font();
    let svg_path = with_suffix(stem, "svg");
    let png_path = with_suffix(stem, "png");

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        draw_on(&root, fig).map_err(|e| drawing_error(&svg_path, e))?;
    }
    let svg = super::crisp::align_strokes(&svg);
    let png = super::raster::svg_to_png(&svg)?;
    crate::io::write_atomic(&png_path, &png)?;
    crate::io::write_atomic(&svg_path, svg.as_bytes())
}

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &impl Figure,
) -> DResult<(), DB> {
    root.fill(&style::WHITE)?;
    fig.draw(root)?;
    root.present()
}

/// Width of `s` in whole pixels (rounded up) at text size `size`.
pub(crate) fn text_width(s: &str, size: f64) -> u32 {
    style::text_width(s, size).ceil() as u32
}

/// Draws `s` anchored at `pos` (pixels relative to `area`).
pub(crate) fn put_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &str,
    style: &TextStyle,
    pos: (i32, i32),
    anchor: (HPos, VPos),
) -> DResult<(), DB> {
    if s.is_empty() {
        return Ok(());
    }
    area.draw_text(s, &style.pos(Pos::new(anchor.0, anchor.1)), pos)
}

/// Draws a figure title centred at the top of `area`, shrinking the font until it fits
/// the width, and returns the area below it. An empty title takes no space.
pub(crate) fn title_area<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    sizes: Sizes,
) -> DResult<DrawingArea<DB, Shift>, DB> {
    if title.is_empty() {
        return Ok(area.margin(6, 0, 0, 0));
    }
    let (w, _) = area.dim_in_pixel();
    let mut size = sizes.title;
    while size > 10.0 && text_width(title, size) + 20 > w {
        size -= 1.0;
    }
    let pad = 10;
    put_text(
        area,
        title,
        &text(size),
        (w as i32 / 2, pad),
        (HPos::Center, VPos::Top),
    )?;
    let (_, below) = area.split_vertically(pad + (size * 1.25) as i32 + 4);
    Ok(below)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suffix_is_appended_not_replaced() {
        assert_eq!(
            with_suffix(Path::new("a/fig.v2"), "png"),
            PathBuf::from("a/fig.v2.png")
        );
        assert_eq!(
            with_suffix(Path::new("fig"), "svg"),
            PathBuf::from("fig.svg")
        );
    }
}
