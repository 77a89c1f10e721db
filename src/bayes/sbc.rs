//! Simulation-based calibration (Talts, Betancourt, Simpson, Vehtari & Gelman 2018).
//!
//! For each replication: draw `z*` from the prior, simulate magnitudes from the
//! likelihood at `z*` ([`FrfPosterior::simulate`]), find the start and sample the
//! posterior of the simulated data exactly as a real run does, and record the rank of
//! `z*_j` among `L` posterior draws, for every coordinate `j`. If prior, simulator,
//! likelihood and sampler agree, each rank is uniform on `0..=L`; a chi-square test on
//! binned ranks checks it ([`rank_uniformity`]).
//!
//! The `L` draws are the walkers of all ensembles at the last step: the ensemble's
//! stationary law is the product of `W` copies of the posterior, so once the sampler
//! has converged they are independent draws (no thinning needed, unlike single-chain
//! SBC).

use super::data::FrfData;
use super::posterior::{FrfPosterior, PosteriorOptions};
use super::prior::PriorKind;
use super::start::{ball_positions, find_start};
use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
use crate::mcmc::{LogDensity, Moves, Sampler, SamplerConfig, Start, WeightedMove};
use crate::model::StructuralModel;
use crate::update::{DampingModel, MultistartOptions, ResidualForm, VariablesConfig};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Settings of an SBC run.
#[derive(Debug, Clone, PartialEq)]
pub struct SbcOptions {
    pub n_replications: usize,
    /// Walkers per ensemble.
    pub n_walkers: usize,
    pub n_ensembles: usize,
    /// Sampler steps per replication; ranks use the walkers at the last step.
    pub n_steps: u64,
    /// Multistart solves for each replication's start.
    pub n_starts: usize,
    /// Initial ball in Gauss-Newton standard deviations.
    pub ball_factor: f64,
    pub moves: Vec<WeightedMove>,
    pub seed: u64,
}

/// Ranks of every replication.
#[derive(Debug, Clone, PartialEq)]
pub struct SbcResult {
    /// Sampled coordinates ([`FrfPosterior::names`]).
    pub names: Vec<String>,
    /// `ranks[j][r]`: rank of coordinate `j`'s true value in replication `r`, in `0..=n_draws`.
    pub ranks: Vec<Vec<usize>>,
    /// Posterior draws per replication (`L`).
    pub n_draws: usize,
    /// Mean acceptance fraction over replications.
    pub mean_acceptance: f64,
}

/// Chi-square test of uniform ranks.
#[derive(Debug, Clone, PartialEq)]
pub struct RankTest {
    pub name: String,
    /// Replications per bin.
    pub counts: Vec<usize>,
    pub chi_square: f64,
    /// Degrees of freedom (`bins - 1`).
    pub dof: usize,
    /// `P(X^2 >= chi_square)` under uniform ranks.
    pub p_value: f64,
}

/// Runs SBC on `post`'s prior and likelihood (its measured magnitudes are ignored; its
/// points and sigmas define the experiment). Replications run in parallel (over the
/// ranks of an MPI run, see [`crate::dist::farm`]);
/// replication `r` draws everything from stream `r` of `seed`, so the result does not
/// depend on the thread count.
pub fn run_sbc(post: &FrfPosterior, options: &SbcOptions) -> Result<SbcResult> {
    if options.n_replications == 0 {
        return Err(Error::Usage("SBC needs at least one replication".into()));
    }
    Moves::from_specs(&options.moves)?;
    let dim = post.dim();
    let replication = |r: usize| -> Result<(Vec<usize>, f64)> {
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
        rng.set_stream(r as u64);
        let truth = post.sample_prior(&mut rng)?;
        let y = post.simulate(&truth, &mut rng)?;
        let p = post.with_magnitude(y)?;
        let rep_seed = options.seed.wrapping_add(1 + r as u64);
        let ms = MultistartOptions {
            n_starts: options.n_starts,
            seed: rep_seed,
            ..Default::default()
        };
        let start = find_start(&p, &ms)?;
        let n = options.n_walkers * options.n_ensembles;
        let positions = ball_positions(&p, &start, n, options.ball_factor, rep_seed)?;
        let mut config = SamplerConfig::new(options.n_walkers, rep_seed);
        config.n_ensembles = options.n_ensembles;
        config.max_steps = options.n_steps;
        config.check_every = options.n_steps.max(1);
        let moves = Moves::from_specs(&options.moves)?;
        let mut sampler = Sampler::new(&p, moves, config, Start::Positions(positions))?;
        let run = sampler.run(None)?;
        let draws = sampler.positions();
        let ranks = (0..dim)
            .map(|j| draws.iter().filter(|z| z[j] < truth[j]).count())
            .collect();
        Ok((ranks, run.acceptance))
    };
    // Over the ranks of an MPI run, one replication per rank at a time (each on its
    // rank's threads); in one process, the replications in parallel.
    let reps: Vec<Result<(Vec<usize>, f64)>> = if crate::dist::active().size() > 1 {
        crate::dist::farm(options.n_replications, replication, |_, _| Ok(()))?
            .into_iter()
            .map(Ok)
            .collect()
    } else {
        (0..options.n_replications)
            .into_par_iter()
            .map(replication)
            .collect()
    };
    let mut ranks = vec![Vec::with_capacity(options.n_replications); dim];
    let mut acc = 0.0;
    for rep in reps {
        let (r, a) = rep?;
        for (j, v) in r.into_iter().enumerate() {
            ranks[j].push(v);
        }
        acc += a;
    }
    Ok(SbcResult {
        names: post.names(),
        ranks,
        n_draws: options.n_walkers * options.n_ensembles,
        mean_acceptance: acc / options.n_replications as f64,
    })
}

