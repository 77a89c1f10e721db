//! `report.md`, `findings.json`, `posterior.json` and figures of the `tower-hmd` study.
//! Every number in the report comes from the run; every conclusion from
//! [`super::tower_assess`], which this module only renders.

use std::fmt::Write as _;
use std::path::Path;

use super::posterior::{
    observed_blocks, posterior_summary, write_inference_data, write_summary, PosteriorSummary,
    INFERENCE_DATA_FILE,
};
use super::report::{md_table, posterior_table, quantile_band_panel, run_line, sig, trace_figure};
use super::tower::{AUTHOR_GAINS, DAMPER_MASS_KG, FLOOR_COLUMN, FLOOR_MASS_KG};
use super::tower_assess::{assess, Findings, FrequencyRatios, FLOOR_OUTLIER_RATIO};
use super::tower_model::{natural_freq_hz, N};
use super::tower_residuals::{
    ResidualAnalysis, MODE_HALF_WIDTH_HZ, PEAK_HALF_WINDOW_HZ, PEAK_MIN_RATIO, REPRODUCED_FREQ_TOL,
    REPRODUCED_MAC,
};
use super::tower_run::{TowerFit, TowerStudy};
use crate::error::Result;
use crate::plot::{band_overlay, heatmap, BandOverlaySpec, HeatmapSpec};

/// `posterior.json`: the full-band fit's parameters (k, xi, s, gains) then the derived
/// frequencies.
pub fn posterior_file(s: &TowerStudy) -> PosteriorSummary {
    let f = &s.full;
    posterior_summary(
        &[&f.sampled],
        f.rows.iter().chain(&f.freq_rows).cloned().collect(),
        f.lik.data.n_points(),
    )
}

/// `inference_data.nc` of the fit: stiffnesses, damping ratios, `s` and the natural
/// frequencies of `posterior.json` (the channel gains there are conditional draws, not
/// functions of a posterior draw, and are left out).
fn write_tower_inference_data(f: &TowerFit, out: &Path) -> Result<()> {
    let rows: Vec<_> = f.rows[..2 * N + 1]
        .iter()
        .chain(&f.freq_rows)
        .cloned()
        .collect();
    let reported = |z: &[f64]| {
        let mut v: Vec<f64> = z[..2 * N + 1].iter().map(|x| x.exp()).collect();
        let freq = natural_freq_hz(&v[..N]).unwrap_or_else(|_| vec![f64::NAN; N]);
        v.extend(freq);
        v
    };
    write_inference_data(
        &out.join(INFERENCE_DATA_FILE),
        &f.sampled,
        &rows,
        reported,
        Some(observed_blocks(f.lik.posterior())),
        "tower-hmd",
    )
}

/// Writes `report.md`, `findings.json`, `posterior.json` and figures into `out`.
pub fn write(s: &TowerStudy, out: &Path, timings: &[(String, f64)]) -> Result<()> {
    let findings = assess(s);
    super::report::write_findings(&findings, out)?;
    write_summary(&posterior_file(s), &out.join("posterior.json"))?;
    write_tower_inference_data(&s.full, out)?;
    figures(s, out)?;
    let md = report(s, &findings, timings);
    crate::io::write_atomic(&out.join("report.md"), md.as_bytes())
}

fn band_label(b: (f64, f64)) -> String {
    format!("{}-{} Hz", b.0, b.1)
}

fn peak_table(a: &ResidualAnalysis) -> String {
    let mut headers = vec![
        "measured peak (Hz)".to_string(),
        "nearest model mode".into(),
        "model f (Hz)".into(),
        "f error (%)".into(),
        "MAC".into(),
    ];
    headers.extend((1..=N).map(|c| format!("RMS z floor {c}")));
    headers.push("reproduced".into());
    let hdr: Vec<&str> = headers.iter().map(String::as_str).collect();
    let rows: Vec<Vec<String>> = a
        .peaks
        .iter()
        .map(|p| {
            let mut row = vec![
                format!("{:.3}", p.peak.freq_hz),
                format!("{}", p.mode + 1),
                format!("{:.3}", p.model_freq_hz),
                format!("{:+.1}", 100.0 * p.freq_error()),
                format!("{:.3}", p.mac),
            ];
            row.extend(p.rms_z.iter().map(|z| format!("{z:.1}")));
            row.push(if p.reproduced() { "yes" } else { "no" }.into());
            row
        })
        .collect();
    md_table(&hdr, &rows)
}

/// `v` joined by ", " (each through `item`), or "none".
fn list_or_none<T>(v: &[T], item: impl Fn(&T) -> String, sep: &str) -> String {
    if v.is_empty() {
        "none".into()
    } else {
        v.iter().map(item).collect::<Vec<_>>().join(sep)
    }
}

