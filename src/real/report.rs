//! Small helpers for the Markdown reports and figures of the real-data studies.

use std::path::Path;

use num_complex::Complex64;

use super::posterior::{AtBound, ParameterSummary, QuantileBands, Sampled};
use crate::error::Result;
use crate::plot::{traces, BandPanel, Curve, Interval, Scale, TraceParam, TracesSpec};

/// A Markdown table.
pub fn md_table(headers: &[&str], rows: &[Vec<String>]) -> String {
    let mut s = format!("| {} |\n", headers.join(" | "));
    s += &format!("|{}\n", "---|".repeat(headers.len()));
    for r in rows {
        s += &format!("| {} |\n", r.join(" | "));
    }
    s
}

/// `x` with `sig` significant digits (plain notation for moderate magnitudes).
pub fn sig(x: f64, sig: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".into();
    }
    let mag = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&mag) {
        return format!("{:.*e}", sig.saturating_sub(1), x);
    }
    let decimals = (sig as i32 - 1 - mag).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The standard posterior table: mean, sd, c.o.v., 95% interval, R-hat, ESS.
pub fn posterior_table(rows: &[ParameterSummary]) -> String {
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.name.clone(),
                r.unit.clone(),
                sig(r.mean, 5),
                sig(r.sd, 3),
                format!("{:.2}", 100.0 * r.cv),
                format!("[{}, {}]", sig(r.q2_5, 5), sig(r.q97_5, 5)),
                format!("{:.4}", r.rhat),
                format!("{:.0}", r.ess_bulk),
                format!("{:.0}", r.ess_tail),
                match r.at_bound {
                    Some(AtBound::Lower) => "lower".into(),
                    Some(AtBound::Upper) => "upper".into(),
                    None => "no".into(),
                },
            ]
        })
        .collect();
    md_table(
        &[
            "parameter",
            "unit",
            "mean",
            "sd",
            "c.o.v. (%)",
            "95% interval",
            "R-hat",
            "ESS bulk",
            "ESS tail",
            "at bound",
        ],
        &body,
    )
}

/// One line on how a run went.
pub fn run_line(s: &Sampled) -> String {
    format!(
        "{} walkers x 4 ensembles, {} steps, {} likelihood evaluations, acceptance {:.3}, \
         worst R-hat {:.4}, smallest ESS {:.0}, {:.1} s; stopped: {}.",
        s.n_walkers,
        s.n_steps,
        s.n_evaluations,
        s.acceptance,
        s.worst_rhat,
        s.min_ess,
        s.wall_s,
        s.stopped_because
    )
}

/// Trace figure of the first ensemble's walkers, coordinate `p` mapped by `f[p]`.
pub fn trace_figure(
    s: &Sampled,
    names: &[(String, String)],
    map: &dyn Fn(usize, f64) -> f64,
    title: &str,
    stem: &Path,
) -> Result<()> {
    let full = &s.full;
    let params = names
        .iter()
        .enumerate()
        .map(|(p, (name, unit))| TraceParam {
            name: name.clone(),
            unit: unit.clone(),
            walkers: (0..full.n_walkers)
                .map(|c| {
                    (0..full.n_draws)
                        .map(|d| map(p, full.draw(c, d)[p]))
                        .collect()
                })
                .collect(),
            reference: None,
        })
        .collect();
    let thin = full.thin_steps.max(1);
    traces(
        &TracesSpec {
            title: title.into(),
            params,
            burn_in: Some((s.draws.discarded_steps / thin) as usize),
            x_label: format!("Kept step (every {thin} steps)"),
            size_px: None,
        },
        stem,
    )
}

/// Writes a study's findings as `findings.json` in `out` (atomically).
pub fn write_findings<T: serde::Serialize>(findings: &T, out: &Path) -> Result<()> {
    let path = out.join("findings.json");
    let json = serde_json::to_vec_pretty(findings).map_err(|e| crate::error::Error::Io {
        path: path.clone(),
        source: std::io::Error::other(e),
    })?;
    crate::io::write_atomic(&path, &json)
}

/// Band-overlay panel of one channel: the model's posterior median and its 50 % and 95 %
/// bands `q` on `freq_hz`, with the measured `|H|` of `measured` on top (log scale).
pub fn quantile_band_panel(
    title: String,
    freq_hz: &[f64],
    q: &QuantileBands,
    measured: &[Complex64],
) -> BandPanel {
    BandPanel {
        title,
        y_label: "|H| ((m/s²)/N)".into(),
        y_scale: Scale::Log,
        freq_hz: freq_hz.to_vec(),
        median: q[2].clone(),
        band_50: Some(Interval {
            lo: q[1].clone(),
            hi: q[3].clone(),
        }),
        band_95: Some(Interval {
            lo: q[0].clone(),
            hi: q[4].clone(),
        }),
        measured: Some(Curve {
            freq_hz: freq_hz.to_vec(),
            values: measured.iter().map(|h| h.norm()).collect(),
        }),
        bands: vec![],
    }
}
