//! `report.md`, `findings.json`, `posterior.json` and figures of the `wheel-frf` study.
//! Every conclusion comes from [`super::wheel_assess`], which this module only renders.

use std::fmt::Write as _;
use std::path::Path;

use super::posterior::{
    observed_blocks, posterior_summary, write_inference_data, write_summary, ParameterSummary,
    PosteriorSummary, Sampled,
};
use super::report::{md_table, posterior_table, quantile_band_panel, run_line, sig, trace_figure};
use super::wheel::WheelData;
use super::wheel_assess::{assess, Findings, Separation};
use super::wheel_run::{BandResult, WheelStudy, PLOT_CHANNELS, SCATTER_MIN_RESIDUE};
use crate::error::Result;
use crate::plot::{
    band_overlay, bar_chart, corner, frf_magnitudes, BandOverlaySpec, BarChartSpec, BarGroup,
    ChannelFrf, CornerParam, CornerSpec, FreqBand, FrfMagnitudesSpec, Scale,
};

/// Rows of every band with globally numbered names (`f1`, `xi1`, `s_band1`, ...).
pub fn all_rows(s: &WheelStudy) -> Vec<ParameterSummary> {
    let mut out = Vec::new();
    let mut mode = 0;
    for (bi, b) in s.bands.iter().enumerate() {
        let m = b.lik.n_modes();
        for r in 0..m {
            let mut f = b.rows[2 * r].clone();
            f.name = format!("f{}", mode + r + 1);
            let mut xi = b.rows[2 * r + 1].clone();
            xi.name = format!("xi{}", mode + r + 1);
            out.push(f);
            out.push(xi);
        }
        let mut sr = b.rows[2 * m].clone();
        sr.name = format!("s_band{}", bi + 1);
        out.push(sr);
        for r in 0..m {
            let mut a = b.rows[2 * m + 1 + r].clone();
            a.name = format!("mode{} {}", mode + r + 1, a.name);
            out.push(a);
        }
        for q in 0..2 {
            let mut a = b.rows[3 * m + 1 + q].clone();
            a.name = format!("band{} {}", bi + 1, a.name);
            out.push(a);
        }
        mode += m;
    }
    out
}

/// `posterior.json`: all bands, each sampled separately (see [`posterior_summary`] for
/// how the bookkeeping fields combine).
pub fn posterior_file(s: &WheelStudy) -> PosteriorSummary {
    let runs: Vec<&Sampled> = s.bands.iter().map(|b| &b.sampled).collect();
    posterior_summary(
        &runs,
        all_rows(s),
        s.bands.iter().map(|b| b.lik.data.n_points()).sum(),
    )
}

/// `inference_data_band<k>.nc` of one band (each band is a posterior of its own):
/// `f<r>` (Hz) and `xi<r>` of its modes and `s_band<k>`, named as in `posterior.json`
/// ([`all_rows`]; band `band` (0-based) whose first mode is `first_mode`). The residues
/// there are conditional draws, not functions of a posterior draw, and are left out.
fn write_band_inference_data(
    b: &BandResult,
    band: usize,
    first_mode: usize,
    path: &Path,
) -> Result<()> {
    let m = b.lik.n_modes();
    let mut rows = b.rows[..2 * m + 1].to_vec();
    for (i, r) in rows.iter_mut().enumerate() {
        r.name = match (i < 2 * m, i % 2) {
            (true, 0) => format!("f{}", first_mode + i / 2 + 1),
            (true, _) => format!("xi{}", first_mode + i / 2 + 1),
            _ => format!("s_band{}", band + 1),
        };
    }
    // Coordinates: per mode f (Hz) and ln xi, then ln s.
    let reported = |z: &[f64]| {
        z.iter()
            .take(2 * m + 1)
            .enumerate()
            .map(|(i, &v)| if i % 2 == 0 && i < 2 * m { v } else { v.exp() })
            .collect()
    };
    let observed = Some(observed_blocks(&b.lik.posterior));
    write_inference_data(path, &b.sampled, &rows, reported, observed, "wheel-frf")
}

