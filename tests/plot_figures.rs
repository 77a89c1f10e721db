//! Every figure on small synthetic data writes a PNG (magic bytes) and an SVG (with the
//! title text), and edge cases (empty series, NaN, zeros and negatives on log axes,
//! single points, constant data) draw without panicking. Every PNG is the rasterisation
//! of its SVG (rendered again here and compared byte for byte).
//!
//! Set `FRFBAYES_PLOT_DIR=/some/dir` to keep the figures for viewing.

use frfbayes::plot::*;
use frfbayes::Error;
use num_complex::Complex64;
use std::path::{Path, PathBuf};

const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

struct Out {
    _tmp: Option<tempfile::TempDir>,
    dir: PathBuf,
}

fn out_dir() -> Out {
    match std::env::var_os("FRFBAYES_PLOT_DIR") {
        Some(d) => {
            let dir = PathBuf::from(d);
            std::fs::create_dir_all(&dir).unwrap();
            Out { _tmp: None, dir }
        }
        None => {
            let t = tempfile::tempdir().unwrap();
            let dir = t.path().to_path_buf();
            Out { _tmp: Some(t), dir }
        }
    }
}

/// Checks both files exist, the PNG starts with the PNG signature and has the given
/// size, the SVG is an SVG containing `title`, and no temporary file is left.
fn check(stem: &Path, title: &str, size: (u32, u32)) {
    let png = std::fs::read(stem.with_extension("png")).expect("png written");
    assert!(png.len() > 1000, "png too small: {}", png.len());
    assert_eq!(png[..8], PNG_MAGIC);
    // IHDR: width and height big-endian at bytes 16..24
    let w = u32::from_be_bytes(png[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(png[20..24].try_into().unwrap());
    assert_eq!((w, h), size);
    let svg = std::fs::read_to_string(stem.with_extension("svg")).expect("svg written");
    assert!(svg.starts_with("<svg"), "{}", &svg[..40.min(svg.len())]);
    assert!(svg.contains(title), "svg lacks title {title:?}");
    assert!(
        svg.contains(r#"font-family="DejaVu Sans""#),
        "svg text must name the bundled font"
    );
    assert!(
        svg_to_png(&svg).unwrap() == png,
        "{}: the PNG is not the rasterisation of the SVG",
        stem.display()
    );
    let dir = stem.parent().unwrap();
    let prefix = format!(".{}.", stem.file_name().unwrap().to_string_lossy());
    for e in std::fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.starts_with(&prefix), "temporary file left: {name}");
    }
}

fn freq_grid(n: usize, max_hz: f64) -> Vec<f64> {
    (0..n).map(|i| max_hz * i as f64 / (n - 1) as f64).collect()
}

/// |sum_i a_i / (f_i^2 - f^2 + 2 j zeta f_i f)| for a few modes, a stand-in FRF.
fn synthetic_frf(freq_hz: &[f64], modes_hz: &[f64], amps: &[f64], zeta: f64) -> Vec<f64> {
    freq_hz
        .iter()
        .map(|&f| {
            modes_hz
                .iter()
                .zip(amps)
                .map(|(&fi, &a)| a / Complex64::new(fi * fi - f * f, 2.0 * zeta * fi * f))
                .sum::<Complex64>()
                .norm()
        })
        .collect()
}

const MODES_HZ: [f64; 4] = [2.1, 6.0, 9.4, 12.2];

fn bands() -> Vec<FreqBand> {
    MODES_HZ
        .iter()
        .map(|&f| FreqBand {
            lo_hz: f * 0.96,
            hi_hz: f * 1.04,
        })
        .collect()
}

#[test]
fn frf_magnitudes_writes_png_and_svg() {
    let out = out_dir();
    let f = freq_grid(1500, 25.0);
    let channels = (0..4)
        .map(|c| {
            let amps: Vec<f64> = (0..4).map(|m| 1.0 + 0.5 * ((c + m) % 3) as f64).collect();
            let mag = synthetic_frf(&f, &MODES_HZ, &amps, 0.02 + 0.005 * c as f64);
            let coh = f
                .iter()
                .map(|&x| 1.0 - 0.6 * (-(x - 4.0 - c as f64).powi(2)).exp() - 0.2 * (-x).exp())
                .collect();
            ChannelFrf {
                label: format!("Floor {} acc", c + 1),
                magnitude: mag,
                coherence: coh,
            }
        })
        .collect();
    let spec = FrfMagnitudesSpec {
        title: "Hammer test 1: accelerance, impact at floor 1".into(),
        y_label: "|A| (m/s²/N)".into(),
        freq_hz: f,
        channels,
        bands: bands(),
        size_px: None,
    };
    let stem = out.dir.join("frf_magnitudes");
    frf_magnitudes(&spec, &stem).unwrap();
    check(&stem, "Hammer test 1", (1000, 760));
}

/// RGBA pixels and width of a PNG.
fn decode_png(path: &Path) -> (Vec<u8>, usize) {
    let p = resvg::tiny_skia::Pixmap::load_png(path).expect("PNG decodes");
    (p.data().to_vec(), p.width() as usize)
}

/// Pixels in the box `x0..x1` by `y0..y1` whose red channel is below 128.
fn dark_pixels(px: &[u8], w: usize, (x0, x1): (usize, usize), (y0, y1): (usize, usize)) -> usize {
    (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| 4 * (y * w + x)))
        .filter(|&i| px[i] < 128)
        .count()
}

