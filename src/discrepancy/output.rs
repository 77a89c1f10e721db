//! The output folder of `frfbayes diagnose`: `diagnosis.json`, `diagnosis.md` (and the
//! same as a self-contained `report.html`), figures,
//! `models.json` (every fit), written into a staging folder and swapped in only when
//! complete, so a failed run never leaves a half-written folder or loses the last one.

use super::data::DiagnosisData;
use super::diagnose::{Diagnosis, ModelResult};
use super::figures::{channel_misfits, channels_to_show, write_figures};
use super::report::record;
use super::verdict::decisive_ln_bayes_factor;
use crate::error::{Error, Result};
use crate::io::{write_atomic, StagedDir};
use crate::mcmc::{Draws, InferenceData, INFERENCE_DATA_FILE};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.digits$}"),
        _ => "-".into(),
    }
}

fn model_row(
    data: &DiagnosisData,
    m: &ModelResult,
    nominal_ln_z: f64,
    laplace: Option<f64>,
    reason: &str,
) -> String {
    let ev = m.evidence.as_ref();
    format!(
        "| {} | {} | {:.1} | {} | {} | {} | {} | {} | {} | {} |",
        m.name.replace('_', " "),
        data.shown(&m.location),
        m.map.ln_likelihood,
        fmt_opt(ev.and_then(|e| e.gain_bound_nats), 1),
        fmt_opt(laplace, 1),
        ev.map_or("-".into(), |e| e.estimator.label().replace('_', " ")),
        ev.map_or("-".into(), |e| format!("{:.1} +- {:.1}", e.ln_z, e.ln_z_sd)),
        fmt_opt(ev.and_then(|e| e.ln_z_ti()), 1),
        ev.map_or("-".into(), |e| format!("{:.1}", e.ln_z - nominal_ln_z)),
        reason
    )
}

/// The accepted effects, the later rounds and the adequacy tests, as Markdown.
fn open_world_section(d: &Diagnosis) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## Effects, rounds and adequacy\n");
    if d.effects.is_empty() {
        let _ = writeln!(s, "No effect accepted.\n");
    } else {
        let _ = writeln!(
            s,
            "| # | effect | location | parameters (final model, mean [95 %]) |"
        );
        let _ = writeln!(s, "|---|---|---|---|");
        for (k, e) in d.effects.iter().enumerate() {
            let params: Vec<String> = e
                .effect_parameters
                .iter()
                .map(|(n, v)| {
                    format!(
                        "{n} {:.4e} [{:.4e}, {:.4e}] {}",
                        v.mean, v.q2_5, v.q97_5, v.unit
                    )
                })
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                k + 1,
                e.hypothesis,
                d.data.shown(&e.location),
                params.join("; ")
            );
        }
        s.push('\n');
    }
    for (k, r) in d.later.iter().enumerate() {
        let _ = writeln!(
            s,
            "Round {} (on the model with {}; ln Z {:.1} +- {:.1}):\n",
            k + 2,
            r.extends.join(", "),
            r.base_ln_z,
            r.base_ln_z_sd
        );
        for (f, why) in r.finalists.iter().zip(&r.decision.reasons) {
            let _ = writeln!(s, "- {} at {}: {why}", f.name, d.data.shown(&f.location));
        }
        s.push('\n');
    }
    let q = &d.adequacy;
    let _ = writeln!(
        s,
        "Adequacy of the final model (Bendat-Piersol errors plus a {:.1} % floor for all \
         points and the cells; where the inconsistent checks point, 0.3 % per point and a \
         smooth 0.3 % gain and phase error per estimate and band, the checks' own null; \
         each sum referred to a chi^2 of the effective dof that the noise's correlation \
         between neighbouring bins leaves; level {:.0} %, Holm \
         over the cells and over the checks; cells locate, they do not decide): **{}**.\n",
        100.0 * super::adequacy::ADEQUACY_FLOOR,
        100.0 * super::adequacy::ADEQUACY_LEVEL,
        if q.adequate {
            "adequate"
        } else {
            "not adequate"
        }
    );
    let _ = writeln!(
        s,
        "| place | tests | channels | bands (Hz) | points | chi2 per point | effective dof | p (Holm) | fails |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for t in std::iter::once(&q.global)
        .chain(&q.failed_cells)
        .chain(&q.checks)
    {
        let bands: Vec<String> = t
            .bands_hz
            .iter()
            .map(|(a, b)| format!("{a:.2}-{b:.2}"))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.2} | {:.0} | {:.2e} | {} |",
            t.source,
            if t.tests.len() > 4 {
                format!("{} tests", t.tests.len())
            } else {
                t.tests.join(", ")
            },
            if t.channels.len() > 4 {
                format!("{} channels", t.channels.len())
            } else {
                t.channels.join(", ")
            },
            if t.off_band {
                "off-band".to_string()
            } else {
                bands.join(", ")
            },
            t.n_points,
            t.chi2_per_point,
            t.effective_dof,
            t.p_adjusted,
            if t.failed { "yes" } else { "no" }
        );
    }
    let _ = writeln!(
        s,
        "\n{} cells tested; only failing cells are listed (they show where the residual \
         concentrates and do not decide).\n",
        q.n_cells
    );
    if let Some(why) = &q.checks_unavailable {
        let _ = writeln!(s, "The consistency checks could not run: {why}.\n");
    }
    s
}

