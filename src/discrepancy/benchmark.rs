//! The missing-physics benchmark: simulated campaigns with a known effect (or none),
//! listed in `experiments/models/discrepancy/cases.toml`, diagnosed blind, and scored.
//!
//! [`read_cases`] reads the case list; the caller simulates and diagnoses each case
//! (`diagnose` never sees the case file); [`score`] compares verdicts and locations and
//! [`benchmark_markdown`] writes the confusion matrix, the location accuracy and the fit
//! before and after.

use super::verdict::DiagnosisRecord;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One benchmark case as listed in `cases.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchmarkCase {
    pub id: String,
    /// Simulation model, relative to the case file's folder.
    pub model: PathBuf,
    /// Expected verdict: a hypothesis name or `"none"`.
    pub verdict: String,
    /// Expected location, in the `diagnosis.json` form.
    pub location: serde_json::Value,
    /// What was put in, in words.
    pub size: String,
    pub noise_scale: f64,
    pub seed: u64,
    /// The true values of the effect's parameters, named and in the units `diagnose`
    /// reports them (`effect_parameters`); for scoring intervals only.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub truth: BTreeMap<String, f64>,
    /// Top of the analysed band, Hz (`diagnose --freq-max-hz`), when the case sets it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub freq_max_hz: Option<f64>,
}

#[derive(Debug, Deserialize)]
struct CaseFile {
    hypotheses: Vec<String>,
    #[serde(rename = "case")]
    cases: Vec<RawCase>,
}

#[derive(Debug, Deserialize)]
struct RawCase {
    id: String,
    model: PathBuf,
    verdict: String,
    location: toml::Value,
    size: String,
    noise_scale: f64,
    seed: u64,
    #[serde(default)]
    truth: BTreeMap<String, f64>,
    #[serde(default)]
    freq_max_hz: Option<f64>,
}

/// Reads `cases.toml`: the hypothesis names and the cases (model paths made absolute).
pub fn read_cases(path: &Path) -> Result<(Vec<String>, Vec<BenchmarkCase>)> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let file: CaseFile = toml::from_str(&text).map_err(|e| Error::Invalid {
        path: path.to_path_buf(),
        what: e.to_string(),
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut cases = Vec::with_capacity(file.cases.len());
    for c in file.cases {
        let location = serde_json::to_value(&c.location).map_err(|e| Error::Invalid {
            path: path.to_path_buf(),
            what: format!("case {}: location: {e}", c.id),
        })?;
        if c.verdict != "none" && !file.hypotheses.contains(&c.verdict) {
            return Err(Error::Invalid {
                path: path.to_path_buf(),
                what: format!(
                    "case {}: verdict {:?} is neither \"none\" nor one of {:?}",
                    c.id, c.verdict, file.hypotheses
                ),
            });
        }
        cases.push(BenchmarkCase {
            id: c.id,
            model: dir.join(c.model),
            verdict: c.verdict,
            location,
            size: c.size,
            noise_scale: c.noise_scale,
            seed: c.seed,
            truth: c.truth,
            freq_max_hz: c.freq_max_hz,
        });
    }
    Ok((file.hypotheses, cases))
}

/// A diagnosed case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseOutcome {
    pub case: BenchmarkCase,
    pub record: DiagnosisRecord,
    /// Channel name -> quantity name of the campaign (to compare channel and quantity
    /// locations).
    pub channel_quantity: BTreeMap<String, String>,
    pub seconds: f64,
}

impl CaseOutcome {
    /// The verdict is the expected one.
    pub fn verdict_correct(&self) -> bool {
        self.record.verdict == self.case.verdict
    }

    /// Verdict and location are both right (for `none`, the verdict alone).
    pub fn location_correct(&self) -> bool {
        self.verdict_correct()
            && locations_match(
                &self.case.location,
                &self.record.location,
                &self.channel_quantity,
            )
    }
}

/// Whether two locations name the same place. Channel sets compare as sets, and
/// `{"quantity": q}` equals the set of all channels of quantity `q` (responses only).
pub fn locations_match(
    expected: &serde_json::Value,
    got: &serde_json::Value,
    channel_quantity: &BTreeMap<String, String>,
) -> bool {
    let channels = |v: &serde_json::Value| -> Option<BTreeSet<String>> {
        if let Some(list) = v.get("channels").and_then(|c| c.as_array()) {
            return Some(
                list.iter()
                    .filter_map(|c| c.as_str().map(str::to_string))
                    .collect(),
            );
        }
        let q = v.get("quantity")?.as_str()?;
        Some(
            channel_quantity
                .iter()
                .filter(|(_, cq)| cq.as_str() == q)
                .map(|(c, _)| c.clone())
                .collect(),
        )
    };
    match (channels(expected), channels(got)) {
        (Some(a), Some(b)) => a == b,
        (None, None) => expected == got,
        _ => false,
    }
}

/// Confusion matrix (expected verdict -> got verdict -> count), over `labels` in order
/// (`none` first, then the hypotheses).
pub fn confusion(outcomes: &[CaseOutcome], labels: &[String]) -> Vec<Vec<usize>> {
    let index = |v: &str| labels.iter().position(|l| l == v);
    let mut m = vec![vec![0usize; labels.len() + 1]; labels.len()];
    for o in outcomes {
        if let Some(i) = index(&o.case.verdict) {
            let j = index(&o.record.verdict).unwrap_or(labels.len());
            m[i][j] += 1;
        }
    }
    m
}

/// The benchmark report: summary figures, confusion matrix, per-case table.
pub fn benchmark_markdown(outcomes: &[CaseOutcome], hypotheses: &[String], title: &str) -> String {
    let mut labels = vec!["none".to_string()];
    labels.extend(hypotheses.iter().cloned());
    let n = outcomes.len();
    let n_verdict = outcomes.iter().filter(|o| o.verdict_correct()).count();
    let n_located = outcomes.iter().filter(|o| o.location_correct()).count();
    let n_none = outcomes.iter().filter(|o| o.case.verdict == "none").count();
    let n_false = outcomes
        .iter()
        .filter(|o| o.case.verdict == "none" && o.record.verdict != "none")
        .count();
    let n_missed = outcomes
        .iter()
        .filter(|o| o.case.verdict != "none" && o.record.verdict == "none")
        .count();
    let mut s = String::new();
    let _ = writeln!(s, "# {title}\n");
    let _ = writeln!(
        s,
        "{n} cases diagnosed blind (the tool sees only the campaign). Verdict right in \
         {n_verdict}/{n}; verdict and location right in {n_located}/{n}. False alarms on \
         the {n_none} cases with nothing missing: {n_false}; effects missed (verdict `none`): \
         {n_missed}.\n"
    );
    let _ = writeln!(s, "## Confusion matrix (rows: truth, columns: verdict)\n");
    let m = confusion(outcomes, &labels);
    let short = |l: &str| l.replace('_', " ");
    let _ = write!(s, "| truth \\ verdict |");
    for l in &labels {
        let _ = write!(s, " {} |", short(l));
    }
    let _ = writeln!(s, " other |");
    let _ = writeln!(s, "|---|{}", "---|".repeat(labels.len() + 1));
    for (i, l) in labels.iter().enumerate() {
        if m[i].iter().sum::<usize>() == 0 {
            continue;
        }
        let _ = write!(s, "| {} |", short(l));
        for (j, v) in m[i].iter().enumerate() {
            if i == j {
                let _ = write!(s, " **{v}** |");
            } else {
                let _ = write!(s, " {v} |");
            }
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "\n## Cases\n");
    let _ = writeln!(
        s,
        "| case | put in | verdict | location (expected / found) | best delta ln Z | FDAC before -> after | chi2/point before -> after | time, s |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for o in outcomes {
        let r = &o.record;
        let mark = if o.location_correct() {
            "ok"
        } else if o.verdict_correct() {
            "ok, location wrong"
        } else {
            "WRONG"
        };
        let best = r
            .hypotheses
            .iter()
            .map(|h| h.delta_log_evidence)
            .fold(f64::NEG_INFINITY, f64::max);
        let _ = writeln!(
            s,
            "| {} | {} | {} ({mark}) | {} / {} | {:.1} | {:.4} -> {:.4} | {:.2} -> {:.2} | {:.0} |",
            o.case.id,
            o.case.size,
            r.verdict,
            o.case.location,
            r.location,
            best,
            r.fit_before.fdac_mean,
            r.fit_after.fdac_mean,
            r.fit_before.chi2_per_point,
            r.fit_after.chi2_per_point,
            o.seconds
        );
    }
    s.push_str(&super::effect_coverage::coverage_markdown(outcomes));
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_shipped_case_file_reads() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/discrepancy/cases.toml");
        let (hyps, cases) = read_cases(&path).unwrap();
        assert_eq!(hyps.len(), 6);
        assert!(cases.len() >= 21);
        assert_eq!(cases.iter().filter(|c| c.verdict == "none").count(), 3);
        for h in &hyps {
            assert!(cases.iter().filter(|c| &c.verdict == h).count() >= 3, "{h}");
        }
        assert!(cases.iter().all(|c| c.model.exists()), "model files exist");
        for c in cases.iter().filter(|c| c.verdict == "none") {
            assert!(c.truth.is_empty(), "{}", c.id);
        }
        for c in cases.iter().filter(|c| c.verdict != "none") {
            assert!(!c.truth.is_empty(), "{}: no truth", c.id);
        }
    }

    #[test]
    fn the_null_and_coverage_case_files_read() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/discrepancy");
        let (_, nulls) = read_cases(&dir.join("nulls/cases.toml")).unwrap();
        assert_eq!(nulls.len(), 30);
        assert!(nulls
            .iter()
            .all(|c| c.verdict == "none" && c.model.exists()));
        let red = nulls
            .iter()
            .filter(|c| {
                let m = crate::simulate::SimModel::from_path(&c.model).unwrap();
                m.noise.ar1_coefficient > 0.0
            })
            .count();
        assert_eq!(red, 20, "20 of the 30 nulls have red noise");
        let (hyps, cov) = read_cases(&dir.join("coverage/cases.toml")).unwrap();
        assert!(cov.len() >= 30);
        for c in &cov {
            assert!(hyps.contains(&c.verdict) && c.model.exists(), "{}", c.id);
            assert!(!c.truth.is_empty(), "{}: no truth", c.id);
        }
    }

    #[test]
    fn quantity_and_channel_locations_compare_as_sets() {
        let cq: BTreeMap<String, String> = [
            ("acc1", "acceleration"),
            ("acc2", "acceleration"),
            ("disp1", "displacement"),
        ]
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
        assert!(locations_match(
            &json!({"quantity": "acceleration"}),
            &json!({"channels": ["acc2", "acc1"]}),
            &cq
        ));
        assert!(!locations_match(
            &json!({"quantity": "acceleration"}),
            &json!({"channels": ["acc1"]}),
            &cq
        ));
        assert!(locations_match(
            &json!({"story": 2}),
            &json!({"story": 2}),
            &cq
        ));
        assert!(!locations_match(
            &json!({"story": 2}),
            &json!({"floor": 2}),
            &cq
        ));
        assert!(locations_match(&json!({}), &json!({}), &cq));
        assert!(!locations_match(&json!({}), &json!({"channels": []}), &cq));
    }
}
