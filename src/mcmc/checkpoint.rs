//! Checkpoints: the full sampler state, so that a resumed run ends bit-identical to an
//! uninterrupted one.
//!
//! File layout (little-endian): the 8 magic bytes `FRFBMCMC`, a `u64` header length,
//! the JSON header (settings, move names, step, tau history, per-ensemble current
//! state, accept counts and RNG states as (key, stream, word position)), then for each
//! ensemble the stored chain, its log densities and its pointwise terms as raw `f64`.
//! Every `f64` of the state is saved by its bits (JSON decimal round trips are not
//! guaranteed exact). Written atomically with [`crate::io::write_atomic_with`].

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::config::validate;
use super::density::LogDensity;
use super::ensemble::Ensemble;
use super::moves::Moves;
use super::rng::RngState;
use super::sampler::{Sampler, SamplerConfig, TauCheck};
use crate::error::{Error, Result};
use crate::io::write_atomic_with;

const MAGIC: &[u8; 8] = b"FRFBMCMC";
const FORMAT_VERSION: u32 = 1;

#[derive(Serialize, Deserialize)]
struct Header {
    format_version: u32,
    crate_version: String,
    dim: usize,
    n_pointwise: usize,
    moves: String,
    config: SamplerConfig,
    /// Exact bits of `tau_multiple` and `tau_rel_change`.
    config_float_bits: [u64; 2],
    step: u64,
    history: Vec<TauRecord>,
    ensembles: Vec<EnsembleRecord>,
}

#[derive(Serialize, Deserialize)]
struct TauRecord {
    step: u64,
    tau_steps_bits: Vec<u64>,
    window_found: bool,
}

#[derive(Serialize, Deserialize)]
struct EnsembleRecord {
    positions_bits: Vec<u64>,
    ln_p_bits: Vec<u64>,
    pointwise_bits: Vec<u64>,
    walker_rngs: Vec<RngState>,
    rng: RngState,
    accepted: Vec<u64>,
    n_stored: usize,
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn unbits(v: &[u64]) -> Vec<f64> {
    v.iter().map(|&x| f64::from_bits(x)).collect()
}

impl<'d, D: LogDensity + ?Sized> Sampler<'d, D> {
    /// Writes the full state to `path` atomically. Refused after a failed step (the
    /// state may be half-updated; resume from the previous checkpoint instead).
    pub fn save_checkpoint(&self, path: &Path) -> Result<()> {
        if let Some(why) = &self.failed {
            return Err(Error::Usage(format!(
                "not saving a checkpoint of a failed run ({why})"
            )));
        }
        let header = Header {
            format_version: FORMAT_VERSION,
            crate_version: env!("CARGO_PKG_VERSION").into(),
            dim: self.density.dim(),
            n_pointwise: self.ensembles[0].n_pointwise,
            moves: self.moves.describe(),
            config: self.config.clone(),
            config_float_bits: [
                self.config.tau_multiple.to_bits(),
                self.config.tau_rel_change.to_bits(),
            ],
            step: self.step,
            history: self
                .history
                .iter()
                .map(|h| TauRecord {
                    step: h.step,
                    tau_steps_bits: bits(&h.tau_steps),
                    window_found: h.window_found,
                })
                .collect(),
            ensembles: self
                .ensembles
                .iter()
                .map(|e| {
                    Ok(EnsembleRecord {
                        positions_bits: bits(&e.positions),
                        ln_p_bits: bits(&e.ln_p),
                        pointwise_bits: bits(&e.pointwise),
                        walker_rngs: e
                            .walker_rngs
                            .iter()
                            .map(RngState::of)
                            .collect::<Result<_>>()?,
                        rng: RngState::of(&e.rng)?,
                        accepted: e.accepted.clone(),
                        n_stored: e.n_stored(),
                    })
                })
                .collect::<Result<_>>()?,
        };
        let json = serde_json::to_vec(&header)
            .map_err(|e| Error::Numerical(format!("checkpoint header: {e}")))?;
        write_atomic_with(path, |w| {
            w.write_all(MAGIC)?;
            w.write_all(&(json.len() as u64).to_le_bytes())?;
            w.write_all(&json)?;
            for e in &self.ensembles {
                for v in [&e.chain, &e.chain_ln_p, &e.chain_pointwise] {
                    write_f64s(w, v)?;
                }
            }
            Ok(())
        })
    }

