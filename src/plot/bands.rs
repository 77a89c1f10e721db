//! Posterior-predictive bands of a model FRF with the measured FRF on top.

use super::axis::{data_range, limits, union, NiceAxis};
use super::legend;
use super::panel::{self, Entry, Occupied, Panel, Stroke, Swatch};
use super::render::{render, title_area, DResult, Figure};
use super::style::{self, NORMAL};
use super::{same_len, Curve, FreqBand, Scale};
use crate::error::Result;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::prelude::DrawingBackend;
use plotters::style::{Color, RGBColor};
use std::path::Path;

/// Lower and upper edge of an interval on the panel's frequency grid.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Interval {
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
}

/// One panel of [`BandOverlaySpec`] (one channel pair).
#[derive(Clone, Debug, PartialEq)]
pub struct BandPanel {
    pub title: String,
    /// Magnitude axis text with unit.
    pub y_label: String,
    /// Default [`Scale::Log`].
    pub y_scale: Scale,
    /// Grid of the model quantiles.
    pub freq_hz: Vec<f64>,
    pub median: Vec<f64>,
    /// Central 50% interval (shaded darker).
    pub band_50: Option<Interval>,
    /// Central 95% interval (shaded lighter).
    pub band_95: Option<Interval>,
    /// Measured FRF, drawn on top: dots up to 200 points, a thin line beyond.
    pub measured: Option<Curve>,
    pub bands: Vec<FreqBand>,
}

impl Default for BandPanel {
    fn default() -> Self {
        BandPanel {
            title: String::new(),
            y_label: String::new(),
            y_scale: Scale::Log,
            freq_hz: Vec::new(),
            median: Vec::new(),
            band_50: None,
            band_95: None,
            measured: None,
            bands: Vec::new(),
        }
    }
}

/// Posterior-predictive bands: median line, shaded 50% and 95% intervals of the model
/// FRF and the measured FRF on top; one panel per channel pair in a grid, the legend in
/// the first panel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BandOverlaySpec {
    pub title: String,
    pub panels: Vec<BandPanel>,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`BandOverlaySpec`].
pub fn band_overlay(spec: &BandOverlaySpec, stem: &Path) -> Result<()> {
    for p in &spec.panels {
        let what = format!("band overlay \"{}\"", p.title);
        let n = p.freq_hz.len();
        same_len(&what, "freq_hz", n, "median", p.median.len())?;
        for (name, band) in [("band_50", &p.band_50), ("band_95", &p.band_95)] {
            if let Some(b) = band {
                same_len(&what, "freq_hz", n, &format!("{name}.lo"), b.lo.len())?;
                same_len(&what, "freq_hz", n, &format!("{name}.hi"), b.hi.len())?;
            }
        }
        if let Some(m) = &p.measured {
            m.check(&format!("{what}, measured"))?;
        }
    }
    render(spec, spec.size_px, stem)
}

const MEDIAN_BLUE: RGBColor = RGBColor(0, 84, 140);
const POINTS_MAX: usize = 200;
/// Opacity of the blue interval shades (the 50% band lies on the 95% band).
const ALPHA_95: f64 = 0.18;
const ALPHA_50: f64 = 0.38;

/// Legend entries for everything any of `panels` draws.
fn entries(panels: &[BandPanel]) -> Vec<Entry> {
    let any = |f: fn(&BandPanel) -> bool| panels.iter().any(f);
    let mut e = Vec::new();
    if any(|p| p.band_95.is_some()) {
        e.push(Entry {
            label: "95% band".into(),
            swatch: Swatch::Patch(style::OI_BLUE.mix(ALPHA_95)),
        });
    }
    if any(|p| p.band_50.is_some()) {
        e.push(Entry {
            label: "50% band".into(),
            swatch: Swatch::Patch(style::OI_BLUE.mix(ALPHA_50)),
        });
    }
    e.push(Entry {
        label: "Model median".into(),
        swatch: Swatch::Line(Stroke::solid(MEDIAN_BLUE, 2)),
    });
    if any(|p| {
        p.measured
            .as_ref()
            .is_some_and(|m| m.freq_hz.len() <= POINTS_MAX)
    }) {
        e.push(Entry {
            label: "Measured".into(),
            swatch: Swatch::Dot(style::BLACK.to_rgba()),
        });
    }
    if any(|p| {
        p.measured
            .as_ref()
            .is_some_and(|m| m.freq_hz.len() > POINTS_MAX)
    }) {
        e.push(Entry {
            label: "Measured".into(),
            swatch: Swatch::Line(Stroke::solid(style::BLACK, 1)),
        });
    }
    if any(|p| !p.bands.is_empty()) {
        e.push(Entry {
            label: "Selected band".into(),
            swatch: Swatch::Patch(style::band_shade()),
        });
    }
    e
}

