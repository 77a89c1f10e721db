//! Figures of a diagnosis: hypothesis ranking, measured / nominal / extended FRFs at the
//! channels where the verdict changes the fit most, and the effect's posterior.

use super::bin_correlation::widened;
use super::diagnose::{effect_columns, Diagnosis, ModelResult};
use super::report::hypothesis_evidence;
use crate::error::Result;
use crate::plot::{
    bar_chart, corner, frf_comparison, line_chart, BarChartSpec, BarGroup, ComparisonPanel,
    CornerParam, CornerSpec, Curve, Density2d, FrfComparisonSpec, LineChartSpec, Mark, RefLine,
    Scale, Series,
};
use num_complex::Complex64;
use std::path::Path;

/// One (segment, channel) of the data with its chi2 under two models.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelMisfit {
    pub segment: usize,
    pub channel: usize,
    pub label: String,
    /// Sum of squared standardised residuals (nominal error floor) per real datum.
    pub chi2_nominal: f64,
    pub chi2_extended: f64,
}

/// Per channel chi2 of the nominal model and of `extended` (or the nominal again).
pub fn channel_misfits(
    d: &Diagnosis,
    extended: Option<&ModelResult>,
) -> Result<Vec<ChannelMisfit>> {
    let nom = &d.nominal;
    let eta = nom.map.eta;
    let p0 = nom.posterior.predict(&nom.map.z)?;
    let p1 = match extended {
        Some(f) => f.posterior.predict(&f.map.z)?,
        None => p0.clone(),
    };
    let h = nom.posterior.measured();
    let mut out = Vec::new();
    for (si, seg) in nom.posterior.model().layout().iter().enumerate() {
        for (ci, r) in seg.iter().enumerate() {
            let chi2 = |p: &[Complex64]| {
                let mut s = 0.0;
                for (k, i) in r.clone().enumerate() {
                    let rel = d.data.segments[si].channels[ci].rel_err[k];
                    let var = (rel * rel + eta * eta) * h[i].norm_sqr();
                    s += (p[i] - h[i]).norm_sqr() / var;
                }
                s / (2 * r.len()).max(1) as f64
            };
            out.push(ChannelMisfit {
                segment: si,
                channel: ci,
                label: format!(
                    "{} / {}",
                    d.data.segments[si].name, d.data.segments[si].channels[ci].channel.name
                ),
                chi2_nominal: chi2(&p0),
                chi2_extended: chi2(&p1),
            });
        }
    }
    Ok(out)
}

/// The channels to show: largest improvement under the verdict, or largest nominal misfit.
pub fn channels_to_show(
    misfits: &[ChannelMisfit],
    has_winner: bool,
    n: usize,
) -> Vec<ChannelMisfit> {
    let mut m = misfits.to_vec();
    if has_winner {
        m.sort_by(|a, b| {
            (b.chi2_nominal - b.chi2_extended).total_cmp(&(a.chi2_nominal - a.chi2_extended))
        });
    } else {
        m.sort_by(|a, b| b.chi2_nominal.total_cmp(&a.chi2_nominal));
    }
    m.truncate(n);
    m
}

