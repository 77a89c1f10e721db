//! Posterior sampling of the updating variants (`[bayes]` of an experiment file) and the
//! statistics `identifiability.md` reports from the draws: coefficients of variation,
//! correlations, the stiffness-to-mass ratios `k_r / m_r`, and the natural frequencies
//! and modal damping ratios of every draw.
//!
//! Each variant is sampled exactly as `frfbayes sample` would sample it
//! ([`sample_posterior`]): the same FRF estimates the updating used, the Bendat &
//! Piersol noise model with a sampled scale, uniform priors in the experiment's bounds
//! (log-uniform damping), a window applied to the model exactly (so the damping is the
//! structure's, not the windowed data's).

use super::config::{BayesSection, ExperimentConfig};
use super::driver::Progress;
use super::pipeline::{TableId, Variant};
use crate::bayes::run::{
    posterior_of, sample_prepared, PosteriorSample, Prepared, SampleSettings, TestSelection,
};
use crate::bayes::summary::physical_values;
use crate::bayes::FrfPosterior;
use crate::error::Result;
use crate::mcmc::Draws;
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::signal::TestFrf;
use rayon::prelude::*;

/// Most draws whose modes are solved for the modal statistics.
const MAX_MODAL_DRAWS: usize = 4000;

/// Posterior mean and coefficient of variation of a derived quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanCv {
    pub mean: f64,
    /// `sd / |mean|`, a fraction.
    pub cv: f64,
}

/// Natural frequency and modal damping ratio of one mode over the draws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModalStats {
    pub freq_hz: MeanCv,
    pub xi: MeanCv,
}

/// One variant's posterior.
#[derive(Debug, Clone)]
pub struct VariantPosterior {
    pub variant: Variant,
    /// `table1 caughey_receptance`.
    pub name: String,
    pub sample: PosteriorSample,
    /// Per reported parameter: its prior box in physical units.
    pub prior_box: Vec<[f64; 2]>,
    /// Per mode, ascending.
    pub modal: Vec<ModalStats>,
    /// What the variant was sampled with.
    pub settings: SampleSettings,
}

impl VariantPosterior {
    /// Index of a reported parameter (`m1`, `k3`, `xi2`, `noise_scale`).
    pub fn index(&self, name: &str) -> Option<usize> {
        self.sample.params.iter().position(|p| p.name == name)
    }

    /// Every kept draw of a reported parameter (physical units).
    pub fn column(&self, j: usize) -> Vec<f64> {
        column(&self.sample.physical, j)
    }

    /// Draws of a named parameter.
    pub fn named(&self, name: &str) -> Option<Vec<f64>> {
        self.index(name).map(|j| self.column(j))
    }
}

/// Every draw of coordinate `j`.
pub fn column(draws: &Draws, j: usize) -> Vec<f64> {
    draws
        .values
        .iter()
        .skip(j)
        .step_by(draws.dim)
        .copied()
        .collect()
}

/// Mean and coefficient of variation (sample sd, n - 1).
pub fn mean_cv(x: &[f64]) -> MeanCv {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    MeanCv {
        mean,
        cv: var.sqrt() / mean.abs(),
    }
}

/// Pearson correlation of two equally long samples.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    sab / (saa * sbb).sqrt()
}

/// `table1 caughey_receptance`.
pub fn variant_name(v: &Variant) -> String {
    format!("{} {}", v.table.key(), v.column())
}

/// The run settings of one variant: [`SampleSettings::new`]'s defaults, the
/// experiment's FRF estimation, bounds and seed, and the `[bayes]` overrides.
pub fn variant_settings(
    cfg: &ExperimentConfig,
    bayes: &BayesSection,
    variant: &Variant,
) -> Result<SampleSettings> {
    let tests = match variant.table {
        TableId::Table1 => TestSelection::Hammer,
        TableId::Table2 => TestSelection::ShakeTable,
    };
    let mut s = SampleSettings::new(
        cfg.data.clone(),
        variant.damping,
        variant.kind,
        tests,
        cfg.seed,
    )?;
    s.estimate = cfg.estimate.clone();
    s.variables = match (variant.table, &cfg.update.variables_shake_table) {
        (TableId::Table2, Some(v)) => v.clone(),
        _ => cfg.update.variables.clone(),
    };
    if let Some(v) = bayes.walkers_per_dim {
        s.walkers_per_dim = v;
    }
    if let Some(v) = bayes.n_ensembles {
        s.n_ensembles = v;
    }
    if let Some(v) = bayes.max_steps {
        s.max_steps = v;
    }
    if let Some(v) = bayes.thin_by {
        s.thin_by = v;
    }
    if let Some(v) = bayes.n_starts {
        s.n_starts = v;
    }
    if let Some(v) = bayes.residual {
        s.residual = v;
    }
    if let Some(v) = bayes.rel_sigma_floor {
        s.rel_sigma_floor = v;
    }
    Ok(s)
}