#[test]
fn png_is_anti_aliased_with_text_where_the_title_is() {
    let out = out_dir();
    let f = freq_grid(400, 20.0);
    let spec = LineChartSpec {
        title: "WWWWWWWW".into(),
        x_label: "x".into(),
        y_label: "y".into(),
        series: vec![Series {
            label: "diagonal".into(),
            x: f.clone(),
            y: f.clone(),
            mark: Mark::Line,
        }],
        ..Default::default()
    };
    let stem = out.dir.join("aa");
    line_chart(&spec, &stem).unwrap();
    check(&stem, "WWWWWWWW", (1000, 700));
    let (px, w) = decode_png(&stem.with_extension("png"));
    // The title (28 px text, top 10 px, centred): ink inside its box, none beside it.
    let half = 80; // 8 W's are about 8 * 0.99 em * 22.6 px = 179 px wide
    assert!(dark_pixels(&px, w, (500 - half, 500 + half), (10, 40)) > 500);
    assert_eq!(dark_pixels(&px, w, (0, 300), (0, 40)), 0);
    assert_eq!(dark_pixels(&px, w, (700, 1000), (0, 40)), 0);
    // Anti-aliasing: the glyph edges of the title are grey levels between the white
    // background and the black ink (an aliased renderer leaves none).
    let title_box = (10..40).flat_map(|y| (500 - half..500 + half).map(move |x| 4 * (y * w + x)));
    let grey: Vec<u8> = title_box
        .map(|i| px[i])
        .filter(|&g| g > 10 && g < 245)
        .collect();
    let levels: std::collections::BTreeSet<u8> = grey.iter().copied().collect();
    assert!(
        grey.len() > 100 && levels.len() >= 8,
        "{} grey pixels, {} levels",
        grey.len(),
        levels.len()
    );
}

