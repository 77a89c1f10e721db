//! Frequentist coverage of the posterior with the FRF estimator in the loop.
//!
//! For each of `n_campaigns` simulated hammer campaigns: draw a truth (masses, stiffnesses
//! and modal damping within plausible ranges around a base model), simulate the campaign
//! with the base model's sensor noise ([`crate::simulate`]), estimate H1 and build the
//! posterior exactly as `frfbayes sample` does ([`super::run::prepare_campaign`]), sample
//! it ([`super::run::sample_prepared`]) and record, per parameter, whether the central
//! interval of level `level` covers the truth and the standardised error
//! `(posterior mean - truth) / posterior sd`.
//!
//! With honest posteriors, the number of campaigns covering a parameter is
//! `Binomial(n, level)` and the standardised errors have mean 0 and sd 1; the report gives
//! the two-sided 95 % binomial bounds ([`binomial_bounds`]). Errors shared by the
//! parameters of one campaign (one estimate, one posterior) make the 12 coverages of a
//! campaign dependent, so the pooled count is judged against the same bounds per
//! parameter only.

use super::run::{prepare_campaign, sample_prepared, SampleSettings};
use crate::error::{Error, Result};
use crate::mcmc::quantile;
use crate::simulate::{DampingSpec, SimModel, Simulator, StructureSpec, TestSpec};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use statrs::distribution::{Binomial, DiscreteCDF};

/// Which sensor noise the simulated campaigns carry (for the diagnosis of the cause).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseSources {
    /// Every channel's noise as in the base model.
    All,
    /// Only the force channel's noise.
    ForceOnly,
    /// Only the response channels' noise.
    ResponsesOnly,
}

/// Settings of a coverage study.
#[derive(Debug, Clone)]
pub struct CoverageOptions {
    /// Base simulation model (structure ignored: the truth is drawn; its hammer tests,
    /// sampling and noise are used; shake-table tests are dropped).
    pub base: SimModel,
    pub n_campaigns: usize,
    /// Master seed (truths and noise).
    pub seed: u64,
    /// Central interval level (0.9).
    pub level: f64,
    pub noise: NoiseSources,
    /// Settings of the posterior and the sampler (`campaign` is not used).
    pub settings: SampleSettings,
    /// Masses drawn uniformly in `nominal x [lo, hi]`.
    pub mass_factor: [f64; 2],
    /// Stiffnesses drawn uniformly in `nominal x [lo, hi]`.
    pub stiffness_factor: [f64; 2],
    /// Damping ratios: the base model's modal ratios times a log-uniform factor in `[lo, hi]`.
    pub damping_factor: [f64; 2],
}

/// One campaign's result, per parameter (the parameters of [`CoverageReport::names`]).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CampaignResult {
    pub index: usize,
    pub noise_seed: u64,
    pub truth: Vec<f64>,
    pub mean: Vec<f64>,
    pub sd: Vec<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub noise_scale: f64,
    pub converged: bool,
    pub wall_s: f64,
}

impl CampaignResult {
    /// `(mean - truth) / sd` per parameter.
    pub fn z(&self) -> Vec<f64> {
        (0..self.truth.len())
            .map(|j| (self.mean[j] - self.truth[j]) / self.sd[j])
            .collect()
    }
    /// Whether the interval covers the truth, per parameter.
    pub fn covered(&self) -> Vec<bool> {
        (0..self.truth.len())
            .map(|j| self.lower[j] <= self.truth[j] && self.truth[j] <= self.upper[j])
            .collect()
    }
}

/// All campaigns of a study.
#[derive(Debug, Clone, Serialize)]
pub struct CoverageReport {
    /// Parameters with a known truth (`m1`.., `k1`.., `xi1`..).
    pub names: Vec<String>,
    pub level: f64,
    pub noise: NoiseSources,
    pub campaigns: Vec<CampaignResult>,
}

/// Two-sided bounds `[lo, hi]` on the number of successes of `Binomial(n, p)` with at
/// most `alpha / 2` probability below `lo` and above `hi` each.
pub fn binomial_bounds(n: usize, p: f64, alpha: f64) -> Result<(u64, u64)> {
    let b = Binomial::new(p, n as u64).map_err(|e| Error::Numerical(format!("binomial: {e}")))?;
    let lo = (0..=n as u64)
        .find(|&k| b.cdf(k) > alpha / 2.0)
        .unwrap_or(0);
    let hi = (0..=n as u64)
        .find(|&k| b.cdf(k) >= 1.0 - alpha / 2.0)
        .unwrap_or(n as u64);
    Ok((lo, hi))
}

/// The engineer's shear frame of a simulation config (the study is of shear frames).
fn frame_nominal(model: &SimModel) -> Result<crate::io::NominalModel> {
    match &model.structure {
        crate::simulate::StructureSpec::ShearFrame { floor_mass_kg, .. } => {
            model.nominal_model(floor_mass_kg.len())
        }
        _ => Err(crate::Error::Usage(
            "the coverage study simulates shear frames; the base model is a general one".into(),
        )),
    }
}

