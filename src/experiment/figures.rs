//! Figures of an updating run: FRF comparisons like the paper's Figures 4, 5, 8, 9 and
//! per-test FRF estimates with their selected bands. Drawing only: every number comes
//! from the pipeline.

use super::config::FigureSpec;
use super::pipeline::{model_curve, TableId, VariantRun};
use crate::error::{Error, Result};
use crate::frf::labels::{pair_label, y_label};
use crate::frf::{Excitation, FrfKind, FrfPair};
use crate::plot::{
    self, ChannelFrf, ComparisonPanel, Curve, FreqBand, FrfComparisonSpec, FrfMagnitudesSpec,
};
use crate::signal::{InputKind, TestFrf};
use crate::update::DampingModel;
use std::path::Path;

/// Frequency range drawn in comparison figures, Hz (the paper plots 0-10 Hz).
const FIG_RANGE_HZ: (f64, f64) = (0.2, 10.0);

fn bands(frf: &TestFrf) -> Vec<FreqBand> {
    frf.bands
        .iter()
        .map(|b| FreqBand {
            lo_hz: b.lo_hz,
            hi_hz: b.hi_hz,
        })
        .collect()
}

/// Draws one comparison figure (receptance and accelerance panels) from the runs.
pub fn comparison_figure(
    spec: &FigureSpec,
    runs: &[VariantRun],
    frfs: &[TestFrf],
    stem: &Path,
) -> Result<()> {
    let table = if spec.table == "table1" {
        TableId::Table1
    } else {
        TableId::Table2
    };
    let test = figure_test(spec, table, frfs)?;
    let mut panels = Vec::new();
    for kind in [FrfKind::Receptance, FrfKind::Accelerance] {
        panels.push(comparison_panel(spec, table, kind, runs, test)?);
    }
    let damping = match spec.damping {
        DampingModel::Rayleigh => "Rayleigh",
        DampingModel::Caughey => "Caughey",
    };
    let what = if table == TableId::Table1 {
        "Hammer test"
    } else {
        "Shake-table test"
    };
    plot::frf_comparison(
        &FrfComparisonSpec {
            title: format!("{what}: initial, experimental and updated FRFs ({damping} damping; FDAC over the selected bands)"),
            panels,
            size_px: Some((1400, 600)),
        },
        stem,
    )
}

/// The test of `table` that the figure draws: the hammer test at the figure's excited
/// floor, or the ground-excitation test.
fn figure_test<'a>(spec: &FigureSpec, table: TableId, frfs: &'a [TestFrf]) -> Result<&'a TestFrf> {
    frfs.iter()
        .filter(|f| table.includes(f))
        .find(|f| match (&f.input, spec.excited_floor) {
            (InputKind::Force { floor, .. }, Some(e)) => *floor == e,
            (InputKind::Ground { .. }, _) => true,
            _ => false,
        })
        .ok_or_else(|| {
            Error::Usage(format!(
                "figure: no {} test with excited floor {:?}",
                spec.table, spec.excited_floor
            ))
        })
}

/// The run of the variant (`table`, `damping`, `kind`).
fn variant_run(
    runs: &[VariantRun],
    table: TableId,
    damping: DampingModel,
    kind: FrfKind,
) -> Result<&VariantRun> {
    runs.iter()
        .find(|r| {
            r.variant.table == table && r.variant.damping == damping && r.variant.kind == kind
        })
        .ok_or_else(|| {
            Error::Usage(format!(
                "figure: variant {:?} {:?} was not run",
                damping, kind
            ))
        })
}

/// One FRF kind's panel: the measured `|H1|` of `test` over [`FIG_RANGE_HZ`] with the
/// initial and updated models of the matching run and their FDACs.
fn comparison_panel(
    spec: &FigureSpec,
    table: TableId,
    kind: FrfKind,
    runs: &[VariantRun],
    test: &TestFrf,
) -> Result<ComparisonPanel> {
    let excitation = match spec.excited_floor {
        Some(e) if table == TableId::Table1 => Excitation::Dof(e - 1),
        _ => Excitation::Ground,
    };
    let run = variant_run(runs, table, spec.damping, kind)?;
    let response = test
        .responses
        .iter()
        .find(|r| r.kind == kind && r.channel.floor == spec.response_floor)
        .ok_or_else(|| {
            Error::Usage(format!(
                "figure: test {} has no {kind:?} channel at floor {}",
                test.test, spec.response_floor
            ))
        })?;
    let pair = FrfPair {
        response: spec.response_floor - 1,
        excitation,
        kind,
    };
    let idx: Vec<usize> = (0..test.freq_hz.len())
        .filter(|&k| test.freq_hz[k] >= FIG_RANGE_HZ.0 && test.freq_hz[k] <= FIG_RANGE_HZ.1)
        .collect();
    let freq_hz: Vec<f64> = idx.iter().map(|&k| test.freq_hz[k]).collect();
    let omega: Vec<f64> = freq_hz
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f)
        .collect();
    let experimental = Curve {
        freq_hz: freq_hz.clone(),
        values: idx.iter().map(|&k| response.h1[k].norm()).collect(),
    };
    let initial = model_curve(
        &run.problem,
        &run.problem.variables().initial(),
        pair,
        &omega,
    )?;
    let updated = model_curve(&run.problem, &run.result.best.theta, pair, &omega)?;
    let label = pair_label(&pair);
    let fdac = run.fdac.iter().find(|(l, _, _)| *l == label);
    Ok(ComparisonPanel {
        title: format!(
            "{} {label}",
            if kind == FrfKind::Receptance {
                "receptance"
            } else {
                "accelerance"
            }
        ),
        y_label: y_label(kind, table == TableId::Table2).into(),
        experimental,
        initial: Some(Curve {
            freq_hz: freq_hz.clone(),
            values: initial,
        }),
        updated: Some(Curve {
            freq_hz,
            values: updated,
        }),
        fdac_initial: fdac.map(|f| f.1),
        fdac_updated: fdac.map(|f| f.2),
        bands: bands(test),
    })
}

/// Draws one test's FRF estimates (one figure per FRF kind) with bands and coherence.
pub fn estimate_figures(frf: &TestFrf, dir: &Path) -> Result<()> {
    let ground = matches!(frf.input, InputKind::Ground { .. });
    let idx: Vec<usize> = (0..frf.freq_hz.len())
        .filter(|&k| frf.freq_hz[k] > 0.0 && frf.freq_hz[k] <= FIG_RANGE_HZ.1 * 1.5)
        .collect();
    for kind in [FrfKind::Receptance, FrfKind::Accelerance] {
        let channels: Vec<ChannelFrf> = frf
            .responses
            .iter()
            .filter(|r| r.kind == kind)
            .map(|r| ChannelFrf {
                label: r.channel.name.clone(),
                magnitude: idx.iter().map(|&k| r.h1[k].norm()).collect(),
                coherence: idx.iter().map(|&k| r.coherence[k]).collect(),
            })
            .collect();
        if channels.is_empty() {
            continue;
        }
        let name = if kind == FrfKind::Receptance {
            "receptance"
        } else {
            "accelerance"
        };
        plot::frf_magnitudes(
            &FrfMagnitudesSpec {
                title: format!(
                    "{}: {name} (H1), selected half-power bands shaded",
                    frf.test
                ),
                y_label: y_label(kind, ground).into(),
                freq_hz: idx.iter().map(|&k| frf.freq_hz[k]).collect(),
                channels,
                bands: bands(frf),
                size_px: None,
            },
            &dir.join(format!("frf_{name}")),
        )?;
    }
    Ok(())
}
