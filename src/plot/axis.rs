//! One axis type for every figure: linear, logarithmic or categorical, with tick positions
//! and labels chosen up front, so the space the labels need is known before drawing and
//! linear and log panels share one chart type.

use super::Scale;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::ranged1d::{KeyPointHint, KeyPointWeight, NoDefaultFormatting, Ranged};
use std::ops::Range;

/// Log axes never span more than this many decades: below `max * 10^-12` lines are
/// pinned to the bottom edge, so a stray numerical zero cannot flatten a whole figure.
pub(crate) const MAX_LOG_DECADES: f64 = 12.0;

/// Range used when there is no valid data at all.
const EMPTY_LINEAR: (f64, f64) = (0.0, 1.0);
const EMPTY_LOG: (f64, f64) = (0.1, 10.0);

/// An axis with precomputed ticks; values outside the range are pinned to its edge.
#[derive(Clone, Debug)]
pub(crate) struct NiceAxis {
    lo: f64,
    hi: f64,
    log: bool,
    majors: Vec<f64>,
    minors: Vec<f64>,
    labels: Vec<String>,
}

/// Whether `v` can be drawn on an axis of this scale.
pub(crate) fn valid(v: f64, scale: Scale) -> bool {
    v.is_finite() && (scale == Scale::Linear || v > 0.0)
}

/// Smallest and largest drawable value, `None` when there is none.
pub(crate) fn data_range(
    values: impl IntoIterator<Item = f64>,
    scale: Scale,
) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|&v| valid(v, scale))
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((a, b)) => Some((a.min(v), b.max(v))),
        })
}

/// Merges two optional ranges.
pub(crate) fn union(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (x, None) | (None, x) => x,
    }
}

/// Turns a data range into axis limits: a default when empty, a sensible width when all
/// values are equal, the log span capped at [`MAX_LOG_DECADES`], then `pad` (fraction of
/// the span, in log space for log axes) added on both sides.
pub(crate) fn limits(range: Option<(f64, f64)>, scale: Scale, pad: f64) -> (f64, f64) {
    match scale {
        Scale::Linear => {
            let (mut lo, mut hi) = range.unwrap_or(EMPTY_LINEAR);
            if hi - lo <= 1e-12 * hi.abs().max(lo.abs()) {
                let half = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
                lo -= half;
                hi += half;
            }
            let p = pad * (hi - lo);
            (lo - p, hi + p)
        }
        Scale::Log => {
            let (lo, hi) = range.unwrap_or(EMPTY_LOG);
            let (mut a, mut b) = (lo.log10(), hi.log10());
            if b - a < 1e-9 {
                a -= 0.5;
                b += 0.5;
            }
            a = a.max(b - MAX_LOG_DECADES);
            let p = pad * (b - a);
            (10f64.powf(a - p), 10f64.powf(b + p))
        }
    }
}

impl NiceAxis {
    /// An axis over `lo..hi` (from [`limits`]) with about `target` labelled ticks.
    pub(crate) fn new(scale: Scale, (lo, hi): (f64, f64), target: usize) -> Self {
        let target = target.max(2);
        match scale {
            Scale::Linear => {
                let (majors, labels) = linear_ticks(lo, hi, target);
                NiceAxis {
                    lo,
                    hi,
                    log: false,
                    majors,
                    minors: Vec::new(),
                    labels,
                }
            }
            Scale::Log => log_axis(lo, hi, target),
        }
    }

    /// Categories `0..n` centred on integers, no tick labels from plotters (the caller
    /// draws them, possibly rotated).
    pub(crate) fn categorical(n: usize) -> Self {
        NiceAxis {
            lo: -0.5,
            hi: n.max(1) as f64 - 0.5,
            log: false,
            majors: Vec::new(),
            minors: Vec::new(),
            labels: Vec::new(),
        }
    }

    /// Axis limits.
    pub(crate) fn lo_hi(&self) -> (f64, f64) {
        (self.lo, self.hi)
    }

    pub(crate) fn is_log(&self) -> bool {
        self.log
    }

