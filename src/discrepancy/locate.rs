//! Where simulation and recordings differ: the consistency checks
//! ([`super::consistency`]), optionally a residual map ([`super::residual_map`]), and a
//! short list of findings in plain words, strongest first.
//!
//! Strength of a finding: the chi^2 excess `(statistic - dof) / sqrt(2 dof)` of its
//! strongest check (a z-like number that does not saturate like a p-value does).

use super::consistency::{
    CheckDetails, CheckKind, CheckResult, ConsistencyReport, RatioFit, Verdict,
};
use super::residual_map::ResidualMap;
use crate::error::Result;
use crate::io::write_atomic;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// One finding.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Finding {
    /// Which check family.
    pub kind: CheckKind,
    /// Chi^2 excess of the strongest check behind it.
    pub strength: f64,
    /// One sentence.
    pub text: String,
    /// Names of the checks behind it.
    pub checks: Vec<String>,
}

/// Output of the locate step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocateReport {
    pub consistency: ConsistencyReport,
    pub residual_map: Option<ResidualMap>,
    /// Strongest first.
    pub findings: Vec<Finding>,
}

fn excess(c: &CheckResult) -> f64 {
    let super::consistency::NullDistribution::ChiSquared { dof } = c.null;
    (c.statistic - dof as f64) / (2.0 * dof as f64).sqrt()
}

/// Inverse-variance weighted mean and its standard error, inflated by the Birge ratio
/// of the values' spread when they scatter more than their errors say.
fn wmean(v: &[(f64, f64)]) -> (f64, f64) {
    let w: f64 = v.iter().map(|(_, s)| 1.0 / (s * s)).sum();
    let m = v.iter().map(|(x, s)| x / (s * s)).sum::<f64>() / w;
    let chi2: f64 = v.iter().map(|(x, s)| ((x - m) / s).powi(2)).sum();
    let birge = if v.len() > 1 {
        (chi2 / (v.len() - 1) as f64).max(1.0)
    } else {
        1.0
    };
    (m, (birge / w).sqrt())
}

fn ratio(c: &CheckResult) -> Option<&RatioFit> {
    match &c.details {
        CheckDetails::Ratio(f) => Some(f),
        _ => None,
    }
}

/// What a ratio fit says, in words: the dominant feature(s) among delay, constant gain
/// and gain change with `|z| > 3`.
fn ratio_words(v: &[&RatioFit], sign: &[f64]) -> String {
    let d: Vec<(f64, f64)> = v
        .iter()
        .zip(sign)
        .map(|(f, s)| (s * f.delay_s, f.delay_se_s))
        .collect();
    let g: Vec<(f64, f64)> = v
        .iter()
        .zip(sign)
        .map(|(f, s)| (s * f.ln_gain0, f.ln_gain0_se))
        .collect();
    let c: Vec<(f64, f64)> = v
        .iter()
        .zip(sign)
        .map(|(f, s)| (s * f.ln_gain_change, f.ln_gain_change_se))
        .collect();
    let (dm, ds) = wmean(&d);
    let (gm, gs) = wmean(&g);
    let (cm, cs) = wmean(&c);
    let fmax = v.iter().map(|f| f.freq_max_hz).fold(0.0, f64::max);
    let mut parts = Vec::new();
    if (dm / ds).abs() > 3.0 {
        parts.push(format!(
            "{} by {:.2} +- {:.2} ms",
            if dm > 0.0 { "lags" } else { "leads" },
            1e3 * dm.abs(),
            1e3 * ds
        ));
    }
    if (gm / gs).abs() > 3.0 {
        parts.push(format!("gain {:+.2} +- {:.2} %", 100.0 * gm, 100.0 * gs));
    }
    if (cm / cs).abs() > 3.0 {
        parts.push(format!(
            "gain changing by {:+.2} +- {:.2} % up to {:.1} Hz",
            100.0 * cm,
            100.0 * cs,
            fmax
        ));
    }
    if parts.is_empty() {
        "differs (no single delay, gain or gain trend explains it)".into()
    } else {
        parts.join(", ")
    }
}

