//! FRF magnitude figures: one test's channels with their coherence, and the paper's
//! initial / experimental / updated comparison (Figures 4, 5, 8 and 9).

use super::axis::{data_range, limits, union, NiceAxis};
use super::panel::{self, Entry, Occupied, Panel, Stroke, Swatch};
use super::render::{render, title_area, DResult, Figure};
use super::style::{self, Dash, NORMAL};
use super::{same_len, Curve, FreqBand, Scale};
use crate::error::Result;
use plotters::coord::Shift;
use plotters::drawing::DrawingArea;
use plotters::prelude::DrawingBackend;
use plotters::style::Color;
use std::path::Path;

const FREQ_DESC: &str = "Frequency (Hz)";
const BAND_LABEL: &str = "Selected band";

/// One channel of [`FrfMagnitudesSpec`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelFrf {
    /// Legend text, e.g. "floor 3 acc".
    pub label: String,
    /// |H| on the spec's `freq_hz` grid.
    pub magnitude: Vec<f64>,
    /// Coherence (0..1) on the same grid; empty if not available.
    pub coherence: Vec<f64>,
}

/// One test's FRF magnitudes (log y) for several channels, the selected bands shaded,
/// and underneath a panel with each channel's coherence (omitted when no channel has
/// one).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrfMagnitudesSpec {
    pub title: String,
    /// Magnitude axis text with unit, e.g. "|H| (m/s²/N)"; empty: "FRF magnitude".
    pub y_label: String,
    pub freq_hz: Vec<f64>,
    pub channels: Vec<ChannelFrf>,
    pub bands: Vec<FreqBand>,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`FrfMagnitudesSpec`].
pub fn frf_magnitudes(spec: &FrfMagnitudesSpec, stem: &Path) -> Result<()> {
    let n = spec.freq_hz.len();
    for ch in &spec.channels {
        let what = format!("FRF magnitudes, channel \"{}\"", ch.label);
        same_len(&what, "freq_hz", n, "magnitude", ch.magnitude.len())?;
        if !ch.coherence.is_empty() {
            same_len(&what, "freq_hz", n, "coherence", ch.coherence.len())?;
        }
    }
    render(spec, spec.size_px, stem)
}

impl Figure for FrfMagnitudesSpec {
    fn default_size(&self) -> (u32, u32) {
        (1000, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, NORMAL)?;
        let has_coh = self.channels.iter().any(|c| !c.coherence.is_empty());
        let (top, bottom) = if has_coh {
            let (_, h) = body.dim_in_pixel();
            let (t, b) = body.split_vertically((h as f64 * 0.68) as u32);
            (t, Some(b))
        } else {
            (body, None)
        };
        let x_lim = limits(
            data_range(self.freq_hz.iter().copied(), Scale::Linear),
            Scale::Linear,
            0.0,
        );
        let (top_w, top_h) = top.dim_in_pixel();
        let x = NiceAxis::new(Scale::Linear, x_lim, panel::ticks_for(top_w, 95, 10));
        let mag_range = self.channels.iter().fold(None, |acc, c| {
            union(acc, data_range(c.magnitude.iter().copied(), Scale::Log))
        });
        let y_lim = limits(mag_range, Scale::Log, 0.04);
        let y = NiceAxis::new(Scale::Log, y_lim, panel::ticks_for(top_h, 60, 8));
        let coh = NiceAxis::new(
            Scale::Linear,
            limits(Some((0.0, 1.0)), Scale::Linear, 0.03),
            4,
        );
        let y_desc = if self.y_label.is_empty() {
            "FRF magnitude"
        } else {
            &self.y_label
        };
        let y_area =
            panel::y_area(&y, y_desc, NORMAL).max(panel::y_area(&coh, "Coherence", NORMAL));
        let x_top = if has_coh {
            x.clone().without_labels()
        } else {
            x.clone()
        };
        self.magnitude_panel(&top, x_top, y, y_desc, y_area, has_coh)?;
        if let Some(bottom) = bottom {
            self.coherence_panel(&bottom, x, coh, y_area)?;
        }
        Ok(())
    }
}

impl FrfMagnitudesSpec {
    /// Line style of channel `i`: 2 px for up to four channels, 1 px beyond.
    fn look(&self, i: usize) -> Stroke {
        let width = if self.channels.len() <= 4 { 2 } else { 1 };
        let (color, dash) = style::series_look(i);
        Stroke {
            color: color.to_rgba(),
            width,
            dash,
        }
    }