impl SbcResult {
    /// [`rank_uniformity`] of every coordinate.
    pub fn uniformity(&self, bins: usize) -> Result<Vec<RankTest>> {
        self.names
            .iter()
            .zip(&self.ranks)
            .map(|(name, r)| {
                let mut t = rank_uniformity(r, self.n_draws, bins)?;
                t.name = name.clone();
                Ok(t)
            })
            .collect()
    }
}

/// Pearson chi-square test that `ranks` (each in `0..=n_draws`) are uniform: rank `v`
/// goes to bin `floor(v bins / (n_draws + 1))`, whose probability under uniformity is
/// its share of the `n_draws + 1` rank values (equal shares when `bins` divides
/// `n_draws + 1`).
pub fn rank_uniformity(ranks: &[usize], n_draws: usize, bins: usize) -> Result<RankTest> {
    if bins < 2 || bins > n_draws + 1 {
        return Err(Error::Usage(format!(
            "rank test: need 2 to {} bins, got {bins}",
            n_draws + 1
        )));
    }
    if let Some(v) = ranks.iter().find(|&&v| v > n_draws) {
        return Err(Error::Usage(format!("rank {v} above the {n_draws} draws")));
    }
    let bin = |v: usize| v * bins / (n_draws + 1);
    let mut counts = vec![0usize; bins];
    for &v in ranks {
        counts[bin(v)] += 1;
    }
    let mut share = vec![0usize; bins];
    for v in 0..=n_draws {
        share[bin(v)] += 1;
    }
    let n = ranks.len() as f64;
    let chi_square = counts
        .iter()
        .zip(&share)
        .map(|(&o, &s)| {
            let e = n * s as f64 / (n_draws + 1) as f64;
            (o as f64 - e).powi(2) / e
        })
        .sum();
    let dof = bins - 1;
    let law = ChiSquared::new(dof as f64).map_err(|e| Error::Numerical(e.to_string()))?;
    Ok(RankTest {
        name: String::new(),
        counts,
        chi_square,
        dof,
        p_value: law.sf(chi_square),
    })
}