    /// Rebuilds a sampler from a checkpoint written by [`Sampler::save_checkpoint`].
    /// `density` and `moves` must be the ones of the original run (dimension, pointwise
    /// terms and move names are checked); settings come from the checkpoint.
    pub fn resume(density: &'d D, moves: Moves, path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let bad = |what: String| Error::invalid(path, what);
        if bytes.len() < 16 || &bytes[..8] != MAGIC {
            return Err(bad(
                "not a frfbayes MCMC checkpoint (bad magic bytes)".into()
            ));
        }
        let header_len = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes")) as usize;
        let body = bytes
            .get(16..16usize.saturating_add(header_len))
            .ok_or_else(|| bad("truncated checkpoint header".into()))?;
        let header: Header =
            serde_json::from_slice(body).map_err(|e| bad(format!("checkpoint header: {e}")))?;
        if header.format_version != FORMAT_VERSION {
            return Err(bad(format!(
                "checkpoint format version {} (this build reads {FORMAT_VERSION})",
                header.format_version
            )));
        }
        if header.dim != density.dim() {
            return Err(bad(format!(
                "checkpoint has {} parameters, the density {}",
                header.dim,
                density.dim()
            )));
        }
        if moves.describe() != header.moves {
            return Err(bad(format!(
                "checkpoint was written with moves [{}], resuming with [{}]",
                header.moves,
                moves.describe()
            )));
        }
        let mut config = header.config;
        config.tau_multiple = f64::from_bits(header.config_float_bits[0]);
        config.tau_rel_change = f64::from_bits(header.config_float_bits[1]);
        validate(density, &moves, &config)?;
        let np = header.n_pointwise;
        let expect_np = if config.store_pointwise {
            density.n_pointwise()
        } else {
            0
        };
        if np != expect_np {
            return Err(bad(format!(
                "checkpoint stores {np} pointwise terms, the density gives {expect_np}"
            )));
        }
        let (dim, w) = (header.dim, config.n_walkers);
        if header.ensembles.len() != config.n_ensembles {
            return Err(bad("number of ensembles differs from the settings".into()));
        }
        let mut rest = &bytes[16 + header_len..];
        let mut ensembles = Vec::with_capacity(header.ensembles.len());
        for (i, r) in header.ensembles.into_iter().enumerate() {
            let ok = r.positions_bits.len() == w * dim
                && r.ln_p_bits.len() == w
                && r.pointwise_bits.len() == w * np
                && r.walker_rngs.len() == w
                && r.accepted.len() == w;
            if !ok {
                return Err(bad(format!(
                    "ensemble {i}: state sizes do not match the settings"
                )));
            }
            let n = r.n_stored;
            let chain = read_f64s(&mut rest, n * w * dim)
                .ok_or_else(|| bad(format!("ensemble {i}: truncated chain")))?;
            let chain_ln_p = read_f64s(&mut rest, n * w)
                .ok_or_else(|| bad(format!("ensemble {i}: truncated chain")))?;
            let chain_pointwise = read_f64s(&mut rest, n * w * np)
                .ok_or_else(|| bad(format!("ensemble {i}: truncated chain")))?;
            ensembles.push(Ensemble {
                dim,
                n_pointwise: np,
                positions: unbits(&r.positions_bits),
                ln_p: unbits(&r.ln_p_bits),
                pointwise: unbits(&r.pointwise_bits),
                walker_rngs: r.walker_rngs.iter().map(RngState::restore).collect(),
                rng: r.rng.restore(),
                accepted: r.accepted,
                chain,
                chain_ln_p,
                chain_pointwise,
            });
        }
        if !rest.is_empty() {
            return Err(bad("trailing bytes after the stored chains".into()));
        }
        Ok(Sampler {
            density,
            moves,
            config,
            ensembles,
            step: header.step,
            history: header
                .history
                .into_iter()
                .map(|h| TauCheck {
                    step: h.step,
                    tau_steps: unbits(&h.tau_steps_bits),
                    window_found: h.window_found,
                })
                .collect(),
            failed: None,
            evaluator: Box::new(super::evaluate::Ranks),
        })
    }
}

fn write_f64s(w: &mut dyn Write, v: &[f64]) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(8 * v.len().min(1 << 16));
    for chunk in v.chunks(1 << 16) {
        buf.clear();
        for x in chunk {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        w.write_all(&buf)?;
    }
    Ok(())
}

fn read_f64s(rest: &mut &[u8], n: usize) -> Option<Vec<f64>> {
    let len = n.checked_mul(8)?;
    if rest.len() < len {
        return None;
    }
    let (head, tail) = rest.split_at(len);
    *rest = tail;
    Some(
        head.chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect(),
    )
}
