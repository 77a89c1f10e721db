//! Renders the bridge study ([`super::bridge_run::BridgeStudy`]) and its findings
//! ([`super::bridge_assess`]): `report.md`, `findings.json`, `smu.json`,
//! `posterior.json`, tables (Markdown and CSV) and figures (PNG and SVG). Nothing here
//! computes a finding; it formats what the study and its assessment computed.

use std::path::Path;

use super::bridge::{smu_bounds, SMU_PUBLISHED_ALPHA, SMU_PUBLISHED_OBJECTIVE};
use super::bridge_assess::{assess, Findings};
use super::bridge_run::{BridgeStudy, SmuFit};
use super::posterior::{
    posterior_summary, write_inference_data, write_summary, INFERENCE_DATA_FILE,
};
use super::report::{md_table, posterior_table, run_line, sig, trace_figure};
use crate::error::{Error, Result};
use crate::io::write_atomic;
use crate::plot::{
    bar_chart, line_chart, BarChartSpec, BarGroup, LineChartSpec, Mark, RefLine, Scale, Series,
};

/// SMU's own time for 100 starts (fmincon, its analytic Jacobian), from its results.
const SMU_WALL_S: f64 = 4593.0;
const SMU_MEDIAN_START_S: f64 = 41.0;

fn write_json(path: &Path, v: &serde_json::Value) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(v).map_err(|e| Error::Numerical(e.to_string()))?;
    write_atomic(path, &bytes)
}

/// `smu.json`: the SMU-weighting fit in SMU's order.
fn smu_json(fit: &SmuFit) -> serde_json::Value {
    serde_json::json!({
        "alpha": fit.alpha,
        "objective": fit.objective,
        "n_starts": fit.n_starts,
        "n_reached": fit.n_reached,
        "wall_s": fit.wall_s + fit.polish_s,
        "multistart_wall_s": fit.wall_s,
        "polish_wall_s": fit.polish_s,
        "threads": fit.threads,
        "objective_reduced_basis": fit.objective_reduced,
        "weighting": fit.weighting,
        "on_bound": fit.on_bound,
        "gradient": fit.gradient,
    })
}

/// Writes every output of the study into `out`.
pub fn write(study: &BridgeStudy, out: &Path, timings: &[(String, f64)]) -> Result<()> {
    let findings = assess(study);
    super::report::write_findings(&findings, out)?;
    write_json(&out.join("smu.json"), &smu_json(&study.smu))?;
    write_json(&out.join("smu_per_entry.json"), &smu_json(&study.per_entry))?;
    write_json(
        &out.join("basis_check.json"),
        &serde_json::to_value(&study.basis).map_err(|e| Error::Numerical(e.to_string()))?,
    )?;
    let post = &study.posterior;
    let summary = posterior_summary(&[&post.sampled], post.rows.clone(), 5 + 5 * 57);
    write_summary(&summary, &out.join("posterior.json"))?;
    // The reported parameters are the sampled coordinates themselves.
    write_inference_data(
        &out.join(INFERENCE_DATA_FILE),
        &post.sampled,
        &post.rows,
        <[f64]>::to_vec,
        Some(post.observed.clone()),
        "bridge-fe",
    )?;
    let (fit_md, fit_csv) = fit_table(study);
    write_atomic(&out.join("smu_fit.csv"), fit_csv.as_bytes())?;
    let (post_md, post_csv) = identification_table(study);
    write_atomic(&out.join("identification.csv"), post_csv.as_bytes())?;
    let (pred_md, pred_csv) = predictive_table(&findings);
    write_atomic(&out.join("predictive.csv"), pred_csv.as_bytes())?;
    figures(study, &findings, out)?;
    let tables = Tables {
        fit_md,
        post_md,
        pred_md,
    };
    let md = report_md(study, &findings, &tables, timings);
    write_atomic(&out.join("report.md"), md.as_bytes())
}

fn bound_str(b: i8) -> &'static str {
    match b {
        -1 => "lower",
        1 => "upper",
        _ => "",
    }
}

