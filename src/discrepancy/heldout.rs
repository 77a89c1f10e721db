//! Predictive check on data held out of the fit: leave one segment (test or impact) out,
//! fit the nominal model and the hypothesis to the rest (MAP, from their full-data fits),
//! and score the held-out segment by its log-likelihood under each fit (plug-in log
//! predictive density, error floor included). Effects carry over between the fits by
//! their physical values. A hypothesis refitted by replaying the tests in the time
//! domain ([`super::refine`]) is refitted and scored the same way here.
//!
//! The gain of a hypothesis is the sum over segments of its held-out log density minus
//! the nominal model's. Its standard error is `sqrt(n) sd(per-segment gains)` (the
//! segments are independent recordings). A hypothesis that only bends the nominal model
//! towards noise or estimator artefacts of the fitted segments does not predict a
//! recording it has not seen.
//!
//! The segments' gains are far from normal: a shake-table record holds several times
//! the data of one hammer impact, so one segment can dominate the spread and hide a gain
//! that every segment shows. The verdict therefore tests the per-segment gains with the
//! exact one-sided Wilcoxon signed-rank test ([`signed_rank_p_greater`]), which asks
//! whether gains are positive more often and by more than chance would give, whatever
//! their scale.

use super::data::DiagnosisData;
use super::fit::{fit_map, MapOptions};
use super::hypothesis::Hypothesis;
use super::location::Location;
use super::posterior::ModelPosterior;
use super::refine::replay_map_options;
use super::time_domain::TimeDomainModel;
use crate::error::{Error, Result};
use crate::io::Campaign;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Held-out comparison of one hypothesis against the nominal model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// Held-out segment names.
    pub segments: Vec<String>,
    /// Held-out log density of each segment under the nominal fit and the hypothesis' fit.
    pub nominal: Vec<f64>,
    pub hypothesis: Vec<f64>,
    /// Sum of `hypothesis - nominal`.
    pub gain: f64,
    /// `sqrt(n) sd(per-segment gains)`.
    pub gain_se: f64,
    /// One-sided exact Wilcoxon signed-rank p-value of the per-segment gains (null: the
    /// gains are symmetric about zero; alternative: shifted above zero).
    pub p_value: f64,
    /// Number of segments with a non-zero gain (the signed-rank test's sample size).
    pub n_ranked: usize,
}

fn subset(data: &DiagnosisData, keep: impl Fn(usize) -> bool) -> DiagnosisData {
    let mut d = data.clone();
    d.segments = data
        .segments
        .iter()
        .enumerate()
        .filter(|(i, _)| keep(*i))
        .map(|(_, s)| s.clone())
        .collect();
    d
}

/// A model: the nominal one (`None`) or an extension at its location.
type Model = Option<(Arc<dyn Hypothesis>, Location)>;

/// A posterior of `data` under the first model of `chain` that can act on it (a
/// hypothesis cannot when, say, its channels are not in these segments), and its index;
/// the nominal model when none can.
fn first_posterior(data: DiagnosisData, chain: &[Model]) -> Result<(ModelPosterior, usize)> {
    let data = Arc::new(data);
    for (k, m) in chain.iter().enumerate() {
        if m.is_some() {
            if let Ok(p) = ModelPosterior::new(data.clone(), m.clone()) {
                return Ok((p, k));
            }
        }
    }
    Ok((ModelPosterior::new(data, None)?, chain.len()))
}

/// Steps of a held-out fit that replays the tests (it starts from the full-data fit).
const HELD_OUT_REPLAY_EVALUATIONS: usize = 6;

/// The frame (and error floor) of `z`, then the coordinates in `post` of the leading
/// physical effect values `effect` (all of them for the model they came from, the
/// accepted effects' for the model it extends: effects lead in the order they were
/// accepted). An effect's coordinate may be scaled by the data, as the cubic spring's is
/// by the largest drift weight, so coordinates do not carry over between subsets of the
/// data.
fn start_for(z: &[f64], effect: &[f64], post: &ModelPosterior) -> Vec<f64> {
    let mut out = z[..=post.eta_index()].to_vec();
    out.extend(
        post.effect_params()
            .iter()
            .zip(effect)
            .map(|(p, &v)| p.coordinate_of(v)),
    );
    out
}