/// Writes every figure into `dir`; returns the stems written (relative to `dir`).
pub fn write_figures(d: &Diagnosis, dir: &Path) -> Result<Vec<String>> {
    let mut written = Vec::new();
    // Ranking.
    let rows = hypothesis_evidence(d);
    bar_chart(
        &BarChartSpec {
            title: "Log evidence of each hypothesis minus the nominal model's".into(),
            x_label: "hypothesis (best location)".into(),
            y_label: "delta ln Z".into(),
            categories: rows.iter().map(|r| r.name.replace('_', " ")).collect(),
            groups: vec![BarGroup {
                label: "delta ln Z".into(),
                values: rows
                    .iter()
                    .map(|r| r.delta_log_evidence.max(-1e6))
                    .collect(),
            }],
            y_scale: Scale::Linear,
            show_values: true,
            size_px: Some((1000, 520)),
        },
        &dir.join("ranking"),
    )?;
    written.push("ranking".to_string());

    // FRFs where the verdict matters most.
    let winner = d.winner.map(|w| &d.finalists[w]);
    let shown = channels_to_show(&channel_misfits(d, winner)?, winner.is_some(), 4);
    let nom = &d.nominal;
    let p0 = nom.posterior.predict(&nom.map.z)?;
    let p1 = match winner {
        Some(f) => Some(f.posterior.predict(&f.map.z)?),
        None => None,
    };
    let layout = nom.posterior.model().layout();
    for (k, c) in shown.iter().enumerate() {
        let r = layout[c.segment][c.channel].clone();
        let seg = &d.data.segments[c.segment];
        let ch = &seg.channels[c.channel];
        let freq: Vec<f64> = ch.freq_index.iter().map(|&i| seg.freq_hz[i]).collect();
        let meas = &nom.posterior.measured()[r.clone()];
        let curve = |v: &[Complex64]| Curve {
            freq_hz: freq.clone(),
            values: v.iter().map(|z| z.norm()).collect(),
        };
        frf_comparison(
            &FrfComparisonSpec {
                title: format!("{}: measured, nominal and extended model", c.label),
                panels: vec![ComparisonPanel {
                    title: c.label.clone(),
                    y_label: "|H| (channel / input)".into(),
                    experimental: curve(meas),
                    initial: Some(curve(&p0[r.clone()])),
                    updated: p1.as_ref().map(|p| curve(&p[r.clone()])),
                    fdac_initial: None,
                    fdac_updated: None,
                    bands: Vec::new(),
                }],
                size_px: Some((900, 520)),
            },
            &dir.join(format!("frf_{k}")),
        )?;
        written.push(format!("frf_{k}"));
        // Phase difference to the measurement, degrees: what timing and sensors change.
        let phase = |v: &[Complex64]| -> Vec<f64> {
            v.iter()
                .zip(meas)
                .map(|(m, e)| (m / e).arg().to_degrees())
                .collect()
        };
        let mut series = vec![Series {
            label: "nominal - measured".into(),
            x: freq.clone(),
            y: phase(&p0[r.clone()]),
            mark: Mark::LineAndPoints,
        }];
        if let Some(p) = &p1 {
            series.push(Series {
                label: "extended - measured".into(),
                x: freq.clone(),
                y: phase(&p[r.clone()]),
                mark: Mark::LineAndPoints,
            });
        }
        line_chart(
            &LineChartSpec {
                title: format!("{}: phase of model / measurement", c.label),
                x_label: "Frequency (Hz)".into(),
                y_label: "Phase difference (deg)".into(),
                series,
                x_scale: Scale::Linear,
                y_scale: Scale::Linear,
                x_refs: Vec::new(),
                y_refs: vec![RefLine {
                    value: 0.0,
                    label: String::new(),
                }],
                size_px: Some((900, 420)),
            },
            &dir.join(format!("phase_{k}")),
        )?;
        written.push(format!("phase_{k}"));
    }

    // The effect's posterior: the final model's, whose summaries the report gives, else
    // the first round's verdict's or best finalist's; from the draws its summaries came
    // from (the importance sample or the tempered run's; none when Laplace alone gave
    // the evidence).
    let shown = [d.final_model.as_ref(), winner, d.finalists.first()]
        .into_iter()
        .flatten()
        .find_map(|f| Some((f, f.evidence.as_ref()?.posterior_draws()?)));
    if let Some((f, draws)) = shown {
        let round = match d.final_model.as_ref() {
            Some(m) if std::ptr::eq(m, f) => "final model",
            _ => "first round",
        };
        // Spread as the reported intervals are (each effect coordinate by its
        // `sd_inflation`, [`super::bin_correlation`]).
        let dim = draws.first().map_or(0, Vec::len);
        let mut factors = vec![1.0; dim];
        let first = f.posterior.eta_index() + 1;
        for (k, (_, e)) in f.effect.iter().enumerate() {
            if let Some(x) = factors.get_mut(first + k) {
                *x = e.sd_inflation;
            }
        }
        let (lo, hi) = f.posterior.bounds();
        let draws = widened(&draws, &factors, lo, hi);
        let columns = effect_columns(&f.posterior, draws.iter().map(Vec::as_slice))?;
        let mut params = Vec::new();
        for (ep, values) in f.posterior.effect_params().iter().zip(columns) {
            params.push(CornerParam {
                name: ep.name.clone(),
                unit: ep.unit.to_string(),
                values,
                reference: None,
            });
        }
        if !params.is_empty() {
            corner(
                &CornerSpec {
                    title: format!(
                        "Posterior of the effect ({round}): {} at {}",
                        f.name, f.location
                    ),
                    params,
                    bins: 30,
                    density: Density2d::Binned,
                    reference_label: String::new(),
                    size_px: None,
                },
                &dir.join("effect_posterior"),
            )?;
            written.push("effect_posterior".to_string());
        }
    }
    Ok(written)
}