#[allow(clippy::needless_range_loop)] // j indexes parallel arrays
fn fit_table(study: &BridgeStudy) -> (String, String) {
    let bounds = smu_bounds();
    let (s, p) = (&study.smu, &study.per_entry);
    let mut rows = Vec::new();
    let mut csv = String::from(
        "alpha,lower,upper,smu_published,ours_smu,dev_box_frac,ours_per_entry,df_dalpha_smu\n",
    );
    for j in 0..17 {
        let w = bounds[j].1 - bounds[j].0;
        let dev = (s.alpha[j] - SMU_PUBLISHED_ALPHA[j]).abs() / w;
        rows.push(vec![
            study.names[j].clone(),
            format!("[{}, {}]", bounds[j].0, bounds[j].1),
            format!("{}", SMU_PUBLISHED_ALPHA[j]),
            format!("{:.4} {}", s.alpha[j], bound_str(s.on_bound[j])),
            format!("{dev:.1e}"),
            format!("{:.4} {}", p.alpha[j], bound_str(p.on_bound[j])),
            sig(s.gradient[j], 3),
        ]);
        csv += &format!(
            "{},{},{},{},{},{},{},{}\n",
            study.names[j],
            bounds[j].0,
            bounds[j].1,
            SMU_PUBLISHED_ALPHA[j],
            s.alpha[j],
            dev,
            p.alpha[j],
            s.gradient[j]
        );
    }
    let md = md_table(
        &[
            "alpha",
            "box",
            "SMU published",
            "ours (SMU weighting)",
            "|ours - SMU| / width",
            "ours (per-entry weighting)",
            "df/dalpha at ours",
        ],
        &rows,
    );
    (md, csv)
}

#[allow(clippy::needless_range_loop)] // j indexes parallel arrays
fn identification_table(study: &BridgeStudy) -> (String, String) {
    let post = &study.posterior;
    let bounds = smu_bounds();
    let mut rows = Vec::new();
    let mut csv =
        String::from("alpha,lower,upper,map,mean,sd,q2_5,q97_5,sd_over_prior_sd,verdict\n");
    for j in 0..17 {
        let r = &post.rows[j];
        let ratio = r.sd / post.prior_sd[j];
        rows.push(vec![
            study.names[j].clone(),
            format!("[{}, {}]", bounds[j].0, bounds[j].1),
            format!("{:.4}", study.per_entry.alpha[j]),
            format!("{:.4}", r.mean),
            format!("[{:.4}, {:.4}]", r.q2_5, r.q97_5),
            format!("{ratio:.3}"),
            post.verdicts[j].label().into(),
        ]);
        csv += &format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            study.names[j],
            bounds[j].0,
            bounds[j].1,
            study.per_entry.alpha[j],
            r.mean,
            r.sd,
            r.q2_5,
            r.q97_5,
            ratio,
            post.verdicts[j].label()
        );
    }
    let md = md_table(
        &[
            "alpha",
            "prior box",
            "optimum (per-entry)",
            "posterior mean",
            "95% interval",
            "sd / prior sd",
            "what the 5 modes say",
        ],
        &rows,
    );
    (md, csv)
}

fn predictive_table(fd: &Findings) -> (String, String) {
    let mut rows = Vec::new();
    let mut csv = String::from("mode,freq_meas_hz,freq_sd_hz,freq_q50_hz,freq_q2_5_hz,freq_q97_5_hz,z,mac_q50,mac_q2_5,mac_q97_5\n");
    for (i, m) in fd.predictive.iter().enumerate() {
        let (f50, flo, fhi) = (m.freq_hz.q50, m.freq_hz.q2_5, m.freq_hz.q97_5);
        let (m50, mlo, mhi) = (m.mac.q50, m.mac.q2_5, m.mac.q97_5);
        let z = m.z;
        rows.push(vec![
            format!("{}", i + 1),
            format!("{:.4} ± {:.4}", m.freq_meas_hz, m.freq_sd_hz),
            format!("{f50:.4} [{flo:.4}, {fhi:.4}]"),
            format!("{z:+.2}"),
            format!("{m50:.4} [{mlo:.4}, {mhi:.4}]"),
        ]);
        csv += &format!(
            "{},{},{},{f50},{flo},{fhi},{z},{m50},{mlo},{mhi}\n",
            i + 1,
            m.freq_meas_hz,
            m.freq_sd_hz
        );
    }
    let md = md_table(
        &[
            "mode",
            "measured f (Hz) ± test scatter",
            "predicted f: median [95%]",
            "(median - measured) / scatter",
            "MAC with the measured shape: median [95%]",
        ],
        &rows,
    );
    (md, csv)
}

