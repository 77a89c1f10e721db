//! Physical consistency checks of the recordings (issue 5, step 1): tests that separate
//! causes of a mismatch *before* any model is fitted, each from the FRF estimates and
//! their own noise.
//!
//! | check | compares | a failure means |
//! |---|---|---|
//! | `acc_vs_disp` | accelerance against `(j w)^2` x receptance, same floor and test | the two transducers differ: time offset (phase slope), sensor dynamics (magnitude curvature), calibration (constant) |
//! | `impact_level` | weakest against strongest impact of a hammer test: pole of every band | amplitude-dependent (nonlinear) structure |
//! | `hammer_vs_shake` | poles from the hammer tests against the shake-table test | boundary conditions / input path differ between the set-ups, or amplitude dependence |
//! | `reciprocity` | `H_re` (force at e) against `H_er` (force at r), same quantity | sensor timing / calibration per channel, or a non-reciprocal system |
//! | `drift` | poles of the same mode across the hammer tests | the structure changed between tests, or test-dependent effects |
//!
//! ## Null distributions
//! - Ratio checks (`acc_vs_disp`, `reciprocity`): the log ratio `ln r = ln|r| + j arg r`
//!   of two estimates has, per bin, Gaussian real and imaginary parts of variance
//!   `eps_1^2 + eps_2^2` (first-order propagation of the circular complex noise of each
//!   estimate, `segment` module docs; the two estimates' noises are independent, or
//!   positively correlated through a shared force channel, which only makes the test
//!   conservative). Neighbouring bins of one estimate are not independent: the hammer
//!   tests' exponential window correlates their noise as `c(d)` (`|c(1)| = 0.69` for the
//!   default window), turned by the estimate's own phase between the two bins
//!   ([`fit::RatioPoints`]). Fitting `arg r = phase0 - omega delay` and
//!   `ln|r| = g0 + g2 omega^2` by weighted least squares, the four coefficients are
//!   Gaussian with the sandwich covariance `s^2 A^-1 B A^-1` of that correlation and are
//!   all 0 under the null, so their Wald statistic is chi^2 with 4 dof
//!   ([`fit::fit_ratio`]; seeded oracle over windowed noise: 22 rejections at 5 % in 400
//!   draws, 235 with the bins taken as independent).
//! - Pole checks (`impact_level`, `hammer_vs_shake`, `drift`): each segment's pole is
//!   fitted per band ([`pole_fit::fit_pole`]); estimates from different segments are independent
//!   with the fitted standard errors, so `z = (a - b) / sqrt(se_a^2 + se_b^2)` is standard
//!   normal under the null, and a sum of `k` independent `z^2` (or the weighted spread of
//!   `T` estimates about their weighted mean, `T - 1` dof per quantity) is chi^2 with `k`
//!   dof. Frequency and damping of one pole are correlated; their z's are combined with
//!   the 2 x 2 covariance (Mahalanobis distance), still chi^2.
//!
//! - Estimator bias: every estimate also carries a smooth relative error `delta`
//!   ([`ConsistencyOptions::estimator_rel_error`], 0.3 %) that its random error does not
//!   describe; ratio fits and poles add its effect to their covariances
//!   ([`fit::fit_ratio`], [`pole_fit::PoleFit::with_smooth_error`]). Without it the checks
//!   reject the benchmark's `none` campaigns: the hammer estimates then differ between
//!   tests by up to 0.4 % in gain and 0.1-0.2 ms in phase slope, and between impacts by
//!   1e-5 in frequency, far beyond their random errors (over the 30 null campaigns of
//!   `experiments/models/discrepancy/nulls`, with the bins' correlation counted: 136
//!   of 1,293 checks inconsistent without it, 3 with it). `acc_vs_disp` takes none: its
//!   two channels share the blocks, windows and force and measure one floor's motion,
//!   so the error cancels in their ratio (0 of those 600 checks inconsistent without it).
//! - Shared input noise: where the input's noise dominates (shake table near resonance)
//!   all channels of a segment share one error factor, so a pole fitted jointly to all
//!   channels gets the standard errors of its best single channel (a joint fit cannot do
//!   better when the errors are shared).
//!
//! What the checks cannot see: a time offset or filter on the *input* channel of the
//! hammer tests cancels in every ratio of two responses and leaves the poles unchanged;
//! only a model fit (the phase of the FRFs) reveals it.
//!
//! Every check gives a p-value; the verdicts control the family-wise error rate over
//! *all* checks of a campaign with Holm's step-down procedure at `level` (default 1 %).

mod checks;
pub mod fit;
pub mod pole_fit;
mod poles;
mod segment;

pub use fit::{fit_ratio, RatioFit};
pub use pole_fit::{fit_pole, PoleData, PoleFit};
pub use segment::{band_window, impact_segments, ChannelEstimate, SegmentFrf};

use crate::error::Result;
use crate::io::{Campaign, TestKind};
use crate::signal::{estimate_campaign, EstimateOptions, TestFrf};
use serde::{Deserialize, Serialize};

