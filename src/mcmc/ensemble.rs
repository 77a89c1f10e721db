//! One ensemble of walkers: its state, its initialisation and one red-blue step.
//!
//! Step (emcee's `RedBlueMove.propose`): pick a move with the ensemble stream; assign
//! walker `i` to split `i mod n_splits`, shuffled with the ensemble stream when
//! `randomize_split`; for each split in turn, every walker of the split proposes from
//! the other walkers (the complement, fixed during the split) and is accepted when
//! `ln u < ln_factor + ln p(q) - ln p(x)`. Proposal and `u` use only the walker's own
//! stream, and the densities of a split's proposals are one batch for an
//! [`Evaluator`] (threads, or ranks and threads), so the results are independent of
//! the thread and rank count.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

use super::density::{checked_ln_density, LogDensity};
use super::evaluate::{Batch, Evaluator};
use super::moves::{Complement, Move, Moves};
use super::rng::{ensemble_rng, walker_rng};
use crate::error::{Error, Result};

/// State of one ensemble. Positions are row-major (walker, parameter).
#[derive(Debug, Clone)]
pub(crate) struct Ensemble {
    pub dim: usize,
    pub n_pointwise: usize,
    pub positions: Vec<f64>,
    pub ln_p: Vec<f64>,
    /// Pointwise log-likelihood of the current states (walker, term); empty if unused.
    pub pointwise: Vec<f64>,
    pub walker_rngs: Vec<ChaCha8Rng>,
    pub rng: ChaCha8Rng,
    /// Accepted proposals per walker.
    pub accepted: Vec<u64>,
    /// Stored states (stored step, walker, parameter), ln p (stored step, walker) and
    /// pointwise terms (stored step, walker, term).
    pub chain: Vec<f64>,
    pub chain_ln_p: Vec<f64>,
    pub chain_pointwise: Vec<f64>,
}

impl Ensemble {
    /// Builds ensemble `index` from explicit positions (walker-major, `dim` each),
    /// evaluates them and checks the ensemble is usable: all log densities finite and
    /// the walkers' covariance of full rank.
    pub fn from_positions<D: LogDensity + ?Sized>(
        density: &D,
        key: [u8; 32],
        index: usize,
        positions: Vec<f64>,
        walker_rngs: Vec<ChaCha8Rng>,
        store_pointwise: bool,
        evaluator: &dyn Evaluator,
    ) -> Result<Self> {
        let dim = density.dim();
        let n_walkers = walker_rngs.len();
        let n_pointwise = if store_pointwise {
            density.n_pointwise()
        } else {
            0
        };
        if let Some(i) = positions.iter().position(|v| !v.is_finite()) {
            return Err(Error::Usage(format!(
                "ensemble {index}: initial walker {} has a non-finite coordinate {}",
                i / dim,
                i % dim
            )));
        }
        check_full_rank(index, &positions, n_walkers, dim)?;
        let mut ln_p = vec![0.0; n_walkers];
        let mut pointwise = vec![0.0; n_walkers * n_pointwise];
        let batch = Batch {
            ln_p: &mut ln_p,
            pointwise: &mut pointwise,
            n_pointwise,
            parallel: true,
        };
        let point = |w: usize, pw: &mut [f64]| {
            checked_ln_density(density, &positions[w * dim..(w + 1) * dim], pw)
        };
        evaluator.evaluate(batch, &point)?;
        if let Some(w) = ln_p.iter().position(|lp| !lp.is_finite()) {
            return Err(Error::Usage(format!(
                "ensemble {index}: initial walker {w} at {:?} has log density {}; \
                 start inside the support (smaller ball or a better center)",
                &positions[w * dim..(w + 1) * dim],
                ln_p[w]
            )));
        }
        Ok(Ensemble {
            dim,
            n_pointwise,
            positions,
            ln_p,
            pointwise,
            walker_rngs,
            rng: ensemble_rng(key, index),
            accepted: vec![0; n_walkers],
            chain: Vec::new(),
            chain_ln_p: Vec::new(),
            chain_pointwise: Vec::new(),
        })
    }

