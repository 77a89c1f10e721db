//! Figures, each written as `<stem>.png` and `<stem>.svg`.
//!
//! A figure function takes a plain data struct (a "spec") and an output stem; it draws
//! what it is given and never recomputes science (histograms of samples and display
//! decimation are the only arithmetic). Both files are written atomically: a failed run
//! leaves earlier figures untouched.
//!
//! Conventions shared by all figures:
//! - Values that cannot be drawn are skipped, never an error: NaN and infinities
//!   anywhere, zeros and negatives on log axes. Lines break at skipped points; a panel
//!   with nothing to draw says "no data".
//! - Lengths that must match (a frequency grid and its values) are checked, and a
//!   mismatch is an [`Error::Usage`] naming the series.
//! - The PNG is the SVG rasterised by resvg (`raster.rs`): the same drawing, anti-aliased,
//!   with text in the bundled font only (no system fonts), so it is reproducible.
//! - Text uses the bundled DejaVu Sans (`src/plot/fonts/`, Bitstream Vera licence beside
//!   it); colours are Okabe-Ito for lines, ColorBrewer RdBu for signed maps and Blues for
//!   densities, all safe for the common colour-vision deficiencies.
//! - `size_px: None` picks a default of about 1000 x 700 px (larger for grids of panels).
//! - Lines with more points than the plot has pixels are drawn through a min/max
//!   envelope per pixel column, which looks the same and keeps SVG files small.

mod axis;
mod bands;
mod bars;
mod corner;
mod crisp;
mod frf;
mod heatmap;
mod labels;
mod legend;
mod lines;
mod panel;
mod raster;
mod render;
mod style;
mod traces;

pub use bands::{band_overlay, BandOverlaySpec, BandPanel, Interval};
pub use bars::{bar_chart, BarChartSpec, BarGroup};
pub use corner::{corner, CornerParam, CornerSpec, Density2d};
pub use frf::{
    frf_comparison, frf_magnitudes, ChannelFrf, ComparisonPanel, FrfComparisonSpec,
    FrfMagnitudesSpec,
};
pub use heatmap::{heatmap, HeatmapSpec};
pub use lines::{line_chart, LineChartSpec, Mark, RefLine, Series};
pub use raster::svg_to_png;
pub use traces::{traces, TraceParam, TracesSpec};

use crate::error::{Error, Result};

/// Axis scale.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Scale {
    #[default]
    Linear,
    /// Base-10 logarithmic; zeros, negatives and NaN are skipped.
    Log,
}

/// A frequency band to shade, in Hz (e.g. a selected half-power band).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FreqBand {
    pub lo_hz: f64,
    pub hi_hz: f64,
}

/// Values on their own frequency grid (`freq_hz.len() == values.len()`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curve {
    pub freq_hz: Vec<f64>,
    pub values: Vec<f64>,
}

impl Curve {
    fn check(&self, what: &str) -> Result<()> {
        same_len(
            what,
            "freq_hz",
            self.freq_hz.len(),
            "values",
            self.values.len(),
        )
    }
}

/// `Error::Usage` unless `a == b`.
fn same_len(what: &str, a_name: &str, a: usize, b_name: &str, b: usize) -> Result<()> {
    if a == b {
        Ok(())
    } else {
        Err(Error::Usage(format!(
            "figure data {what}: {a_name} has {a} values but {b_name} has {b}; they must match"
        )))
    }
}