    /// Labels of the major ticks, in order (for measuring the space they need).
    pub(crate) fn labels(&self) -> &[String] {
        &self.labels
    }

    /// Drops tick labels (shared axes of stacked panels); grid lines stay.
    pub(crate) fn without_labels(mut self) -> Self {
        self.labels.iter_mut().for_each(String::clear);
        self
    }

    /// Drops ticks, labels and grid lines.
    pub(crate) fn without_ticks(mut self) -> Self {
        self.majors.clear();
        self.minors.clear();
        self.labels.clear();
        self
    }

    /// Position of `v` along the axis in [0, 1] (clamped); NaN and non-positive values on
    /// a log axis go to 0.
    pub(crate) fn fraction(&self, v: f64) -> f64 {
        let t = if self.log {
            if v > 0.0 {
                (v.ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln())
            } else {
                0.0
            }
        } else {
            (v - self.lo) / (self.hi - self.lo)
        };
        if t.is_nan() {
            0.0
        } else {
            t.clamp(0.0, 1.0)
        }
    }
}

impl Ranged for NiceAxis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = self.fraction(*value);
        limit.0 + ((limit.1 - limit.0) as f64 * t).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.max_num_points() == 0 {
            return Vec::new();
        }
        match hint.weight() {
            KeyPointWeight::Bold => self.majors.clone(),
            KeyPointWeight::Any => {
                let mut all = self.majors.clone();
                all.extend_from_slice(&self.minors);
                all
            }
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

impl ValueFormatter<f64> for NiceAxis {
    fn format_ext(&self, value: &f64) -> String {
        self.majors
            .iter()
            .position(|m| m == value)
            .map(|i| self.labels[i].clone())
            .unwrap_or_default()
    }
}

/// A "nice" step (1, 2, 2.5 or 5 times a power of ten) giving about `target` intervals.
fn nice_step(span: f64, target: usize) -> f64 {
    let raw = span / target as f64;
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw * (1.0 - 1e-9))
        .unwrap_or(10.0 * mag)
}