/// `diagnosis.md`.
pub fn markdown(d: &Diagnosis, title: &str, figures: &[String]) -> Result<String> {
    let rec = record(d);
    let mut s = String::new();
    let _ = writeln!(s, "# Diagnosis: {title}\n");
    let _ = writeln!(s, "**Verdict: `{}`** at `{}`.\n", rec.verdict, rec.location);
    let _ = writeln!(s, "{}\n", rec.explanation);
    s.push_str(&open_world_section(d));
    let _ = writeln!(s, "## Fit\n");
    let _ = writeln!(s, "| | mean FDAC | chi2 per point |");
    let _ = writeln!(s, "|---|---|---|");
    let _ = writeln!(
        s,
        "| nominal model | {:.4} | {:.2} |",
        d.fit_before.fdac_mean, d.fit_before.chi2_per_point
    );
    let _ = writeln!(
        s,
        "| final model (every accepted effect) | {:.4} | {:.2} |\n",
        d.fit_after.fdac_mean, d.fit_after.chi2_per_point
    );
    let _ = writeln!(
        s,
        "chi2 per point uses the estimates' Bendat-Piersol errors plus the nominal model's \
         fitted relative error floor eta = {:.4}; 1 means agreement within noise.\n",
        d.nominal.map.eta
    );

    let _ = writeln!(s, "## Hypothesis ranking\n");
    let nominal_ln_z = d.nominal.ln_z().unwrap_or(f64::NAN);
    let lap = |name: &str| {
        d.laplace
            .iter()
            .find(|(n, _)| n == name)
            .and_then(|(_, v)| *v)
    };
    let _ = writeln!(
        s,
        "| model | location | max ln L | gain bound | ln Z (Laplace, logit) | estimator | ln Z +- sd | ln Z (TI) | delta ln Z | decision |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    let _ = writeln!(
        s,
        "{}",
        model_row(
            &d.data,
            &d.nominal,
            nominal_ln_z,
            lap("nominal"),
            "reference"
        )
    );
    for (f, reason) in d.finalists.iter().zip(&d.decision.reasons) {
        let _ = writeln!(
            s,
            "{}",
            model_row(&d.data, f, nominal_ln_z, lap(&f.name), reason)
        );
    }
    for sr in &d.searches {
        if d.finalists.iter().any(|f| f.name == sr.name) {
            continue;
        }
        if let Some(b) = sr.best() {
            let why = if b.map.ln_likelihood <= d.nominal.map.ln_likelihood {
                "fits no better than the nominal model"
            } else {
                "not among the best fits; Laplace only"
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.1} | {:.1} | {} | laplace | - | - | {} | {why} |",
                sr.name.replace('_', " "),
                d.data.shown(&b.location),
                b.map.ln_likelihood,
                b.map.ln_likelihood - d.nominal.map.ln_likelihood,
                fmt_opt(lap(sr.name), 1),
                fmt_opt(lap(sr.name).map(|v| v - nominal_ln_z), 1),
            );
        }
    }
    let _ = writeln!(
        s,
        "\nDecisive means delta ln Z >= ln 150 = {:.2} after two standard deviations (Kass & \
         Raftery's 'very strong'), with a gain bound (max ln L over the nominal model's, which \
         bounds delta ln Z) of ln 150 or more. Estimators: `gain bound` (no run: the bound \
         rules the hypothesis out; its ln Z is Laplace's capped at the bound, sd 0), \
         `outranked` (no run: another hypothesis, whose Laplace delta ln Z less two \
         allowances is above this one's bound by ln 150 or more, passed every test; ln Z \
         as for the bound), \
         `laplace` (at the mode in logit coordinates, far below the threshold, or far above \
         it where no other passing hypothesis is within reach; its sd is a stated allowance \
         of {:.0} nats; a winner decided so gets a run, as it becomes the next round's base), \
         `importance sampling` (from the stepping-stone's reference at the posterior, kept \
         where its weights' Pareto k < 0.5 and ESS >= n/5; delta-method sd), \
         `generalised stepping-stone` (tempered ensembles from that reference; sd from {} \
         independent replicates), \
         `stepping stone` (from the prior, where no mode was found; thermodynamic \
         integration (TI) on its ladder as a check).\n",
        decisive_ln_bayes_factor(),
        super::model_evidence::LAPLACE_ALLOWANCE_NATS,
        crate::infer::screened::GSS_REPLICATES,
    );
    for m in std::iter::once(&d.nominal).chain(&d.finalists) {
        if let Some(why) = m.evidence.as_ref().and_then(|e| e.laplace_failure.as_ref()) {
            let _ = writeln!(
                s,
                "- {}: no Laplace in logit coordinates ({why}).",
                m.name.replace('_', " ")
            );
        }
    }
    let _ = writeln!(s);
    for (stem, cap) in [("ranking", "Hypothesis ranking")] {
        if figures.iter().any(|f| f == stem) {
            let _ = writeln!(s, "![{cap}]({stem}.png)\n");
        }
    }

    let _ = writeln!(s, "## Locations tried\n");
    for sr in &d.searches {
        let tried: Vec<String> = sr
            .tried
            .iter()
            .take(6)
            .map(|t| {
                format!(
                    "{} ({:.1})",
                    d.data.shown(&t.location),
                    t.map.ln_likelihood - d.nominal.map.ln_likelihood
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "- {}: {}{}",
            sr.name.replace('_', " "),
            tried.join(", "),
            if sr.tried.len() > 6 { ", ..." } else { "" }
        );
        for (loc, e) in &sr.failed {
            let _ = writeln!(s, "  - {loc}: not fitted: {e}");
        }
    }
    let _ = writeln!(
        s,
        "\n(max ln L gain over the nominal fit in brackets, best first)\n"
    );

    if !rec.effect_parameters.is_empty() {
        let _ = writeln!(s, "## Effect parameters\n");
        let _ = writeln!(s, "| parameter | mean | 2.5 % | 97.5 % | unit |");
        let _ = writeln!(s, "|---|---|---|---|---|");
        for (n, e) in &rec.effect_parameters {
            let _ = writeln!(
                s,
                "| {n} | {:.4e} | {:.4e} | {:.4e} | {} |",
                e.mean, e.q2_5, e.q97_5, e.unit
            );
        }
        let _ = writeln!(s);
    }
    if figures.iter().any(|f| f == "effect_posterior") {
        let _ = writeln!(s, "![Effect posterior](effect_posterior.png)\n");
    }
    for f in &d.finalists {
        if let Some(h) = &f.held_out {
            let _ = writeln!(
                s,
                "Held-out check of {} (leave one segment out; log density of the held-out \
                 segment, hypothesis minus nominal): total {:.1} +- {:.1} nats; one-sided \
                 Wilcoxon signed-rank p = {:.4} over {} segments with a non-zero gain.\n",
                f.name, h.gain, h.gain_se, h.p_value, h.n_ranked
            );
            let _ = writeln!(s, "| held-out segment | nominal | hypothesis | gain |");
            let _ = writeln!(s, "|---|---|---|---|");
            for i in 0..h.segments.len() {
                let _ = writeln!(
                    s,
                    "| {} | {:.1} | {:.1} | {:.1} |",
                    h.segments[i],
                    h.nominal[i],
                    h.hypothesis[i],
                    h.hypothesis[i] - h.nominal[i]
                );
            }
            let _ = writeln!(s);
        }
    }

    let _ = writeln!(s, "## Where simulation and recordings differ\n");
    match &d.locate {
        Ok(l) => {
            let _ = writeln!(s, "{}\n", l.to_markdown());
        }
        Err(e) => {
            let _ = writeln!(s, "The consistency checks could not run: {e}\n");
        }
    }
    for (stem, cap) in [
        ("residual_before", "Residual map, nominal model"),
        ("residual_after", "Residual map, after the verdict"),
    ] {
        if figures.iter().any(|f| f == stem) {
            let _ = writeln!(s, "![{cap}]({stem}.png)\n");
        }
    }
    let _ = writeln!(s, "## Where the nominal model misfits most\n");
    let winner = d.winner.map(|w| &d.finalists[w]);
    let mis = channel_misfits(d, winner)?;
    let shown = channels_to_show(&mis, winner.is_some(), 10);
    let _ = writeln!(
        s,
        "| segment / channel | chi2 per point, nominal | after verdict |"
    );
    let _ = writeln!(s, "|---|---|---|");
    for m in &shown {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} |",
            m.label, m.chi2_nominal, m.chi2_extended
        );
    }
    let _ = writeln!(s);
    for k in 0..4 {
        if figures.iter().any(|f| f == &format!("frf_{k}")) {
            let _ = writeln!(s, "![FRF {k}](frf_{k}.png) ![Phase {k}](phase_{k}.png)\n");
        }
    }
    let _ = writeln!(
        s,
        "## Data\n\n{} segments (tests, or impacts of hammer tests on their own), {} complex \
         FRF points; run time {:.0} s.\n",
        d.data.segments.len(),
        d.data.n_points(),
        d.elapsed_s
    );
    let _ = writeln!(s, "| stage | wall time, s |\n|---|---|");
    for (what, t) in &d.timings {
        let _ = writeln!(s, "| {what} | {t:.1} |");
    }
    Ok(s)
}