fn figures(study: &BridgeStudy, fd: &Findings, out: &Path) -> Result<()> {
    let post = &study.posterior;
    let names: Vec<String> = study.names.clone();
    bar_chart(
        &BarChartSpec {
            title: "Bridge: posterior sd over prior sd of each alpha (1 = the data say nothing)"
                .into(),
            x_label: "Stiffness group".into(),
            y_label: "sd / prior sd".into(),
            categories: names.clone(),
            groups: vec![BarGroup {
                label: String::new(),
                values: (0..17)
                    .map(|j| post.rows[j].sd / post.prior_sd[j])
                    .collect(),
            }],
            y_scale: Scale::Log,
            show_values: false,
            size_px: None,
        },
        &out.join("fig_contraction"),
    )?;
    let bounds = smu_bounds();
    let unit = |j: usize, v: f64| (v - bounds[j].0) / (bounds[j].1 - bounds[j].0);
    let x: Vec<f64> = (1..=17).map(|j| j as f64).collect();
    let series = |label: &str, f: &dyn Fn(usize) -> f64, mark| Series {
        label: label.into(),
        x: x.clone(),
        y: (0..17).map(|j| unit(j, f(j))).collect(),
        mark,
    };
    line_chart(
        &LineChartSpec {
            title: "Bridge: where each alpha sits in its box (0 = lower, 1 = upper bound)".into(),
            x_label: "Stiffness group (1 Frame, 2 Truss, 3-13 Conc1-11, 14-17 y1 z1 y2 z2)".into(),
            y_label: "Position in the box".into(),
            series: vec![
                series("posterior 2.5 %", &|j| post.rows[j].q2_5, Mark::Points),
                series(
                    "posterior median",
                    &|j| post.rows[j].q50,
                    Mark::LineAndPoints,
                ),
                series("posterior 97.5 %", &|j| post.rows[j].q97_5, Mark::Points),
                series(
                    "SMU published optimum",
                    &|j| SMU_PUBLISHED_ALPHA[j],
                    Mark::Points,
                ),
            ],
            y_refs: vec![
                RefLine {
                    value: 0.0,
                    label: "bounds".into(),
                },
                RefLine {
                    value: 1.0,
                    label: String::new(),
                },
            ],
            ..LineChartSpec::default()
        },
        &out.join("fig_box_positions"),
    )?;
    predictive_figure(fd, out)?;
    basis_figure(study, out)?;
    starts_figure(study, out)?;
    let mut trace_names: Vec<(String, String)> =
        names.iter().map(|n| (n.clone(), "-".into())).collect();
    trace_names.push(("ln sigma_eigenvalues".into(), "-".into()));
    trace_names.push(("ln sigma_shapes".into(), "-".into()));
    trace_figure(
        &post.sampled,
        &trace_names,
        &|_, v| v,
        "Bridge posterior: walker traces (first ensemble)",
        &out.join("fig_traces"),
    )
}

fn predictive_figure(fd: &Findings, out: &Path) -> Result<()> {
    let p = &fd.predictive;
    let modes: Vec<f64> = (1..=p.len()).map(|i| i as f64).collect();
    let q = |k: usize| -> Vec<f64> {
        p.iter()
            .map(|m| {
                let f = [m.freq_hz.q50, m.freq_hz.q2_5, m.freq_hz.q97_5][k];
                100.0 * (f / m.freq_meas_hz - 1.0)
            })
            .collect()
    };
    let scatter: Vec<f64> = p
        .iter()
        .map(|m| 100.0 * m.freq_sd_hz / m.freq_meas_hz)
        .collect();
    line_chart(
        &LineChartSpec {
            title: "Bridge: posterior-predictive frequencies against the measured ones".into(),
            x_label: "Mode".into(),
            y_label: "Predicted / measured - 1 (%)".into(),
            series: vec![
                Series {
                    label: "posterior median".into(),
                    x: modes.clone(),
                    y: q(0),
                    mark: Mark::LineAndPoints,
                },
                Series {
                    label: "95 % interval".into(),
                    x: modes.clone(),
                    y: q(1),
                    mark: Mark::Points,
                },
                Series {
                    label: String::new(),
                    x: modes.clone(),
                    y: q(2),
                    mark: Mark::Points,
                },
                Series {
                    label: "+ test-to-test scatter".into(),
                    x: modes.clone(),
                    y: scatter.clone(),
                    mark: Mark::Line,
                },
                Series {
                    label: "- test-to-test scatter".into(),
                    x: modes.clone(),
                    y: scatter.iter().map(|v| -v).collect(),
                    mark: Mark::Line,
                },
            ],
            y_refs: vec![RefLine {
                value: 0.0,
                label: "measured".into(),
            }],
            ..LineChartSpec::default()
        },
        &out.join("fig_predictive_frequencies"),
    )
}

