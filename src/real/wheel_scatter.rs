//! Empirical checks of the wheel posterior: the channel-to-channel scatter of every
//! mode's poles, and the frequency/damping uncertainty comparison with Au's law (see
//! [`super::wheel_run`] for the derivation of the `1 / xi` ratio).

use super::wheel::N_CHANNELS;
use super::wheel_run::{varpro_start, BandResult};
use crate::error::{Error, Result};

/// Channels whose residue for a mode is at least this fraction of the largest enter the
/// channel-by-channel scatter.
pub const SCATTER_MIN_RESIDUE: f64 = 0.25;

/// Channel-to-channel scatter of a mode's poles: every channel with a large enough
/// residue fitted on its own (variable projection), an empirical uncertainty that
/// includes model error, unlike the posterior (which assumes independent errors).
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelScatter {
    /// Channels used (1-based).
    pub channels: Vec<usize>,
    pub f_mean_hz: f64,
    pub xi_mean: f64,
    pub cov_f: f64,
    pub cov_xi: f64,
}

/// The scatter of every mode of a band across channels (see [`ChannelScatter`]).
pub fn channel_scatter(b: &BandResult) -> Result<Vec<ChannelScatter>> {
    let lik = &b.lik;
    let fits0 = lik
        .fit_channels(&b.start)
        .ok_or_else(|| Error::Numerical("rank-deficient basis at the start".into()))?;
    let mut per_channel: Vec<Option<Vec<f64>>> = Vec::new();
    for c in 0..N_CHANNELS {
        let one = lik.with_channels(&[c]).ok();
        per_channel.push(one.and_then(|one| varpro_start(&one).ok()));
    }
    let stats = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        (m, sd / m)
    };
    Ok((0..lik.n_modes())
        .map(|r| {
            let amax = fits0.iter().map(|f| f.theta[r].norm()).fold(0.0, f64::max);
            let chans: Vec<usize> = (0..N_CHANNELS)
                .filter(|&c| {
                    fits0[c].theta[r].norm() >= SCATTER_MIN_RESIDUE * amax
                        && per_channel[c].is_some()
                })
                .collect();
            let f: Vec<f64> = chans
                .iter()
                .filter_map(|&c| per_channel[c].as_ref().map(|x| x[2 * r]))
                .collect();
            let xi: Vec<f64> = chans
                .iter()
                .filter_map(|&c| per_channel[c].as_ref().map(|x| x[2 * r + 1].exp()))
                .collect();
            let (fm, cf) = stats(&f);
            let (xm, cx) = stats(&xi);
            ChannelScatter {
                channels: chans.iter().map(|c| c + 1).collect(),
                f_mean_hz: fm,
                xi_mean: xm,
                cov_f: cf,
                cov_xi: cx,
            }
        })
        .collect())
}

/// Frequency against damping uncertainty of one mode.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CovComparison {
    pub f_hz: f64,
    pub xi: f64,
    pub cov_f: f64,
    pub cov_xi: f64,
    /// `cov_xi / cov_f`.
    pub ratio: f64,
    /// `1 / xi`, the ratio predicted by Au's law (asymptotic band) and by the
    /// isotropic pole uncertainty of FRF data.
    pub predicted_ratio: f64,
}

/// The comparison for every mode of `bands`, in band order.
pub fn cov_comparison(bands: &[BandResult]) -> Vec<CovComparison> {
    bands
        .iter()
        .flat_map(|b| {
            (0..b.lik.n_modes()).map(move |r| {
                let (f, xi) = (&b.rows[2 * r], &b.rows[2 * r + 1]);
                CovComparison {
                    f_hz: f.mean,
                    xi: xi.mean,
                    cov_f: f.cv,
                    cov_xi: xi.cv,
                    ratio: xi.cv / f.cv,
                    predicted_ratio: 1.0 / xi.mean,
                }
            })
        })
        .collect()
}