/// Multiples of a nice step inside `lo..=hi`.
fn steps_within(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    if step.is_nan() || step <= 0.0 || step.is_infinite() {
        return Vec::new();
    }
    let k0 = (lo / step - 1e-9).ceil() as i64;
    let k1 = (hi / step + 1e-9).floor() as i64;
    if k1 < k0 || k1 - k0 > 1000 {
        return Vec::new();
    }
    (k0..=k1)
        .map(|k| {
            let v = k as f64 * step;
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect()
}

fn linear_ticks(lo: f64, hi: f64, target: usize) -> (Vec<f64>, Vec<String>) {
    let step = nice_step(hi - lo, target);
    let ticks = steps_within(lo, hi, step);
    let labels = linear_labels(&ticks, step);
    (ticks, labels)
}

/// Decimals that show a step of `step` exactly (2.5 needs one more than 2 or 5).
fn decimals_for(step: f64) -> usize {
    let e = (step.log10() + 1e-9).floor();
    let m = step / 10f64.powf(e);
    let extra = if (m - 2.5).abs() < 1e-6 { 1.0 } else { 0.0 };
    (-e + extra).max(0.0) as usize
}

/// Labels for ticks spaced `step` apart: plain decimals while they stay short (at most
/// 7 characters, magnitudes 10⁻³ to 10⁶), `m×10ⁿ` otherwise.
fn linear_labels(ticks: &[f64], step: f64) -> Vec<String> {
    let big = ticks.iter().fold(0.0f64, |a, t| a.max(t.abs()));
    let dec = decimals_for(step);
    let plain: Vec<String> = ticks.iter().map(|&t| format!("{t:.dec$}")).collect();
    let short = plain
        .iter()
        .all(|l| l.trim_start_matches('-').chars().count() <= 7);
    if big == 0.0 || ((1e-3..1e6).contains(&big) && short) {
        return plain;
    }
    let e = big.log10().floor();
    let scale = 10f64.powf(e);
    let dec = decimals_for(step / scale);
    ticks
        .iter()
        .map(|&t| {
            if t == 0.0 {
                "0".to_string()
            } else {
                format!("{:.*}×10{}", dec, t / scale, superscript(e as i64))
            }
        })
        .collect()
}

fn log_axis(lo: f64, hi: f64, target: usize) -> NiceAxis {
    let (a, b) = (lo.log10(), hi.log10());
    let d0 = (a - 1e-9).ceil() as i64;
    let d1 = (b + 1e-9).floor() as i64;
    let n_dec = d1 - d0 + 1;
    let within = |v: f64| v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9);
    let mut majors = Vec::new();
    let mut minors = Vec::new();
    let labels;
    let count_125 = ((d0 - 1)..=d1)
        .flat_map(|d| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(d as i32)))
        .filter(|&v| within(v))
        .count();
    if n_dec >= 3 || (n_dec == 2 && count_125 > target + 2) {
        let s = [1i64, 2, 3, 4, 5, 10, 20, 50]
            .into_iter()
            .find(|&s| (n_dec as f64 / s as f64).ceil() as usize <= target)
            .unwrap_or(100);
        for d in d0..=d1 {
            let v = 10f64.powi(d as i32);
            if d.rem_euclid(s) == 0 {
                majors.push(v);
            } else {
                minors.push(v);
            }
        }
        if s == 1 && b - a <= 8.0 {
            for d in (d0 - 1)..=d1 {
                for m in 2..=9 {
                    let v = m as f64 * 10f64.powi(d as i32);
                    if within(v) {
                        minors.push(v);
                    }
                }
            }
        }
        labels = majors.iter().map(|&v| decade_label(v)).collect();
    } else {
        for d in (d0 - 1)..=d1 {
            for m in 1..=9 {
                let v = m as f64 * 10f64.powi(d as i32);
                if within(v) {
                    if matches!(m, 1 | 2 | 5) {
                        majors.push(v);
                    } else {
                        minors.push(v);
                    }
                }
            }
        }
        if majors.len() >= 2 {
            // Up to two decades: 1-2-5 labels, plain decimals for ordinary magnitudes.
            let plain = lo >= 1e-3 && hi < 1e5;
            labels = majors.iter().map(|&v| one_digit_label(v, plain)).collect();
        } else {
            // Narrower than a 1-2-5 step: linear ticks inside the range.
            let (m, l) = linear_ticks(lo, hi, target);
            majors = m;
            minors.clear();
            labels = l;
        }
    }
    NiceAxis {
        lo,
        hi,
        log: true,
        majors,
        minors,
        labels,
    }
}

fn decade_label(v: f64) -> String {
    format!("10{}", superscript(v.log10().round() as i64))
}

fn one_digit_label(v: f64, plain: bool) -> String {
    let e = (v.log10() + 1e-9).floor();
    let m = (v / 10f64.powf(e)).round();
    if plain {
        let dec = (-e).max(0.0) as usize;
        format!("{v:.dec$}")
    } else if m == 1.0 {
        decade_label(v)
    } else {
        format!("{m}×10{}", superscript(e as i64))
    }
}