#[test]
fn frf_comparison_writes_png_and_svg() {
    let out = out_dir();
    let f = freq_grid(800, 15.0);
    let amps = [1.0, -0.8, 0.6, -0.3];
    let exp: Vec<f64> = synthetic_frf(&f, &MODES_HZ, &amps, 0.03)
        .iter()
        .enumerate()
        .map(|(i, v)| v * (1.0 + 0.15 * ((i * 7919) % 13) as f64 / 13.0))
        .collect();
    let init = synthetic_frf(&f, &[2.3, 6.6, 10.1, 13.0], &amps, 0.03);
    let upd = synthetic_frf(&f, &MODES_HZ, &amps, 0.031);
    let w2: Vec<f64> = f
        .iter()
        .map(|x| (2.0 * std::f64::consts::PI * x).powi(2))
        .collect();
    let acc = |v: &[f64]| v.iter().zip(&w2).map(|(a, b)| a * b).collect::<Vec<_>>();
    let curve = |v: Vec<f64>| Curve {
        freq_hz: f.clone(),
        values: v,
    };
    let spec = FrfComparisonSpec {
        title: "Hammer test: initial, experimental and updated FRFs (Rayleigh damping)".into(),
        panels: vec![
            ComparisonPanel {
                title: "(a) Receptance H₄,₁".into(),
                y_label: "|H| (m/N)".into(),
                experimental: curve(exp.clone()),
                initial: Some(curve(init.clone())),
                updated: Some(curve(upd.clone())),
                fdac_initial: Some(0.412),
                fdac_updated: Some(0.955),
                bands: bands(),
            },
            ComparisonPanel {
                title: "(b) Accelerance A₄,₁".into(),
                y_label: "|A| (m/s²/N)".into(),
                experimental: curve(acc(&exp)),
                initial: Some(curve(acc(&init))),
                updated: Some(curve(acc(&upd))),
                fdac_initial: None,
                fdac_updated: Some(0.971),
                bands: bands(),
            },
        ],
        size_px: None,
    };
    let stem = out.dir.join("frf_comparison");
    frf_comparison(&spec, &stem).unwrap();
    check(&stem, "Rayleigh damping", (1200, 620));
    assert!(std::fs::read_to_string(stem.with_extension("svg"))
        .unwrap()
        .contains("FDAC 0.955"));
}

