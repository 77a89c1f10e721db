//! Figures of a sampling run: corner plot, walker traces, posterior bands of model FRFs
//! over the measured ones, and the coefficient of variation of every parameter.

use super::predictive::{predictive_bands, PredictiveTarget};
use super::run::{Prepared, SampleSettings};
use super::summary::{physical_draws, OutputParam};
use crate::error::Result;
use crate::frf::labels::{pair_label, y_label};
use crate::frf::{Excitation, FrfPair};
use crate::mcmc::{Burn, Draws, Sampler};
use crate::plot::{
    band_overlay, bar_chart, corner, traces, BandOverlaySpec, BandPanel, BarChartSpec, BarGroup,
    CornerParam, CornerSpec, Curve, FreqBand, Interval, Scale, TraceParam, TracesSpec,
};
use std::path::Path;

/// Most points per walker in the trace figure.
const MAX_TRACE_POINTS: u64 = 1000;
/// Dense grid of the band figure: from this fraction of the lowest half-power band's
/// lower edge ...
const GRID_LOW: f64 = 0.5;
/// ... to this multiple of the highest band's upper edge.
const GRID_HIGH: f64 = 1.2;

/// Writes `corner`, `traces`, `predictive` and `cv` into `out`.
pub fn write_figures(
    out: &Path,
    prep: &Prepared,
    sampler: &Sampler<'_, super::FrfPosterior>,
    params: &[OutputParam],
    draws: &Draws,
    settings: &SampleSettings,
) -> Result<()> {
    let post = &prep.posterior;
    let phys = physical_draws(post, params, draws);
    let label = |p: &OutputParam| p.name.clone();
    let unit = |p: &OutputParam| {
        if p.unit == "1" {
            String::new()
        } else {
            p.unit.clone()
        }
    };
    let title = format!(
        "{:?} {:?}, {:?} tests: posterior",
        settings.damping, settings.frf, settings.tests
    );
    corner(
        &CornerSpec {
            title: title.clone(),
            params: params
                .iter()
                .enumerate()
                .map(|(j, p)| CornerParam {
                    name: label(p),
                    unit: unit(p),
                    values: phys
                        .values
                        .iter()
                        .skip(j)
                        .step_by(phys.dim)
                        .copied()
                        .collect(),
                    reference: None,
                })
                .collect(),
            ..Default::default()
        },
        &out.join("corner"),
    )?;

    // Traces of the first ensemble from step 0, thinned to at most MAX_TRACE_POINTS.
    let steps = sampler.step_count();
    let thin = steps.div_ceil(MAX_TRACE_POINTS).max(1);
    let full = physical_draws(
        post,
        params,
        &sampler.draws(Burn::Steps { discard: 0, thin })?,
    );
    let w = full.n_walkers;
    traces(
        &TracesSpec {
            title: format!(
                "{title}: walker traces (ensemble 1 of {})",
                full.n_chains / w
            ),
            params: params
                .iter()
                .enumerate()
                .map(|(j, p)| TraceParam {
                    name: label(p),
                    unit: unit(p),
                    walkers: (0..w)
                        .map(|c| (0..full.n_draws).map(|d| full.draw(c, d)[j]).collect())
                        .collect(),
                    reference: None,
                })
                .collect(),
            burn_in: Some((draws.discarded_steps / full.thin_steps) as usize),
            x_label: format!("Step / {}", full.thin_steps),
            ..Default::default()
        },
        &out.join("traces"),
    )?;

    predictive_figure(out, prep, draws, settings, &title)?;

    bar_chart(
        &BarChartSpec {
            title: format!("{title}: coefficient of variation"),
            x_label: "Parameter".into(),
            y_label: "CV = sd / mean (%)".into(),
            categories: params.iter().map(label).collect(),
            groups: vec![BarGroup {
                label: String::new(),
                values: (0..params.len())
                    .map(|j| {
                        let v: Vec<f64> = phys
                            .values
                            .iter()
                            .skip(j)
                            .step_by(phys.dim)
                            .copied()
                            .collect();
                        let n = v.len() as f64;
                        let mean = v.iter().sum::<f64>() / n;
                        let sd =
                            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                        100.0 * sd / mean.abs()
                    })
                    .collect(),
            }],
            y_scale: Scale::Log,
            show_values: true,
            size_px: None,
        },
        &out.join("cv"),
    )
}