/// `-12` as `⁻¹²`.
pub(crate) fn superscript(n: i64) -> String {
    n.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_ticks_are_nice() {
        let ax = NiceAxis::new(Scale::Linear, (0.0, 10.0), 5);
        assert_eq!(ax.majors, vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        assert_eq!(ax.labels, vec!["0", "2", "4", "6", "8", "10"]);
        let ax = NiceAxis::new(Scale::Linear, (-0.013, 0.011), 5);
        assert_eq!(
            ax.labels,
            vec!["-0.010", "-0.005", "0.000", "0.005", "0.010"]
        );
        let ax = NiceAxis::new(Scale::Linear, (0.0, 1.0), 4);
        assert_eq!(ax.labels, vec!["0.00", "0.25", "0.50", "0.75", "1.00"]);
        let ax = NiceAxis::new(Scale::Linear, (0.0, 3.0e6), 3);
        assert_eq!(ax.labels, vec!["0", "1×10⁶", "2×10⁶", "3×10⁶"]);
        let ax = NiceAxis::new(Scale::Linear, (0.99e5, 1.03e5), 3);
        assert_eq!(ax.labels, vec!["100000", "102000"]);
        let ax = NiceAxis::new(Scale::Linear, (1.0e-5, 3.0e-5), 3);
        assert_eq!(ax.labels, vec!["1×10⁻⁵", "2×10⁻⁵", "3×10⁻⁵"]);
    }

    #[test]
    fn log_ticks_decades_and_narrow() {
        let ax = NiceAxis::new(Scale::Log, (2e-7, 3e-3), 6);
        assert_eq!(ax.labels, vec!["10⁻⁶", "10⁻⁵", "10⁻⁴", "10⁻³"]);
        assert!(ax.minors.iter().any(|&m| (m / 2e-7 - 1.0).abs() < 1e-9));
        // 12 decades with 6 labels: every second decade
        let ax = NiceAxis::new(Scale::Log, (1e-12, 1.0), 6);
        assert_eq!(ax.labels, vec!["10⁻¹²", "10⁻⁹", "10⁻⁶", "10⁻³", "10⁰"]);
        // inside one decade: 1-2-5
        let ax = NiceAxis::new(Scale::Log, (0.15, 0.9), 6);
        assert_eq!(ax.labels, vec!["0.2", "0.5"]);
        // two decades: 1-2-5, plain or with powers of ten
        let ax = NiceAxis::new(Scale::Log, (0.3, 73.0), 6);
        assert_eq!(ax.labels, vec!["0.5", "1", "2", "5", "10", "20", "50"]);
        let ax = NiceAxis::new(Scale::Log, (3e-7, 2e-5), 6);
        assert_eq!(
            ax.labels,
            vec!["5×10⁻⁷", "10⁻⁶", "2×10⁻⁶", "5×10⁻⁶", "10⁻⁵", "2×10⁻⁵"]
        );
        // too many 1-2-5 labels for the target: decades only
        let ax = NiceAxis::new(Scale::Log, (0.11, 99.0), 3);
        assert_eq!(ax.labels, vec!["10⁰", "10¹"]);
        // narrower still: linear ticks
        let ax = NiceAxis::new(Scale::Log, (0.31, 0.39), 5);
        assert!(ax.majors.len() >= 2, "{:?}", ax.majors);
        assert!(ax.majors.iter().all(|&v| (0.31..=0.39).contains(&v)));
    }

    #[test]
    fn limits_handle_degenerate_data() {
        assert_eq!(limits(None, Scale::Linear, 0.0), (0.0, 1.0));
        assert_eq!(limits(Some((0.0, 0.0)), Scale::Linear, 0.0), (-1.0, 1.0));
        assert_eq!(limits(Some((5.0, 5.0)), Scale::Linear, 0.0), (4.5, 5.5));
        let (lo, hi) = limits(Some((2.0, 2.0)), Scale::Log, 0.0);
        assert!((lo * hi - 4.0).abs() < 1e-12 && (hi / lo - 10.0).abs() < 1e-9);
        let (lo, hi) = limits(Some((1e-30, 1.0)), Scale::Log, 0.0);
        assert!((lo - 1e-12).abs() < 1e-24 && hi == 1.0);
        assert_eq!(
            data_range([f64::NAN, -1.0, 0.0, 3.0], Scale::Log),
            Some((3.0, 3.0))
        );
        assert_eq!(
            data_range([f64::NAN, -1.0, f64::INFINITY], Scale::Linear),
            Some((-1.0, -1.0))
        );
    }

    #[test]
    fn map_pins_out_of_range_values() {
        let ax = NiceAxis::new(Scale::Log, (1.0, 100.0), 3);
        assert_eq!(ax.map(&10.0, (0, 100)), 50);
        assert_eq!(ax.map(&-1.0, (0, 100)), 0);
        assert_eq!(ax.map(&1e9, (0, 100)), 100);
        assert_eq!(ax.map(&f64::NAN, (100, 0)), 100);
    }
}
