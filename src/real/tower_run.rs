//! The `tower-hmd` study: FRFs from the damper force, a least-squares start, ensemble
//! sampling of the 5-story shear model with channel gains, and where the fit fails.

// Index loops over several parallel arrays (channels, bins, modes) read more clearly
// than zipped iterators here.
#![allow(clippy::needless_range_loop)]

use std::path::Path;

use super::posterior::{
    near_bound, quantile_bands, quantile_sorted, row_from_chains, sample_to_targets,
    ParameterSummary, QuantileBands, Sampled, Sampling, Targets,
};
use super::tower::{estimate_frf, load, TowerFrf};
use super::tower_model::{
    model_frf, natural_freq_hz, TowerData, TowerLikelihood, K_CENTRE_N_PER_M, N,
};
use super::tower_residuals::{shear_model_residuals, ResidualAnalysis};
use crate::error::Result;
use crate::infer::{fit_multistart, FitOptions};
use crate::mcmc::{Ball, LogDensity, Start};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Welch segment (samples): 40.96 s, 0.0244 Hz resolution.
pub const SEGMENT_LEN: usize = 4096;
/// Fitted band (Hz).
pub const BAND_HZ: (f64, f64) = (0.4, 6.2);
/// Walkers per ensemble (>= 2 x 11 coordinates).
pub const N_WALKERS: usize = 24;
/// Posterior draws for the predictive bands.
pub const MAX_BAND_DRAWS: usize = 800;

/// Low band for the check fit: the first two modes only (Hz).
pub const LOW_BAND_HZ: (f64, f64) = (0.4, 2.2);

/// One fit of the shear model to one band.
#[derive(Debug, Clone)]
pub struct TowerFit {
    pub band_hz: (f64, f64),
    pub lik: TowerLikelihood,
    pub start: Vec<f64>,
    pub n_at_best: usize,
    pub sampled: Sampled,
    /// `k`, `xi`, `s`, then the gains.
    pub rows: Vec<ParameterSummary>,
    /// Natural frequencies (derived).
    pub freq_rows: Vec<ParameterSummary>,
    /// Posterior median of the coordinates and the conditional-mean gains there.
    pub median: Vec<f64>,
    pub g_median: [f64; N],
}

/// Everything the report needs.
#[derive(Debug, Clone)]
pub struct TowerStudy {
    pub frf: TowerFrf,
    /// Fit to [`BAND_HZ`] (the posterior of `posterior.json`).
    pub full: TowerFit,
    /// Fit to [`LOW_BAND_HZ`].
    pub low: TowerFit,
    /// Per-mode and per-channel residuals over [`BAND_HZ`] at the posterior median of
    /// the whole-band fit, and of the low-band fit (above [`LOW_BAND_HZ`]: predictions).
    pub residuals: ResidualAnalysis,
    pub residuals_low: ResidualAnalysis,
    /// Model |H| quantiles (2.5, 25, 50, 75, 97.5 %) per floor on the full band grid.
    pub bands_abs: Vec<QuantileBands>,
}

/// Runs the study on the records in `dir`.
pub fn run(dir: &Path, seed: u64, sampling: &mut Sampling<'_>) -> Result<TowerStudy> {
    let records = load(dir)?;
    let frf = estimate_frf(&records, SEGMENT_LEN)?;
    let full = fit_band(&frf, BAND_HZ, seed, sampling)?;
    let low = fit_band(&frf, LOW_BAND_HZ, seed.wrapping_add(1), sampling)?;
    let residuals = shear_model_residuals(&full.lik, &full.median, &full.g_median)?;
    let residuals_low = shear_model_residuals(&full.lik, &low.median, &low.g_median)?;
    let lik = &full.lik;
    let d = &full.sampled.draws;
    let total = d.n_chains * d.n_draws;
    let stride = total.div_ceil(MAX_BAND_DRAWS).max(1);
    let nb = lik.data.freq_hz.len();
    let mut samples = vec![vec![Vec::new(); nb]; N];
    for s in (0..total).step_by(stride) {
        let t = d.draw(s / d.n_draws, s % d.n_draws);
        let (k, xi, _) = TowerLikelihood::unpack(t);
        let g = lik.gain_fit(t)?.mean();
        let h = model_frf(&lik.data.freq_hz, &k, &xi, &g)?;
        for c in 0..N {
            for i in 0..nb {
                samples[c][i].push(h[c][i].norm());
            }
        }
    }
    let bands_abs = samples.into_iter().map(quantile_bands).collect();
    Ok(TowerStudy {
        frf,
        full,
        low,
        residuals,
        residuals_low,
        bands_abs,
    })
}