    /// The magnitude panel with the bands shaded and the legend; it carries the
    /// frequency axis text unless the coherence panel sits underneath (`has_coh`).
    fn magnitude_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: NiceAxis,
        y: NiceAxis,
        y_desc: &str,
        y_area: u32,
        has_coh: bool,
    ) -> DResult<(), DB> {
        let mut chart = panel::build(
            area,
            Panel {
                title: "",
                x,
                y,
                x_desc: if has_coh { "" } else { FREQ_DESC },
                y_desc,
                sizes: NORMAL,
                x_area: panel::x_area(!has_coh, if has_coh { "" } else { FREQ_DESC }, NORMAL),
                y_area,
                margin_right: 26,
            },
        )?;
        panel::shade_bands(&mut chart, &self.bands)?;
        let mut occ = Occupied::default();
        let mut entries = Vec::new();
        for (i, ch) in self.channels.iter().enumerate() {
            panel::line(
                &mut chart,
                &self.freq_hz,
                &ch.magnitude,
                self.look(i),
                None,
                &mut occ,
            )?;
            entries.push(Entry {
                label: ch.label.clone(),
                swatch: Swatch::Line(self.look(i)),
            });
        }
        finish_panel(&mut chart, entries, &occ, !self.bands.is_empty())
    }

    /// The coherence panel under the magnitudes, on the same frequency axis.
    fn coherence_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: NiceAxis,
        coh: NiceAxis,
        y_area: u32,
    ) -> DResult<(), DB> {
        let mut chart = panel::build(
            area,
            Panel {
                title: "",
                x,
                y: coh,
                x_desc: FREQ_DESC,
                y_desc: "Coherence",
                sizes: NORMAL,
                x_area: panel::x_area(true, FREQ_DESC, NORMAL),
                y_area,
                margin_right: 26,
            },
        )?;
        panel::shade_bands(&mut chart, &self.bands)?;
        let mut occ = Occupied::default();
        for (i, ch) in self.channels.iter().enumerate() {
            panel::line(
                &mut chart,
                &self.freq_hz,
                &ch.coherence,
                self.look(i),
                None,
                &mut occ,
            )?;
        }
        panel::frame(&mut chart)
    }
}

/// One panel of [`FrfComparisonSpec`]: one channel pair in one FRF kind.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ComparisonPanel {
    /// e.g. "(a) Receptance H₄,₁".
    pub title: String,
    /// Magnitude axis text with unit, e.g. "|H| (m/N)".
    pub y_label: String,
    pub experimental: Curve,
    /// Model before updating.
    pub initial: Option<Curve>,
    /// Model after updating.
    pub updated: Option<Curve>,
    /// FDAC of the initial model against the experiment, shown in the legend.
    pub fdac_initial: Option<f64>,
    /// FDAC of the updated model against the experiment, shown in the legend.
    pub fdac_updated: Option<f64>,
    pub bands: Vec<FreqBand>,
}

/// Initial, experimental and updated FRF magnitudes (log y) of one channel pair, one
/// panel per FRF kind side by side (the paper's Figures 4, 5, 8, 9).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrfComparisonSpec {
    pub title: String,
    pub panels: Vec<ComparisonPanel>,
    pub size_px: Option<(u32, u32)>,
}

/// Writes `<stem>.png` and `<stem>.svg` for [`FrfComparisonSpec`].
pub fn frf_comparison(spec: &FrfComparisonSpec, stem: &Path) -> Result<()> {
    for p in &spec.panels {
        p.experimental
            .check(&format!("FRF comparison \"{}\", experimental", p.title))?;
        if let Some(c) = &p.initial {
            c.check(&format!("FRF comparison \"{}\", initial", p.title))?;
        }
        if let Some(c) = &p.updated {
            c.check(&format!("FRF comparison \"{}\", updated", p.title))?;
        }
    }
    render(spec, spec.size_px, stem)
}

fn with_fdac(name: &str, fdac: Option<f64>) -> String {
    match fdac {
        Some(v) if v.is_finite() => format!("{name} (FDAC {v:.3})"),
        _ => name.to_string(),
    }
}