/// Writes everything into `out`.
pub fn write(
    s: &WheelStudy,
    data: &WheelData,
    out: &Path,
    timings: &[(String, f64)],
) -> Result<()> {
    write_summary(&posterior_file(s), &out.join("posterior.json"))?;
    let mut first_mode = 0;
    for (k, b) in s.bands.iter().enumerate() {
        let path = out.join(format!("inference_data_band{}.nc", k + 1));
        write_band_inference_data(b, k, first_mode, &path)?;
        first_mode += b.lik.n_modes();
    }
    let findings = assess(s);
    super::report::write_findings(&findings, out)?;
    figures(s, &findings, data, out)?;
    let md = report(s, &findings, timings);
    crate::io::write_atomic(&out.join("report.md"), md.as_bytes())
}

/// `report.md`: the data and model, each band's posterior, the frequency-against-damping
/// comparison with Au's law, the channel-to-channel scatter, figures and timings.
fn report(s: &WheelStudy, fd: &Findings, timings: &[(String, f64)]) -> String {
    let mut r = String::new();
    intro_section(&mut r);
    band_posteriors_section(&mut r, s);
    au_law_section(&mut r, fd);
    scatter_section(&mut r, s, fd);
    figures_and_timings_section(&mut r, s, timings);
    r
}

/// The title, the data's provenance and the model and likelihood.
fn intro_section(r: &mut String) {
    let _ = writeln!(
        r,
        "# Light-rail wheel: Bayesian modal parameters from measured accelerance\n"
    );
    let _ = writeln!(
        r,
        "Data: `LRV_wheel_FRF.mat` (a university course's hammer test of a resilient \
         wheel, free-free; 12 rim accelerometers, 0-5000 Hz in 1/3 Hz steps; not made by \
         this project; used for validation only). Generated by `frfbayes real wheel-frf`; \
         every number below comes from the run.\n"
    );
    let _ = writeln!(r, "## Model and likelihood\n");
    let _ = writeln!(
        r,
        "Per band, all 12 channels share the poles: `H_c(w) = sum_r A_cr (-w^2) / (w_r^2 - \
         w^2 + 2 j xi_r w_r w) + B_c + D_c (w/w_0)^2`, complex residues `A_cr` and complex \
         out-of-band terms `B_c` (modes below: mass line) and `D_c` (modes above: \
         stiffness line). Each measured value is complex Gaussian with variance \
         `s^2 |H|^2 (1 - gamma^2) / gamma^2` (coherence weights; `1 - gamma^2 >= 1e-4`), \
         `s` sampled. The residues and residual terms enter linearly and are integrated \
         out exactly (flat prior); the ensemble sampler explores `(f_r, ln xi_r, ln s)`, \
         and for each posterior draw the residues are drawn from their exact conditional \
         Gaussian. Priors: `f_r` uniform over the band (ordered within the pair), `xi` \
         log-uniform in [1e-4, 0.2], `s` log-uniform in [1e-3, 1e4].\n"
    );
}

