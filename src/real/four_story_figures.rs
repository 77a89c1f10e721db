//! Figures of the `four-story-modal` study (PNG + SVG): corner plot, traces, frequency
//! errors of every model, mode shapes and posterior-predictive p-values.

use std::path::Path;

use super::four_story_run::{FourStoryStudy, Ppc};
use super::report::trace_figure;
use crate::error::Result;
use crate::plot::{
    bar_chart, corner, line_chart, BarChartSpec, BarGroup, CornerParam, CornerSpec, LineChartSpec,
    Mark, RefLine, Scale, Series,
};

/// Writes the figures of the study (PNG + SVG) into `out`.
pub fn write(s: &FourStoryStudy, out: &Path) -> Result<()> {
    corner_and_traces(s, out)?;
    frequency_errors(s, out)?;
    mode_shapes(s, out)?;
    ppc_pvalues(s, out)
}

/// The corner plot of the main posterior (Table 1's updated stiffnesses as references)
/// and its walker traces: `corner` and `traces`.
fn corner_and_traces(s: &FourStoryStudy, out: &Path) -> Result<()> {
    let v = &s.main;
    let names: Vec<(String, String)> = v
        .rows
        .iter()
        .map(|r| (r.name.clone(), r.unit.clone()))
        .collect();
    let params = (0..v.lik.names().len())
        .map(|p| CornerParam {
            name: names[p].0.clone(),
            unit: names[p].1.clone(),
            values: v.sampled.chains(p, f64::exp).concat(),
            reference: (p < 4).then(|| s.paper_models[4].0.stiffness_n_per_m[p]),
        })
        .collect();
    corner(
        &CornerSpec {
            title: "Four-story frame: posterior (masses fixed at Table 1 values)".into(),
            params,
            reference_label: "Table 1, Caughey, accelerance".into(),
            ..Default::default()
        },
        &out.join("corner"),
    )?;
    trace_figure(
        &v.sampled,
        &names,
        &|_, x| x.exp(),
        "Four-story frame: walker traces",
        &out.join("traces"),
    )
}

/// Model minus measured natural frequency (%) of the posterior median, the held-out
/// fit's predictive median and the paper's models: `frequency_errors`.
fn frequency_errors(s: &FourStoryStudy, out: &Path) -> Result<()> {
    let modes_x: Vec<f64> = (1..=4).map(f64::from).collect();
    let err = |f: &[f64]| -> Vec<f64> {
        (0..4)
            .map(|i| 100.0 * (f[i] / s.data.freq_hz[i] - 1.0))
            .collect()
    };
    let mut series = vec![Series {
        label: "posterior median (modes 1-4)".into(),
        x: modes_x.clone(),
        y: err(&s.main_median.freq_hz),
        mark: Mark::LineAndPoints,
    }];
    series.push(Series {
        label: "held-out fit (modes 1-3), predictive median".into(),
        x: modes_x.clone(),
        y: err(&s
            .holdout_ppc
            .modes
            .iter()
            .map(|m| m.f_rep[1])
            .collect::<Vec<_>>()),
        mark: Mark::LineAndPoints,
    });
    for (t, p) in s.paper_models.iter().take(5) {
        series.push(Series {
            label: t.label.into(),
            x: modes_x.clone(),
            y: err(&p.freq_hz),
            mark: Mark::LineAndPoints,
        });
    }
    line_chart(
        &LineChartSpec {
            title: "Model minus measured natural frequency".into(),
            x_label: "Mode".into(),
            y_label: "Frequency error (%)".into(),
            series,
            y_refs: vec![RefLine {
                value: 0.0,
                label: "measured".into(),
            }],
            ..Default::default()
        },
        &out.join("frequency_errors"),
    )
}

/// Measured (points) and posterior-median (lines) mode shapes: `mode_shapes`.
fn mode_shapes(s: &FourStoryStudy, out: &Path) -> Result<()> {
    // Each mode drawn about x = mode number (shape scaled by 0.45), ground at floor 0.
    let floors: Vec<f64> = (0..=4).map(f64::from).collect();
    let offset = |i: usize, v: &[f64]| -> Vec<f64> {
        std::iter::once(0.0)
            .chain(v.iter().copied())
            .map(|x| (i + 1) as f64 + 0.45 * x)
            .collect()
    };
    let mut series = vec![];
    for i in 0..4 {
        series.push(Series {
            label: if i == 0 {
                "measured".into()
            } else {
                String::new()
            },
            x: offset(i, &s.data.unit_shape(i))[1..].to_vec(),
            y: floors[1..].to_vec(),
            mark: Mark::Points,
        });
        series.push(Series {
            label: format!("mode {} model, MAC {:.4}", i + 1, s.main_median.mac[i]),
            x: offset(i, s.main_median.shapes.column(i).as_slice()),
            y: floors.clone(),
            mark: Mark::Line,
        });
    }
    line_chart(
        &LineChartSpec {
            title: "Mode shapes: measured (points) and posterior-median shear frame (lines)".into(),
            x_label: "Mode number + 0.45 x unit-length shape component".into(),
            y_label: "Floor (0 = ground)".into(),
            series,
            x_refs: (1..=4)
                .map(|i| RefLine {
                    value: f64::from(i),
                    label: String::new(),
                })
                .collect(),
            ..Default::default()
        },
        &out.join("mode_shapes"),
    )
}

/// Posterior-predictive p-values of every frequency and shape for the three fits:
/// `ppc_pvalues`.
fn ppc_pvalues(s: &FourStoryStudy, out: &Path) -> Result<()> {
    let cats: Vec<String> = (1..=4)
        .map(|i| format!("f{i}"))
        .chain((1..=4).map(|i| format!("shape {i}")))
        .collect();
    let pv = |p: &Ppc| -> Vec<f64> {
        p.modes
            .iter()
            .map(|m| m.p_freq)
            .chain(p.modes.iter().map(|m| m.p_shape))
            .map(|x| x.max(1e-4))
            .collect()
    };
    bar_chart(
        &BarChartSpec {
            title: "Posterior-predictive p-values (floored at 1e-4)".into(),
            x_label: "Datum".into(),
            y_label: "p-value".into(),
            categories: cats,
            groups: vec![
                BarGroup {
                    label: "fixed masses, modes 1-4".into(),
                    values: pv(&s.main_ppc),
                },
                BarGroup {
                    label: "fixed masses, fit to modes 1-3".into(),
                    values: pv(&s.holdout_ppc),
                },
                BarGroup {
                    label: "free mass ratios, modes 1-4".into(),
                    values: pv(&s.free_mass_ppc),
                },
            ],
            y_scale: Scale::Log,
            show_values: false,
            size_px: None,
        },
        &out.join("ppc_pvalues"),
    )
}