    /// Builds ensemble `index` as `center + scale ⊙ N(0, I)` per walker, each walker
    /// drawing from its own stream.
    #[allow(clippy::too_many_arguments)]
    pub fn from_ball<D: LogDensity + ?Sized>(
        density: &D,
        key: [u8; 32],
        index: usize,
        n_walkers: usize,
        center: &[f64],
        scale: &[f64],
        store_pointwise: bool,
        evaluator: &dyn Evaluator,
    ) -> Result<Self> {
        let dim = density.dim();
        if center.len() != dim || scale.len() != dim {
            return Err(Error::Usage(format!(
                "initial ball: center has {} and scale {} entries, the density has {dim} \
                 parameters",
                center.len(),
                scale.len()
            )));
        }
        if let Some(i) = scale.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::Usage(format!(
                "initial ball: scale of parameter {i} is {}; it must be positive and finite",
                scale[i]
            )));
        }
        let mut rngs: Vec<ChaCha8Rng> = (0..n_walkers).map(|w| walker_rng(key, index, w)).collect();
        let mut positions = Vec::with_capacity(n_walkers * dim);
        for rng in rngs.iter_mut() {
            for (c, s) in center.iter().zip(scale) {
                let n: f64 = rng.sample(StandardNormal);
                positions.push(c + s * n);
            }
        }
        Self::from_positions(
            density,
            key,
            index,
            positions,
            rngs,
            store_pointwise,
            evaluator,
        )
    }

    pub fn n_walkers(&self) -> usize {
        self.ln_p.len()
    }

    /// One red-blue step with a move picked from `moves`; returns how many proposals
    /// had a finite log density. Each half is proposed (in parallel, each walker from
    /// its own stream), evaluated as one batch by `evaluator`, then accepted in walker
    /// order. With `parallel`, the walkers of each half are spread over rayon's pool;
    /// without, they run on this thread (for callers that already run several
    /// ensembles in parallel). The outcome is the same either way, and whatever the
    /// evaluator.
    pub fn step<D: LogDensity + ?Sized>(
        &mut self,
        density: &D,
        moves: &Moves,
        randomize_split: bool,
        parallel: bool,
        evaluator: &dyn Evaluator,
    ) -> Result<u64> {
        let n_walkers = self.n_walkers();
        let mv = moves.select(&mut self.rng);
        let n_splits = mv.n_splits();
        let mut split_of: Vec<usize> = (0..n_walkers).map(|i| i % n_splits).collect();
        if randomize_split {
            for i in (1..n_walkers).rev() {
                let j = self.rng.random_range(0..=i);
                split_of.swap(i, j);
            }
        }
        let mut n_finite = 0;
        for split in 0..n_splits {
            n_finite += self.step_half(density, mv, &split_of, split, parallel, evaluator)?;
        }
        Ok(n_finite)
    }

    /// Proposes, evaluates and accepts the walkers of one split (see [`Ensemble::step`]).
    fn step_half<D: LogDensity + ?Sized>(
        &mut self,
        density: &D,
        mv: &dyn Move,
        split_of: &[usize],
        split: usize,
        parallel: bool,
        evaluator: &dyn Evaluator,
    ) -> Result<u64> {
        let (dim, np) = (self.dim, self.n_pointwise);
        let members: Vec<usize> = (0..split_of.len())
            .filter(|&i| split_of[i] == split)
            .collect();
        // One row per walker of the split (rows of at least one entry, for `par_chunks_mut`).
        let q_stride = dim.max(1);
        let mut proposals = vec![0.0; members.len() * q_stride];
        let mut ln_q = vec![0.0; members.len()];
        let mut q_pointwise = vec![0.0; members.len() * np];
        {
            let comp_refs: Vec<&[f64]> = self
                .positions
                .chunks(dim)
                .zip(split_of)
                .filter(|(_, &s)| s != split)
                .map(|(x, _)| x)
                .collect();
            let complement = Complement::new(&comp_refs);
            let fitted = mv.for_complement(&complement);
            let mv = fitted.as_deref().unwrap_or(mv);
            let rngs: Vec<&mut ChaCha8Rng> = self
                .walker_rngs
                .iter_mut()
                .zip(split_of)
                .filter(|(_, &s)| s == split)
                .map(|(r, _)| r)
                .collect();
            let positions = &self.positions;
            let min_len = if parallel { 1 } else { members.len().max(1) };
            let ln_factors: Vec<f64> = members
                .par_iter()
                .zip(rngs)
                .zip(proposals.par_chunks_mut(q_stride))
                .with_min_len(min_len)
                .map(|((&w, rng), q)| {
                    mv.propose(
                        &positions[w * dim..(w + 1) * dim],
                        &complement,
                        rng,
                        &mut q[..dim],
                    )
                })
                .collect();
            let batch = Batch {
                ln_p: &mut ln_q,
                pointwise: &mut q_pointwise,
                n_pointwise: np,
                parallel,
            };
            let proposals = &proposals;
            let point = |j: usize, pw: &mut [f64]| {
                checked_ln_density(density, &proposals[j * q_stride..j * q_stride + dim], pw)
            };
            evaluator.evaluate(batch, &point)?;
            // The accept step, in walker order; `u` comes from the walker's stream
            // after its proposal's draws.
            for (j, &w) in members.iter().enumerate() {
                let u: f64 = self.walker_rngs[w].random();
                if ln_factors[j] + ln_q[j] - self.ln_p[w] > u.ln() {
                    self.positions[w * dim..(w + 1) * dim]
                        .copy_from_slice(&proposals[j * q_stride..j * q_stride + dim]);
                    self.ln_p[w] = ln_q[j];
                    self.pointwise[w * np..(w + 1) * np]
                        .copy_from_slice(&q_pointwise[j * np..(j + 1) * np]);
                    self.accepted[w] += 1;
                }
            }
        }
        Ok(ln_q.iter().filter(|v| v.is_finite()).count() as u64)
    }

    /// Appends the current state to the stored chain.
    pub fn store(&mut self) {
        self.chain.extend_from_slice(&self.positions);
        self.chain_ln_p.extend_from_slice(&self.ln_p);
        self.chain_pointwise.extend_from_slice(&self.pointwise);
    }

    /// Number of stored states.
    pub fn n_stored(&self) -> usize {
        self.chain_ln_p.len() / self.n_walkers()
    }
}

