//! The sampler's settings ([`SamplerConfig`]), their defaults and their validation
//! against a density and a move mixture.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::density::LogDensity;
use super::moves::Moves;
use super::rng::MAX_WALKERS;
use crate::error::{Error, Result};

/// Fewest independent ensembles (R-hat compares them).
pub const MIN_ENSEMBLES: usize = 4;

/// [`Burn::Auto`](crate::mcmc::Burn::Auto) and [`Burn::Tau`](crate::mcmc::Burn::Tau) thin
/// less when needed to keep this many draws per walker.
pub const MIN_DRAWS_PER_WALKER: u64 = 100;

/// Where and how often to write checkpoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckpointConfig {
    /// Checkpoint file (written atomically).
    pub path: PathBuf,
    /// Write every this many steps (and when the run ends).
    pub every_steps: u64,
}

/// Sampler settings. `SamplerConfig::new(n_walkers, seed)` gives the defaults, and so
/// does deserialising (e.g. from TOML) with only `n_walkers` and `seed` given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplerConfig {
    /// Walkers per ensemble (>= 2 x dim).
    pub n_walkers: usize,
    /// Independent ensembles (>= 4; default 4).
    #[serde(default = "defaults::n_ensembles")]
    pub n_ensembles: usize,
    /// Master seed: all random streams derive from it.
    pub seed: u64,
    /// Step cap (default 100 000).
    #[serde(default = "defaults::max_steps")]
    pub max_steps: u64,
    /// Steps between convergence checks (default 100, as in emcee's example).
    #[serde(default = "defaults::check_every")]
    pub check_every: u64,
    /// Chain must be longer than this many tau (default 50).
    #[serde(default = "defaults::tau_multiple")]
    pub tau_multiple: f64,
    /// Largest relative change of tau between checks (default 0.01).
    #[serde(default = "defaults::tau_rel_change")]
    pub tau_rel_change: f64,
    /// Store every this many steps (default 1).
    #[serde(default = "defaults::one")]
    pub thin_by: u64,
    /// Shuffle walkers between splits every step (emcee's default, true).
    #[serde(default = "defaults::yes")]
    pub randomize_split: bool,
    /// Store the density's pointwise log-likelihood with the chain (default false; see
    /// also [`Draws::compute_pointwise`](crate::mcmc::Draws::compute_pointwise)).
    #[serde(default)]
    pub store_pointwise: bool,
    /// Periodic checkpoints (default none).
    #[serde(default)]
    pub checkpoint: Option<CheckpointConfig>,
}

mod defaults {
    pub fn n_ensembles() -> usize {
        super::MIN_ENSEMBLES
    }
    pub fn max_steps() -> u64 {
        100_000
    }
    pub fn check_every() -> u64 {
        100
    }
    pub fn tau_multiple() -> f64 {
        50.0
    }
    pub fn tau_rel_change() -> f64 {
        0.01
    }
    pub fn one() -> u64 {
        1
    }
    pub fn yes() -> bool {
        true
    }
}

impl SamplerConfig {
    /// Defaults: 4 ensembles, 100 000 step cap, checks every 100 steps, 50 tau, 1%.
    pub fn new(n_walkers: usize, seed: u64) -> Self {
        SamplerConfig {
            n_walkers,
            n_ensembles: defaults::n_ensembles(),
            seed,
            max_steps: defaults::max_steps(),
            check_every: defaults::check_every(),
            tau_multiple: defaults::tau_multiple(),
            tau_rel_change: defaults::tau_rel_change(),
            thin_by: 1,
            randomize_split: true,
            store_pointwise: false,
            checkpoint: None,
        }
    }
}

pub(super) fn validate<D: LogDensity + ?Sized>(
    density: &D,
    moves: &Moves,
    c: &SamplerConfig,
) -> Result<()> {
    let dim = density.dim();
    if dim == 0 {
        return Err(Error::Usage("the density has no parameters".into()));
    }
    if c.n_walkers < 2 * dim {
        return Err(Error::Usage(format!(
            "{} walkers for {dim} parameters: use at least 2 x {dim} = {} walkers",
            c.n_walkers,
            2 * dim
        )));
    }
    if c.n_walkers > MAX_WALKERS {
        return Err(Error::Usage(format!("at most {MAX_WALKERS} walkers")));
    }
    if c.n_ensembles < MIN_ENSEMBLES {
        return Err(Error::Usage(format!(
            "{} ensembles: use at least {MIN_ENSEMBLES} independent ensembles",
            c.n_ensembles
        )));
    }
    if c.check_every == 0 || c.thin_by == 0 {
        return Err(Error::Usage(
            "check_every and thin_by must be at least 1".into(),
        ));
    }
    if c.checkpoint.as_ref().is_some_and(|cp| cp.every_steps == 0) {
        return Err(Error::Usage(
            "checkpoint every_steps must be at least 1".into(),
        ));
    }
    if !(c.tau_multiple > 0.0 && c.tau_rel_change > 0.0) {
        return Err(Error::Usage(
            "tau_multiple and tau_rel_change must be positive".into(),
        ));
    }
    for m in moves.iter() {
        let splits = m.n_splits();
        if splits < 2 || splits > c.n_walkers {
            return Err(Error::Usage(format!(
                "move {} uses {splits} splits; need 2..={} (walkers)",
                m.name(),
                c.n_walkers
            )));
        }
        let smallest_complement = c.n_walkers - c.n_walkers.div_ceil(splits);
        if smallest_complement < m.min_complement() {
            return Err(Error::Usage(format!(
                "move {} needs {} complementary walkers; {} walkers in {splits} splits leave {}",
                m.name(),
                m.min_complement(),
                c.n_walkers,
                smallest_complement
            )));
        }
    }
    Ok(())
}