/// The FRFs shown with bands: every pair of a single test, or the top-floor response
/// of each test.
fn band_pairs(pairs: &[FrfPair], single: bool) -> Vec<FrfPair> {
    if single {
        return pairs.to_vec();
    }
    pairs
        .iter()
        .max_by_key(|p| p.response)
        .copied()
        .into_iter()
        .collect()
}

fn predictive_figure(
    out: &Path,
    prep: &Prepared,
    draws: &Draws,
    settings: &SampleSettings,
    title: &str,
) -> Result<()> {
    let post = &prep.posterior;
    let data = post.data();
    let single = data.blocks.len() == 1;
    let mut targets = Vec::new();
    let mut panels = Vec::new();
    for (b, block) in data.blocks.iter().enumerate() {
        let Some(frf) = prep.frfs.iter().find(|f| f.test == data.tests[b]) else {
            continue;
        };
        let lo = frf
            .bands
            .iter()
            .map(|x| x.lo_hz)
            .fold(f64::INFINITY, f64::min)
            * GRID_LOW;
        let hi = frf.bands.iter().map(|x| x.hi_hz).fold(0.0, f64::max) * GRID_HIGH;
        let idx: Vec<usize> = (0..frf.freq_hz.len())
            .filter(|&k| frf.freq_hz[k] >= lo && frf.freq_hz[k] <= hi && frf.freq_hz[k] > 0.0)
            .collect();
        if idx.is_empty() {
            continue;
        }
        let freq_hz: Vec<f64> = idx.iter().map(|&k| frf.freq_hz[k]).collect();
        for pair in band_pairs(&block.pairs, single) {
            let measured = frf
                .responses
                .iter()
                .find(|r| r.pair(&frf.input).is_ok_and(|p| p == pair))
                .map(|r| Curve {
                    freq_hz: freq_hz.clone(),
                    values: idx.iter().map(|&k| r.h1[k].norm()).collect(),
                });
            targets.push(PredictiveTarget {
                pair,
                omega_rad_s: freq_hz
                    .iter()
                    .map(|f| 2.0 * std::f64::consts::PI * f)
                    .collect(),
                window_tau_s: data.window_tau_s[b],
            });
            panels.push(BandPanel {
                title: format!("{} ({})", pair_label(&pair), frf.test),
                y_label: y_label(pair.kind, pair.excitation == Excitation::Ground).into(),
                freq_hz: freq_hz.clone(),
                measured,
                bands: frf
                    .bands
                    .iter()
                    .map(|x| FreqBand {
                        lo_hz: x.lo_hz,
                        hi_hz: x.hi_hz,
                    })
                    .collect(),
                ..Default::default()
            });
        }
    }
    let bands = predictive_bands(post, draws, &targets, settings.predictive_draws)?;
    for (p, b) in panels.iter_mut().zip(bands) {
        p.median = b.median;
        p.band_50 = Some(Interval {
            lo: b.lo50,
            hi: b.hi50,
        });
        p.band_95 = Some(Interval {
            lo: b.lo95,
            hi: b.hi95,
        });
    }
    band_overlay(
        &BandOverlaySpec {
            title: format!(
                "{title}: model FRF (median, 50 % and 95 % bands of {} draws) and measured |H1|",
                settings
                    .predictive_draws
                    .min(draws.n_chains * draws.n_draws)
            ),
            panels,
            size_px: None,
        },
        &out.join("predictive"),
    )
}
