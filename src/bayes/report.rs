//! `summary.md` and `report.html` of `frfbayes sample`: the numbers of
//! [`PosteriorSummary`] as Markdown (the verdict on convergence first, the settings
//! last), rendered to HTML with the run's figures by [`crate::report`].

use super::summary::PosteriorSummary;
use crate::error::Result;
use crate::io::write_atomic;
use crate::report::{write_html_report, HtmlReport, LEAD, TAIL};
use std::fmt::Write;
use std::path::Path;

/// The Markdown of a finished run; `settings_toml` is the run's `settings.toml`.
pub fn summary_markdown(s: &PosteriorSummary, settings_toml: &str) -> String {
    let mut md = String::from("# Posterior sample (`frfbayes sample`)\n\n## Verdict\n\n");
    let _ = if s.converged {
        writeln!(
            md,
            "**Converged**: every R-hat < 1.01 (max {:.4}) and bulk ESS > 400 (min {:.0}), \
             no stuck walkers.",
            s.rhat_max, s.ess_bulk_min
        )
    } else {
        writeln!(
            md,
            "**Not converged** (needs R-hat < 1.01, bulk ESS > 400, no stuck walkers): max \
             R-hat {:.4}, min bulk ESS {:.0}, {} stuck walkers. Extend it with `--resume \
             --max-steps <more>`.",
            s.rhat_max, s.ess_bulk_min, s.n_stuck_walkers
        )
    };
    let _ = writeln!(
        md,
        "\n{} steps x {} walkers x {} ensembles, acceptance {:.3}, {} evaluations in {:.1} s; \
         stopped: {}; {} draws per walker kept (burn-in {} steps, thinned every {}); {} data \
         points.\n\n## Posterior\n\n\
         | parameter | unit | mean | sd | c.o.v. (%) | 2.5 % | median | 97.5 % | R-hat | ESS bulk | ESS tail | tau (steps) | at bound |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|",
        s.n_steps,
        s.n_walkers,
        s.n_ensembles,
        s.acceptance,
        s.n_likelihood_evals,
        s.wall_s,
        s.stopped_because,
        s.n_draws_per_walker,
        s.discarded_steps,
        s.thin_steps,
        s.n_data_points,
    );
    for p in &s.parameters {
        let bound = p
            .at_bound
            .map_or("no".to_owned(), |b| format!("{b:?}").to_lowercase());
        let _ = writeln!(
            md,
            "| {} | {} | {:.5e} | {:.3e} | {:.3} | {:.5e} | {:.5e} | {:.5e} | {:.4} | {:.0} | {:.0} | {:.1} | {} |",
            p.name, p.unit, p.mean, p.sd, 100.0 * p.cv, p.q2_5, p.q50, p.q97_5, p.rhat,
            p.ess_bulk, p.ess_tail, p.tau, bound
        );
    }
    let _ = write!(
        md,
        "\nAll numbers, per parameter and per ensemble, in `posterior.json`; draws in \
         `draws.csv` and `draws.npy`.\n\n## Settings (`settings.toml`)\n\n```toml\n{}\n```\n",
        settings_toml.trim_end()
    );
    md
}

/// Writes `summary.md` and `report.html` into `out`, after `settings.toml`, the figures
/// and `run.json`.
pub fn write_report(s: &PosteriorSummary, out: &Path) -> Result<()> {
    let settings = super::run::settings_path(out);
    let toml =
        std::fs::read_to_string(&settings).map_err(|e| crate::error::Error::io(&settings, e))?;
    write_atomic(
        &out.join("summary.md"),
        summary_markdown(s, &toml).as_bytes(),
    )?;
    write_html_report(
        out,
        &HtmlReport {
            markdown: &["summary.md"],
            lead: LEAD,
            tail: TAIL,
            title: None,
        },
    )?;
    Ok(())
}
