//! Rendering a figure twice, to PNG and SVG, each written atomically: the SVG is built in
//! memory and written with [`crate::io::write_atomic`]; the PNG is rendered by plotters
//! into a temporary sibling file and renamed into place. A failed run leaves any previous
//! figure untouched and no temporary file behind.

use super::smooth::Smooth;
use super::style::{self, text, Sizes};
use crate::error::{Error, Result};
use plotters::backend::{BitMapBackend, DrawingBackend, SVGBackend};
use plotters::coord::Shift;
use plotters::drawing::{DrawingArea, DrawingAreaErrorKind, IntoDrawingArea};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::TextStyle;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

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
        let root = Smooth {
            inner: SVGBackend::with_string(&mut svg, (w, h)),
            rasterise: false,
        }
        .into_drawing_area();
        draw_on(&root, fig).map_err(|e| drawing_error(&svg_path, e))?;
    }

    let dir = png_path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let tmp = temp_png(&png_path);
    let drawn = {
        let root = Smooth {
            inner: BitMapBackend::new(&tmp, (w, h)),
            rasterise: true,
        }
        .into_drawing_area();
        draw_on(&root, fig).map_err(|e| drawing_error(&png_path, e))
    };
    let renamed =
        drawn.and_then(|()| std::fs::rename(&tmp, &png_path).map_err(|e| Error::io(&png_path, e)));
    if let Err(e) = renamed {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
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

/// A unique temporary sibling ending in `.png` (plotters picks the encoder from it).
fn temp_png(path: &Path) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "figure".into());
    path.with_file_name(format!(".{name}.{}.{n}.tmp.png", std::process::id()))
}

/// Estimated width of `s` in pixels.
pub(crate) fn text_width<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &str,
    size: f64,
) -> u32 {
    if s.is_empty() {
        return 0;
    }
    area.estimate_text_size(s, &text(size))
        .map(|(w, _)| w)
        .unwrap_or((0.6 * size * s.chars().count() as f64) as u32)
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
    while size > 10.0 && text_width(area, title, size) + 20 > w {
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