/// Writes the whole output folder `out` (replacing it only on success).
pub fn write_diagnosis(d: &Diagnosis, title: &str, out: &Path) -> Result<PathBuf> {
    let staged = StagedDir::new(out)?;
    write_diagnosis_into(d, title, staged.path())?;
    staged.commit()
}

/// `inference_data.nc` ([`crate::mcmc::InferenceData`]): the sampled posterior of the
/// model shown in `effect_posterior.png` (the verdict's hypothesis, else the best
/// finalist), as its evidence run's final (`beta = 1`) stage kept it: every parameter in
/// physical units (frame, `eta`, the effect), chains = the evidence run's replicates;
/// `sample_stats` holds `lp`, `ln_likelihood` and `ln_prior`. Nothing is written when
/// no evidence posterior was sampled (e.g. `--evidence laplace`).
fn write_effect_inference_data(d: &Diagnosis, dir: &Path) -> Result<()> {
    let shown = d.winner.map(|w| &d.finalists[w]).or(d.finalists.first());
    let Some((f, p)) = shown.and_then(|f| {
        let p = f.evidence.as_ref()?.run.as_ref()?.posterior.as_ref()?;
        Some((f, p))
    }) else {
        return Ok(());
    };
    let draws = &p.draws;
    let rows = draws
        .values
        .chunks_exact(draws.dim.max(1))
        .map(|z| f.posterior.physical(z))
        .collect::<Result<Vec<_>>>()?;
    let first = rows.first().map(Vec::as_slice).unwrap_or_default();
    let names = distinct_names(first.iter().map(|v| v.name.as_str()));
    let units: Vec<String> = first.iter().map(|v| v.unit.clone()).collect();
    let phys = Draws {
        dim: names.len(),
        values: rows.iter().flatten().map(|v| v.value).collect(),
        n_pointwise: 0,
        pointwise: Vec::new(),
        ..draws.clone()
    };
    InferenceData::new(&phys, &names, &units)?
        .with_stat("ln_likelihood", p.ln_likelihood.clone())?
        .with_stat("ln_prior", p.ln_prior.clone())?
        .with_attr("frfbayes_command", "diagnose")
        .with_attr("hypothesis", &f.name)
        .with_attr("location", &d.data.shown(&f.location).to_string())
        .write(&dir.join(INFERENCE_DATA_FILE))
}