/// Least-squares start and ensemble sampling of the shear model on `band`.
pub fn fit_band(
    frf: &TowerFrf,
    band: (f64, f64),
    seed: u64,
    sampling: &mut Sampling<'_>,
) -> Result<TowerFit> {
    let data = TowerData::from_frf(frf, band.0, band.1)?;
    let bounds = TowerLikelihood::bounds();
    let lik = TowerLikelihood::new(data)?;
    let (start, n_at_best) = map_start(&lik, &bounds, seed)?;
    let sampled = sample_to_targets(
        &lik,
        Start::Ball(Ball {
            center: start.clone(),
            scale: vec![0.005; start.len()],
        }),
        N_WALKERS,
        seed,
        &Targets {
            first_cap_steps: 4000,
            hard_cap_steps: 12_000,
            ..Default::default()
        },
        &format!("tower: band {}-{} Hz", band.0, band.1),
        sampling,
    )?;
    let mut rows = sampled_rows(&sampled, &bounds);
    rows.extend(gain_rows(&lik, &sampled, seed)?);
    let freq_rows = frequency_rows(&sampled);
    let median: Vec<f64> = (0..lik.dim())
        .map(|q| {
            let mut v = sampled.chains(q, |x| x).concat();
            v.sort_by(f64::total_cmp);
            quantile_sorted(&v, 0.5)
        })
        .collect();
    let g_median = lik.gain_fit(&median)?.mean();
    Ok(TowerFit {
        band_hz: band,
        lik,
        start,
        n_at_best,
        sampled,
        rows,
        freq_rows,
        median,
        g_median,
    })
}

/// The sampler's start: the MAP of `ln k`, `ln xi` at `s = 1` from the prior's centre and
/// Latin hypercube starts, the gains profiled out exactly (the complex-gain blocks'
/// projection), then `ln s` from the residual there; each kept 0.03 inside its `bounds`.
/// Also how many starts reached the best optimum.
fn map_start(lik: &TowerLikelihood, bounds: &[(f64, f64)], seed: u64) -> Result<(Vec<f64>, usize)> {
    let mut x0 = vec![K_CENTRE_N_PER_M.ln(); N];
    x0.extend([0.02f64.ln(); N]);
    let ms = fit_multistart(
        lik.posterior(),
        &[1.0],
        Some(&x0),
        &FitOptions {
            n_starts: 32,
            seed,
            ..Default::default()
        },
    )?;
    let mut start = ms.best.x.clone();
    let fit = lik.gain_fit(&start)?;
    let rss: f64 = fit.rss.iter().sum();
    start.push((rss / lik.data.n_points() as f64).sqrt().ln());
    for (x, (l, h)) in start.iter_mut().zip(bounds) {
        *x = x.clamp(l + 0.03, h - 0.03);
    }
    Ok((start, ms.n_at_best))
}

/// Summary rows of the sampled parameters: `k1..k5` (N/m), `xi1..xi5` and `s`, each
/// flagged when its posterior presses on the prior bound.
fn sampled_rows(sampled: &Sampled, bounds: &[(f64, f64)]) -> Vec<ParameterSummary> {
    let tau = &sampled.tau_steps;
    (0..2 * N + 1)
        .map(|i| {
            let name = match i / N {
                0 => format!("k{}", i + 1),
                1 => format!("xi{}", i - N + 1),
                _ => "s".into(),
            };
            let unit = if i < N { "N/m" } else { "" };
            row_from_chains(
                &name,
                unit,
                &sampled.chains(i, f64::exp),
                N_WALKERS,
                tau[i],
                near_bound(&sampled.chains(i, |v| v), bounds[i]),
            )
        })
        .collect()
}

/// Summary rows of the channel gains `g1..g5`: one exact conditional draw per posterior
/// draw (same chain layout).
fn gain_rows(lik: &TowerLikelihood, sampled: &Sampled, seed: u64) -> Result<Vec<ParameterSummary>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6a1e_5eed);
    let d = &sampled.draws;
    let mut gchains = vec![vec![Vec::with_capacity(d.n_draws); d.n_chains]; N];
    for c in 0..d.n_chains {
        for i in 0..d.n_draws {
            let t = d.draw(c, i);
            let fit = lik.gain_fit(t)?;
            let sd = t[2 * N].exp();
            for ch in 0..N {
                let z: f64 = StandardNormal.sample(&mut rng);
                gchains[ch][c].push(fit.b[ch] / fit.a[ch] + z * sd / (2.0 * fit.a[ch]).sqrt());
            }
        }
    }
    Ok(gchains
        .iter()
        .enumerate()
        .map(|(ch, g)| row_from_chains(&format!("g{}", ch + 1), "", g, N_WALKERS, f64::NAN, None))
        .collect())
}

/// Summary rows of the natural frequencies `f1..f5` (Hz) of the sampled stiffnesses.
fn frequency_rows(sampled: &Sampled) -> Vec<ParameterSummary> {
    let fchains: Vec<Vec<Vec<f64>>> = (0..N)
        .map(|r| {
            sampled.draws.map_chains(|t| {
                let k: Vec<f64> = t[..N].iter().map(|v| v.exp()).collect();
                natural_freq_hz(&k).map_or(f64::NAN, |f| f[r])
            })
        })
        .collect();
    fchains
        .iter()
        .enumerate()
        .map(|(r, c)| row_from_chains(&format!("f{}", r + 1), "Hz", c, N_WALKERS, f64::NAN, None))
        .collect()
}