/// Options of [`check_campaign`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConsistencyOptions {
    /// Family-wise error rate of the verdicts (Holm over all checks).
    pub level: f64,
    /// Half-width of the fitting window around each peak, in half-power bandwidths.
    pub window_half_widths: f64,
    /// Points whose relative error `eps` exceeds this are not used (first-order noise
    /// propagation through `ln` needs `eps` small).
    pub max_rel_std: f64,
    /// Relative accuracy `delta` of one FRF estimate beyond its random error: a smooth
    /// error (bias) in gain and phase over a band, from the estimator itself (ring-down of
    /// earlier impacts in later blocks, the tail cut at the block end, the force window).
    /// [`crate::signal::hammer`] measures the hammer estimator's worst half-power-band
    /// error on exactly simulated noise-free tests as 0.3-0.9 %; the default 0.3 % is
    /// taken as its standard deviation. A ratio of two estimates carries `sqrt(2) delta`.
    pub estimator_rel_error: f64,
    pub estimate: EstimateOptions,
}

impl Default for ConsistencyOptions {
    /// The checks' error model (Bendat-Piersol errors over impact blocks, plus
    /// `estimator_rel_error`) was calibrated on the impact-block estimator, so the checks
    /// use it whatever the campaign-wide default estimator is.
    fn default() -> Self {
        let mut estimate = EstimateOptions::default();
        estimate.hammer.estimator = crate::signal::HammerEstimator::ImpactBlocks;
        ConsistencyOptions {
            level: 0.01,
            window_half_widths: 2.5,
            max_rel_std: 0.3,
            estimator_rel_error: 0.003,
            estimate,
        }
    }
}

impl ConsistencyOptions {
    /// The defaults, looking for `n_peaks` modes below `cap_hz` (none: the whole
    /// estimate): the checks of a diagnosis keep to its analysed band, so that a mode above
    /// it (at the anti-aliasing filter's pass-band edge, say) neither takes the place of
    /// one inside it nor fails a check the likelihood never sees.
    pub fn for_band(n_peaks: usize, cap_hz: Option<f64>) -> Self {
        let mut o = ConsistencyOptions::default();
        o.estimate.bands.n_peaks = Some(n_peaks);
        o.estimate.freq_max_hz = cap_hz;
        o
    }
}

/// Which check.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CheckKind {
    AccVsDisp,
    ImpactLevel,
    HammerVsShake,
    Reciprocity,
    Drift,
}

impl CheckKind {
    pub fn name(self) -> &'static str {
        match self {
            CheckKind::AccVsDisp => "acc_vs_disp",
            CheckKind::ImpactLevel => "impact_level",
            CheckKind::HammerVsShake => "hammer_vs_shake",
            CheckKind::Reciprocity => "reciprocity",
            CheckKind::Drift => "drift",
        }
    }
}

/// Null distribution of a statistic.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NullDistribution {
    ChiSquared { dof: usize },
}

impl NullDistribution {
    /// Upper-tail probability of `x`.
    pub fn p_value(&self, x: f64) -> f64 {
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        match *self {
            NullDistribution::ChiSquared { dof } => match ChiSquared::new(dof.max(1) as f64) {
                Ok(law) if x.is_finite() => law.sf(x.max(0.0)),
                _ => f64::NAN,
            },
        }
    }
}

/// Outcome of one check at the family-wise level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Consistent,
    Inconsistent,
}

/// What a check compared.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Compared {
    /// Segments (tests, or `test#impactN`).
    pub segments: Vec<String>,
    pub channels: Vec<String>,
    /// Frequency bands, Hz.
    pub bands_hz: Vec<(f64, f64)>,
}

/// A pole of one segment (natural frequency and damping ratio, without the exponential
/// window), with standard errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoleEstimate {
    pub segment: String,
    pub freq_hz: f64,
    pub freq_se_hz: f64,
    pub xi: f64,
    pub xi_se: f64,
}

/// One mode compared across segments.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModeComparison {
    /// Mode (band) number, 1-based.
    pub mode: usize,
    pub estimates: Vec<PoleEstimate>,
    /// Largest frequency difference relative to the first estimate (e.g. strong vs weak).
    pub freq_shift_rel: f64,
    /// Its z-score.
    pub freq_shift_z: f64,
    /// chi^2 contribution of this mode.
    pub chi2: f64,
    /// Mean FRF ratio (second / first segment) over the band, dB (`impact_level`).
    pub ratio_db: Option<f64>,
}

/// Quantities behind a check, for reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum CheckDetails {
    Ratio(RatioFit),
    Modes { modes: Vec<ModeComparison> },
}

/// One consistency check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CheckResult {
    pub kind: CheckKind,
    /// `kind` plus what it compared, e.g. `acc_vs_disp hammer-floor1 floor 2`.
    pub name: String,
    pub compared: Compared,
    pub statistic: f64,
    pub null: NullDistribution,
    pub p_value: f64,
    /// Holm-adjusted p-value over all checks of the report.
    pub p_adjusted: f64,
    pub verdict: Verdict,
    /// One plain sentence with the fitted effect and its uncertainty.
    pub summary: String,
    pub details: CheckDetails,
}

