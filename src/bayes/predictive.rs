//! Posterior bands of model FRFs on dense frequency grids: the model magnitude at a
//! subset of posterior draws, summarised by pointwise quantiles (median, central 50 %
//! and 95 % intervals). The bands show the uncertainty of the model FRF (the mean of
//! the likelihood); the measurement noise `s sigma_k` is defined only at the selected
//! points and is not added.

use super::posterior::FrfPosterior;
use crate::error::{Error, Result};
use crate::frf::{FrfBlock, FrfPair};
use crate::mcmc::{quantile, Draws};
use crate::predict::Predict;
use rayon::prelude::*;

/// One FRF to draw bands for.
#[derive(Debug, Clone, PartialEq)]
pub struct PredictiveTarget {
    pub pair: FrfPair,
    /// Dense grid, rad/s.
    pub omega_rad_s: Vec<f64>,
    /// Exponential window of the measured FRF it is compared with.
    pub window_tau_s: Option<f64>,
}

/// Pointwise quantiles of one target's model magnitude.
#[derive(Debug, Clone, PartialEq)]
pub struct PredictiveBands {
    pub median: Vec<f64>,
    pub lo50: Vec<f64>,
    pub hi50: Vec<f64>,
    pub lo95: Vec<f64>,
    pub hi95: Vec<f64>,
    /// Draws used.
    pub n_draws: usize,
}

/// Bands of every target from `n_samples` draws spread evenly over `draws` (sampled
/// coordinates; all chains and draws in order, every `len / n_samples`-th one).
pub fn predictive_bands(
    post: &FrfPosterior,
    draws: &Draws,
    targets: &[PredictiveTarget],
    n_samples: usize,
) -> Result<Vec<PredictiveBands>> {
    super::summary::check_draws(post, draws)?;
    let total = draws.n_chains * draws.n_draws;
    if total == 0 || n_samples == 0 {
        return Err(Error::Usage("no draws for posterior bands".into()));
    }
    let n = n_samples.min(total);
    let picks: Vec<usize> = (0..n).map(|i| i * total / n).collect();
    let blocks: Vec<FrfBlock> = targets
        .iter()
        .map(|t| FrfBlock {
            omega_rad_s: t.omega_rad_s.clone(),
            pairs: vec![t.pair],
        })
        .collect();
    let taus: Vec<Option<f64>> = targets.iter().map(|t| t.window_tau_s).collect();
    let fp = post.predictor_over(&blocks, &taus)?;
    let curves: Vec<Result<Vec<f64>>> = picks
        .par_iter()
        .map(|&i| {
            let z = &draws.values[i * draws.dim..(i + 1) * draws.dim];
            let mut ws = fp.workspace();
            let mut out = vec![0.0; fp.n_outputs()];
            fp.predict(&z[..post.n_free()], &mut ws, &mut out)?;
            Ok(out)
        })
        .collect();
    let curves = curves.into_iter().collect::<Result<Vec<_>>>()?;
    let mut offset = 0;
    let mut out = Vec::with_capacity(targets.len());
    for t in targets {
        let m = t.omega_rad_s.len();
        let mut b = PredictiveBands {
            median: Vec::with_capacity(m),
            lo50: Vec::with_capacity(m),
            hi50: Vec::with_capacity(m),
            lo95: Vec::with_capacity(m),
            hi95: Vec::with_capacity(m),
            n_draws: n,
        };
        let mut col = vec![0.0; n];
        for k in offset..offset + m {
            for (c, curve) in col.iter_mut().zip(&curves) {
                *c = curve[k];
            }
            col.sort_by(f64::total_cmp);
            b.median.push(quantile(&col, 0.5));
            b.lo50.push(quantile(&col, 0.25));
            b.hi50.push(quantile(&col, 0.75));
            b.lo95.push(quantile(&col, 0.025));
            b.hi95.push(quantile(&col, 0.975));
        }
        offset += m;
        out.push(b);
    }
    Ok(out)
}