fn basis_figure(study: &BridgeStudy, out: &Path) -> Result<()> {
    let pts = &study.basis.points;
    let x: Vec<f64> = (1..=pts.len()).map(|i| i as f64).collect();
    let series = (0..5)
        .map(|i| Series {
            label: format!("mode {}", i + 1),
            x: x.clone(),
            y: pts
                .iter()
                .map(|p| p.eigenvalue_rel[i].abs().max(1e-16))
                .collect(),
            mark: Mark::Points,
        })
        .collect();
    line_chart(
        &LineChartSpec {
            title: format!(
                "Reduced basis ({} vectors) against the exact solve at {} random points of the box",
                study.basis.size,
                pts.len()
            ),
            x_label: "Check point".into(),
            y_label: "|lambda_reduced / lambda_exact - 1|".into(),
            series,
            y_scale: Scale::Log,
            ..LineChartSpec::default()
        },
        &out.join("fig_basis_error"),
    )
}

fn starts_figure(study: &BridgeStudy, out: &Path) -> Result<()> {
    let sorted = |f: &SmuFit| {
        let mut v = f.start_objectives.clone();
        v.sort_by(f64::total_cmp);
        v
    };
    let s = sorted(&study.smu);
    let p = sorted(&study.per_entry);
    line_chart(
        &LineChartSpec {
            title: "Bridge: SMU's objective at the end of each start, sorted".into(),
            x_label: "Start (sorted by end objective)".into(),
            y_label: "f = sum r^2".into(),
            series: vec![
                Series {
                    label: "SMU weighting (as computed)".into(),
                    x: (1..=s.len()).map(|i| i as f64).collect(),
                    y: s,
                    mark: Mark::Points,
                },
                Series {
                    label: "per-entry weighting".into(),
                    x: (1..=p.len()).map(|i| i as f64).collect(),
                    y: p,
                    mark: Mark::Points,
                },
            ],
            y_scale: Scale::Log,
            y_refs: vec![RefLine {
                value: SMU_PUBLISHED_OBJECTIVE,
                label: "SMU published 2.8474".into(),
            }],
            ..LineChartSpec::default()
        },
        &out.join("fig_multistart"),
    )
}

/// The Markdown tables of [`write`], rendered before the report.
struct Tables {
    fit_md: String,
    post_md: String,
    pred_md: String,
}

/// `report.md`: findings, then one section per stage (optimum, basis, identification,
/// predictive check) and the stage timings.
fn report_md(
    study: &BridgeStudy,
    fd: &Findings,
    tables: &Tables,
    timings: &[(String, f64)],
) -> String {
    let mut md = findings_section(study, fd);
    md += &optimum_section(study, &tables.fit_md);
    md += &basis_section(study);
    md += &identification_section(study, fd, &tables.post_md);
    let pred_md = &tables.pred_md;
    md += &format!(
        "## 4. Posterior-predictive frequencies and MACs\n\n{pred_md}\n\
         ![predictive](fig_predictive_frequencies.png)\n\n"
    );
    md += "## Run\n\n";
    md += &md_table(
        &["stage", "wall (s)"],
        &timings
            .iter()
            .map(|(k, v)| vec![k.clone(), format!("{v:.1}")])
            .collect::<Vec<_>>(),
    );
    md
}

/// The title, data and findings: SMU's optimum reproduced, time, per-entry weighting and
/// the posterior in numbers.
fn findings_section(study: &BridgeStudy, fd: &Findings) -> String {
    let (s, p) = (&study.smu, &study.per_entry);
    let n = &fd.identified;
    let (se, ss) = (&fd.sigma_eigenvalues, &fd.sigma_shapes);
    format!(
        "# Steel pedestrian bridge (946 DOFs): SMU's updating, reproduced, and its posterior\n\n\
         Data: `../shared/data/real/bridge-fe` (SMU, GPL-3.0), read in place. Formulation: \
         `docs/bridge-smu.md`.\n\n\
         ## Findings\n\n\
         - **SMU's optimum reproduced.** SMU weighting (as SMU computes it): f = {:.6} \
         (SMU published {SMU_PUBLISHED_OBJECTIVE}; {:.6} at its 4-decimal alphas), every alpha \
         within {:.1e} of its box width of the published one, {} of 17 on a bound. \
         {} of {} starts reached the best f (within 1e-6).\n\
         - **Time.** {} starts in {:.1} s wall on {} threads ({:.2} s per start per thread) plus \
         {:.1} s of exact polish; SMU: {SMU_WALL_S:.0} s ({SMU_MEDIAN_START_S:.0} s median per start).\n\
         - **Per-entry weighting** (what SMU's script probably meant): f = {:.6}, {} of 17 on a \
         bound, {} of {} starts reached it.\n\
         - **The posterior** (5 modes, per-entry scatter, sampled noise scales): {} alphas \
         identified by the data, {} partly, {} prior only, {} pushed against a bound. \
         Noise scales: sigma_eigenvalues {:.2} [{:.2}, {:.2}], sigma_shapes {:.2} [{:.2}, {:.2}] \
         (1 = the test-to-test scatter explains the misfit).\n\n",
        s.objective,
        study.published_objective,
        fd.max_dev_from_published_box_frac,
        fd.n_on_bound_smu,
        s.n_reached,
        s.n_starts,
        s.n_starts,
        s.wall_s,
        s.threads,
        s.wall_s * s.threads as f64 / s.n_starts as f64,
        s.polish_s,
        p.objective,
        fd.n_on_bound_per_entry,
        p.n_reached,
        p.n_starts,
        n.by_data,
        n.partly,
        n.prior_only,
        n.at_bound,
        se.geometric_mean,
        se.q2_5,
        se.q97_5,
        ss.geometric_mean,
        ss.q2_5,
        ss.q97_5,
    )
}

