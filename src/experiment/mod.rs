//! Experiments as configuration files: one TOML in `experiments/` per study, run by
//! `frfbayes run experiments/<name>.toml`; `frfbayes repro` is
//! `experiments/paper_repro.toml` with its defaults.

pub mod config;
pub mod pipeline;
pub mod tables;

pub use config::ExperimentConfig;
pub mod driver;
pub mod figures;
pub mod identifiability;
pub mod identifiability_report;
pub mod posterior;
pub mod posterior_figures;
pub mod posterior_report;
pub mod report;
