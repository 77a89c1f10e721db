//! Figures of the posterior part of `identifiability.md`: coefficient-of-variation bar
//! charts, corner plots, correlation heatmaps and the k/m ridge.

use super::posterior::{correlation, mean_cv, VariantPosterior};
use crate::error::Result;
use crate::plot::{
    self, BarChartSpec, BarGroup, CornerParam, CornerSpec, HeatmapSpec, LineChartSpec, Mark, Scale,
    Series,
};
use std::path::Path;

/// Most draws in a corner plot and per series of the ridge plot.
const MAX_PLOT_DRAWS: usize = 20_000;
const MAX_RIDGE_POINTS: usize = 1500;
/// Variants with a corner plot and a correlation heatmap.
const DETAILED: [&str; 2] = ["table1 caughey_receptance", "table2 caughey_receptance"];

fn file_key(name: &str) -> String {
    name.replace(' ', "_")
}

fn stride(v: &[f64], max: usize) -> Vec<f64> {
    let s = v.len().div_ceil(max).max(1);
    v.iter().step_by(s).copied().collect()
}

/// CV bar charts, corner plots, correlation heatmaps and the k/m ridge.
pub fn write_posterior_figures(posts: &[VariantPosterior], dir: &Path) -> Result<()> {
    for table in ["table1", "table2"] {
        cv_bar_chart(posts, table, dir)?;
    }
    for p in posts.iter().filter(|p| DETAILED.contains(&p.name.as_str())) {
        corner_and_correlation(p, dir)?;
    }
    ridge_km(posts, dir)
}

/// Bar chart of the posterior coefficient of variation (%) of every parameter of the
/// variants of `table` ("table1" or "table2"): `posterior_cv_<table>`; nothing when the
/// table has no variant.
fn cv_bar_chart(posts: &[VariantPosterior], table: &str, dir: &Path) -> Result<()> {
    let sel: Vec<&VariantPosterior> = posts.iter().filter(|p| p.name.starts_with(table)).collect();
    if sel.is_empty() {
        return Ok(());
    }
    let mut categories: Vec<String> = Vec::new();
    for p in &sel {
        for q in &p.sample.params {
            if !categories.contains(&q.name) {
                categories.push(q.name.clone());
            }
        }
    }
    let groups = sel
        .iter()
        .map(|p| BarGroup {
            label: p.name.trim_start_matches(table).trim().to_string(),
            values: categories
                .iter()
                .map(|c| {
                    p.index(c)
                        .map(|j| 100.0 * p.sample.summary.parameters[j].cv)
                        .unwrap_or(f64::NAN)
                })
                .collect(),
        })
        .collect();
    plot::bar_chart(
        &BarChartSpec {
            title: format!("{table}: posterior coefficient of variation of every parameter"),
            x_label: "parameter".into(),
            y_label: "CV (%)".into(),
            categories,
            groups,
            y_scale: Scale::Log,
            show_values: false,
            size_px: Some((1300, 650)),
        },
        &dir.join(format!("posterior_cv_{table}")),
    )
}

/// Corner plot and correlation heatmap of one variant's posterior draws:
/// `posterior_corner_<variant>` and `posterior_correlation_<variant>`.
fn corner_and_correlation(p: &VariantPosterior, dir: &Path) -> Result<()> {
    let params = &p.sample.params;
    let columns: Vec<Vec<f64>> = (0..params.len()).map(|j| p.column(j)).collect();
    plot::corner(
        &CornerSpec {
            title: format!("{}: posterior", p.name),
            params: params
                .iter()
                .zip(&columns)
                .map(|(q, c)| CornerParam {
                    name: q.name.clone(),
                    unit: if q.unit == "1" {
                        String::new()
                    } else {
                        q.unit.clone()
                    },
                    values: stride(c, MAX_PLOT_DRAWS),
                    reference: None,
                })
                .collect(),
            ..Default::default()
        },
        &dir.join(format!("posterior_corner_{}", file_key(&p.name))),
    )?;
    let n = params.len();
    let values = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| correlation(&columns[i], &columns[j]))
                .collect()
        })
        .collect();
    let labels: Vec<String> = params.iter().map(|q| q.name.clone()).collect();
    plot::heatmap(
        &HeatmapSpec {
            title: format!("{}: posterior correlation of the parameters", p.name),
            x_label: String::new(),
            y_label: String::new(),
            row_labels: labels.clone(),
            col_labels: labels,
            values,
            colour_label: "correlation".into(),
            limit: Some(1.0),
            show_values: true,
            size_px: Some((1000, 900)),
        },
        &dir.join(format!("posterior_correlation_{}", file_key(&p.name))),
    )
}

/// The k/m ridge (`posterior_ridge_km`), when either Caughey receptance variant has
/// been sampled.
fn ridge_km(posts: &[VariantPosterior], dir: &Path) -> Result<()> {
    // The ridge: k_r / mean(k_r) against m_r / mean(m_r) for the Caughey receptance
    // variants, ground excitation per story, then hammer (all stories in one series,
    // drawn last so the tight cloud stays visible).
    let mut series = Vec::new();
    for name in ["table2 caughey_receptance", "table1 caughey_receptance"] {
        let Some(p) = posts.iter().find(|p| p.name == name) else {
            continue;
        };
        let mut hammer = Series {
            label: format!("{name} (hammer), stories 1-4"),
            mark: Mark::Points,
            ..Default::default()
        };
        for r in 1..=4 {
            let (Some(m), Some(k)) = (p.named(&format!("m{r}")), p.named(&format!("k{r}"))) else {
                continue;
            };
            let (mm, mk) = (mean_cv(&m).mean, mean_cv(&k).mean);
            let x: Vec<f64> = stride(&m, MAX_RIDGE_POINTS)
                .iter()
                .map(|v| v / mm)
                .collect();
            let y: Vec<f64> = stride(&k, MAX_RIDGE_POINTS)
                .iter()
                .map(|v| v / mk)
                .collect();
            if p.name.starts_with("table1") {
                hammer.x.extend(x);
                hammer.y.extend(y);
            } else {
                series.push(Series {
                    label: format!("{name} (shake table), story {r}"),
                    x,
                    y,
                    mark: Mark::Points,
                });
            }
        }
        if !hammer.x.is_empty() {
            series.push(hammer);
        }
    }
    if !series.is_empty() {
        plot::line_chart(
            &LineChartSpec {
                title: "Posterior draws of story stiffness against floor mass (each over its posterior mean): the k/m ridge of ground excitation".into(),
                x_label: "m_r / mean(m_r)".into(),
                y_label: "k_r / mean(k_r)".into(),
                series,
                size_px: Some((1100, 900)),
                ..Default::default()
            },
            &dir.join("posterior_ridge_km"),
        )?;
    }
    Ok(())
}