/// Errors unless the walkers span all `dim` directions: every parameter must vary, and
/// the smallest eigenvalue of the walkers' correlation matrix must exceed
/// `1e-10` times the largest (a flat ensemble would stay flat under affine moves).
fn check_full_rank(index: usize, positions: &[f64], n_walkers: usize, dim: usize) -> Result<()> {
    let x = nalgebra::DMatrix::from_row_slice(n_walkers, dim, positions);
    let mean = x.row_mean();
    let mut centred = x.clone();
    for mut row in centred.row_iter_mut() {
        row -= &mean;
    }
    let cov = centred.transpose() * &centred / (n_walkers as f64 - 1.0);
    let sd: Vec<f64> = (0..dim).map(|i| cov[(i, i)].sqrt()).collect();
    if let Some(i) = sd.iter().position(|s| s.is_nan() || *s <= 0.0) {
        return Err(Error::Usage(format!(
            "ensemble {index}: all initial walkers have the same value of parameter {i}; \
             give it a positive spread"
        )));
    }
    // Singular values of the standardised walker matrix (the square roots of the
    // correlation matrix's eigenvalues, without squaring the condition number): an
    // exactly degenerate ensemble (walkers confined to a hyperplane) gives a ratio at
    // rounding level, ~1e-16; a legitimately anisotropic one (a posterior ridge, one
    // direction 1e8 times longer than another) stays far above the 1e-12 threshold.
    let z = nalgebra::DMatrix::from_fn(n_walkers, dim, |w, i| centred[(w, i)] / sd[i]);
    let s = z.singular_values();
    let (lo, hi) = (s.min(), s.max());
    if lo.is_nan() || lo <= 1e-12 * hi {
        return Err(Error::Usage(format!(
            "ensemble {index}: the initial walkers are degenerate (singular values of the \
             standardised walkers from {lo:.3e} to {hi:.3e}); they must span all {dim} dimensions"
        )));
    }
    Ok(())
}