/// Each band's posterior table, sampler line and whitened residual RMS per channel.
fn band_posteriors_section(r: &mut String, s: &WheelStudy) {
    let _ = writeln!(r, "## Posterior per band\n");
    for (bi, b) in s.bands.iter().enumerate() {
        let _ = writeln!(
            r,
            "### Band {}: {} ({}-{} Hz, {} bins x 12 channels)\n",
            bi + 1,
            b.lik.spec.label,
            b.lik.spec.lo_hz,
            b.lik.spec.hi_hz,
            b.lik.data.freq_hz.len()
        );
        let _ = writeln!(r, "{}", posterior_table(&b.rows));
        let _ = writeln!(r, "Sampler: {}\n", run_line(&b.sampled));
        let _ = writeln!(
            r,
            "Whitened residual RMS / s per channel (1 = the coherence weights describe the \
             scatter's shape): {}.\n",
            b.rms_z
                .iter()
                .map(|z| format!("{z:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
}

/// The ratio of damping to frequency c.o.v. per mode against Au's law (`1/xi`), and the
/// verdict.
fn au_law_section(r: &mut String, fd: &Findings) {
    let cmp = &fd.modes;
    let _ = writeln!(r, "## Frequency against damping uncertainty (Au's law)\n");
    let _ = writeln!(
        r,
        "Comparison used (derivation in `src/real/wheel_run.rs`): for a lightly damped \
         mode the pole `lambda = -xi w_n + j w_d` is equally uncertain along both axes (Au \
         2014 for ambient data; for FRF data the Fisher information of `(Re lambda, Im \
         lambda)` is isotropic because the model is holomorphic in `lambda`), so \
         `sd(xi) = cov(f)` and **`cov(xi) / cov(f) = 1 / xi`**. Au's law, `cov(f) ~ \
         sqrt(xi / (2 pi N_c B_f))`, `cov(xi) ~ sqrt(1 / (2 pi xi N_c B_xi))`, gives the \
         same ratio `(1/xi) sqrt(B_f / B_xi) -> 1/xi` for wide bands.\n"
    );
    let rows: Vec<Vec<String>> = cmp
        .iter()
        .enumerate()
        .map(|(i, c)| {
            vec![
                format!("{}", i + 1),
                sig(c.f_hz, 6),
                format!("{:.5}", c.xi),
                format!("{:.2e}", c.cov_f),
                format!("{:.2e}", c.cov_xi),
                format!("{:.0}", c.ratio),
                format!("{:.0}", c.predicted_ratio),
                format!("{:.2}", c.ratio / c.predicted_ratio),
            ]
        })
        .collect();
    let _ = writeln!(
        r,
        "{}",
        md_table(
            &[
                "mode",
                "f (Hz)",
                "xi",
                "cov(f)",
                "cov(xi)",
                "cov(xi)/cov(f)",
                "1/xi",
                "measured / predicted"
            ],
            &rows
        )
    );
    let _ = writeln!(r, "{}", verdict(fd));
}

/// The channel-by-channel fits: the scatter of their estimates against the posterior's
/// c.o.v.s.
fn scatter_section(r: &mut String, s: &WheelStudy, fd: &Findings) {
    let cmp = &fd.modes;
    let _ = writeln!(r, "### Channel-to-channel scatter\n");
    let _ = writeln!(
        r,
        "The posterior assumes independent errors across frequency and channels, so its \
         c.o.v.s are conditional on the model (smooth model error is correlated and makes \
         them too small). An empirical check that includes model error: each channel with \
         a residue of at least {:.0} % of the mode's largest is fitted on its own, and the \
         scatter of the estimates across channels is taken as the uncertainty.\n",
        100.0 * SCATTER_MIN_RESIDUE
    );
    let rows: Vec<Vec<String>> = s
        .scatter
        .iter()
        .zip(cmp)
        .enumerate()
        .map(|(i, (sc, c))| {
            vec![
                format!("{}", i + 1),
                format!("{}", sc.channels.len()),
                sig(sc.f_mean_hz, 6),
                format!("{:.5}", sc.xi_mean),
                format!("{:.2e}", sc.cov_f),
                format!("{:.2e}", sc.cov_xi),
                format!("{:.0}", sc.cov_xi / sc.cov_f),
                format!("{:.0}", 1.0 / sc.xi_mean),
                format!("{:.0}", sc.cov_f / c.cov_f),
                format!("{:.0}", sc.cov_xi / c.cov_xi),
            ]
        })
        .collect();
    let _ = writeln!(
        r,
        "{}",
        md_table(
            &[
                "mode",
                "channels",
                "f mean (Hz)",
                "xi mean",
                "scatter cov(f)",
                "scatter cov(xi)",
                "cov(xi)/cov(f)",
                "1/xi",
                "scatter / posterior cov(f)",
                "scatter / posterior cov(xi)",
            ],
            &rows
        )
    );
    let sc = &fd.scatter;
    let _ = writeln!(
        r,
        "Across channels the damping ratio scatters {:.0}-{:.0} times more (relative) than \
         the natural frequency; over `1/xi` that is {:.2}-{:.2}. The scatter is {:.0}-{:.0} \
         times the posterior sd for the frequency and {:.0}-{:.0} times for the damping: \
         the independent-error posterior is far too confident, but both estimates agree \
         that damping is the poorly identified parameter.\n",
        sc.cov_ratio.min,
        sc.cov_ratio.max,
        sc.cov_ratio_over_inverse_xi.min,
        sc.cov_ratio_over_inverse_xi.max,
        sc.f_scatter_over_posterior.min,
        sc.f_scatter_over_posterior.max,
        sc.xi_scatter_over_posterior.min,
        sc.xi_scatter_over_posterior.max,
    );
}

/// The list of figures and the stage timings (seconds).
fn figures_and_timings_section(r: &mut String, s: &WheelStudy, timings: &[(String, f64)]) {
    let _ = writeln!(r, "## Figures\n");
    let _ = writeln!(
        r,
        "- `overview.png/.svg`: measured |H| and coherence of channels 1-3, analysis bands shaded"
    );
    for bi in 0..s.bands.len() {
        let _ = writeln!(
            r,
            "- `band{}_frf.png/.svg`: measured |H| (points) and the posterior of the model |H| (median, 50% and 95% bands), channels 1-4",
            bi + 1
        );
    }
    let _ = writeln!(
        r,
        "- `cov.png/.svg`: c.o.v. of natural frequency and damping ratio per mode, and cov(f)/xi"
    );
    let _ = writeln!(r, "- `pair_corner.png/.svg`, `pair_traces.png/.svg`: the close pair's posterior and walker traces");
    let _ = writeln!(r, "\n## Timings\n");
    for (stage, t) in timings {
        let _ = writeln!(r, "- {stage}: {t:.2} s");
    }
}

fn verdict(fd: &Findings) -> String {
    let orders = match fd.separation {
        Separation::TwoOrdersOrMore => "two orders of magnitude or more",
        Separation::AtLeastOneOrder => "at least an order of magnitude",
        Separation::LessThanOneOrderForSomeModes => {
            "less than an order of magnitude for some modes"
        }
    };
    format!(
        "Damping is the poorly identified parameter: its c.o.v. is {:.0}-{:.0} times the \
         frequency's ({orders}). Measured / predicted ratio `cov(xi)/cov(f)` over `1/xi`: \
         {:.2}-{:.2}; {} of {} modes within a factor 2 of Au's law.\n",
        fd.cov_ratio.min,
        fd.cov_ratio.max,
        fd.measured_over_predicted.min,
        fd.measured_over_predicted.max,
        fd.n_within_factor_2,
        fd.modes.len()
    )
}

/// Every figure of the study: the overview, each band's FRF posterior, the c.o.v.s and
/// the close pair's corner plot and traces.
fn figures(s: &WheelStudy, fd: &Findings, data: &WheelData, out: &Path) -> Result<()> {
    overview_figure(s, data, out)?;
    for (bi, b) in s.bands.iter().enumerate() {
        band_figure(bi, b, out)?;
    }
    cov_figure(fd, out)?;
    pair_figures(s, out)
}

/// `overview`: measured |H| and coherence of channels 1-3, the analysis bands shaded.
fn overview_figure(s: &WheelStudy, data: &WheelData, out: &Path) -> Result<()> {
    let chans = [0usize, 1, 2];
    frf_magnitudes(
        &FrfMagnitudesSpec {
            title: "Wheel: measured accelerance and coherence".into(),
            y_label: "|H| ((m/s²)/N)".into(),
            freq_hz: data.freq_hz.clone(),
            channels: chans
                .iter()
                .map(|&c| ChannelFrf {
                    label: format!("channel {} ({} deg)", c + 1, 15 * c),
                    magnitude: data.frf[c].iter().map(|h| h.norm()).collect(),
                    coherence: data.coherence[c].clone(),
                })
                .collect(),
            bands: s
                .bands
                .iter()
                .map(|b| FreqBand {
                    lo_hz: b.lik.spec.lo_hz,
                    hi_hz: b.lik.spec.hi_hz,
                })
                .collect(),
            size_px: None,
        },
        &out.join("overview"),
    )
}

/// `band<k>_frf` of band `bi` (0-based): measured |H| and the posterior of the model's
/// (median, 50 % and 95 % bands) on the plotted channels.
fn band_figure(bi: usize, b: &BandResult, out: &Path) -> Result<()> {
    let f = &b.lik.data.freq_hz;
    let panels = PLOT_CHANNELS
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            quantile_band_panel(
                format!("channel {} ({} deg)", c + 1, 15 * c),
                f,
                &b.bands_abs[i],
                &b.lik.data.y[c],
            )
        })
        .collect();
    band_overlay(
        &BandOverlaySpec {
            title: format!(
                "Band {}: {} — model posterior and measurement",
                bi + 1,
                b.lik.spec.label
            ),
            panels,
            size_px: None,
        },
        &out.join(format!("band{}_frf", bi + 1)),
    )
}

/// `cov`: the posterior c.o.v. of natural frequency and damping ratio per mode, and
/// cov(f) / xi (the damping c.o.v. Au's law predicts).
fn cov_figure(fd: &Findings, out: &Path) -> Result<()> {
    let cmp = &fd.modes;
    bar_chart(
        &BarChartSpec {
            title: "Posterior c.o.v. of natural frequency and damping ratio".into(),
            x_label: "Mode (natural frequency)".into(),
            y_label: "Coefficient of variation".into(),
            categories: cmp.iter().map(|c| format!("{:.0} Hz", c.f_hz)).collect(),
            groups: vec![
                BarGroup {
                    label: "cov(f)".into(),
                    values: cmp.iter().map(|c| c.cov_f).collect(),
                },
                BarGroup {
                    label: "cov(xi)".into(),
                    values: cmp.iter().map(|c| c.cov_xi).collect(),
                },
                BarGroup {
                    label: "cov(f) / xi (predicted cov(xi))".into(),
                    values: cmp.iter().map(|c| c.cov_f / c.xi).collect(),
                },
            ],
            y_scale: Scale::Log,
            show_values: false,
            size_px: None,
        },
        &out.join("cov"),
    )
}

/// `pair_corner` and `pair_traces`: the posterior and walker traces of the band with the
/// close pair of modes (if any).
fn pair_figures(s: &WheelStudy, out: &Path) -> Result<()> {
    if let Some(pair) = s.bands.iter().find(|b| b.lik.n_modes() == 2) {
        let names = ["f_a", "xi_a", "f_b", "xi_b", "s"];
        let units = ["Hz", "", "Hz", "", ""];
        let tf = |p: usize, v: f64| if p % 2 == 1 || p == 4 { v.exp() } else { v };
        let params = (0..5)
            .map(|p| CornerParam {
                name: names[p].into(),
                unit: units[p].into(),
                values: pair.sampled.chains(p, |v| tf(p, v)).concat(),
                reference: None,
            })
            .collect();
        corner(
            &CornerSpec {
                title: format!("Close pair {}: posterior", pair.lik.spec.label),
                params,
                ..Default::default()
            },
            &out.join("pair_corner"),
        )?;
        let nm: Vec<(String, String)> = (0..5)
            .map(|p| (names[p].to_string(), units[p].to_string()))
            .collect();
        trace_figure(
            &pair.sampled,
            &nm,
            &tf,
            "Close pair: walker traces",
            &out.join("pair_traces"),
        )?;
    }
    Ok(())
}