fn fit_section(r: &mut String, f: &TowerFit) {
    let _ = writeln!(r, "{}", posterior_table(&f.rows));
    let _ = writeln!(
        r,
        "(`g_c` are drawn conditionally, so their `tau` is not defined.)\n"
    );
    let _ = writeln!(r, "Natural frequencies of the sampled models:\n");
    let _ = writeln!(r, "{}", posterior_table(&f.freq_rows));
    let _ = writeln!(r, "Sampler: {}\n", run_line(&f.sampled));
    let _ = writeln!(
        r,
        "Start: 32-start least squares with signed gains, {} of which reached the best cost.\n",
        f.n_at_best
    );
}

/// `report.md`: the data, the FRF estimation and model, the two posteriors, where the
/// shear model fails, the figures and the stage timings.
fn report(s: &TowerStudy, fd: &Findings, timings: &[(String, f64)]) -> String {
    let mut r = String::new();
    intro_section(&mut r, s);
    posteriors_section(&mut r, s, fd);
    failures_section(&mut r, s, fd);
    figures_and_timings_section(&mut r, timings);
    r
}

/// The title, the data's provenance, the FRF estimation and the model.
fn intro_section(r: &mut String, s: &TowerStudy) {
    let f = &s.full;
    let _ = writeln!(
        r,
        "# Unison Tower: damper-force FRFs against a 5-story shear model\n"
    );
    let _ = writeln!(
        r,
        "Data: three white-noise records (40960 samples at 100 Hz each) of a building \
         forced by its hybrid mass damper on the 5th floor (repository \
         eunchurn/system-identification-unison-tower-matlab; no licence, used for \
         validation only). Generated by `frfbayes real tower-hmd`; every number below \
         comes from the run.\n"
    );
    let _ = writeln!(r, "## FRF estimation\n");
    let _ = writeln!(
        r,
        "Input: the damper force on the building `F = -m_d a_d`, `m_d` = {} kg (the \
         author's 1.5 tf), `a_d` = column 2 x {}. Outputs: floors 1-5 (columns {}) with \
         the author's gains {}. Welch H1 with Hann segments of {} samples ({:.2} s, \
         {:.4} Hz resolution), 50% overlap, {} segments over the three records.\n",
        DAMPER_MASS_KG,
        AUTHOR_GAINS[1],
        FLOOR_COLUMN
            .iter()
            .map(|c| (c + 1).to_string())
            .collect::<Vec<_>>()
            .join(", "),
        FLOOR_COLUMN
            .iter()
            .map(|&c| format!("{}", AUTHOR_GAINS[c]))
            .collect::<Vec<_>>()
            .join(", "),
        s.frf.segment_len,
        s.frf.segment_len as f64 / 100.0,
        100.0 / s.frf.segment_len as f64,
        s.frf.n_segments
    );
    let _ = writeln!(r, "## Model\n");
    let _ = writeln!(
        r,
        "5-story shear frame, floor masses fixed at the author's {:.1} kg (a mass scale and \
         a gain scale cannot be told apart), story stiffnesses `k1-k5`, modal damping \
         `xi1-xi5`, a real gain `g_c` per floor channel relative to the author's \
         calibration (force and acceleration gains together), and a noise scale `s` on \
         the H1 variance `|H|^2 (1 - gamma^2) / (n_d gamma^2)`: `s = 1` means the \
         estimator noise explains the scatter. The gains are integrated out exactly \
         (flat prior on the real line) and drawn from their conditional Gaussian for \
         every posterior draw; the sampler explores `ln k`, `ln xi`, `ln s` (priors \
         log-uniform: `k` within a factor 10 of 2.5e6 N/m, `xi` in [0.002, 0.3]). Two \
         fits: the whole band {} ({} bins x 5 floors; the posterior of `posterior.json`) \
         and the band of the first two modes only, {}.\n",
        FLOOR_MASS_KG,
        band_label(f.band_hz),
        f.lik.data.freq_hz.len(),
        band_label(s.low.band_hz)
    );
}