/// All checks of a campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConsistencyReport {
    /// Family-wise error rate.
    pub level: f64,
    /// Multiple-testing correction used: `"holm"`.
    pub correction: String,
    pub checks: Vec<CheckResult>,
    /// Checks that could not be made and why.
    pub skipped: Vec<String>,
}

impl ConsistencyReport {
    /// Checks judged inconsistent, strongest (smallest p) first.
    pub fn inconsistent(&self) -> Vec<&CheckResult> {
        let mut v: Vec<&CheckResult> = self
            .checks
            .iter()
            .filter(|c| c.verdict == Verdict::Inconsistent)
            .collect();
        v.sort_by(|a, b| a.p_value.total_cmp(&b.p_value));
        v
    }
}

/// Holm's step-down adjusted p-values (same order as the input): with the p-values sorted
/// ascending, `p_adj(i) = max_{j <= i} min(1, (m - j + 1) p_(j))`. Rejecting where
/// `p_adj < level` controls the family-wise error rate at `level` for any dependence.
/// NaN p-values are treated as 1.
pub fn holm_adjust(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let clean: Vec<f64> = p
        .iter()
        .map(|&v| if v.is_nan() { 1.0 } else { v })
        .collect();
    let mut idx: Vec<usize> = (0..m).collect();
    idx.sort_by(|&a, &b| clean[a].total_cmp(&clean[b]));
    let mut out = vec![1.0; m];
    let mut running: f64 = 0.0;
    for (rank, &i) in idx.iter().enumerate() {
        let v = ((m - rank) as f64 * clean[i]).min(1.0);
        running = running.max(v);
        out[i] = running;
    }
    out
}

/// Runs every check that the campaign's tests allow (see the module docs) on estimates
/// from [`estimate_campaign`] and per-impact estimates ([`impact_segments`]).
pub fn check_campaign(campaign: &Campaign, opts: &ConsistencyOptions) -> Result<ConsistencyReport> {
    let mut est_opts = opts.estimate;
    if est_opts.bands.n_peaks.is_none() {
        est_opts.bands.n_peaks = Some(campaign.nominal.n_floors());
    }
    let estimates = estimate_campaign(campaign, &est_opts)?;
    let mut impacts = Vec::new();
    for (test, est) in campaign.tests.iter().zip(&estimates) {
        if matches!(test.kind, TestKind::Hammer { .. }) {
            impacts.push(impact_segments(test, est, &est_opts)?);
        }
    }
    check_estimates(&estimates, &impacts, opts)
}

/// [`check_campaign`] on given estimates: `impacts` holds the per-impact segments of each
/// hammer test (any order; tests with fewer than two impacts are skipped).
pub fn check_estimates(
    estimates: &[TestFrf],
    impacts: &[Vec<SegmentFrf>],
    opts: &ConsistencyOptions,
) -> Result<ConsistencyReport> {
    let segments: Vec<SegmentFrf> = estimates.iter().map(SegmentFrf::from_test).collect();
    let mut checks = Vec::new();
    let mut skipped = Vec::new();
    checks::acc_vs_disp(&segments, opts, &mut checks, &mut skipped);
    poles::impact_level(impacts, opts, &mut checks, &mut skipped);
    let poles = poles::test_poles(&segments, opts, &mut skipped);
    poles::hammer_vs_shake(&segments, &poles, &mut checks, &mut skipped);
    checks::reciprocity(&segments, opts, &mut checks, &mut skipped);
    poles::drift(&segments, &poles, &mut checks, &mut skipped);
    let adj = holm_adjust(&checks.iter().map(|c| c.p_value).collect::<Vec<_>>());
    for (c, a) in checks.iter_mut().zip(adj) {
        c.p_adjusted = a;
        c.verdict = if a < opts.level {
            Verdict::Inconsistent
        } else {
            Verdict::Consistent
        };
    }
    Ok(ConsistencyReport {
        level: opts.level,
        correction: "holm".into(),
        checks,
        skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holm_matches_hand_computation() {
        // sorted 0.01, 0.02, 0.03, 0.5 -> 0.04, 0.06, 0.06, 0.5
        let adj = holm_adjust(&[0.03, 0.01, 0.5, 0.02]);
        let want = [0.06, 0.04, 0.5, 0.06];
        for (a, w) in adj.iter().zip(want) {
            assert!((a - w).abs() < 1e-15, "{adj:?}");
        }
        assert_eq!(holm_adjust(&[f64::NAN, 0.2]), vec![1.0, 0.4]);
        assert!(holm_adjust(&[]).is_empty());
    }

    #[test]
    fn chi2_p_value() {
        let n = NullDistribution::ChiSquared { dof: 2 };
        // chi^2_2 survival = exp(-x/2)
        assert!((n.p_value(3.0) - (-1.5f64).exp()).abs() < 1e-12);
        assert!(n.p_value(f64::NAN).is_nan());
    }
}
