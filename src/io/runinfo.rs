//! `run.json`: what produced a result folder (command line, configuration, seed, versions,
//! timings), so any figure can be regenerated.

use super::atomic::write_atomic;
use crate::error::Result;
use serde::Serialize;
use std::path::Path;
use std::time::Instant;

/// The record written as `run.json` beside every result.
#[derive(Debug, Clone, Serialize)]
pub struct RunInfo {
    /// The command line, as typed.
    pub command: Vec<String>,
    /// frfbayes version (Cargo package version).
    pub frfbayes_version: &'static str,
    /// rustc version that built the binary, when known at build time.
    pub rustc: Option<&'static str>,
    /// Build profile (`release` or `debug`).
    pub profile: &'static str,
    /// Worker threads used by rayon.
    pub threads: usize,
    /// Master seed.
    pub seed: u64,
    /// The experiment configuration as resolved (defaults filled in).
    pub config: serde_json::Value,
    /// Where the data came from.
    pub data: String,
    /// Wall-clock seconds of each named stage, in order.
    pub timings_s: Vec<(String, f64)>,
    /// Unix time at start, seconds.
    pub started_unix_s: u64,
}

impl RunInfo {
    /// A record for a run starting now.
    pub fn start(seed: u64, config: serde_json::Value, data: String) -> Self {
        RunInfo {
            command: std::env::args().collect(),
            frfbayes_version: env!("CARGO_PKG_VERSION"),
            rustc: option_env!("RUSTC_VERSION"),
            profile: if cfg!(debug_assertions) {
                "debug"
            } else {
                "release"
            },
            threads: rayon::current_num_threads(),
            seed,
            config,
            data,
            timings_s: Vec::new(),
            started_unix_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
        }
    }

    /// Runs `f` and records its wall time under `stage`.
    pub fn time<T>(&mut self, stage: &str, f: impl FnOnce() -> T) -> T {
        let t0 = Instant::now();
        let out = f();
        self.timings_s
            .push((stage.to_string(), t0.elapsed().as_secs_f64()));
        out
    }

    /// Writes `dir/run.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let json =
            serde_json::to_vec_pretty(self).map_err(|e| crate::Error::Numerical(e.to_string()))?;
        write_atomic(&dir.join("run.json"), &json)
    }
}
