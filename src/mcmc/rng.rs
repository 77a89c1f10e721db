//! Random streams: one ChaCha8 key from the user's seed, one stream per walker and one
//! per ensemble (move selection and split shuffling), so results do not depend on the
//! number of threads. RNG states are saved as (key, stream, word position), which
//! restores a generator exactly.

use crate::error::{Error, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Largest number of walkers per ensemble (stream ids pack ensemble and walker).
pub(crate) const MAX_WALKERS: usize = u32::MAX as usize - 1;

/// The 256-bit ChaCha key derived from a user seed.
pub(crate) fn key_from_seed(seed: u64) -> [u8; 32] {
    ChaCha8Rng::seed_from_u64(seed).get_seed()
}

fn stream_rng(key: [u8; 32], stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(stream);
    rng
}

/// The stream of walker `walker` of ensemble `ensemble`.
pub(crate) fn walker_rng(key: [u8; 32], ensemble: usize, walker: usize) -> ChaCha8Rng {
    stream_rng(key, ((ensemble as u64) << 32) | walker as u64)
}

/// The ensemble-level stream (move selection, split shuffling) of ensemble `ensemble`.
pub(crate) fn ensemble_rng(key: [u8; 32], ensemble: usize) -> ChaCha8Rng {
    stream_rng(key, ((ensemble as u64) << 32) | u32::MAX as u64)
}

/// Serialisable exact state of a [`ChaCha8Rng`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct RngState {
    key: [u8; 32],
    stream: u64,
    word_pos: u64,
}

impl RngState {
    pub(crate) fn of(rng: &ChaCha8Rng) -> Result<Self> {
        let word_pos = u64::try_from(rng.get_word_pos())
            .map_err(|_| Error::Numerical("random stream position exceeds 2^64 words".into()))?;
        Ok(RngState {
            key: rng.get_seed(),
            stream: rng.get_stream(),
            word_pos,
        })
    }

    pub(crate) fn restore(&self) -> ChaCha8Rng {
        let mut rng = stream_rng(self.key, self.stream);
        rng.set_word_pos(u128::from(self.word_pos));
        rng
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn saved_state_continues_the_same_stream() {
        let mut a = walker_rng(key_from_seed(7), 3, 11);
        for _ in 0..37 {
            let _: f64 = a.random();
        }
        let _: u32 = a.random(); // odd word position
        let mut b = RngState::of(&a).unwrap().restore();
        for _ in 0..100 {
            assert_eq!(a.random::<u64>(), b.random::<u64>());
        }
    }

    #[test]
    fn streams_differ() {
        let key = key_from_seed(1);
        let mut a = walker_rng(key, 0, 0);
        let mut b = walker_rng(key, 0, 1);
        let mut c = ensemble_rng(key, 0);
        let (x, y, z): (u64, u64, u64) = (a.random(), b.random(), c.random());
        assert!(x != y && y != z && x != z);
    }
}