/// Log density of segment `i` under a fit of all other segments by the first model of
/// `chain` that can act on them (the model compared, then the models it extends),
/// starting from `z` (effect: physical values `effect`). Segment `i` is scored by the
/// first model from there on that can act on it, with the fit's frame and effects. With
/// `replay`, fits by the first model of `chain` replay the tests in the time domain.
fn held_out_density(
    data: &DiagnosisData,
    i: usize,
    chain: &[Model],
    (z, effect): (&[f64], &[f64]),
    map: &MapOptions,
    replay: Option<&Campaign>,
) -> Result<f64> {
    let with_replay = |post: ModelPosterior, k: usize| -> Result<ModelPosterior> {
        match replay {
            Some(c) if k == 0 => {
                let td = TimeDomainModel::new(c, post.data().clone())?;
                post.with_time_domain(Arc::new(td))
            }
            _ => Ok(post),
        }
    };
    let (post, k) = first_posterior(subset(data, |j| j != i), chain)?;
    let post = with_replay(post, k)?;
    let map = if post.is_time_domain() {
        &replay_map_options(map, HELD_OUT_REPLAY_EVALUATIONS, 1)
    } else {
        map
    };
    let fit = fit_map(&post, &[start_for(z, effect, &post)], map)?;
    let fitted_effect = post.effect_physical(&fit.z)?;
    let rest = chain.get(k..).unwrap_or(&[]);
    let (post_one, k_one) = first_posterior(subset(data, |j| j == i), rest)?;
    let post_one = with_replay(post_one, k + k_one)?;
    let z_one = start_for(&fit.z, &fitted_effect, &post_one);
    // With the model's H at the fit as the gain carrier when the options ask for it.
    let pred = post_one.predict(&z_one)?;
    let eta = z_one[post_one.eta_index()].exp();
    Ok(post_one
        .at_map_predicted(&z_one, pred.clone())?
        .ln_likelihood_of(&pred, eta))
}

/// Leave-one-segment-out comparison of `hypothesis` at `location` (full-data MAP
/// `hyp_z`) with the model it extends, `base` (the nominal model when `None`; full-data
/// MAP `base_z`). Needs two segments.
#[allow(clippy::too_many_arguments)]
pub fn held_out(
    data: &DiagnosisData,
    base: &Model,
    base_z: &[f64],
    hypothesis: &Arc<dyn Hypothesis>,
    location: &Location,
    hyp_z: &[f64],
    map: &MapOptions,
    replay: Option<&Campaign>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<HeldOut> {
    let n = data.segments.len();
    if n < 2 {
        return Err(Error::Usage(
            "a held-out check needs at least two segments (tests or impacts)".into(),
        ));
    }
    let mut out = HeldOut {
        segments: Vec::with_capacity(n),
        nominal: Vec::with_capacity(n),
        hypothesis: Vec::with_capacity(n),
        gain: 0.0,
        gain_se: 0.0,
        p_value: 1.0,
        n_ranked: 0,
    };
    let hyp = Some((hypothesis.clone(), location.clone()));
    let shared = Arc::new(data.clone());
    let effect = ModelPosterior::new(shared.clone(), hyp.clone())?.effect_physical(hyp_z)?;
    let base_effect = ModelPosterior::new(shared, base.clone())?.effect_physical(base_z)?;
    let base_chain = [base.clone()];
    let chain = [hyp, base.clone()];
    for i in 0..n {
        out.segments.push(data.segments[i].name.clone());
        out.nominal.push(held_out_density(
            data,
            i,
            &base_chain,
            (base_z, &base_effect),
            map,
            None,
        )?);
        out.hypothesis.push(held_out_density(
            data,
            i,
            &chain,
            (hyp_z, &effect),
            map,
            replay,
        )?);
        progress(i + 1, n);
    }
    let gains: Vec<f64> = out
        .hypothesis
        .iter()
        .zip(&out.nominal)
        .map(|(h, n)| h - n)
        .collect();
    let mean = gains.iter().sum::<f64>() / n as f64;
    let var = gains.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    out.gain = mean * n as f64;
    out.gain_se = (var * n as f64).sqrt();
    (out.p_value, out.n_ranked) = signed_rank_p_greater(&gains, &out.nominal);
    Ok(out)
}

/// Exact one-sided p-value of the Wilcoxon signed-rank statistic `W+` (the sum of the
/// ranks of |gain| over the positive gains): the probability, with every sign equally
/// likely and independent, of a `W+` at least as large as observed.
///
/// Gains that are zero to rounding (|gain| below 1e-9 of the segment's log density, as
/// where a hypothesis cannot act on a segment) are dropped, as in Wilcoxon's original
/// test. Tied magnitudes share their mean rank. The null distribution is enumerated by
/// dynamic programming over doubled ranks (integers even with ties), so the p-value is
/// exact for any number of segments. With no non-zero gain the p-value is 1.
///
/// Returns the p-value and the number of non-zero gains ranked.
pub fn signed_rank_p_greater(gains: &[f64], scale: &[f64]) -> (f64, usize) {
    let mut mags: Vec<(f64, bool)> = gains
        .iter()
        .zip(scale.iter().chain(std::iter::repeat(&0.0)))
        .filter(|(g, s)| g.abs() > 1e-9 * s.abs().max(1.0))
        .map(|(g, _)| (g.abs(), *g > 0.0))
        .collect();
    let n = mags.len();
    if n == 0 {
        return (1.0, 0);
    }
    mags.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Doubled mean ranks: a tie group over 1-based ranks i+1..=j gets i+1+j.
    let mut doubled = vec![0usize; n];
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        while j < n && mags[j].0 == mags[i].0 {
            j += 1;
        }
        for r in &mut doubled[i..j] {
            *r = i + 1 + j;
        }
        i = j;
    }
    let observed: usize = doubled
        .iter()
        .zip(&mags)
        .filter(|(_, m)| m.1)
        .map(|(r, _)| r)
        .sum();
    let total: usize = doubled.iter().sum();
    // prob[w] = P(doubled W+ = w) under the null.
    let mut prob = vec![0.0f64; total + 1];
    prob[0] = 1.0;
    let mut reach = 0;
    for &r in &doubled {
        reach += r;
        for w in (0..=reach).rev() {
            let with = if w >= r { prob[w - r] } else { 0.0 };
            prob[w] = 0.5 * (prob[w] + with);
        }
    }
    (prob[observed..].iter().sum::<f64>().min(1.0), n)
}

