//! The experiment file: one TOML per study in `experiments/`.
//!
//! ```toml
//! name = "paper_repro"
//! description = "..."
//! data = "bundled:four-story"      # or a campaign folder (relative to the working directory)
//! out = "results/paper_repro"
//! seed = 20240917
//!
//! [estimate]                       # FRF estimation (see frfbayes::signal::EstimateOptions)
//! exp_window_tau_s = 20.0          # common exponential window of impact blocks (s); omit for none
//! band_factor = 1.0                # selected points: band_factor x the half-power band of each peak
//!
//! [update]
//! starts = 64                      # multistart local solves per variant
//! residual = "magnitude"           # or "log_magnitude"
//! weighting = "none"               # or "coherence" (Bendat & Piersol sigma per point)
//! [update.variables]               # bounds, start values, fixed values (frfbayes::update::VariablesConfig)
//! beta = [-0.1, 0.111]
//!
//! [[figure]]                       # like the paper's Figures 4, 5, 8, 9
//! table = "table1"                 # table1 = hammer tests, table2 = shake-table test
//! damping = "rayleigh"
//! response_floor = 4
//! excited_floor = 1                # hammer only
//! ```

use crate::error::{Error, Result};
use crate::signal::EstimateSection;
use crate::update::{DampingModel, ResidualForm, VariablesConfig};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole experiment.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentConfig {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// `bundled:four-story` or a campaign folder.
    #[serde(default = "default_data")]
    pub data: String,
    /// Output folder.
    pub out: PathBuf,
    #[serde(default)]
    pub seed: u64,
    #[serde(default)]
    pub estimate: EstimateSection,
    #[serde(default)]
    pub update: UpdateSection,
    #[serde(default, rename = "figure")]
    pub figures: Vec<FigureSpec>,
    /// Posterior sampling of the variants (`[bayes]`); absent: none.
    #[serde(default)]
    pub bayes: Option<BayesSection>,
}

fn default_data() -> String {
    "bundled:four-story".into()
}

/// How measured points are weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// The paper's plain least squares.
    #[default]
    None,
    /// Divide each residual by the Bendat & Piersol standard deviation of the point.
    Coherence,
}

/// Model-updating settings of an experiment.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UpdateSection {
    /// Local solves per variant.
    pub starts: usize,
    pub residual: ResidualForm,
    pub weighting: Weighting,
    pub variables: VariablesConfig,
    /// Bounds etc. for the shake-table table only (overrides `variables`).
    pub variables_shake_table: Option<VariablesConfig>,
}

impl Default for UpdateSection {
    fn default() -> Self {
        UpdateSection {
            starts: 64,
            residual: ResidualForm::Magnitude,
            weighting: Weighting::None,
            variables: VariablesConfig::default(),
            variables_shake_table: None,
        }
    }
}

/// Posterior sampling of the updating variants ([`crate::bayes`]), reported in
/// `identifiability.md`. Every field overrides the default of
/// [`SampleSettings::new`](crate::bayes::run::SampleSettings::new); FRF estimation and
/// bounds are the experiment's own.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BayesSection {
    /// Variants to sample, as `table1 caughey_receptance`; empty: every variant.
    pub variants: Vec<String>,
    pub walkers_per_dim: Option<usize>,
    pub n_ensembles: Option<usize>,
    pub max_steps: Option<u64>,
    pub thin_by: Option<u64>,
    /// Multistart local solves for the start point.
    pub n_starts: Option<usize>,
    pub residual: Option<ResidualForm>,
    pub rel_sigma_floor: Option<f64>,
}

/// One comparison figure (initial / experimental / updated, receptance and accelerance).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FigureSpec {
    /// `table1` (hammer tests) or `table2` (shake-table test).
    pub table: String,
    pub damping: DampingModel,
    pub response_floor: usize,
    #[serde(default)]
    pub excited_floor: Option<usize>,
}

impl ExperimentConfig {
    /// Reads an experiment file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let cfg: ExperimentConfig =
            toml::from_str(&text).map_err(|e| Error::invalid(path, e.to_string()))?;
        cfg.validate().map_err(|e| Error::invalid(path, e))?;
        Ok(cfg)
    }

    /// The paper reproduction shipped in the repository (`experiments/paper_repro.toml`).
    pub fn paper_repro() -> Result<Self> {
        Self::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/paper_repro.toml"))
    }

    fn validate(&self) -> std::result::Result<(), String> {
        if self.update.starts == 0 {
            return Err("update.starts must be at least 1".into());
        }
        if self.estimate.band_factor.is_nan() || self.estimate.band_factor <= 0.0 {
            return Err("estimate.band_factor must be positive".into());
        }
        if let Some(b) = &self.bayes {
            let known: Vec<String> = super::pipeline::Variant::all()
                .iter()
                .map(|v| format!("{} {}", v.table.key(), v.column()))
                .collect();
            if let Some(v) = b.variants.iter().find(|v| !known.contains(v)) {
                return Err(format!(
                    "bayes.variants: unknown variant {v:?} (have: {})",
                    known.join(", ")
                ));
            }
        }
        for f in &self.figures {
            if f.table != "table1" && f.table != "table2" {
                return Err(format!(
                    "figure.table must be \"table1\" or \"table2\", got {:?}",
                    f.table
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn json(v: impl Serialize) -> serde_json::Value {
        serde_json::to_value(v).unwrap()
    }

    /// `SampleSettings::new` (in `crate::bayes`, below this module) uses the default FRF
    /// estimation and bounds; they must stay those of the paper's experiment file.
    #[test]
    fn paper_repro_estimate_and_bounds_are_the_defaults() {
        let paper = ExperimentConfig::paper_repro().unwrap();
        assert_eq!(json(&paper.estimate), json(EstimateSection::default()));
        assert_eq!(
            json(&paper.update.variables),
            json(VariablesConfig::default())
        );
    }
}