fn floors_text(f: &[usize]) -> String {
    f.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Findings from the inconsistent checks (see the module docs), strongest first.
pub fn findings(rep: &ConsistencyReport) -> Vec<Finding> {
    let bad: Vec<&CheckResult> = rep
        .checks
        .iter()
        .filter(|c| c.verdict == Verdict::Inconsistent)
        .collect();
    let mut out = Vec::new();
    // (a) accelerometer vs displacement sensor: per floor over tests, then all floors
    let mut by_floor: BTreeMap<usize, Vec<&CheckResult>> = BTreeMap::new();
    for c in bad.iter().filter(|c| c.kind == CheckKind::AccVsDisp) {
        let floor = c
            .name
            .rsplit(' ')
            .next()
            .and_then(|s| s.parse().ok())
            .unwrap_or(0);
        by_floor.entry(floor).or_default().push(c);
    }
    if !by_floor.is_empty() {
        let all: Vec<&CheckResult> = by_floor.values().flatten().copied().collect();
        let fits: Vec<&RatioFit> = all.iter().filter_map(|c| ratio(c)).collect();
        let floors: Vec<usize> = by_floor.keys().copied().collect();
        out.push(Finding {
            kind: CheckKind::AccVsDisp,
            strength: all.iter().map(|c| excess(c)).fold(f64::MIN, f64::max),
            text: format!(
                "acceleration vs displacement on floor(s) {} ({} of the test x floor pairs): the accelerometer {} relative to the displacement sensor",
                floors_text(&floors),
                all.len(),
                ratio_words(&fits, &vec![1.0; fits.len()])
            ),
            checks: all.iter().map(|c| c.name.clone()).collect(),
        });
    }
    // (d) reciprocity: which channels recur; delay of a channel = sign by its position
    let recip: Vec<&CheckResult> = bad
        .iter()
        .filter(|c| c.kind == CheckKind::Reciprocity)
        .copied()
        .collect();
    let mut by_channel: BTreeMap<String, Vec<(&CheckResult, f64)>> = BTreeMap::new();
    for c in &recip {
        if let [num, den] = c.compared.channels.as_slice() {
            by_channel.entry(num.clone()).or_default().push((c, 1.0));
            by_channel.entry(den.clone()).or_default().push((c, -1.0));
        }
    }
    for (ch, v) in &by_channel {
        if v.len() < 2 {
            continue;
        }
        let fits: Vec<&RatioFit> = v.iter().filter_map(|(c, _)| ratio(c)).collect();
        let signs: Vec<f64> = v.iter().map(|(_, s)| *s).collect();
        out.push(Finding {
            kind: CheckKind::Reciprocity,
            strength: v.iter().map(|(c, _)| excess(c)).fold(f64::MIN, f64::max),
            text: format!(
                "{ch} breaks reciprocity in {} pairs: it {} relative to its reciprocal partners",
                v.len(),
                ratio_words(&fits, &signs)
            ),
            checks: v.iter().map(|(c, _)| c.name.clone()).collect(),
        });
    }
    if by_channel.values().all(|v| v.len() < 2) {
        for c in &recip {
            out.push(Finding {
                kind: CheckKind::Reciprocity,
                strength: excess(c),
                text: format!("reciprocity fails: {}", c.summary),
                checks: vec![c.name.clone()],
            });
        }
    }
    // (b), (c), (e): one finding per check with the largest shifts
    for c in bad.iter().filter(|c| {
        matches!(
            c.kind,
            CheckKind::ImpactLevel | CheckKind::HammerVsShake | CheckKind::Drift
        )
    }) {
        let CheckDetails::Modes { modes } = &c.details else {
            continue;
        };
        let Some(m) = modes.iter().max_by(|a, b| a.chi2.total_cmp(&b.chi2)) else {
            continue;
        };
        let text = match c.kind {
            CheckKind::ImpactLevel => format!(
                "amplitude dependence in {}: mode {} moves {:+.2} % (z {:+.0}) from the weak to the strong impact{}",
                c.compared.segments.first().map_or("", |s| s.split('#').next().unwrap_or(s)),
                m.mode,
                100.0 * m.freq_shift_rel,
                m.freq_shift_z,
                m.ratio_db.map_or(String::new(), |r| format!(", FRF ratio {r:+.2} dB over the band"))
            ),
            CheckKind::HammerVsShake => format!("hammer and shake-table tests disagree: {}", c.summary),
            _ => format!(
                "{} differs between hammer tests (largest deviation {:+.3} %, z {:+.1})",
                c.name.trim_start_matches("drift "),
                100.0 * m.freq_shift_rel,
                m.freq_shift_z
            ),
        };
        out.push(Finding {
            kind: c.kind,
            strength: excess(c),
            text,
            checks: vec![c.name.clone()],
        });
    }
    out.sort_by(|a, b| b.strength.total_cmp(&a.strength));
    out
}

impl LocateReport {
    /// Combines the checks and (optionally) a residual map, deriving the findings.
    pub fn new(consistency: ConsistencyReport, residual_map: Option<ResidualMap>) -> Self {
        let findings = findings(&consistency);
        LocateReport {
            consistency,
            residual_map,
            findings,
        }
    }

    /// Markdown: findings, then every check, then the residual map.
    pub fn to_markdown(&self) -> String {
        let c = &self.consistency;
        let mut s = String::new();
        let _ = writeln!(s, "## Where recordings and model disagree\n");
        let _ = writeln!(
            s,
            "{} consistency checks; {} inconsistent at a family-wise error rate of {} ({} over all checks).\n",
            c.checks.len(),
            c.inconsistent().len(),
            c.level,
            if c.correction == "holm" { "Holm" } else { &c.correction }
        );
        if self.findings.is_empty() {
            let _ = writeln!(s, "No check found an inconsistency.\n");
        } else {
            let _ = writeln!(s, "### Findings (strongest first)\n");
            for f in &self.findings {
                let _ = writeln!(s, "- {} (strength {:.0})", f.text, f.strength);
            }
            let _ = writeln!(s);
        }
        let _ = writeln!(s, "### Checks\n");
        let _ = writeln!(s, "| check | statistic | dof | p | Holm p | verdict |");
        let _ = writeln!(s, "|---|---|---|---|---|---|");
        for k in &c.checks {
            let super::consistency::NullDistribution::ChiSquared { dof } = k.null;
            let _ = writeln!(
                s,
                "| {} | {:.1} | {} | {:.2e} | {:.2e} | {} |",
                k.name,
                k.statistic,
                dof,
                k.p_value,
                k.p_adjusted,
                match k.verdict {
                    Verdict::Consistent => "consistent",
                    Verdict::Inconsistent => "**inconsistent**",
                }
            );
        }
        if !c.skipped.is_empty() {
            let _ = writeln!(s, "\nNot checked:\n");
            for k in &c.skipped {
                let _ = writeln!(s, "- {k}");
            }
        }
        if let Some(m) = &self.residual_map {
            let _ = writeln!(s, "\n### Residual map\n");
            s.push_str(&m.to_markdown());
        }
        s
    }

    /// Writes `<dir>/locate.json` and `<dir>/locate.md`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let json = serde_json::to_string_pretty(self)
            .map_err(|e| crate::Error::Usage(format!("locate report JSON: {e}")))?;
        write_atomic(&dir.join("locate.json"), json.as_bytes())?;
        write_atomic(&dir.join("locate.md"), self.to_markdown().as_bytes())
    }
}