#[test]
fn bar_chart_grouped_and_log() {
    let out = out_dir();
    let cats: Vec<String> = ["k1", "k2", "k3", "k4", "m1", "m2", "m3", "m4", "a0", "a1"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let spec = BarChartSpec {
        title: "Coefficient of variation of the updated parameters".into(),
        x_label: "Parameter".into(),
        y_label: "CV (%)".into(),
        groups: vec![
            BarGroup {
                label: "Rayleigh".into(),
                values: (0..10).map(|i| 0.5 + 1.7 * i as f64).collect(),
            },
            BarGroup {
                label: "Caughey".into(),
                values: (0..10).map(|i| 0.3 + 0.9 * (i * i) as f64).collect(),
            },
        ],
        categories: cats,
        y_scale: Scale::Log,
        show_values: false,
        size_px: None,
    };
    let stem = out.dir.join("bar_chart");
    bar_chart(&spec, &stem).unwrap();
    check(&stem, "Coefficient of variation", (1000, 700));

    // Linear, one group, long labels (rotated), negative values, NaN, values printed.
    let spec = BarChartSpec {
        title: "Relative change of stiffness".into(),
        y_label: "Δk / k₀ (%)".into(),
        categories: (1..=12).map(|i| format!("story {i} stiffness")).collect(),
        groups: vec![BarGroup {
            label: String::new(),
            values: (0..12)
                .map(|i| {
                    if i == 5 {
                        f64::NAN
                    } else {
                        (i as f64 - 4.0) * 1.3
                    }
                })
                .collect(),
        }],
        show_values: true,
        ..Default::default()
    };
    let stem = out.dir.join("bar_chart_linear");
    bar_chart(&spec, &stem).unwrap();
    check(&stem, "Relative change", (1000, 700));
}

#[test]
fn corner_binned_and_scatter() {
    let out = out_dir();
    // Deterministic correlated "samples" from a low-discrepancy sequence.
    let n = 4000;
    let u = |i: usize, k: f64| ((i as f64 * k).fract() - 0.5) * 2.0;
    let a: Vec<f64> = (0..n)
        .map(|i| u(i, 0.618_033_988_7) + 0.3 * u(i, 0.414_213_56))
        .collect();
    let b: Vec<f64> = (0..n)
        .map(|i| 0.7 * a[i] + 0.4 * u(i, 0.732_050_8))
        .collect();
    let c: Vec<f64> = (0..n).map(|i| 1e-3 * (5.0 + u(i, 0.236_067_977))).collect();
    let params = vec![
        CornerParam {
            name: "α₁".into(),
            unit: String::new(),
            values: a,
            reference: Some(0.1),
        },
        CornerParam {
            name: "α₂".into(),
            unit: String::new(),
            values: b,
            reference: Some(-0.2),
        },
        CornerParam {
            name: "a₁".into(),
            unit: "s".into(),
            values: c,
            reference: None,
        },
    ];
    let spec = CornerSpec {
        title: "Posterior of the stiffness corrections".into(),
        params,
        reference_label: "Truth".into(),
        ..Default::default()
    };
    let stem = out.dir.join("corner");
    corner(&spec, &stem).unwrap();
    check(&stem, "Posterior of the stiffness", (770, 770));
    let spec = CornerSpec {
        density: Density2d::Scatter,
        title: "Scatter corner".into(),
        ..spec
    };
    let stem = out.dir.join("corner_scatter");
    corner(&spec, &stem).unwrap();
    check(&stem, "Scatter corner", (770, 770));
}

#[test]
fn traces_write() {
    let out = out_dir();
    let params = (0..5)
        .map(|p| TraceParam {
            name: format!("k{}", p + 1),
            unit: "N/m".into(),
            walkers: (0..16)
                .map(|w| {
                    (0..3000)
                        .map(|s| {
                            let settle = (-(s as f64) / 300.0).exp();
                            1e4 * (1.0 + 0.1 * p as f64)
                                + 800.0 * settle * (w as f64 - 7.5)
                                + 50.0 * ((s * (w + 3) * 7919 % 101) as f64 / 101.0 - 0.5)
                        })
                        .collect()
                })
                .collect(),
            reference: Some(1e4 * (1.0 + 0.1 * p as f64)),
        })
        .collect();
    let spec = TracesSpec {
        title: "Walker traces".into(),
        params,
        burn_in: Some(1000),
        ..Default::default()
    };
    let stem = out.dir.join("traces");
    traces(&spec, &stem).unwrap();
    check(&stem, "Walker traces", (1000, 605));
}

#[test]
fn band_overlay_writes() {
    let out = out_dir();
    let f = freq_grid(600, 15.0);
    let amps = [1.0, -0.8, 0.6, -0.3];
    let med = synthetic_frf(&f, &MODES_HZ, &amps, 0.03);
    let scale = |k: f64| med.iter().map(|v| v * k).collect::<Vec<_>>();
    let fm = freq_grid(120, 15.0);
    let measured = synthetic_frf(&fm, &MODES_HZ, &amps, 0.028)
        .iter()
        .enumerate()
        .map(|(i, v)| v * (1.0 + 0.2 * (((i * 37) % 11) as f64 / 11.0 - 0.5)))
        .collect();
    let panel = BandPanel {
        title: "H₄,₁".into(),
        y_label: "|H| (m/N)".into(),
        freq_hz: f.clone(),
        median: med.clone(),
        band_50: Some(Interval {
            lo: scale(0.85),
            hi: scale(1.18),
        }),
        band_95: Some(Interval {
            lo: scale(0.6),
            hi: scale(1.6),
        }),
        measured: Some(Curve {
            freq_hz: fm,
            values: measured,
        }),
        bands: bands(),
        ..Default::default()
    };
    let spec = BandOverlaySpec {
        title: "Posterior-predictive receptance".into(),
        panels: vec![panel.clone()],
        size_px: None,
    };
    let stem = out.dir.join("band_overlay");
    band_overlay(&spec, &stem).unwrap();
    check(&stem, "Posterior-predictive", (1000, 700));
    let spec = BandOverlaySpec {
        title: "Four panels".into(),
        panels: vec![panel; 4],
        size_px: Some((1100, 800)),
    };
    let stem = out.dir.join("band_overlay_grid");
    band_overlay(&spec, &stem).unwrap();
    check(&stem, "Four panels", (1100, 800));
}

#[test]
fn heatmap_writes() {
    let out = out_dir();
    let rows: Vec<String> = (1..=3)
        .flat_map(|t| (1..=4).map(move |c| format!("test {t} / floor {c}")))
        .collect();
    let cols: Vec<String> = MODES_HZ
        .iter()
        .map(|f| format!("{:.1}–{:.1} Hz", f * 0.96, f * 1.04))
        .collect();
    let values = (0..rows.len())
        .map(|r| {
            (0..cols.len())
                .map(|c| {
                    if r == 4 && c == 2 {
                        f64::NAN
                    } else {
                        ((r * 5 + c * 3) % 11) as f64 * 0.6 - 3.0
                    }
                })
                .collect()
        })
        .collect();
    let spec = HeatmapSpec {
        title: "Residual z-scores per band".into(),
        x_label: "Frequency band".into(),
        y_label: "Test / channel".into(),
        row_labels: rows,
        col_labels: cols,
        values,
        colour_label: "z-score".into(),
        limit: Some(3.0),
        show_values: true,
        size_px: None,
    };
    let stem = out.dir.join("heatmap");
    heatmap(&spec, &stem).unwrap();
    check(&stem, "Residual z-scores", (900, 512));
}

#[test]
fn line_chart_log_axes() {
    let out = out_dir();
    let lags: Vec<f64> = (0..200).map(|l| l as f64).collect();
    let series = (0..3)
        .map(|p| Series {
            label: format!("k{}", p + 1),
            x: lags.clone(),
            y: lags
                .iter()
                .map(|l| (-l / (10.0 + 15.0 * p as f64)).exp())
                .collect(),
            mark: Mark::Line,
        })
        .collect();
    let spec = LineChartSpec {
        title: "Autocorrelation of the chains".into(),
        x_label: "Lag (steps)".into(),
        y_label: "Autocorrelation".into(),
        series,
        y_refs: vec![RefLine {
            value: 0.0,
            label: "zero".into(),
        }],
        ..Default::default()
    };
    let stem = out.dir.join("line_chart");
    line_chart(&spec, &stem).unwrap();
    check(&stem, "Autocorrelation", (1000, 700));

    let eig: Vec<f64> = (0..10).map(|i| 10f64.powf(6.0 - 1.3 * i as f64)).collect();
    let spec = LineChartSpec {
        title: "Fisher information eigenvalues".into(),
        x_label: "Index".into(),
        y_label: "Eigenvalue".into(),
        series: vec![Series {
            label: "eigenvalues".into(),
            x: (1..=10).map(|i| i as f64).collect(),
            y: eig,
            mark: Mark::LineAndPoints,
        }],
        y_scale: Scale::Log,
        y_refs: vec![RefLine {
            value: 1e-3,
            label: "identifiability threshold".into(),
        }],
        ..Default::default()
    };
    let stem = out.dir.join("line_chart_log");
    line_chart(&spec, &stem).unwrap();
    check(&stem, "Fisher information", (1000, 700));
}

/// Empty, NaN, non-positive on log axes, single points and constant data: no panic,
/// files still written.
#[test]
fn edge_cases_do_not_panic() {
    let out = out_dir();
    let d = &out.dir;
    let nan = f64::NAN;
    let weird: Vec<Vec<f64>> = vec![
        vec![],
        vec![nan; 5],
        vec![0.0, -1.0, 0.0, -2.0, 0.0],
        vec![1.0],
        vec![3.0; 5],
        vec![1.0, nan, 0.0, f64::INFINITY, 2.0],
    ];
    for (k, y) in weird.iter().enumerate() {
        let x: Vec<f64> = (0..y.len()).map(|i| i as f64).collect();
        for (sx, sy) in [(Scale::Linear, Scale::Linear), (Scale::Log, Scale::Log)] {
            let spec = LineChartSpec {
                title: format!("edge {k}"),
                series: vec![Series {
                    label: "s".into(),
                    x: x.clone(),
                    y: y.clone(),
                    mark: Mark::LineAndPoints,
                }],
                x_scale: sx,
                y_scale: sy,
                ..Default::default()
            };
            let stem = d.join(format!("edge_line_{k}_{sx:?}"));
            line_chart(&spec, &stem).unwrap();
            check(&stem, &format!("edge {k}"), (1000, 700));
        }
        let spec = FrfMagnitudesSpec {
            title: format!("edge frf {k}"),
            freq_hz: x.clone(),
            channels: vec![ChannelFrf {
                label: "c".into(),
                magnitude: y.clone(),
                coherence: y.clone(),
            }],
            bands: vec![
                FreqBand {
                    lo_hz: 3.0,
                    hi_hz: 1.0,
                },
                FreqBand {
                    lo_hz: nan,
                    hi_hz: 2.0,
                },
            ],
            ..Default::default()
        };
        frf_magnitudes(&spec, &d.join(format!("edge_frf_{k}"))).unwrap();
        let spec = FrfComparisonSpec {
            title: format!("edge cmp {k}"),
            panels: vec![ComparisonPanel {
                experimental: Curve {
                    freq_hz: x.clone(),
                    values: y.clone(),
                },
                ..Default::default()
            }],
            ..Default::default()
        };
        frf_comparison(&spec, &d.join(format!("edge_cmp_{k}"))).unwrap();
        let spec = BarChartSpec {
            title: format!("edge bars {k}"),
            categories: (0..y.len()).map(|i| i.to_string()).collect(),
            groups: vec![BarGroup {
                label: "g".into(),
                values: y.clone(),
            }],
            y_scale: if k % 2 == 0 {
                Scale::Log
            } else {
                Scale::Linear
            },
            show_values: true,
            ..Default::default()
        };
        bar_chart(&spec, &d.join(format!("edge_bars_{k}"))).unwrap();
        let spec = CornerSpec {
            title: format!("edge corner {k}"),
            params: vec![
                CornerParam {
                    name: "a".into(),
                    values: y.clone(),
                    reference: Some(nan),
                    ..Default::default()
                },
                CornerParam {
                    name: "b".into(),
                    values: y.iter().rev().copied().collect(),
                    reference: Some(1.0),
                    ..Default::default()
                },
            ],
            ..Default::default()
        };
        corner(&spec, &d.join(format!("edge_corner_{k}"))).unwrap();
        let spec = TracesSpec {
            title: format!("edge traces {k}"),
            params: vec![TraceParam {
                name: "a".into(),
                walkers: vec![y.clone(), vec![]],
                reference: Some(nan),
                ..Default::default()
            }],
            burn_in: Some(10),
            ..Default::default()
        };
        traces(&spec, &d.join(format!("edge_traces_{k}"))).unwrap();
        let spec = BandOverlaySpec {
            title: format!("edge bands {k}"),
            panels: vec![BandPanel {
                freq_hz: x.clone(),
                median: y.clone(),
                band_95: Some(Interval {
                    lo: y.clone(),
                    hi: y.clone(),
                }),
                measured: Some(Curve {
                    freq_hz: x.clone(),
                    values: y.clone(),
                }),
                ..Default::default()
            }],
            ..Default::default()
        };
        band_overlay(&spec, &d.join(format!("edge_bands_{k}"))).unwrap();
        let spec = HeatmapSpec {
            title: format!("edge heat {k}"),
            row_labels: vec!["r".into()],
            col_labels: (0..y.len()).map(|i| i.to_string()).collect(),
            values: vec![y.clone()],
            show_values: true,
            ..Default::default()
        };
        heatmap(&spec, &d.join(format!("edge_heat_{k}"))).unwrap();
    }
    // Entirely empty specs.
    line_chart(&LineChartSpec::default(), &d.join("empty_line")).unwrap();
    frf_magnitudes(&FrfMagnitudesSpec::default(), &d.join("empty_frf")).unwrap();
    frf_comparison(&FrfComparisonSpec::default(), &d.join("empty_cmp")).unwrap();
    bar_chart(&BarChartSpec::default(), &d.join("empty_bars")).unwrap();
    corner(&CornerSpec::default(), &d.join("empty_corner")).unwrap();
    traces(&TracesSpec::default(), &d.join("empty_traces")).unwrap();
    band_overlay(&BandOverlaySpec::default(), &d.join("empty_bands")).unwrap();
    heatmap(&HeatmapSpec::default(), &d.join("empty_heat")).unwrap();
    check(&d.join("empty_heat"), "<svg", (900, 500));
}

#[test]
fn mismatched_lengths_and_bad_sizes_are_usage_errors() {
    let out = out_dir();
    let spec = LineChartSpec {
        series: vec![Series {
            label: "bad".into(),
            x: vec![1.0, 2.0],
            y: vec![1.0],
            mark: Mark::Line,
        }],
        ..Default::default()
    };
    let e = line_chart(&spec, &out.dir.join("bad")).unwrap_err();
    assert!(
        matches!(&e, Error::Usage(m) if m.contains("\"bad\"")),
        "{e}"
    );
    assert!(!out.dir.join("bad.png").exists());
    let spec = LineChartSpec {
        size_px: Some((10, 10)),
        ..Default::default()
    };
    assert!(matches!(
        line_chart(&spec, &out.dir.join("tiny")),
        Err(Error::Usage(_))
    ));
    let spec = HeatmapSpec {
        row_labels: vec!["a".into()],
        col_labels: vec!["x".into(), "y".into()],
        values: vec![vec![1.0]],
        ..Default::default()
    };
    assert!(matches!(
        heatmap(&spec, &out.dir.join("h")),
        Err(Error::Usage(_))
    ));
    let spec = CornerSpec {
        params: vec![
            CornerParam {
                name: "a".into(),
                values: vec![1.0, 2.0],
                ..Default::default()
            },
            CornerParam {
                name: "b".into(),
                values: vec![1.0],
                ..Default::default()
            },
        ],
        ..Default::default()
    };
    assert!(matches!(
        corner(&spec, &out.dir.join("c")),
        Err(Error::Usage(_))
    ));
    assert!(matches!(
        line_chart(&LineChartSpec::default(), Path::new("")),
        Err(Error::Usage(_))
    ));
}

#[test]
fn existing_figure_is_replaced_atomically() {
    let out = out_dir();
    let stem = out.dir.join("sub/dir/replace");
    let mut spec = LineChartSpec {
        title: "first version".into(),
        ..Default::default()
    };
    line_chart(&spec, &stem).unwrap();
    spec.title = "second version".into();
    line_chart(&spec, &stem).unwrap();
    check(&stem, "second version", (1000, 700));
    // A stem with a dot keeps it: fig.v2 -> fig.v2.png
    let dotted = out.dir.join("fig.v2");
    line_chart(&spec, &dotted).unwrap();
    assert!(out.dir.join("fig.v2.png").exists() && out.dir.join("fig.v2.svg").exists());
}

/// Crowded figures squeezed into the smallest accepted size, and one very wide figure:
/// layouts degrade (overlap) but never panic or fail.
#[test]
fn crowded_and_tiny_figures_still_render() {
    let out = out_dir();
    let d = &out.dir;
    let f = freq_grid(400, 20.0);
    let mag = synthetic_frf(&f, &MODES_HZ, &[1.0, 0.5, 0.3, 0.2], 0.02);
    let long = |i: usize| format!("a rather long label number {i}");
    for (k, size) in [(200, 200), (4000, 200)].into_iter().enumerate() {
        let s = Some(size);
        let spec = FrfMagnitudesSpec {
            title: "tiny frf with a very long title that cannot possibly fit".into(),
            freq_hz: f.clone(),
            channels: (0..30)
                .map(|c| ChannelFrf {
                    label: long(c),
                    magnitude: mag.iter().map(|v| v * (1.0 + c as f64)).collect(),
                    coherence: vec![0.9; f.len()],
                })
                .collect(),
            bands: bands(),
            size_px: s,
            ..Default::default()
        };
        frf_magnitudes(&spec, &d.join(format!("tiny_frf_{k}"))).unwrap();
        check(&d.join(format!("tiny_frf_{k}")), "tiny frf", size);
        let curve = Curve {
            freq_hz: f.clone(),
            values: mag.clone(),
        };
        let panel = ComparisonPanel {
            title: long(0),
            y_label: long(1),
            experimental: curve.clone(),
            initial: Some(curve.clone()),
            updated: Some(curve.clone()),
            fdac_updated: Some(0.9),
            ..Default::default()
        };
        let spec = FrfComparisonSpec {
            title: "tiny cmp".into(),
            panels: vec![panel; 5],
            size_px: s,
        };
        frf_comparison(&spec, &d.join(format!("tiny_cmp_{k}"))).unwrap();
        let spec = BarChartSpec {
            title: "tiny bars".into(),
            categories: (0..30).map(long).collect(),
            groups: (0..4)
                .map(|g| BarGroup {
                    label: long(g),
                    values: (0..30).map(|i| (i + g) as f64).collect(),
                })
                .collect(),
            show_values: true,
            size_px: s,
            ..Default::default()
        };
        bar_chart(&spec, &d.join(format!("tiny_bars_{k}"))).unwrap();
        let spec = CornerSpec {
            title: "tiny corner".into(),
            params: (0..10)
                .map(|p| CornerParam {
                    name: long(p),
                    unit: "N/m".into(),
                    values: (0..500)
                        .map(|i| ((i * (p + 3)) % 17) as f64 * 1e5)
                        .collect(),
                    reference: Some(3e5),
                })
                .collect(),
            size_px: s,
            ..Default::default()
        };
        corner(&spec, &d.join(format!("tiny_corner_{k}"))).unwrap();
        let spec = TracesSpec {
            title: "tiny traces".into(),
            params: (0..10)
                .map(|p| TraceParam {
                    name: long(p),
                    walkers: vec![(0..100).map(|i| (i * p) as f64).collect(); 4],
                    ..Default::default()
                })
                .collect(),
            size_px: s,
            ..Default::default()
        };
        traces(&spec, &d.join(format!("tiny_traces_{k}"))).unwrap();
        let spec = BandOverlaySpec {
            title: "tiny bands".into(),
            panels: vec![
                BandPanel {
                    freq_hz: f.clone(),
                    median: mag.clone(),
                    ..Default::default()
                };
                7
            ],
            size_px: s,
        };
        band_overlay(&spec, &d.join(format!("tiny_bands_{k}"))).unwrap();
        let spec = HeatmapSpec {
            title: "tiny heat".into(),
            row_labels: (0..40).map(long).collect(),
            col_labels: (0..12).map(long).collect(),
            values: vec![(0..12).map(|c| c as f64 - 6.0).collect(); 40],
            show_values: true,
            colour_label: long(0),
            size_px: s,
            ..Default::default()
        };
        heatmap(&spec, &d.join(format!("tiny_heat_{k}"))).unwrap();
        let spec = LineChartSpec {
            title: "tiny lines".into(),
            series: (0..30)
                .map(|i| Series {
                    label: long(i),
                    x: f.clone(),
                    y: mag.clone(),
                    mark: Mark::LineAndPoints,
                })
                .collect(),
            y_scale: Scale::Log,
            size_px: s,
            ..Default::default()
        };
        line_chart(&spec, &d.join(format!("tiny_lines_{k}"))).unwrap();
    }
}