/// `names` made distinct for InferenceData's variables: a later name equal to an
/// earlier one (the cubic spring's `k3` after story 3's, a second effect's `delay`) gets
/// `effect_` in front, then `_2`, `_3`, ... until it is new.
fn distinct_names<'a>(names: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for name in names {
        let mut candidate = name.to_string();
        if out.contains(&candidate) {
            candidate = format!("effect_{name}");
        }
        let stem = candidate.clone();
        let mut n = 2;
        while out.contains(&candidate) {
            candidate = format!("{stem}_{n}");
            n += 1;
        }
        out.push(candidate);
    }
    out
}

/// Writes the output files into `dir` (a staging folder).
pub fn write_diagnosis_into(d: &Diagnosis, title: &str, dir: &Path) -> Result<()> {
    let dir = dir.to_path_buf();
    let mut figures = write_figures(d, &dir)?;
    use super::residual_map::MapValue;
    if let Ok(l) = &d.locate {
        l.write(&dir)?;
        if let Some(m) = &l.residual_map {
            m.heatmap(
                MapValue::Chi2PerPoint,
                "Residuals of the nominal model (chi2 per point)",
                &dir.join("residual_before"),
            )?;
            m.write_tables(&dir.join("residual_before"))?;
            figures.push("residual_before".into());
        }
    }
    if let Some(m) = &d.residual_after {
        m.heatmap(
            MapValue::Chi2PerPoint,
            "Residuals after the verdict (chi2 per point)",
            &dir.join("residual_after"),
        )?;
        m.write_tables(&dir.join("residual_after"))?;
        figures.push("residual_after".into());
    }
    write_effect_inference_data(d, &dir)?;
    let rec = record(d);
    let json = serde_json::to_string_pretty(&rec)
        .map_err(|e| Error::Numerical(format!("diagnosis.json: {e}")))?;
    write_atomic(&dir.join("diagnosis.json"), json.as_bytes())?;
    let md = markdown(d, title, &figures)?;
    write_atomic(&dir.join("diagnosis.md"), md.as_bytes())?;
    crate::report::write_html_report(
        &dir,
        &crate::report::HtmlReport {
            markdown: &["diagnosis.md", "locate.md"],
            lead: crate::report::LEAD,
            tail: crate::report::TAIL,
            title: None,
        },
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::distinct_names;

    #[test]
    fn inference_data_names_are_made_distinct() {
        let names = ["k1", "k3", "eta", "k3", "delay", "delay", "delay"];
        assert_eq!(
            distinct_names(names.into_iter()),
            [
                "k1",
                "k3",
                "eta",
                "effect_k3",
                "delay",
                "effect_delay",
                "effect_delay_2"
            ]
        );
    }
}
