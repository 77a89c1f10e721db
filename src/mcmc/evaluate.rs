//! How a batch of proposals is evaluated: the red-blue half of an ensemble (or an
//! initial ensemble) is one batch, and an [`Evaluator`] computes its log densities.
//!
//! The sampler's logic (moves, splits, accept steps) never depends on where a density
//! was computed, so every evaluator gives the same chain for a seed:
//! - [`Threads`]: rayon's pool of this process, in order (`par_iter().map().collect()`);
//! - [`Ranks`] (the default): the batch cut into one block of points per rank of
//!   [`crate::dist::active`], each block on its rank's threads, the values gathered on
//!   every rank. Every rank runs the same sampler with the same seed, so each proposes
//!   the same points; with one rank it is [`Threads`].

use rayon::prelude::*;

use crate::dist;
use crate::error::{Error, Result};

/// The log density (and pointwise terms) of point `i` of a batch, written into the
/// slice it is given (length: the batch's pointwise terms per point).
pub type PointFn<'a> = dyn Fn(usize, &mut [f64]) -> Result<f64> + Sync + 'a;

/// One batch: `ln_p[i]` and `pointwise[i * n_pointwise..]` of every point `i`.
pub struct Batch<'a> {
    /// Log density per point (output).
    pub ln_p: &'a mut [f64],
    /// Pointwise terms, point-major (output; empty when `n_pointwise` is 0).
    pub pointwise: &'a mut [f64],
    /// Pointwise terms per point.
    pub n_pointwise: usize,
    /// Spread the points over the threads; `false` when the caller already runs
    /// several batches in parallel.
    pub parallel: bool,
}

/// Evaluates batches of points. `evaluate` must fill every output from `point` alone,
/// so that the result does not depend on the evaluator; on failure it returns the
/// error of the first failed point (in point order) where it can.
pub trait Evaluator: Send + Sync {
    /// Fills `batch` with `point(i, ..)` for every point `i`.
    fn evaluate(&self, batch: Batch<'_>, point: &PointFn<'_>) -> Result<()>;

    /// True when `evaluate` is a collective call of several ranks right now: callers
    /// must then evaluate their batches one after the other, from the calling thread.
    fn collective(&self) -> bool {
        false
    }
}

/// rayon's pool of this process.
#[derive(Debug, Clone, Copy, Default)]
pub struct Threads;

impl Evaluator for Threads {
    fn evaluate(&self, batch: Batch<'_>, point: &PointFn<'_>) -> Result<()> {
        let n = batch.ln_p.len();
        // Without `parallel`, one piece as long as the batch: rayon runs it on this
        // thread without splitting it into tasks.
        let min_len = if batch.parallel { 1 } else { n.max(1) };
        let np = batch.n_pointwise;
        let values: Vec<Result<f64>> = if np == 0 {
            (0..n)
                .into_par_iter()
                .with_min_len(min_len)
                .map(|i| point(i, &mut []))
                .collect()
        } else {
            batch.pointwise[..n * np]
                .par_chunks_mut(np)
                .enumerate()
                .with_min_len(min_len)
                .map(|(i, pw)| point(i, pw))
                .collect()
        };
        for (lp, v) in batch.ln_p.iter_mut().zip(values) {
            *lp = v?;
        }
        Ok(())
    }
}

/// The ranks of [`dist::active`], threads within each rank (the default evaluator).
#[derive(Debug, Clone, Copy, Default)]
pub struct Ranks;

/// The points `[lo, hi)` of rank `rank` of `size` in a batch of `n`.
fn block(n: usize, size: usize, rank: usize) -> (usize, usize) {
    (rank * n / size, (rank + 1) * n / size)
}

impl Evaluator for Ranks {
    fn evaluate(&self, batch: Batch<'_>, point: &PointFn<'_>) -> Result<()> {
        let comm = dist::active();
        let (rank, size) = (comm.rank(), comm.size());
        if size == 1 {
            return Threads.evaluate(batch, point);
        }
        let (n, np) = (batch.ln_p.len(), batch.n_pointwise);
        let (lo, hi) = block(n, size, rank);
        let mut ln_p = vec![0.0; hi - lo];
        let mut pointwise = vec![0.0; (hi - lo) * np];
        let local = Batch {
            ln_p: &mut ln_p,
            pointwise: &mut pointwise,
            n_pointwise: np,
            parallel: true,
        };
        let mine = Threads
            .evaluate(local, &|i, pw| point(lo + i, pw))
            .map(|()| (ln_p, pointwise))
            .map_err(|e| e.to_string());
        for (r, (_, values)) in dist::gather_results(comm, &[(rank, mine)])? {
            let (lp, pw) = values.map_err(|what| Error::Distributed {
                rank: r,
                size,
                what,
            })?;
            let (lo, hi) = block(n, size, r);
            if lp.len() != hi - lo || pw.len() != (hi - lo) * np {
                return Err(Error::Distributed {
                    rank: r,
                    size,
                    what: format!("sent {} values for {} points", lp.len(), hi - lo),
                });
            }
            batch.ln_p[lo..hi].copy_from_slice(&lp);
            batch.pointwise[lo * np..hi * np].copy_from_slice(&pw);
        }
        Ok(())
    }

    fn collective(&self) -> bool {
        dist::active().size() > 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_the_batch_once() {
        for n in 0..20 {
            for size in 1..6 {
                let mut next = 0;
                for r in 0..size {
                    let (lo, hi) = block(n, size, r);
                    assert_eq!(lo, next);
                    next = hi;
                }
                assert_eq!(next, n);
            }
        }
    }

    #[test]
    fn threads_fill_in_order_and_report_the_first_error() {
        let mut ln_p = vec![0.0; 5];
        let mut pw = vec![0.0; 10];
        let batch = Batch {
            ln_p: &mut ln_p,
            pointwise: &mut pw,
            n_pointwise: 2,
            parallel: true,
        };
        let f = |i: usize, pw: &mut [f64]| {
            pw[0] = i as f64;
            pw[1] = -(i as f64);
            Ok(i as f64 * 0.5)
        };
        Ranks.evaluate(batch, &f).unwrap();
        assert_eq!(ln_p, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(pw[6..8], [3.0, -3.0]);
        let batch = Batch {
            ln_p: &mut ln_p,
            pointwise: &mut [],
            n_pointwise: 0,
            parallel: false,
        };
        let bad = |i: usize, _: &mut [f64]| match i {
            1 | 3 => Err(Error::Numerical(format!("point {i}"))),
            _ => Ok(0.0),
        };
        let e = Threads.evaluate(batch, &bad).unwrap_err().to_string();
        assert_eq!(e, "numerical: point 1");
    }
}