impl Figure for FrfComparisonSpec {
    fn default_size(&self) -> (u32, u32) {
        match panel::grid_shape(self.panels.len()) {
            (1, 1) => (1000, 700),
            (1, c) => (600 * c as u32, 620),
            (r, c) => (520 * c as u32, 430 * r as u32 + 60),
        }
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let body = title_area(root, &self.title, NORMAL)?;
        for (p, cell) in self
            .panels
            .iter()
            .zip(panel::grid_cells(&body, self.panels.len()))
        {
            p.draw(&cell)?;
        }
        Ok(())
    }
}

impl ComparisonPanel {
    /// Axes of the panel in `cell`: frequency over all curves, log magnitude.
    fn axes<DB: DrawingBackend>(&self, cell: &DrawingArea<DB, Shift>) -> (NiceAxis, NiceAxis) {
        let curves = [
            Some(&self.experimental),
            self.initial.as_ref(),
            self.updated.as_ref(),
        ];
        let xr = curves.iter().flatten().fold(None, |acc, c| {
            union(acc, data_range(c.freq_hz.iter().copied(), Scale::Linear))
        });
        let yr = curves.iter().flatten().fold(None, |acc, c| {
            union(acc, data_range(c.values.iter().copied(), Scale::Log))
        });
        let (cw, ch) = cell.dim_in_pixel();
        let x_lim = limits(xr, Scale::Linear, 0.0);
        let x = NiceAxis::new(Scale::Linear, x_lim, panel::ticks_for(cw, 95, 8));
        let y_lim = limits(yr, Scale::Log, 0.04);
        let y = NiceAxis::new(Scale::Log, y_lim, panel::ticks_for(ch, 60, 8));
        (x, y)
    }

    /// The panel in `cell`: bands, the initial and updated models, the measurement on
    /// top, and the legend with the FDACs.
    fn draw<DB: DrawingBackend>(&self, cell: &DrawingArea<DB, Shift>) -> DResult<(), DB> {
        let exp_stroke = Stroke::solid(style::BLACK, 1);
        let init_stroke = Stroke {
            color: style::OI_VERMILLION.to_rgba(),
            width: 2,
            dash: Dash::Dashed,
        };
        let upd_stroke = Stroke::solid(style::OI_BLUE, 2);
        let (x, y) = self.axes(cell);
        let y_desc = if self.y_label.is_empty() {
            "FRF magnitude"
        } else {
            &self.y_label
        };
        let y_area = panel::y_area(&y, y_desc, NORMAL);
        let mut chart = panel::build(
            cell,
            Panel {
                title: &self.title,
                x,
                y,
                x_desc: FREQ_DESC,
                y_desc,
                sizes: NORMAL,
                x_area: panel::x_area(true, FREQ_DESC, NORMAL),
                y_area,
                margin_right: 26,
            },
        )?;
        panel::shade_bands(&mut chart, &self.bands)?;
        let mut occ = Occupied::default();
        let mut entries = Vec::new();
        entries.push(Entry {
            label: "Experimental".into(),
            swatch: Swatch::Line(exp_stroke),
        });
        let models = [
            (
                &self.initial,
                init_stroke,
                "Initial model",
                self.fdac_initial,
            ),
            (
                &self.updated,
                upd_stroke,
                "Updated model",
                self.fdac_updated,
            ),
        ];
        for (curve, stroke, name, fdac) in models {
            if let Some(c) = curve {
                panel::line(&mut chart, &c.freq_hz, &c.values, stroke, None, &mut occ)?;
                entries.push(Entry {
                    label: with_fdac(name, fdac),
                    swatch: Swatch::Line(stroke),
                });
            }
        }
        // The measurement goes on top, thin, so the models stay visible under it.
        let e = &self.experimental;
        panel::line(
            &mut chart, &e.freq_hz, &e.values, exp_stroke, None, &mut occ,
        )?;
        finish_panel(&mut chart, entries, &occ, !self.bands.is_empty())
    }
}

/// Ends an FRF panel: the band swatch in the legend when bands are shaded, the frame,
/// a "no data" note when nothing was drawn, and the legend where it covers least.
fn finish_panel<DB: DrawingBackend>(
    chart: &mut panel::Chart<DB>,
    mut entries: Vec<Entry>,
    occ: &Occupied,
    has_bands: bool,
) -> DResult<(), DB> {
    if has_bands {
        entries.push(Entry {
            label: BAND_LABEL.into(),
            swatch: Swatch::Patch(style::band_shade()),
        });
    }
    panel::frame(chart)?;
    if occ.is_empty() {
        panel::note(chart, "no data", NORMAL)?;
    }
    panel::legend(chart, &entries, occ, NORMAL)
}
