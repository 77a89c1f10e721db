//! Strokes of odd width on the pixel grid.
//!
//! plotters places everything at whole-pixel coordinates. A 1 px stroke centred on a
//! pixel boundary covers half of two pixel rows, so every renderer (resvg, browsers)
//! draws it as a two-pixel grey smear: grid lines, axes and thin data lines look blurred.
//! Here each stroke element of odd width (`<line>`, `<polyline>`, and unfilled `<rect>`
//! and `<circle>`) of plotters' SVG gets `transform="translate(.5 .5)"`, which centres it
//! on pixel centres; fills and text are left where they are.

/// Returns `svg` with odd-width strokes moved onto pixel centres.
pub(crate) fn align_strokes(svg: &str) -> String {
    let mut out = String::with_capacity(svg.len() + svg.len() / 16);
    let mut rest = svg;
    while let Some(i) = rest.find('<') {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        let end = rest.find('>').map_or(rest.len(), |e| e + 1);
        let (tag, after) = rest.split_at(end);
        out.push_str(&with_offset(tag));
        rest = after;
    }
    out.push_str(rest);
    out
}

/// Value of attribute `name` in the start tag `tag`.
fn attr<'t>(tag: &'t str, name: &str) -> Option<&'t str> {
    let key = format!(" {name}=\"");
    let start = tag.find(&key)? + key.len();
    tag[start..].split('"').next()
}

/// `tag` with the half-pixel offset if it is an odd-width stroke without a transform.
fn with_offset(tag: &str) -> std::borrow::Cow<'_, str> {
    let name = tag[1..]
        .split(|c: char| c.is_whitespace() || c == '/' || c == '>')
        .next()
        .unwrap_or("");
    let stroke_only = match name {
        "line" | "polyline" => true,
        "rect" | "circle" => attr(tag, "fill") == Some("none"),
        _ => false,
    };
    let stroked = attr(tag, "stroke").is_some_and(|s| s != "none");
    let width: f64 = attr(tag, "stroke-width")
        .map_or(Some(1.0), |w| w.parse().ok())
        .unwrap_or(0.0);
    let odd = width.fract() == 0.0 && (width as i64) % 2 == 1;
    if stroke_only && stroked && odd && attr(tag, "transform").is_none() {
        let at = 1 + name.len();
        format!(
            "{} transform=\"translate(.5 .5)\"{}",
            &tag[..at],
            &tag[at..]
        )
        .into()
    } else {
        tag.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_odd_strokes_move() {
        let svg = "<svg><line opacity=\"1\" stroke=\"#000\" stroke-width=\"1\" x1=\"0\" y1=\"5\" x2=\"9\" y2=\"5\"/>\
<polyline fill=\"none\" stroke=\"#000\" stroke-width=\"2\" points=\"0,0 1,1\"/>\
<rect x=\"1\" y=\"1\" width=\"3\" height=\"3\" fill=\"none\" stroke=\"#000\"/>\
<rect x=\"1\" y=\"1\" width=\"3\" height=\"3\" fill=\"#FFF\" stroke=\"none\"/>\
<polyline fill=\"none\" stroke=\"#000\" stroke-width=\"3\" points=\"0,0\"/>\
<text x=\"1\" y=\"2\">a&lt;b</text></svg>";
        let out = align_strokes(svg);
        let moved: Vec<&str> = out
            .split('<')
            .filter(|t| t.contains("translate(.5 .5)"))
            .collect();
        assert_eq!(moved.len(), 3, "{out}");
        assert!(moved[0].starts_with("line transform"));
        assert!(moved[1].starts_with("rect transform") && moved[1].contains("fill=\"none\""));
        assert!(moved[2].contains("stroke-width=\"3\""));
        assert!(out.contains("<text x=\"1\" y=\"2\">a&lt;b</text></svg>"));
        assert_eq!(out.replace(" transform=\"translate(.5 .5)\"", ""), svg);
    }

    #[test]
    fn a_one_pixel_line_darkens_one_pixel_row() {
        let svg = r##"<svg xmlns="http://www.w3.org/2000/svg" width="20" height="20">
            <rect width="20" height="20" fill="white"/>
            <line stroke="#000000" stroke-width="1" x1="2" y1="10" x2="18" y2="10"/></svg>"##;
        // Red channel of column 10, rows that are not white.
        let column = |svg: &str| -> Vec<u8> {
            let png = super::super::raster::svg_to_png(svg).unwrap();
            let p = resvg::tiny_skia::Pixmap::decode_png(&png).unwrap();
            (0..20)
                .map(|y| p.data()[4 * (y * 20 + 10)])
                .filter(|&r| r < 250)
                .collect()
        };
        let blurred = column(svg);
        assert_eq!(blurred.len(), 2, "{blurred:?}");
        assert!(blurred.iter().all(|&r| r > 100), "{blurred:?}");
        let crisp = column(&align_strokes(svg));
        assert_eq!(crisp.len(), 1, "{crisp:?}");
        assert!(crisp[0] < 10, "{crisp:?}");
    }
}