/// The whole-band posterior with its gain signs and ratios, then the posterior of the
/// first two modes.
fn posteriors_section(r: &mut String, s: &TowerStudy, fd: &Findings) {
    let f = &s.full;
    let _ = writeln!(r, "## Posterior, whole band {}\n", band_label(f.band_hz));
    fit_section(r, f);
    let flipped = &fd.negative_gain_floors;
    let _ = writeln!(
        r,
        "Gains whose 95% interval is negative: {}{}. Gain magnitudes relative to floor \
         1: {}.\n",
        list_or_none(flipped, |c| format!("floor {c}"), ", "),
        if flipped.len() == N {
            " (all five: most simply one sign, that of the force channel, opposite to the \
             author's convention, rather than five calibration errors)"
        } else {
            ""
        },
        fd.gain_ratio_to_floor1
            .iter()
            .map(|g| format!("{g:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        r,
        "## Posterior, first two modes only ({})\n",
        band_label(s.low.band_hz)
    );
    fit_section(r, &s.low);
}

/// Per measured resonance and floor, the MAC and standardised residuals of both fits,
/// and the account of where the fit fails.
fn failures_section(r: &mut String, s: &TowerStudy, fd: &Findings) {
    let f = &s.full;
    let _ = writeln!(
        r,
        "## Where the shear model fails: per mode and per floor\n"
    );
    let _ = writeln!(
        r,
        "Measured resonances are found from the data alone (local maxima of the \
         channel-normalised power within +-{PEAK_HALF_WINDOW_HZ} Hz, above \
         {PEAK_MIN_RATIO} times its median). For each: the nearest model mode, the MAC of \
         the measured operating shape `Im(H1_c) / g_c` with that mode's shape, and the RMS \
         standardised residual `|H1 - H_model| / sd(H1)` of each floor within \
         +-{MODE_HALF_WIDTH_HZ} Hz (sd from the coherence and {} segments; 1 is the \
         estimator noise). Reproduced: frequency within {:.0} % plus one bin and MAC \
         above {REPRODUCED_MAC}.\n",
        s.frf.n_segments,
        100.0 * REPRODUCED_FREQ_TOL
    );
    let _ = writeln!(
        r,
        "Whole-band fit (posterior median, s = {}):\n",
        sig(f.rows[2 * N].q50, 3)
    );
    let _ = writeln!(r, "{}", peak_table(&s.residuals));
    let _ = writeln!(
        r,
        "Fit to the first two modes ({}; s = {}), evaluated over the whole band (peaks \
         above {} Hz are predictions):\n",
        band_label(s.low.band_hz),
        sig(s.low.rows[2 * N].q50, 3),
        s.low.band_hz.1
    );
    let _ = writeln!(r, "{}", peak_table(&s.residuals_low));
    let _ = writeln!(r, "{}", failure_summary(s, fd));
}

/// The list of figures and the stage timings (seconds).
fn figures_and_timings_section(r: &mut String, timings: &[(String, f64)]) {
    let _ = writeln!(r, "## Figures\n");
    let _ = writeln!(r, "- `frf_fit.png/.svg`: measured |H1| and the posterior of the whole-band model |H| per floor");
    let _ = writeln!(r, "- `residual_map.png/.svg`, `residual_map_low.png/.svg`: log10 RMS standardised residual per floor at each measured peak (whole-band fit; fit to the first two modes)");
    let _ = writeln!(
        r,
        "- `traces.png/.svg`: walker traces of the stiffnesses (whole-band fit)\n"
    );
    let _ = writeln!(r, "## Timings\n");
    for (stage, t) in timings {
        let _ = writeln!(r, "- {stage}: {t:.2} s");
    }
}

/// The account of where the fit fails.
fn failure_summary(s: &TowerStudy, fd: &Findings) -> String {
    let mut out = String::new();
    whole_band_failures(&mut out, s, fd);
    low_band_failures(&mut out, s, fd);
    let _ = writeln!(
        out,
        "{}",
        fd.frequency_ratios
            .as_ref()
            .map(frequency_ratios)
            .unwrap_or_default()
    );
    let _ = writeln!(
        out,
        "- Reading: residuals an order of magnitude above the estimator noise at resonances \
         the chain cannot place, or with shapes it cannot form, are missing physics, not \
         noise. Candidates to test as model extensions (the `diagnose` command): \
         flexural (cantilever) behaviour; more storeys than the five measured; torsion \
         from an eccentric damper; a local response of the damper floor; and, where one \
         floor stands out, calibration or mounting of that channel."
    );
    out
}

/// The failure account's lines on the whole-band fit: resonances reproduced and missed,
/// the residuals per floor, and parameters at a prior bound.
fn whole_band_failures(out: &mut String, s: &TowerStudy, fd: &Findings) {
    let _ = writeln!(
        out,
        "- Whole-band fit: {} of {} measured resonances reproduced ({}); not reproduced: \
         {}. Model modes in the band that no measured peak is nearest to: {}. The model \
         misses the data by s = {} times the estimator noise overall (RMS |z| {:.1}).",
        fd.reproduced_peaks_hz.len(),
        s.residuals.peaks.len(),
        list_or_none(&fd.reproduced_peaks_hz, |f| format!("{f:.2} Hz"), ", "),
        list_or_none(
            &fd.missed_peaks,
            |p| format!(
                "{:.2} Hz (model mode {} at {:.2} Hz, MAC {:.2})",
                p.freq_hz, p.model_mode, p.model_freq_hz, p.mac
            ),
            "; "
        ),
        list_or_none(
            &fd.unmatched_modes,
            |m| format!("mode {} ({:.2} Hz)", m.mode, m.freq_hz),
            ", "
        ),
        sig(fd.noise_scale, 3),
        fd.rms_z_total
    );
    let _ = writeln!(
        out,
        "- Per floor over the whole band, RMS |z| = {} (floors 1-5); worst floor {}, best \
         floor {}. Floors above {FLOOR_OUTLIER_RATIO} times the median floor: {}.",
        fd.rms_z_floor
            .iter()
            .map(|z| format!("{z:.1}"))
            .collect::<Vec<_>>()
            .join(", "),
        fd.worst_floor,
        fd.best_floor,
        list_or_none(&fd.outlier_floors, |c| c.to_string(), ", ")
    );
    if !fd.at_bound.is_empty() {
        let _ = writeln!(
            out,
            "- At a prior bound in the whole-band fit: {}. A stiffness at its upper bound \
             means the fit wants that story rigid (the floors above and below moving as \
             one): the five-floor chain gives up one of its own modes to reach the \
             measured shapes.",
            list_or_none(&fd.at_bound, |b| format!("{} ({})", b.name, b.side), ", ")
        );
    }
}

/// The failure account's line on the fit to the first two modes, inside its band and
/// above it.
fn low_band_failures(out: &mut String, s: &TowerStudy, fd: &Findings) {
    let f = &s.full;
    let (lo_in, lo_out) = (&fd.low_inside, &fd.low_above);
    let _ = writeln!(
        out,
        "- Fit to the first two modes: s = {}; at the measured peaks RMS |z| {:.1} inside \
         its band ({} peaks, {} reproduced) and {:.1} above it ({} peaks, {} reproduced: \
         the low modes do not predict the higher ones). Natural frequencies {} Hz (whole \
         band: {} Hz).",
        sig(fd.low_noise_scale, 3),
        lo_in.rms_z,
        lo_in.n_peaks,
        lo_in.n_reproduced,
        lo_out.rms_z,
        lo_out.n_peaks,
        lo_out.n_reproduced,
        s.low
            .freq_rows
            .iter()
            .map(|r| sig(r.q50, 3))
            .collect::<Vec<_>>()
            .join(", "),
        f.freq_rows
            .iter()
            .map(|r| sig(r.q50, 3))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

fn frequency_ratios(q: &FrequencyRatios) -> String {
    let n = q.measured.len();
    let list = |v: &[f64]| {
        v.iter()
            .take(n)
            .map(|x| format!("{x:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "- Frequency ratios `f_n / f_1` of the measured peaks: {}; a uniform 5-story shear \
         chain: {}; a uniform flexural cantilever: {}. Peaks whose ratio lies above the \
         shear chain's and below the cantilever's (a mix of shear and flexure): {}.",
        list(&q.measured),
        list(&q.shear_chain),
        list(&q.cantilever),
        list_or_none(&q.between_shear_and_flexure, |n| n.to_string(), ", ")
    )
}

fn figures(s: &TowerStudy, out: &Path) -> Result<()> {
    let f = &s.full.lik.data.freq_hz;
    let panels = (0..N)
        .map(|c| {
            quantile_band_panel(
                format!("floor {}", c + 1),
                f,
                &s.bands_abs[c],
                &s.full.lik.data.y[c],
            )
        })
        .collect();
    band_overlay(
        &BandOverlaySpec {
            title: "Unison Tower: damper force to floor acceleration".into(),
            panels,
            size_px: None,
        },
        &out.join("frf_fit"),
    )?;
    for (a, stem, what) in [
        (&s.residuals, "residual_map", "whole-band fit"),
        (
            &s.residuals_low,
            "residual_map_low",
            "fit to the first two modes",
        ),
    ] {
        heatmap(
            &HeatmapSpec {
                title: format!(
                    "Where the shear model fails ({what}): log10 RMS standardised residual"
                ),
                x_label: "Measured resonance".into(),
                y_label: "Floor".into(),
                row_labels: (1..=N).map(|c| format!("floor {c}")).collect(),
                col_labels: a
                    .peaks
                    .iter()
                    .map(|p| format!("{:.2} Hz", p.peak.freq_hz))
                    .collect(),
                values: (0..N)
                    .map(|c| a.peaks.iter().map(|p| p.rms_z[c].log10()).collect())
                    .collect(),
                colour_label: "log10 RMS |z|".into(),
                limit: None,
                show_values: true,
                size_px: None,
            },
            &out.join(stem),
        )?;
    }
    let names: Vec<(String, String)> = (0..N)
        .map(|i| (format!("ln k{}", i + 1), String::new()))
        .collect();
    trace_figure(
        &s.full.sampled,
        &names,
        &|_, x| x,
        "Tower: walker traces (ln stiffness)",
        &out.join("traces"),
    )
}
