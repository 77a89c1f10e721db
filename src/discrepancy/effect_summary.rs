//! Posterior summaries of a hypothesis' effect parameters, and the plausibility rule
//! of [`super::verdict`] applied to them.

use super::bin_correlation::{inflation, interval_reaches_box, widened};
use super::hypothesis::Coordinate;
use super::posterior::ModelPosterior;
use super::verdict::EffectSummary;
use crate::error::Result;
use crate::mcmc::quantile;

/// The effect parameters of every draw (rows of `z`) in physical units, one column per
/// parameter.
pub fn effect_columns<'a>(
    post: &ModelPosterior,
    draws: impl IntoIterator<Item = &'a [f64]>,
) -> Result<Vec<Vec<f64>>> {
    let mut cols = vec![Vec::new(); post.effect_params().len()];
    for z in draws {
        for (c, v) in cols.iter_mut().zip(post.effect_physical(z)?) {
            c.push(v);
        }
    }
    Ok(cols)
}

/// Summaries of the effect parameters from posterior draws `draws` (rows of `z`), and
/// whether the effect is plausible: the 95 % interval of every size parameter (one with
/// a no-effect value) excludes that value and stays clear of the box's ends by more than
/// its own width (a posterior piled at the end of the physically plausible range is not
/// an identified effect).
///
/// The reported mean and interval come from the draws widened for the correlation of
/// neighbouring bins and to at least the sandwich sd ([`super::bin_correlation`]; the
/// factor is each summary's
/// `sd_inflation`); plausibility is judged on the draws as sampled, so the decision is
/// the one the benchmark measured before the widening existed.
pub fn effect_summaries(post: &ModelPosterior, draws: &[Vec<f64>]) -> Result<EffectVerdict> {
    let ie = post.eta_index();
    let (lo, hi) = post.bounds();
    let mut out = Vec::new();
    let mut reasons = Vec::new();
    let factors = inflation(post, draws)?;
    let wide = widened(draws, &factors, lo, hi);
    let columns = effect_columns(post, wide.iter().map(Vec::as_slice))?;
    for ((k, p), mut phys) in post.effect_params().iter().enumerate().zip(columns) {
        let i = ie + 1 + k;
        let mut zs: Vec<f64> = draws.iter().map(|d| d[i]).collect();
        zs.sort_by(f64::total_cmp);
        let (z_lo, z_hi) = (quantile(&zs, 0.025), quantile(&zs, 0.975));
        let mean = phys.iter().sum::<f64>() / phys.len().max(1) as f64;
        phys.sort_by(f64::total_cmp);
        let s = EffectSummary {
            mean,
            q2_5: quantile(&phys, 0.025),
            q97_5: quantile(&phys, 0.975),
            unit: p.unit.to_string(),
            sd_inflation: factors[i],
        };
        if let Some(v) = p.no_effect {
            let zv = match p.coordinate {
                Coordinate::Log if v <= 0.0 => f64::NEG_INFINITY,
                _ => p.coordinate_of(v),
            };
            if zv >= z_lo && zv <= z_hi {
                reasons.push(format!(
                    "{} = {:.3e} [{:.3e}, {:.3e}] {} includes no effect ({v})",
                    p.name, s.mean, s.q2_5, s.q97_5, p.unit
                ));
            }
        }
        // Shape parameters (no_effect None, e.g. a damping ratio) may be weakly
        // identified and rest on a prior end without making the effect implausible.
        if p.no_effect.is_some() && interval_reaches_box(z_lo, z_hi, lo[i], hi[i]) {
            reasons.push(format!(
                "{} [{:.3e}, {:.3e}] {} reaches the end of its plausible range [{:.3e}, {:.3e}]",
                p.name,
                s.q2_5,
                s.q97_5,
                p.unit,
                p.physical(lo[i]),
                p.physical(hi[i])
            ));
        }
        out.push((p.name.clone(), s));
    }
    Ok((out, reasons.is_empty(), reasons.join("; ")))
}

/// Effect summaries, plausible or not, and why not.
pub type EffectVerdict = (Vec<(String, EffectSummary)>, bool, String);