/// The base model with a drawn truth for campaign `i` and the chosen noise sources.
fn campaign_model(opts: &CoverageOptions, rng: &mut ChaCha8Rng) -> Result<(SimModel, Vec<f64>)> {
    let mut model = opts.base.clone();
    let nominal = frame_nominal(&model)?;
    let draw = |rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]| lo + (hi - lo) * rng.random::<f64>();
    let masses: Vec<f64> = nominal
        .floor_mass_kg
        .iter()
        .map(|m| m * draw(rng, opts.mass_factor))
        .collect();
    let stiffness: Vec<f64> = nominal
        .story_stiffness_n_per_m
        .iter()
        .map(|k| k * draw(rng, opts.stiffness_factor))
        .collect();
    let base_xi = match &opts.base.damping {
        DampingSpec::Modal { xi } => xi.clone(),
        _ => {
            return Err(Error::Usage(
                "coverage study: the base model needs modal damping (the truth of Caughey)".into(),
            ))
        }
    };
    let [dlo, dhi] = opts.damping_factor;
    let xi: Vec<f64> = base_xi
        .iter()
        .map(|x| x * (dlo.ln() + (dhi.ln() - dlo.ln()) * rng.random::<f64>()).exp())
        .collect();
    model.structure = StructureSpec::ShearFrame {
        floor_mass_kg: masses.clone(),
        story_stiffness_n_per_m: stiffness.clone(),
    };
    model.damping = DampingSpec::Modal { xi: xi.clone() };
    model.nominal = Some(crate::simulate::NominalSpec {
        floor_mass_kg: nominal.floor_mass_kg.clone(),
        story_stiffness_n_per_m: nominal.story_stiffness_n_per_m.clone(),
    });
    model.tests.retain(|t| matches!(t, TestSpec::Hammer { .. }));
    match opts.noise {
        NoiseSources::All => {}
        NoiseSources::ForceOnly => {
            model.noise.acceleration_m_per_s2 = 0.0;
            model.noise.displacement_m = 0.0;
            model.noise.ground_acceleration_m_per_s2 = 0.0;
        }
        NoiseSources::ResponsesOnly => model.noise.force_n = 0.0,
    }
    let truth = masses.into_iter().chain(stiffness).chain(xi).collect();
    Ok((model, truth))
}

/// Names of the truth vector of a model with `n` floors.
fn truth_names(n: usize) -> Vec<String> {
    ["m", "k", "xi"]
        .iter()
        .flat_map(|p| (1..=n).map(move |i| format!("{p}{i}")))
        .collect()
}

/// Runs one campaign of the study.
pub fn run_campaign(opts: &CoverageOptions, index: usize) -> Result<CampaignResult> {
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    rng.set_stream(index as u64 + 1);
    let (model, truth) = campaign_model(opts, &mut rng)?;
    let names = truth_names(frame_nominal(&model)?.floor_mass_kg.len());
    let noise_seed = opts.seed.wrapping_mul(1000).wrapping_add(index as u64);
    let t0 = std::time::Instant::now();
    let campaign = Simulator::new(model)?.run(noise_seed, &|_| {})?;
    let prep = prepare_campaign(&campaign, &opts.settings)?;
    let sample = sample_prepared(&prep, &opts.settings)?;
    let tail = 0.5 * (1.0 - opts.level);
    let mut out = CampaignResult {
        index,
        noise_seed,
        truth,
        mean: Vec::new(),
        sd: Vec::new(),
        lower: Vec::new(),
        upper: Vec::new(),
        noise_scale: f64::NAN,
        converged: sample.summary.converged,
        wall_s: 0.0,
    };
    for name in &names {
        let p = sample
            .params
            .iter()
            .position(|p| &p.name == name)
            .ok_or_else(|| Error::Numerical(format!("coverage: no posterior of {name}")))?;
        let mut v: Vec<f64> = sample.physical.param_chains(p).concat();
        v.sort_by(f64::total_cmp);
        out.mean.push(sample.summary.parameters[p].mean);
        out.sd.push(sample.summary.parameters[p].sd);
        out.lower.push(quantile(&v, tail));
        out.upper.push(quantile(&v, 1.0 - tail));
    }
    if let Some(s) = sample
        .summary
        .parameters
        .iter()
        .find(|p| p.name == "noise_scale")
    {
        out.noise_scale = s.mean;
    }
    out.wall_s = t0.elapsed().as_secs_f64();
    Ok(out)
}

/// Runs the whole study, one campaign after the other (`progress` after each, on rank
/// 0); under MPI the campaigns are dealt over the ranks ([`crate::dist::farm`]).
pub fn run_coverage(
    opts: &CoverageOptions,
    progress: &dyn Fn(&CampaignResult),
) -> Result<CoverageReport> {
    if opts.n_campaigns == 0 || !(opts.level > 0.0 && opts.level < 1.0) {
        return Err(Error::Usage(format!(
            "coverage study: {} campaigns at level {}; need at least one and 0 < level < 1",
            opts.n_campaigns, opts.level
        )));
    }
    // One campaign after the other (dealt over the ranks of an MPI run).
    let campaigns = crate::dist::farm(
        opts.n_campaigns,
        |i| run_campaign(opts, i),
        |_, r| {
            progress(r);
            Ok(())
        },
    )?;
    let n_floors = frame_nominal(&opts.base)?.floor_mass_kg.len();
    Ok(CoverageReport {
        names: truth_names(n_floors),
        level: opts.level,
        noise: opts.noise,
        campaigns,
    })
}

