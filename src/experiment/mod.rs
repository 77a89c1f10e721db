//! Experiments as configuration files: one TOML in `experiments/` per study, run by
//! `frfbayes run experiments/<name>.toml`; `frfbayes repro` is
//! `experiments/paper_repro.toml` with its defaults.

pub mod tables;
pub mod runinfo;