/// The small problem of the SBC tests: the four-story frame's nominal model with k1, k2,
/// k3 free (multipliers in [-0.15, 0.15]), k4 and every mass fixed at nominal,
/// Rayleigh damping with `a0` free (log-uniform in [0.1, 1] 1/s: modal damping
/// 0.15-9 %) and `a1 = 1e-4 s` fixed, and the noise scale log-uniform in
/// [0.5, 2]. Data: receptances `H1,1` and `H4,1` of a force at floor 1 on 40
/// log-spaced frequencies from 0.5 to 8 Hz, with `sigma_k = 5 %` of the nominal
/// magnitude (magnitude residuals) or 5 % (log residuals).
pub fn small_problem(residual: ResidualForm, prior: PriorKind) -> Result<FrfPosterior> {
    let model = StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0])?;
    let omega_rad_s: Vec<f64> = (0..40)
        .map(|i| 2.0 * std::f64::consts::PI * 0.5 * 16f64.powf(i as f64 / 39.0))
        .collect();
    let pairs = [0, 3]
        .iter()
        .map(|&r| FrfPair {
            response: r,
            excitation: Excitation::Dof(0),
            kind: FrfKind::Receptance,
        })
        .collect();
    let blocks = vec![FrfBlock { omega_rad_s, pairs }];
    let mut vars = VariablesConfig {
        alpha: [-0.15, 0.15],
        a0_per_s: [0.1, 1.0],
        initial_a0_per_s: 0.3,
        ..Default::default()
    };
    for name in ["k4", "m1", "m2", "m3", "m4"] {
        vars.fixed.insert(name.into(), 0.0);
    }
    vars.fixed.insert("a1".into(), 1e-4);
    let n = 80;
    let placeholder = FrfData {
        blocks,
        tests: vec!["synthetic".into()],
        window_tau_s: vec![None],
        magnitude: vec![1.0; n],
        residual,
        sigma: vec![1.0; n],
        n_floored: 0,
        n_dropped_bins: 0,
        correlated: Vec::new(),
        bin_correlation: Vec::new(),
    };
    let options = PosteriorOptions {
        prior,
        noise_scale_bounds: [0.5, 2.0],
        ..PosteriorOptions::default()
    };
    let nominal = FrfPosterior::new(
        model.clone(),
        placeholder.clone(),
        DampingModel::Rayleigh,
        &vars,
        options,
    )?;
    let mut z = nominal
        .variables()
        .to_internal(&nominal.variables().initial());
    z.push(0.0);
    let h = nominal.magnitudes(&z)?;
    let sigma = match residual {
        ResidualForm::Magnitude => h.iter().map(|v| 0.05 * v).collect(),
        ResidualForm::LogMagnitude => vec![0.05; n],
    };
    let data = FrfData {
        magnitude: h,
        sigma,
        ..placeholder
    };
    FrfPosterior::new(model, data, DampingModel::Rayleigh, &vars, options)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_of_known_counts() {
        // L = 9 draws -> ranks 0..=9, 5 bins of 2 values; 20 ranks, 4 per bin expected.
        let ranks: Vec<usize> = (0..20).map(|i| i % 10).collect();
        let t = rank_uniformity(&ranks, 9, 5).unwrap();
        assert_eq!(t.counts, vec![4; 5]);
        assert_eq!(t.chi_square, 0.0);
        assert!((t.p_value - 1.0).abs() < 1e-12);
        // All in the first bin: X^2 = (20-4)^2/4 + 4 * 4 = 80, dof 4.
        let t = rank_uniformity(&[0; 20], 9, 5).unwrap();
        assert!((t.chi_square - 80.0).abs() < 1e-12);
        assert!(t.p_value < 1e-15);
        // Unequal shares: L = 3 -> 4 values in 3 bins: {0, 1}, {2}, {3}.
        let t = rank_uniformity(&[0, 1, 2, 3], 3, 3).unwrap();
        assert_eq!(t.counts, vec![2, 1, 1]);
        assert!(t.chi_square.abs() < 1e-12);
        assert!(rank_uniformity(&[4], 3, 2).is_err());
        assert!(rank_uniformity(&[0], 3, 5).is_err());
    }

    /// The p-value matches the chi-square law: X^2 = 9.488 is the 95 % point for 4 dof.
    #[test]
    fn p_value_is_the_chi_square_tail() {
        // 50 ranks over 5 equal bins (L = 4), 10 expected per bin; counts 17, 8, 8, 8, 9.
        let mut ranks = vec![0; 17];
        ranks.extend(vec![1; 8]);
        ranks.extend(vec![2; 8]);
        ranks.extend(vec![3; 8]);
        ranks.extend(vec![4; 9]);
        let t = rank_uniformity(&ranks, 4, 5).unwrap();
        let x2 = (49.0 + 4.0 + 4.0 + 4.0 + 1.0) / 10.0;
        assert!((t.chi_square - x2).abs() < 1e-12);
        let law = ChiSquared::new(4.0).unwrap();
        assert!((t.p_value - (1.0 - law.cdf(x2))).abs() < 1e-14);
        assert!(((1.0 - law.cdf(9.487729)) - 0.05).abs() < 1e-6);
    }
}