#[cfg(test)]
mod tests {
    use super::signed_rank_p_greater;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Oracle: enumerate all 2^n sign patterns.
    fn brute_force(gains: &[f64]) -> f64 {
        let nz: Vec<f64> = gains.iter().copied().filter(|g| *g != 0.0).collect();
        let n = nz.len();
        let rank = |x: f64| {
            let below = nz.iter().filter(|y| y.abs() < x.abs()).count() as f64;
            let equal = nz.iter().filter(|y| y.abs() == x.abs()).count() as f64;
            below + (equal + 1.0) / 2.0
        };
        let ranks: Vec<f64> = nz.iter().map(|g| rank(*g)).collect();
        let observed: f64 = nz
            .iter()
            .zip(&ranks)
            .filter(|(g, _)| **g > 0.0)
            .map(|(_, r)| r)
            .sum();
        let mut count = 0usize;
        for mask in 0..(1usize << n) {
            let w: f64 = (0..n)
                .filter(|i| mask >> i & 1 == 1)
                .map(|i| ranks[i])
                .sum();
            if w >= observed - 1e-12 {
                count += 1;
            }
        }
        count as f64 / (1usize << n) as f64
    }

    #[test]
    fn all_positive_gains_give_two_to_the_minus_n_whatever_their_scale() {
        // The base_flexibility-1 held-out gains: one segment 16x the others.
        let gains = [
            2199.6, 4928.9, 2249.4, 5028.1, 2229.5, 4930.3, 2156.2, 5101.0, 79140.3,
        ];
        let (p, n) = signed_rank_p_greater(&gains, &[]);
        assert_eq!(n, 9);
        assert!((p - 1.0 / 512.0).abs() < 1e-15, "{p}");
        let neg: Vec<f64> = gains.iter().map(|g| -g).collect();
        assert!((signed_rank_p_greater(&neg, &[]).0 - 1.0).abs() < 1e-15);
    }

    #[test]
    fn matches_enumeration_with_ties_and_zeros() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for n in 1..=12 {
            for _ in 0..20 {
                // Integers in -4..=4 give ties and zeros.
                let g: Vec<f64> = (0..n).map(|_| rng.random_range(-4i32..=4) as f64).collect();
                let (p, _) = signed_rank_p_greater(&g, &[]);
                let q = brute_force(&g);
                assert!((p - q).abs() < 1e-12, "{g:?}: {p} vs {q}");
            }
        }
    }

    #[test]
    fn rounding_zeros_are_dropped() {
        let (p, n) = signed_rank_p_greater(&[5.0, 7.5, -1e-12, 4.5], &[1e4, 1e4, 1e4, 1e4]);
        assert!((p - 1.0 / 8.0).abs() < 1e-15, "{p}");
        assert_eq!(n, 3);
        assert_eq!(signed_rank_p_greater(&[0.0, 0.0], &[]), (1.0, 0));
    }
}