/// Section 1: the multistart and the fit table `fit_md`.
fn optimum_section(study: &BridgeStudy, fit_md: &str) -> String {
    let s = &study.smu;
    format!(
        "## 1. SMU's optimum\n\nMultistart: {} uniform-stratified (Latin hypercube) starts in \
         SMU's box, trust-region reflective least squares (ftol = xtol = gtol = 1e-10, at most {} \
         evaluations per start) on the reduced basis, then the best polished with the exact \
         solver. `df/dalpha` is the exact gradient of f at our optimum (central differences, \
         one-sided at a bound): at a lower bound a positive value, at an upper bound a negative \
         one, says f would fall further outside the box.\n\n{fit_md}\n\
         ![multistart](fig_multistart.png)\n\n",
        s.n_starts, study.settings.max_evaluations
    )
}

/// Section 2: the reduced basis and its error against the exact solve.
fn basis_section(study: &BridgeStudy) -> String {
    let b = &study.basis;
    format!(
        "## 2. The reduced basis\n\n{} vectors from {} snapshots (the {} lowest exact modes \
         at the nominal model, the published optimum, each alpha at each bound and {} random \
         points), built in {:.1} s. Against the exact condensed solve at {} fresh random points \
         of the box (lowest 5 modes): eigenvalue error at most {:.2e} (median {:.2e}), 1 - MAC at \
         the 58 measured DOFs at most {:.2e}. One evaluation: {:.1} us reduced, {:.1} ms exact \
         ({:.0}x).\n\n![basis error](fig_basis_error.png)\n\n",
        b.size,
        b.n_snapshots,
        study.settings.basis.modes_per_snapshot,
        study.settings.n_random_snapshots,
        b.build_s,
        b.points.len(),
        b.max_eigenvalue_rel,
        b.median_eigenvalue_rel,
        b.max_one_minus_mac,
        1e6 * b.reduced_eval_s,
        1e3 * b.exact_eval_s,
        b.exact_eval_s / b.reduced_eval_s
    )
}

/// Section 3: the likelihood, the basis at posterior draws, the identification table
/// `post_md`, the sampler's run line and the posterior table.
fn identification_section(study: &BridgeStudy, fd: &Findings, post_md: &str) -> String {
    let post = &study.posterior;
    let mut md = format!(
        "## 3. What the 5 modes identify\n\nLikelihood: eigenvalue residuals over their \
         measured scatter and shape residuals over theirs (per entry), Gaussian, each kind with \
         a sampled noise scale; uniform prior on SMU's box. Sampled on the reduced basis of \
         section 2 ({} vectors), from the Gauss-Newton covariance at the per-entry optimum; \
         the basis checked against the exact solve at {} posterior draws: eigenvalue error at \
         most {:.2e}, 1 - MAC at most {:.2e}.\n\n",
        post.basis_size,
        post.basis_at_draws.len(),
        fd.basis_max_eigenvalue_rel_at_draws,
        fd.basis_max_one_minus_mac_at_draws
    );
    md += &format!(
        "{post_md}\n![contraction](fig_contraction.png)\n\n\
         ![box positions](fig_box_positions.png)\n\n{}\n\n{}\n\n![traces](fig_traces.png)\n\n",
        run_line(&post.sampled),
        posterior_table(&post.rows)
    );
    md
}
