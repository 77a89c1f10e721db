//! The posterior part of `identifiability.md` ([`super::posterior`]) and
//! `posterior.json` (figures: [`super::posterior_figures`]). Every number is computed from the draws; the prose states what the
//! numbers show and picks its wording from them.

use super::posterior::{correlation, mean_cv, VariantPosterior};
use crate::error::{Error, Result};
use crate::frf::FrfKind;
use crate::io::write_atomic;
use std::fmt::Write;
use std::path::Path;

fn is_mk(name: &str) -> bool {
    name.starts_with('m') || name.starts_with('k')
}

fn is_damping(name: &str) -> bool {
    name.starts_with("xi") || name == "a0" || name == "a1"
}

/// `lo`-`hi` with three significant digits.
fn range(v: &[f64]) -> String {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    format!("{} to {}", sig(lo), sig(hi))
}

fn sig(x: f64) -> String {
    if !x.is_finite() {
        "-".into()
    } else if x != 0.0 && (x.abs() < 0.01 || x.abs() >= 1e4) {
        format!("{x:.2e}")
    } else {
        format!("{x:.3}")
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// `posterior.json`: every variant's [`crate::bayes::summary::PosteriorSummary`].
pub fn write_posterior_json(posts: &[VariantPosterior], dir: &Path) -> Result<()> {
    let v: Vec<serde_json::Value> = posts
        .iter()
        .map(|p| serde_json::json!({"variant": p.name, "summary": p.sample.summary}))
        .collect();
    let bytes = serde_json::to_vec_pretty(&serde_json::json!({ "variants": v }))
        .map_err(|e| Error::Numerical(format!("JSON: {e}")))?;
    write_atomic(&dir.join("posterior.json"), &bytes)
}

/// The `## Posterior` sections of `identifiability.md`.
pub fn posterior_markdown(posts: &[VariantPosterior]) -> String {
    let mut md = String::new();
    let Some(first) = posts.first() else {
        return md;
    };
    let s0 = &first.sample.summary;
    let _ = writeln!(
        md,
        "## Posterior (ensemble MCMC)\n\nEvery variant sampled as `frfbayes sample` samples it, on the same FRF estimates: {}, priors uniform in the bounds above (log-uniform damping), the exponential window applied to the model (so damping here is the structure's), {} ensembles of {} x dim walkers (moves {}), run until R-hat < 1.01 and bulk ESS > 400 for every parameter or the step cap. Numbers of every variant in `posterior.json`. Figures: `posterior_cv_table*.png`, `posterior_corner_*.png`, `posterior_correlation_*.png`, `posterior_ridge_km.png`.\n",
        first.settings.describe_noise(),
        s0.n_ensembles,
        s0.n_walkers / s0.parameters.len().max(1),
        crate::mcmc::Moves::from_specs(&crate::bayes::run::default_moves())
            .map_or_else(|e| format!("unknown: {e}"), |m| m.describe())
    );
    convergence(&mut md, posts);
    cv_table(&mut md, posts);
    modal_table(&mut md, posts);
    ridge(&mut md, posts);
    let differences = disagreement(&mut md, posts);
    in_short(&mut md, posts, &differences);
    md
}

/// The closing summary: the numbers behind "damping is poorly identified".
fn in_short(md: &mut String, posts: &[VariantPosterior], d: &Differences) {
    let caughey: Vec<&VariantPosterior> = posts
        .iter()
        .filter(|p| p.modal.iter().all(|m| m.freq_hz.cv > 0.0) && p.index("xi1").is_some())
        .collect();
    if caughey.is_empty() {
        return;
    }
    let ratios: Vec<f64> = caughey
        .iter()
        .flat_map(|p| p.modal.iter().map(|m| m.xi.cv / m.freq_hz.cv))
        .collect();
    let au: Vec<f64> = caughey
        .iter()
        .flat_map(|p| p.modal.iter().map(|m| m.xi.mean * m.xi.cv / m.freq_hz.cv))
        .collect();
    let corr_km: Vec<f64> = caughey
        .iter()
        .filter(|p| p.name.starts_with("table1"))
        .flat_map(|p| {
            (1..=4)
                .filter_map(|r| {
                    Some(correlation(
                        &p.named(&format!("k{r}"))?,
                        &p.named(&format!("m{r}"))?,
                    ))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let xi: Vec<f64> = caughey
        .iter()
        .flat_map(|p| p.modal.iter().map(|m| m.xi.mean))
        .collect();
    let _ = writeln!(
        md,
        "### In short\n\n- With Caughey damping, the damping ratios' posterior CVs are {} times those of the natural frequencies (median {:.0}); xi x CV(xi)/CV(f) is {}, of order one as Au's law says: damping is worse determined than frequency by a factor of order 1/xi (xi here {}).",
        range(&ratios),
        median(ratios.clone()),
        range(&au),
        range(&xi)
    );
    if !corr_km.is_empty() {
        let _ = writeln!(
            md,
            "- Masses and stiffnesses are tied to the frequencies: with hammer data corr(k_r, m_r) is {}, so each is about as uncertain as the common mass-stiffness scale the force amplitude fixes, not as the peak widths.",
            range(&corr_km)
        );
    }
    md.push_str("- Under ground excitation the scale is not identified at all (the k/m ridge above); frequencies, and with them every k_r / m_r, still are.\n");
    let all_cv = |f: fn(&str) -> bool| -> Vec<f64> {
        posts
            .iter()
            .flat_map(|p| p.sample.summary.parameters.iter())
            .filter(|q| f(&q.name))
            .map(|q| 100.0 * q.cv)
            .collect()
    };
    let _ = writeln!(
        md,
        "- Between variants, damping differs by {:.2} % (median; mass and stiffness {:.2} %) at a median |z| of {:.1} (mass and stiffness {:.1}), against median posterior CVs of {:.3} % for damping and {:.3} % for mass and stiffness. {} of {} damping comparisons and {} of {} mass and stiffness comparisons exceed |z| = 3: those differences are systematic, not statistical.\n",
        median(d.rel_d.clone()),
        median(d.rel_mk.clone()),
        median(d.z_d.clone()),
        median(d.z_mk.clone()),
        median(all_cv(is_damping)),
        median(all_cv(is_mk)),
        d.z_d.iter().filter(|z| **z > 3.0).count(),
        d.z_d.len(),
        d.z_mk.iter().filter(|z| **z > 3.0).count(),
        d.z_mk.len(),
    );
}

fn convergence(md: &mut String, posts: &[VariantPosterior]) {
    md.push_str("### Convergence\n\n| variant | points | walkers | steps | kept draws | max R-hat | min bulk ESS | min tail ESS | acceptance | stuck walkers | evaluations/s | sampling (s) | stopped | converged |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for p in posts {
        let s = &p.sample.summary;
        let tail = s
            .parameters
            .iter()
            .map(|q| q.ess_tail)
            .fold(f64::INFINITY, f64::min);
        let _ = writeln!(
            md,
            "| {} | {} | {} x {} | {} | {} | {:.4} | {:.0} | {:.0} | {:.2} | {} | {:.0} | {:.1} | {} | {} |",
            p.name,
            s.n_data_points,
            s.n_ensembles,
            s.n_walkers,
            s.n_steps,
            s.n_draws_per_walker * s.n_walkers * s.n_ensembles,
            s.rhat_max,
            s.ess_bulk_min,
            tail,
            s.acceptance,
            s.n_stuck_walkers,
            s.n_likelihood_evals as f64 / s.wall_s,
            s.wall_s,
            s.stopped_because,
            if s.converged { "yes" } else { "**no**" }
        );
    }
    let bad: Vec<&str> = posts
        .iter()
        .filter(|p| !p.sample.summary.converged)
        .map(|p| p.name.as_str())
        .collect();
    if bad.is_empty() {
        let _ = writeln!(
            md,
            "\n{n} of {n} variants meet R-hat < 1.01 and bulk ESS > 400 for every parameter, with no stuck walker.\n",
            n = posts.len()
        );
    } else {
        let _ = writeln!(
            md,
            "\n**Not converged** (R-hat < 1.01 and bulk ESS > 400 not met by the step cap, or stuck walkers): {}. Their numbers below are provisional.\n",
            bad.join(", ")
        );
    }
}

fn cv_table(md: &mut String, posts: &[VariantPosterior]) {
    let mut names: Vec<String> = Vec::new();
    for p in posts {
        for q in &p.sample.params {
            if !names.contains(&q.name) {
                names.push(q.name.clone());
            }
        }
    }
    md.push_str("### Posterior coefficient of variation of every parameter (%)\n\n`(b)`: the 95 % interval reaches a prior bound (the bound, not the data, then limits the CV).\n\n| parameter |");
    for p in posts {
        let _ = write!(md, " {} |", p.name);
    }
    md.push_str("\n|---|");
    md.push_str(&"---|".repeat(posts.len()));
    md.push('\n');
    for n in &names {
        let _ = write!(md, "| {n} |");
        for p in posts {
            match p.index(n) {
                Some(j) => {
                    let q = &p.sample.summary.parameters[j];
                    let b = if q.at_bound.is_some() { " (b)" } else { "" };
                    let _ = write!(md, " {}{b} |", sig(100.0 * q.cv));
                }
                None => md.push_str(" - |"),
            }
        }
        md.push('\n');
    }
    md.push_str("\nPer variant: ranges of the CVs of masses and stiffnesses, of the damping parameters and of the natural frequencies (over the draws), and how much larger the damping CVs are than the others (medians):\n\n| variant | CV m, k (%) | CV damping (%) | CV f (%) | damping / (m, k) | damping / f |\n|---|---|---|---|---|---|\n");
    for p in posts {
        let rows = &p.sample.summary.parameters;
        let pick = |f: fn(&str) -> bool| -> Vec<f64> {
            rows.iter()
                .filter(|q| f(&q.name))
                .map(|q| 100.0 * q.cv)
                .collect()
        };
        let (mk, d) = (pick(is_mk), pick(is_damping));
        let f: Vec<f64> = p.modal.iter().map(|m| 100.0 * m.freq_hz.cv).collect();
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} |",
            p.name,
            range(&mk),
            range(&d),
            range(&f),
            sig(median(d.clone()) / median(mk)),
            sig(median(d) / median(f))
        );
    }
    md.push('\n');
}

fn modal_table(md: &mut String, posts: &[VariantPosterior]) {
    md.push_str("### Natural frequencies against damping ratios\n\nPer mode, over the draws (damping ratios of Rayleigh variants are `(a0 / omega + a1 omega) / 2`). Au's uncertainty law for modal identification predicts CV(xi) / CV(f) of order 1/xi.\n\n| variant | mode | f (Hz) | CV f (%) | xi | CV xi (%) | CV xi / CV f | xi x (CV xi / CV f) |\n|---|---|---|---|---|---|---|---|\n");
    let mut ratios = Vec::new();
    for p in posts {
        for (i, m) in p.modal.iter().enumerate() {
            let r = m.xi.cv / m.freq_hz.cv;
            ratios.push(r);
            let _ = writeln!(
                md,
                "| {} | {} | {:.3} | {} | {:.4} | {} | {:.0} | {:.2} |",
                p.name,
                i + 1,
                m.freq_hz.mean,
                sig(100.0 * m.freq_hz.cv),
                m.xi.mean,
                sig(100.0 * m.xi.cv),
                r,
                m.xi.mean * r
            );
        }
    }
    if !ratios.is_empty() {
        let _ = writeln!(
            md,
            "\nCV(xi) / CV(f) is {} (median {:.0}): a natural frequency is set by the position of a peak, which every point near it fixes, while its damping is set by the peak's width and height, which only the few points inside its half-power band carry. Mass and stiffness inherit the precision of the frequencies (and of the mode shapes in the peak heights); damping does not.\n",
            range(&ratios),
            median(ratios.clone())
        );
    }
}

fn ridge(md: &mut String, posts: &[VariantPosterior]) {
    md.push_str("### The k/m ridge of ground excitation\n\nPer story: CV of the stiffness, of the mass and of their ratio, their correlation, and how much of the mass prior's width the 95 % interval of the mass covers.\n\n| variant | story | CV k (%) | CV m (%) | CV k/m (%) | corr(k, m) | 95 % interval of m / prior width |\n|---|---|---|---|---|---|---|\n");
    let mut summary: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
    for p in posts {
        let mut gains = Vec::new();
        let mut covers = Vec::new();
        for r in 1..=4 {
            let (Some(jm), Some(jk)) = (p.index(&format!("m{r}")), p.index(&format!("k{r}")))
            else {
                continue;
            };
            let (m, k) = (p.column(jm), p.column(jk));
            let ratio: Vec<f64> = k.iter().zip(&m).map(|(k, m)| k / m).collect();
            let (cm, ck, cr) = (mean_cv(&m).cv, mean_cv(&k).cv, mean_cv(&ratio).cv);
            let q = &p.sample.summary.parameters[jm];
            let [lo, hi] = p.prior_box[jm];
            let width = hi - lo;
            let cover = (q.q97_5 - q.q2_5) / width;
            gains.push(ck.min(cm) / cr);
            covers.push(cover);
            let _ = writeln!(
                md,
                "| {} | {r} | {} | {} | {} | {:.3} | {:.2} |",
                p.name,
                sig(100.0 * ck),
                sig(100.0 * cm),
                sig(100.0 * cr),
                correlation(&k, &m),
                cover
            );
        }
        if !gains.is_empty() {
            summary.push((p.name.clone(), gains, covers));
        }
    }
    md.push('\n');
    for table in ["table1", "table2"] {
        let g: Vec<f64> = summary
            .iter()
            .filter(|s| s.0.starts_with(table))
            .flat_map(|s| s.1.clone())
            .collect();
        let c: Vec<f64> = summary
            .iter()
            .filter(|s| s.0.starts_with(table))
            .flat_map(|s| s.2.clone())
            .collect();
        if g.is_empty() {
            continue;
        }
        let _ = writeln!(
            md,
            "{table}: min(CV k, CV m) / CV(k/m) is {} and the 95 % mass intervals cover {} of the prior width.",
            range(&g),
            range(&c)
        );
    }
    md.push_str("\nWhere the ratio is large and the mass interval covers most of the prior, the data fix k/m (the natural frequencies) and leave the common scale of mass and stiffness to the prior: scaling M and K together leaves every ground-excitation FRF unchanged (Eqs. 15-16). Hammer data carry the force and with it the scale.\n\n");
}

/// `|mean_a - mean_b| / sqrt(sd_a^2 + sd_b^2)` for a parameter two variants share.
fn z(a: &VariantPosterior, b: &VariantPosterior, name: &str) -> Option<(f64, f64, f64)> {
    let (ia, ib) = (a.index(name)?, b.index(name)?);
    let (pa, pb) = (
        &a.sample.summary.parameters[ia],
        &b.sample.summary.parameters[ib],
    );
    Some((
        pa.mean,
        pb.mean,
        (pa.mean - pb.mean).abs() / (pa.sd * pa.sd + pb.sd * pb.sd).sqrt(),
    ))
}

/// Relative differences (%) and z of the compared parameters.
#[derive(Debug, Default)]
struct Differences {
    rel_mk: Vec<f64>,
    rel_d: Vec<f64>,
    z_mk: Vec<f64>,
    z_d: Vec<f64>,
}

fn disagreement(md: &mut String, posts: &[VariantPosterior]) -> Differences {
    md.push_str("### Do the variants agree within their posterior uncertainty?\n\nThe paper finds mass and stiffness consistent across tests and FRF types while damping differs. Differences of posterior means in units of the combined posterior standard deviation (z), receptance against accelerance on the same data, and hammer against shake table for damping:\n\n| parameter | compared | posterior means | difference (%) | z |\n|---|---|---|---|---|\n");
    let (mut z_mk, mut z_d) = (Vec::new(), Vec::new());
    let (mut rel_mk, mut rel_d) = (Vec::new(), Vec::new());
    let mut pairs: Vec<(&VariantPosterior, &VariantPosterior, &str)> = Vec::new();
    for a in posts {
        for b in posts {
            let same_data = a.variant.table == b.variant.table
                && a.variant.damping == b.variant.damping
                && a.variant.kind == FrfKind::Receptance
                && b.variant.kind == FrfKind::Accelerance;
            let across_tests = a.variant.damping == b.variant.damping
                && a.variant.kind == b.variant.kind
                && a.variant.table.key() < b.variant.table.key();
            if same_data {
                pairs.push((a, b, "receptance / accelerance"));
            } else if across_tests {
                pairs.push((a, b, "hammer / shake table"));
            }
        }
    }
    for (a, b, what) in pairs {
        for q in &a.sample.params {
            let n = q.name.as_str();
            let across = what.starts_with("hammer");
            if n == "noise_scale" || (across && !is_damping(n)) {
                continue;
            }
            let Some((ma, mb, zv)) = z(a, b, n) else {
                continue;
            };
            let rel = 200.0 * (ma - mb).abs() / (ma + mb).abs();
            if is_damping(n) {
                z_d.push(zv);
                rel_d.push(rel);
            } else {
                z_mk.push(zv);
                rel_mk.push(rel);
            }
            let label = if across {
                format!("{} {}", a.variant.column(), what)
            } else {
                format!("{} {}", a.name.replace("_receptance", ""), what)
            };
            let _ = writeln!(
                md,
                "| {n} | {label} | {} / {} | {rel:.2} | {zv:.1} |",
                sig(ma),
                sig(mb)
            );
        }
    }
    let max = |v: &[f64]| v.iter().copied().fold(f64::NAN, f64::max);
    let med = |v: &[f64]| median(v.to_vec());
    let _ = writeln!(
        md,
        "\nMass and stiffness: differences median {:.2} %, largest {:.2} %; |z| median {:.1}, largest {:.1}. Damping: differences median {:.2} %, largest {:.2} %; |z| median {:.1}, largest {:.1}. (Hammer against shake table is compared for damping only: the shake table leaves the mass-stiffness scale to the prior.) A |z| far above 2-3 means the variants disagree by more than the data's uncertainty allows: the difference is systematic (model form, sensors, estimator), not noise.\n",
        med(&rel_mk),
        max(&rel_mk),
        med(&z_mk),
        max(&z_mk),
        med(&rel_d),
        max(&rel_d),
        med(&z_d),
        max(&z_d)
    );
    Differences {
        rel_mk,
        rel_d,
        z_mk,
        z_d,
    }
}