/// The posterior of one variant on the experiment's FRF estimates and its start, as
/// `frfbayes sample` prepares them ([`posterior_of`]: the same noise model, band
/// selection and maximum-likelihood start).
pub fn variant_prepared(
    model: &StructuralModel,
    frfs: &[TestFrf],
    variant: &Variant,
    settings: &SampleSettings,
) -> Result<Prepared> {
    let n_peaks = settings
        .estimate
        .options()
        .bands
        .n_peaks
        .unwrap_or(model.n_dof());
    let where_ = format!("the experiment's estimates for {}", variant_name(variant));
    posterior_of(model.clone(), frfs.to_vec(), settings, n_peaks, &where_)
}

/// Natural frequencies and damping ratios of (at most [`MAX_MODAL_DRAWS`] evenly
/// strided) draws.
fn modal_stats(post: &FrfPosterior, draws: &Draws) -> Result<Vec<ModalStats>> {
    let n_total = draws.n_chains * draws.n_draws;
    let stride = n_total.div_ceil(MAX_MODAL_DRAWS).max(1);
    let model = post.model();
    let n_modes = post.n_modes();
    let per_draw: Vec<(Vec<f64>, Vec<f64>)> = (0..n_total)
        .step_by(stride)
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&s| -> Result<(Vec<f64>, Vec<f64>)> {
            let z = &draws.values[s * draws.dim..(s + 1) * draws.dim];
            let theta = post.theta(z);
            let (alpha, beta, damping) = post.variables().split(&theta);
            let modes = Modes::solve(
                &model.stiffness(alpha),
                &model.mass(beta),
                model.ground_influence(),
                Some(n_modes),
            )?;
            let xi = damping.damping_ratios(&modes.omega_rad_s)?;
            let f = modes
                .omega_rad_s
                .iter()
                .map(|w| w / (2.0 * std::f64::consts::PI))
                .collect();
            Ok((f, xi))
        })
        .collect::<Result<_>>()?;
    Ok((0..n_modes)
        .map(|i| {
            let f: Vec<f64> = per_draw.iter().map(|(f, _)| f[i]).collect();
            let xi: Vec<f64> = per_draw.iter().map(|(_, x)| x[i]).collect();
            ModalStats {
                freq_hz: mean_cv(&f),
                xi: mean_cv(&xi),
            }
        })
        .collect())
}

/// The prior box of every reported parameter in physical units (each is an increasing
/// function of one sampled coordinate).
fn prior_box(post: &FrfPosterior, sample: &PosteriorSample) -> Vec<[f64; 2]> {
    let (lo, hi) = (post.prior().lower(), post.prior().upper());
    sample
        .params
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let mut z = sample.start.z.clone();
            z[p.coord] = lo[p.coord];
            let a = physical_values(post, &sample.params, &z)[j];
            z[p.coord] = hi[p.coord];
            [a, physical_values(post, &sample.params, &z)[j]]
        })
        .collect()
}

/// Samples the posterior of every variant `[bayes]` selects that the data have.
pub fn sample_variants(
    cfg: &ExperimentConfig,
    bayes: &BayesSection,
    model: &StructuralModel,
    frfs: &[TestFrf],
    progress: Progress,
) -> Result<Vec<VariantPosterior>> {
    let chosen: Vec<Variant> = Variant::all()
        .into_iter()
        .filter(|v| frfs.iter().any(|f| v.table.includes(f)))
        .filter(|v| bayes.variants.is_empty() || bayes.variants.contains(&variant_name(v)))
        .collect();
    let mut out = Vec::with_capacity(chosen.len());
    for (i, v) in chosen.iter().enumerate() {
        let name = variant_name(v);
        progress(&format!("sampling {name}"), i, chosen.len());
        let settings = variant_settings(cfg, bayes, v)?;
        let prep = variant_prepared(model, frfs, v, &settings)?;
        let sample = sample_prepared(&prep, &settings)?;
        let post = &prep.posterior;
        let modal = modal_stats(post, &sample.draws)?;
        let prior_box = prior_box(post, &sample);
        out.push(VariantPosterior {
            variant: *v,
            name,
            prior_box,
            sample,
            modal,
            settings,
        });
    }
    progress("sampling", chosen.len(), chosen.len());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Oracles: a sample with known mean, sd and correlation.
    #[test]
    fn mean_cv_and_correlation() {
        let a = [1.0, 2.0, 3.0, 4.0];
        let m = mean_cv(&a);
        assert_eq!(m.mean, 2.5);
        // sd = sqrt(5/3).
        assert!((m.cv - (5.0f64 / 3.0).sqrt() / 2.5).abs() < 1e-15);
        let b = [2.0, 4.0, 6.0, 8.0];
        assert!((correlation(&a, &b) - 1.0).abs() < 1e-15);
        let c = [4.0, 3.0, 2.0, 1.0];
        assert!((correlation(&a, &c) + 1.0).abs() < 1e-15);
        let d = [1.0, -1.0, -1.0, 1.0];
        assert!(correlation(&a, &d).abs() < 1e-15);
    }
}