impl Figure for BandOverlaySpec {
    fn default_size(&self) -> (u32, u32) {
        match panel::grid_shape(self.panels.len()) {
            (1, 1) => (1000, 700),
            (1, c) => (600 * c as u32, 620),
            (r, c) => (520 * c as u32, 430 * r as u32 + 60),
        }
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, NORMAL)?;
        // Several panels share one legend strip under the title; one panel has its own.
        let shared = self.panels.len() > 1;
        let body = if shared {
            legend::legend_strip(&body, &entries(&self.panels), NORMAL)?
        } else {
            body
        };
        let cells = panel::grid_cells(&body, self.panels.len());
        for (p, cell) in self.panels.iter().zip(cells) {
            let sy = p.y_scale;
            let mut xr = data_range(p.freq_hz.iter().copied(), Scale::Linear);
            let mut yr = data_range(p.median.iter().copied(), sy);
            for b in [&p.band_50, &p.band_95].into_iter().flatten() {
                yr = union(yr, data_range(b.lo.iter().chain(&b.hi).copied(), sy));
            }
            if let Some(m) = &p.measured {
                xr = union(xr, data_range(m.freq_hz.iter().copied(), Scale::Linear));
                yr = union(yr, data_range(m.values.iter().copied(), sy));
            }
            let (cw, ch) = cell.dim_in_pixel();
            let x_lim = limits(xr, Scale::Linear, 0.0);
            let x = NiceAxis::new(Scale::Linear, x_lim, panel::ticks_for(cw, 95, 8));
            let y = NiceAxis::new(sy, limits(yr, sy, 0.04), panel::ticks_for(ch, 60, 8));
            let y_area = panel::y_area(&y, &p.y_label, NORMAL);
            let mut chart = panel::build(
                &cell,
                Panel {
                    title: &p.title,
                    x,
                    y,
                    x_desc: "Frequency (Hz)",
                    y_desc: &p.y_label,
                    sizes: NORMAL,
                    x_area: panel::x_area(true, "Frequency (Hz)", NORMAL),
                    y_area,
                    margin_right: 26,
                },
            )?;
            panel::shade_bands(&mut chart, &p.bands)?;
            let mut occ = Occupied::default();
            let (shade_95, shade_50) = (style::OI_BLUE.mix(ALPHA_95), style::OI_BLUE.mix(ALPHA_50));
            if let Some(b) = &p.band_95 {
                panel::fill_between(&mut chart, &p.freq_hz, &b.lo, &b.hi, shade_95, &mut occ)?;
            }
            if let Some(b) = &p.band_50 {
                panel::fill_between(&mut chart, &p.freq_hz, &b.lo, &b.hi, shade_50, &mut occ)?;
            }
            let median = Stroke::solid(MEDIAN_BLUE, 2);
            panel::line(&mut chart, &p.freq_hz, &p.median, median, None, &mut occ)?;
            if let Some(m) = &p.measured {
                let black = style::BLACK.to_rgba();
                if m.freq_hz.len() <= POINTS_MAX {
                    panel::points(&mut chart, &m.freq_hz, &m.values, black, 3, &mut occ)?;
                } else {
                    let s = Stroke::solid(style::BLACK, 1);
                    panel::line(&mut chart, &m.freq_hz, &m.values, s, None, &mut occ)?;
                }
            }
            panel::frame(&mut chart)?;
            if occ.is_empty() {
                panel::note(&chart, "no data", NORMAL)?;
            }
            if !shared {
                panel::legend(&chart, &entries(std::slice::from_ref(p)), &occ, NORMAL)?;
            }
        }
        Ok(())
    }
}