/// Per-parameter statistics of a report.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterCoverage {
    pub name: String,
    pub covered: usize,
    pub n: usize,
    pub z_mean: f64,
    /// Root mean square of the standardised errors (1 for honest posteriors).
    pub z_rms: f64,
    pub z_max_abs: f64,
}

impl CoverageReport {
    /// Coverage and standardised-error statistics per parameter.
    pub fn per_parameter(&self) -> Vec<ParameterCoverage> {
        let n = self.campaigns.len();
        (0..self.names.len())
            .map(|j| {
                let z: Vec<f64> = self.campaigns.iter().map(|c| c.z()[j]).collect();
                ParameterCoverage {
                    name: self.names[j].clone(),
                    covered: self.campaigns.iter().filter(|c| c.covered()[j]).count(),
                    n,
                    z_mean: z.iter().sum::<f64>() / n as f64,
                    z_rms: (z.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt(),
                    z_max_abs: z.iter().fold(0.0, |a, v| f64::max(a, v.abs())),
                }
            })
            .collect()
    }

    /// One row per campaign and parameter.
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "campaign,noise_seed,parameter,truth,mean,sd,lower,upper,covered,z,noise_scale,converged\n",
        );
        for c in &self.campaigns {
            let (z, cov) = (c.z(), c.covered());
            for (j, name) in self.names.iter().enumerate() {
                s += &format!(
                    "{},{},{},{:.9e},{:.9e},{:.6e},{:.9e},{:.9e},{},{:.4},{:.4},{}\n",
                    c.index,
                    c.noise_seed,
                    name,
                    c.truth[j],
                    c.mean[j],
                    c.sd[j],
                    c.lower[j],
                    c.upper[j],
                    cov[j],
                    z[j],
                    c.noise_scale,
                    c.converged
                );
            }
        }
        s
    }

    /// Markdown table of [`Self::per_parameter`] with the binomial bounds.
    pub fn to_markdown(&self, title: &str) -> Result<String> {
        let n = self.campaigns.len();
        let (lo, hi) = binomial_bounds(n, self.level, 0.05)?;
        let rows = self.per_parameter();
        let total: usize = rows.iter().map(|r| r.covered).sum();
        let mut s = format!(
            "## {title}\n\n{n} campaigns, noise {:?}, central {:.0} % intervals. \
             Honest posteriors: each parameter covered in {lo}..={hi} of {n} campaigns \
             (95 % two-sided binomial bounds), standardised errors with rms 1.\n\n\
             | parameter | covered | coverage | mean z | rms z | max abs z |\n|---|---|---|---|---|---|\n",
            self.noise,
            100.0 * self.level
        );
        for r in &rows {
            let flag = if (r.covered as u64) < lo || (r.covered as u64) > hi {
                " (outside)"
            } else {
                ""
            };
            s += &format!(
                "| {} | {}/{}{} | {:.2} | {:+.2} | {:.2} | {:.2} |\n",
                r.name,
                r.covered,
                r.n,
                flag,
                r.covered as f64 / r.n as f64,
                r.z_mean,
                r.z_rms,
                r.z_max_abs
            );
        }
        let noise: Vec<f64> = self.campaigns.iter().map(|c| c.noise_scale).collect();
        s += &format!(
            "\nAll parameters pooled: {total}/{} ({:.3}). Converged: {}/{n}. Posterior mean \
             noise scale: {:.3}-{:.3}.\n",
            n * rows.len(),
            total as f64 / (n * rows.len()) as f64,
            self.campaigns.iter().filter(|c| c.converged).count(),
            noise.iter().cloned().fold(f64::INFINITY, f64::min),
            noise.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
        );
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binomial_bounds_of_twenty_at_ninety_percent() {
        // P(X <= 14) = 0.011, P(X <= 15) = 0.043 for Binomial(20, 0.9); P(X = 20) = 0.122
        let (lo, hi) = binomial_bounds(20, 0.9, 0.05).unwrap();
        assert_eq!((lo, hi), (15, 20));
        let b = Binomial::new(0.9, 20).unwrap();
        assert!(b.cdf(lo - 1) <= 0.025 && b.cdf(lo) > 0.025);
    }

    #[test]
    fn coverage_and_z_of_a_campaign() {
        let c = CampaignResult {
            index: 0,
            noise_seed: 0,
            truth: vec![1.0, 2.0],
            mean: vec![1.1, 2.0],
            sd: vec![0.05, 0.1],
            lower: vec![1.02, 1.9],
            upper: vec![1.18, 2.1],
            noise_scale: 1.0,
            converged: true,
            wall_s: 0.0,
        };
        assert_eq!(c.covered(), vec![false, true]);
        let z = c.z();
        assert!((z[0] - 2.0).abs() < 1e-12 && z[1].abs() < 1e-12);
    }
}
