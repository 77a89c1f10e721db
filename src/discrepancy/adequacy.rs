//! Is the final model of a diagnosis adequate? The open-world half of the decision
//! (issue 14, item 2): a model with every accepted effect can still fail to explain the
//! recordings, and then the diagnosis says `unexplained`, where, and what the residual
//! shows, instead of forcing the misfit into the nearest name.
//!
//! The error floor `eta` of the posterior is fitted, so a fitted chi2 is about 1 by
//! construction; adequacy is judged instead against the estimator's own error: the
//! Bendat-Piersol random error of every point, the input channel's correlated error of
//! single impacts (the posterior's whitened residuals,
//! [`ModelPosterior::whitened_residuals_of`]), and a relative floor for the estimator's
//! bias. Points with a relative error above [`MAX_TESTED_REL_ERROR`] are left out
//! (first-order noise propagation fails there).
//!
//! 1. **Global.** With the floor at the estimator's worst measured bias,
//!    [`ADEQUACY_FLOOR`] (0.9 %: [`crate::signal::hammer`] measures the hammer
//!    estimator's worst half-power-band error on exactly simulated noise-free tests as
//!    0.3-0.9 %), the squared whitened residuals of all points are chi^2 with two
//!    degrees of freedom per point when the model is right; the model fails when that
//!    is rejected at [`ADEQUACY_LEVEL`].
//! 2. **Where the consistency checks point.** Every check that found the recordings
//!    inconsistent ([`super::consistency`]; Holm at 1 % over the checks) names tests,
//!    channels and bands. The model explains that finding when it fits those points
//!    within the noise at the checks' own floor (0.3 %,
//!    [`ConsistencyOptions::estimator_rel_error`]), per point and, as in the checks' own
//!    null, as one smooth error of each estimate (segment x channel) over each band, of
//!    that sd in gain and in phase ([`smooth_error_chi2`]): whatever the check measured
//!    on the data, it would measure on the model's predictions too, up to the noise. (A
//!    per-point floor alone let a constant gain offset of a few tenths of a percent over
//!    a band, which the checks allow, fail a test of hundreds of points: null-13 of the
//!    30 nulls, +0.8 % at two accelerometers.) The points
//!    of each inconsistent check are tested the same way, Holm-adjusted over the checks
//!    at [`ADEQUACY_LEVEL`]. So the checks feed the decision: they aim a sharper test at
//!    the places they flag.
//! 3. **Cells** (segment x channel x resonance band of the fitted frame, +-10 %, plus
//!    off-band) are tested like the global test and Holm-adjusted over all cells, but
//!    they only say *where* the residual concentrates; they do not decide. On data
//!    simulated from the true model (benchmark cases none-1 and sensor_timing-3) 3 and
//!    5 of 360 cells failed at this floor, accelerometer cells of hammer tests with
//!    chi2 per point 1.5-5 on 7-100 points and one single point at 43: the estimator's
//!    local errors at that granularity are not yet described by its error model.
//!    (Putting the model's prediction through the estimator by replaying the tests,
//!    [`super::time_domain`], was tried: it removed none of these and added misfits in
//!    the shake-table displacement cells.)
//!
//! **Neighbouring bins.** The points of one estimate are not independent: the hammer
//! blocks' exponential window spreads each bin's noise over its neighbours (`|c(1)| =
//! 0.69` for the default window, [`crate::signal::correlation::exp_window_bin_correlation`]). That leaves the mean of
//! a sum of squared residuals at two per point but multiplies its variance by `1 + 2
//! sum_d |c(d)|^2` (about 2.9 for that window) where the noise outweighs the floor, so
//! each test refers its sum to Satterthwaite's scaled chi^2 with that mean and variance
//! ([`correlated_p_value`]) instead of to chi^2 with two dof per point. The correlation
//! is the windows' own, not measured on the residuals, so that a smooth misfit cannot
//! pass for correlated noise and weaken the test that should find it. Before this, the
//! 30-null study's one false alarm (null-30: red noise at 1.34 times the recorded
//! level, so the estimates' noise far above the floors) failed one check place with chi2
//! per point 1.20 on 319 points, 3.6 independent-point standard deviations high.
//!
//! The model is adequate when nothing fails. Otherwise [`Unexplained`] gives the places
//! (tests, channels, bands; a floor or quantity when every failing channel shares it)
//! and a signature: the mean magnitude and phase of the misfit there, whether it sits on
//! one channel against its neighbours or in some tests and not in others, and the
//! consistency findings at those places (amplitude dependence between strong and weak
//! impacts, change between tests, reciprocity, accelerometers against displacement
//! sensors).

use super::consistency::{CheckKind, CheckResult, ConsistencyOptions, ConsistencyReport};
use super::data::DiagnosisData;
use super::posterior::ModelPosterior;
use crate::error::Result;
use crate::io::Channel;
use crate::signal::correlation::exp_window_bin_correlations;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::collections::BTreeMap;

/// Family-wise level of each family of adequacy tests.
pub const ADEQUACY_LEVEL: f64 = 0.01;

/// Relative error floor of the global test and the cells, beyond the Bendat-Piersol
/// error: the estimator's worst measured bias.
pub const ADEQUACY_FLOOR: f64 = 0.009;

/// Points whose Bendat-Piersol relative error exceeds this are not tested. The standard
/// deviation is scaled by the measured `|h| = |H| |1 + e|`, so a squared residual is
/// inflated by `E[1 / |1 + e|^2] = 1 + 2 eps^2` to second order: 2 % at 0.1, 18 % at
/// 0.3, which a test over thousands of points would call a misfit.
pub const MAX_TESTED_REL_ERROR: f64 = 0.1;

/// One tested place: some points of the data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaceTest {
    /// `all points`, `cell`, or the consistency check's name.
    pub source: String,
    pub tests: Vec<String>,
    pub channels: Vec<String>,
    /// Frequency bands, Hz (empty: the whole range, or off the resonance bands for a
    /// cell whose `off_band` is set).
    pub bands_hz: Vec<(f64, f64)>,
    #[serde(default)]
    pub off_band: bool,
    pub n_points: usize,
    /// Squared whitened residuals per real datum (1 when the model is right).
    pub chi2_per_point: f64,
    /// Degrees of freedom of the chi^2 law the statistic is referred to: `2 n_points`
    /// when the points' errors are independent, fewer where neighbouring bins of one
    /// estimate share their noise (see [`correlated_p_value`]).
    #[serde(default)]
    pub effective_dof: f64,
    pub p_value: f64,
    /// Holm-adjusted within its family.
    pub p_adjusted: f64,
    pub failed: bool,
    /// Mean of `ln|h| - ln|H|` and of `arg h - arg H` (rad) over the points.
    pub mean_ln_ratio: f64,
    pub mean_phase_rad: f64,
}

/// Where the final model fails, in the location keys of `effects`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Where {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floor: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quantity: Option<crate::io::Quantity>,
    pub channels: Vec<String>,
    pub tests: Vec<String>,
    pub bands_hz: Vec<(f64, f64)>,
}

/// What nothing named explains.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Unexplained {
    #[serde(rename = "where")]
    pub place: Where,
    pub signature: Vec<String>,
}

/// The adequacy of the final model (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Adequacy {
    pub adequate: bool,
    /// The global test (floor [`ADEQUACY_FLOOR`]).
    pub global: PlaceTest,
    /// Cells tested, and those that failed (where the residual concentrates; they do
    /// not decide, see the module docs).
    pub n_cells: usize,
    pub failed_cells: Vec<PlaceTest>,
    /// The points of every inconsistent consistency check (floor 0.3 %).
    pub checks: Vec<PlaceTest>,
    /// Why the checks could not be used, if they could not.
    #[serde(default)]
    pub checks_unavailable: Option<String>,
    pub unexplained: Option<Unexplained>,
}

/// One point of the data with its squared whitened residual.
struct Point {
    segment: usize,
    test: String,
    channel: Channel,
    freq_hz: f64,
    ln_ratio: f64,
    phase_rad: f64,
    /// Whitened residual (real and imaginary parts of unit variance under the model);
    /// its squared modulus is the point's chi^2.
    r: Complex64,
    /// The estimate's frequency bin (`None`: unknown, the point taken as independent).
    bin: Option<usize>,
    /// The share of the point's variance that is the estimate's noise (the rest, the
    /// floor, is taken as independent between points): `eps^2 / (eps^2 + floor^2)`.
    noise_share: f64,
    /// What a relative error `delta` of the estimate adds to `r`, per unit `delta`:
    /// `h = H (1 + delta)` moves `r` by `-delta h / sd`, so `a = (h / |h|) / sd_rel`.
    a: Complex64,
}

/// Every point of `post` with its squared whitened residual against `pred` at floor `eta`.
fn points(post: &ModelPosterior, pred: &[Complex64], eta: f64) -> Result<(Vec<Point>, f64)> {
    if pred.len() != post.measured().len() {
        return Err(crate::Error::Usage(format!(
            "adequacy: {} predicted values for {} measured",
            pred.len(),
            post.measured().len()
        )));
    }
    let mut r = vec![0.0; post.n_whitened_residuals()];
    post.whitened_residuals_of(pred, eta, &mut r);
    let h = post.measured();
    let data = post.data();
    let mut out = Vec::with_capacity(h.len());
    for (si, seg) in post.model().layout().iter().enumerate() {
        let sd = &data.segments[si];
        for (ci, range) in seg.iter().enumerate() {
            let ch = &sd.channels[ci];
            for (j, i) in range.clone().enumerate() {
                if ch.rel_err[j] > MAX_TESTED_REL_ERROR {
                    continue;
                }
                let ratio = h[i] / pred[i];
                let sd_rel = (ch.rel_err[j].powi(2) + eta * eta).sqrt();
                out.push(Point {
                    segment: si,
                    test: sd.test.clone(),
                    channel: ch.channel.clone(),
                    freq_hz: sd.freq_hz[ch.freq_index[j]],
                    ln_ratio: ratio.norm().ln(),
                    phase_rad: ratio.arg(),
                    r: Complex64::new(r[2 * i], r[2 * i + 1]),
                    bin: sd.source.bins.get(ch.freq_index[j]).copied(),
                    noise_share: (ch.rel_err[j] / sd_rel).powi(2),
                    a: ch.h[j] / (ch.h[j].norm() * sd_rel),
                });
            }
        }
    }
    // The correlated input-gain terms follow the points' residuals.
    let gains: f64 = r[2 * h.len()..].iter().map(|v| v * v).sum();
    let total = out.iter().map(|p| p.r.norm_sqr()).sum::<f64>() + gains;
    Ok((out, total))
}

fn unique<T: PartialEq + Clone>(v: impl Iterator<Item = T>) -> Vec<T> {
    let mut out: Vec<T> = Vec::new();
    for x in v {
        if !out.contains(&x) {
            out.push(x);
        }
    }
    out
}

/// The test of the points `idx` (`total` overrides their chi^2 sum: the global test
/// includes the correlated-gain terms); `corr` is [`bin_correlation_sq`] of the data.
fn place(
    source: &str,
    pts: &[Point],
    idx: &[usize],
    total: Option<f64>,
    corr: &[Vec<f64>],
) -> PlaceTest {
    let n = idx.len();
    let chi2 = total.unwrap_or_else(|| idx.iter().map(|&i| pts[i].r.norm_sqr()).sum());
    let dof = 2 * n;
    let (p_value, effective_dof) =
        correlated_p_value(chi2, dof.max(1) as f64, chi2_variance(pts, idx, corr));
    let mean =
        |f: &dyn Fn(&Point) -> f64| idx.iter().map(|&i| f(&pts[i])).sum::<f64>() / n.max(1) as f64;
    PlaceTest {
        source: source.into(),
        tests: unique(idx.iter().map(|&i| pts[i].test.clone())),
        channels: unique(idx.iter().map(|&i| pts[i].channel.name.clone())),
        bands_hz: Vec::new(),
        off_band: false,
        n_points: n,
        chi2_per_point: chi2 / dof.max(1) as f64,
        effective_dof,
        p_value,
        p_adjusted: p_value,
        failed: false,
        mean_ln_ratio: mean(&|p| p.ln_ratio),
        mean_phase_rad: mean(&|p| p.phase_rad),
    }
}

/// `|c(d)|^2`, `d = 0..=MAX_CORRELATED_BINS`, of the noise of neighbouring bins of each
/// segment's estimates ([`crate::signal::correlation::exp_window_bin_correlation`]: the hammer blocks' exponential
/// window, or none for the shake-table records, over the transformed record, `1 / (df x
/// zero padding)` s), one table per segment. A segment whose bins are not known gets
/// `[1]`: its points are taken as independent.
fn bin_correlation_sq(data: &DiagnosisData) -> Vec<Vec<f64>> {
    data.segments
        .iter()
        .map(|s| {
            let df_hz = s
                .freq_hz
                .iter()
                .zip(&s.source.bins)
                .find(|(_, &b)| b > 0)
                .map(|(f, &b)| f / b as f64)
                .filter(|df| df.is_finite() && *df > 0.0);
            let Some(df_hz) = df_hz else {
                return vec![1.0];
            };
            let record_s = 1.0 / (df_hz * s.source.estimate.zero_pad_factor.max(1) as f64);
            window_correlation_sq(s.exp_window_tau_s, record_s, df_hz)
        })
        .collect()
}

/// `|c(d)|^2`, `d = 0..=MAX_CORRELATED_BINS`, of a record of `record_s` s under the
/// exponential window `tau_s` (`None`: rectangular) on a grid of `df_hz`.
fn window_correlation_sq(tau_s: Option<f64>, record_s: f64, df_hz: f64) -> Vec<f64> {
    exp_window_bin_correlations(tau_s, record_s, df_hz)
        .iter()
        .map(|c| c.norm_sqr())
        .collect()
}

/// Variance of the sum of the squared whitened residuals of the points `idx` under the
/// model. Each point's `|r|^2` is chi^2 with 2 dof (variance 4); two points of one
/// estimate `d` bins apart share the noise part of their errors with correlation `c(d)`,
/// which adds `2 x 4 |c(d)|^2 s_k s_l` (`s` the noise shares) for complex circular
/// Gaussian errors (`Var r^* r = 4 tr(C^2)`).
fn chi2_variance(pts: &[Point], idx: &[usize], corr: &[Vec<f64>]) -> f64 {
    let mut runs: BTreeMap<(usize, &str), Vec<(usize, f64)>> = BTreeMap::new();
    for &i in idx {
        let p = &pts[i];
        if let Some(bin) = p.bin {
            runs.entry((p.segment, p.channel.name.as_str()))
                .or_default()
                .push((bin, p.noise_share));
        }
    }
    let mut var = 4.0 * idx.len() as f64;
    for ((segment, _), mut run) in runs {
        let c2 = corr.get(segment).map_or(&[][..], |c| c.as_slice());
        run.sort_by_key(|&(bin, _)| bin);
        for (k, &(bk, sk)) in run.iter().enumerate() {
            for &(bl, sl) in &run[k + 1..] {
                match c2.get(bl - bk) {
                    Some(c) => var += 8.0 * c * sk * sl,
                    None => break,
                }
            }
        }
    }
    var
}

/// P-value of a sum of squared whitened residuals `chi2` with mean `dof` and variance
/// `var` under the model, and the degrees of freedom it is referred to: Satterthwaite's
/// (1946) scaled chi^2, `chi2 ~ g chi^2_h` with `g = var / (2 dof)`, `h = 2 dof^2 / var`,
/// the law of a sum of correlated chi^2 terms with their mean and variance. Independent
/// points (`var = 2 dof`) give the plain chi^2 test with `dof`.
fn correlated_p_value(chi2: f64, dof: f64, var: f64) -> (f64, f64) {
    let var = var.max(2.0 * dof);
    let g = var / (2.0 * dof);
    let h = 2.0 * dof * dof / var;
    let p = ChiSquared::new(h).map_or(f64::NAN, |law| law.sf(chi2 / g));
    (p, h)
}

/// Chi^2 of the points `idx` when every estimate (segment x channel) carries, over each
/// band of `bands` (or over all when none), one smooth relative error `delta` of standard
/// deviation `sd` in gain and in phase: the consistency checks' own null
/// ([`ConsistencyOptions::estimator_rel_error`], added to their ratio fits as a smooth
/// error, not per point). Per group, the residuals' covariance is `I + sd^2 a a^*`, so
/// the quadratic form is `|r|^2 - sd^2 |a^* r|^2 / (1 + sd^2 |a|^2)` (Woodbury) and the
/// sum is still chi^2 with two degrees of freedom per point under the model.
fn smooth_error_chi2(pts: &[Point], idx: &[usize], bands: &[(f64, f64)], sd: f64) -> f64 {
    // Per group: |r|^2, a^* r, |a|^2.
    type Sums = (f64, Complex64, f64);
    let mut groups: BTreeMap<(usize, &str, Option<usize>), Sums> = BTreeMap::new();
    for &i in idx {
        let p = &pts[i];
        let band = bands
            .iter()
            .position(|(lo, hi)| (*lo..=*hi).contains(&p.freq_hz));
        let g = groups
            .entry((p.segment, p.channel.name.as_str(), band))
            .or_insert((0.0, Complex64::new(0.0, 0.0), 0.0));
        g.0 += p.r.norm_sqr();
        g.1 += p.a.conj() * p.r;
        g.2 += p.a.norm_sqr();
    }
    let v = sd * sd;
    groups
        .values()
        .map(|(rr, ar, aa)| rr - v * ar.norm_sqr() / (1.0 + v * aa))
        .sum()
}

/// Holm-adjusts a family and marks its failures.
fn judge(family: &mut [&mut PlaceTest]) {
    let p: Vec<f64> = family.iter().map(|t| t.p_value).collect();
    for (t, a) in family.iter_mut().zip(super::consistency::holm_adjust(&p)) {
        t.p_adjusted = a;
        t.failed = a < ADEQUACY_LEVEL;
    }
}

/// Cells: segment x channel x band (`bands` of the fitted frame, then off-band).
fn cells(pts: &[Point], bands: &[(f64, f64)], corr: &[Vec<f64>]) -> Vec<PlaceTest> {
    let mut members: BTreeMap<(usize, &str, Option<usize>), Vec<usize>> = BTreeMap::new();
    for (i, p) in pts.iter().enumerate() {
        let band = bands
            .iter()
            .position(|(lo, hi)| (*lo..=*hi).contains(&p.freq_hz));
        let key = (p.segment, p.channel.name.as_str(), band);
        members.entry(key).or_default().push(i);
    }
    members
        .iter()
        .map(|((_, _, band), idx)| {
            let mut t = place("cell", pts, idx, None, corr);
            match band {
                Some(b) => t.bands_hz = vec![bands[*b]],
                None => t.off_band = true,
            }
            t
        })
        .collect()
}

/// The points a consistency check compared: its tests, its response channels (every
/// channel of those tests when it names none of them), its bands.
fn check_points(pts: &[Point], c: &CheckResult) -> Vec<usize> {
    let test_of = |s: &str| s.split('#').next().unwrap_or(s).to_string();
    let tests: Vec<String> = c.compared.segments.iter().map(|s| test_of(s)).collect();
    let in_tests = |p: &Point| tests.is_empty() || tests.contains(&p.test);
    let names_any = pts
        .iter()
        .any(|p| in_tests(p) && c.compared.channels.contains(&p.channel.name));
    let in_band = |f: f64| {
        c.compared.bands_hz.is_empty()
            || c.compared
                .bands_hz
                .iter()
                .any(|(lo, hi)| (*lo..=*hi).contains(&f))
    };
    (0..pts.len())
        .filter(|&i| {
            let p = &pts[i];
            in_tests(p)
                && (!names_any || c.compared.channels.contains(&p.channel.name))
                && in_band(p.freq_hz)
        })
        .collect()
}

/// Judges the prediction `pred` of the model `post` (see the module docs); `bands` are the fitted frame's resonance bands,
/// `consistency` the checks of the campaign (or why none).
pub fn assess(
    post: &ModelPosterior,
    pred: &[Complex64],
    bands: &[(f64, f64)],
    consistency: std::result::Result<&ConsistencyReport, String>,
) -> Result<Adequacy> {
    let (pts, total) = points(post, pred, ADEQUACY_FLOOR)?;
    let corr = bin_correlation_sq(post.data());
    let all: Vec<usize> = (0..pts.len()).collect();
    let mut global = place("all points", &pts, &all, Some(total), &corr);
    judge(&mut [&mut global]);
    let mut cells = cells(&pts, bands, &corr);
    judge(&mut cells.iter_mut().collect::<Vec<_>>());
    let n_cells = cells.len();
    let failed_cells: Vec<PlaceTest> = cells.into_iter().filter(|c| c.failed).collect();

    let (mut checks, checks_unavailable, inconsistent) = match consistency {
        Ok(report) => {
            let tight = ConsistencyOptions::default().estimator_rel_error;
            let (tpts, _) = points(post, pred, tight)?;
            let tpts = &tpts;
            let inconsistent: Vec<CheckResult> =
                report.inconsistent().into_iter().cloned().collect();
            let tests = inconsistent
                .iter()
                .map(|c| {
                    let idx = check_points(tpts, c);
                    let bands = &c.compared.bands_hz;
                    let chi2 = smooth_error_chi2(tpts, &idx, bands, tight);
                    let mut t = place(&c.name, tpts, &idx, Some(chi2), &corr);
                    t.bands_hz = bands.clone();
                    t
                })
                .collect::<Vec<_>>();
            (tests, None, inconsistent)
        }
        Err(why) => (Vec::new(), Some(why), Vec::new()),
    };
    {
        let mut family: Vec<&mut PlaceTest> =
            checks.iter_mut().filter(|t| t.n_points > 0).collect();
        judge(&mut family);
    }
    let adequate = !global.failed && !checks.iter().any(|c| c.failed);
    let unexplained =
        (!adequate).then(|| unexplained(&global, &failed_cells, &checks, &inconsistent, &pts));
    Ok(Adequacy {
        adequate,
        global,
        n_cells,
        failed_cells,
        checks,
        checks_unavailable,
        unexplained,
    })
}

/// The places and signature of a failed assessment.
fn unexplained(
    global: &PlaceTest,
    cells: &[PlaceTest],
    checks: &[PlaceTest],
    inconsistent: &[CheckResult],
    pts: &[Point],
) -> Unexplained {
    let failing_checks: Vec<&PlaceTest> = checks.iter().filter(|c| c.failed).collect();
    let failing: Vec<&PlaceTest> = if failing_checks.is_empty() {
        cells.iter().collect()
    } else {
        failing_checks
    };
    let places: Vec<&PlaceTest> = if failing.is_empty() {
        vec![global]
    } else {
        failing
    };
    let channels = unique(places.iter().flat_map(|p| p.channels.iter().cloned()));
    let tests = unique(places.iter().flat_map(|p| p.tests.iter().cloned()));
    let mut bands_hz = unique(places.iter().flat_map(|p| p.bands_hz.iter().copied()));
    bands_hz.sort_by(|a, b| a.0.total_cmp(&b.0));
    let meta: Vec<&Channel> = channels
        .iter()
        .filter_map(|n| {
            pts.iter()
                .find(|p| &p.channel.name == n)
                .map(|p| &p.channel)
        })
        .collect();
    let floor = unique(meta.iter().map(|c| c.floor));
    let quantity = unique(meta.iter().map(|c| c.quantity));
    let place = Where {
        floor: (floor.len() == 1).then(|| floor[0]),
        quantity: (quantity.len() == 1).then(|| quantity[0]),
        channels,
        tests,
        bands_hz,
    };
    let signature = signature(&places, &place, inconsistent, pts);
    Unexplained { place, signature }
}

/// What the residual at the failing places shows (see the module docs).
fn signature(
    places: &[&PlaceTest],
    at: &Where,
    inconsistent: &[CheckResult],
    pts: &[Point],
) -> Vec<String> {
    let mut out = Vec::new();
    let n: usize = places.iter().map(|p| p.n_points).sum::<usize>().max(1);
    let w = |f: &dyn Fn(&PlaceTest) -> f64| {
        places.iter().map(|p| f(p) * p.n_points as f64).sum::<f64>() / n as f64
    };
    let (ln_ratio, phase) = (w(&|p| p.mean_ln_ratio), w(&|p| p.mean_phase_rad));
    out.push(format!(
        "the recordings are {:+.1} % in magnitude and {:+.1} degrees in phase from the model there (mean over {} points, chi2 per point up to {:.1})",
        100.0 * ln_ratio.exp_m1(),
        phase.to_degrees(),
        n,
        places.iter().map(|p| p.chi2_per_point).fold(0.0, f64::max)
    ));
    let all_channels = unique(
        pts.iter()
            .filter(|p| at.tests.contains(&p.test))
            .map(|p| p.channel.name.clone()),
    );
    if at.channels.len() == 1 && all_channels.len() > 1 {
        out.push(format!(
            "one channel against its neighbours: only {} misfits, the other {} channels of the same tests fit",
            at.channels[0],
            all_channels.len() - 1
        ));
    }
    let all_tests = unique(
        pts.iter()
            .filter(|p| at.channels.contains(&p.channel.name))
            .map(|p| p.test.clone()),
    );
    if !at.tests.is_empty() && at.tests.len() < all_tests.len() {
        out.push(format!(
            "change between tests: {} of the {} tests recording these channels misfit ({})",
            at.tests.len(),
            all_tests.len(),
            at.tests.join(", ")
        ));
    }
    for c in inconsistent {
        let overlaps = c
            .compared
            .segments
            .iter()
            .any(|s| at.tests.iter().any(|t| s.split('#').next() == Some(t)));
        if !overlaps {
            continue;
        }
        let what = match c.kind {
            CheckKind::ImpactLevel => "amplitude dependence between strong and weak impacts",
            CheckKind::Drift => "the structure changes between tests",
            CheckKind::HammerVsShake => "the hammer and shake-table set-ups disagree",
            CheckKind::Reciprocity => "reciprocity fails",
            CheckKind::AccVsDisp => "accelerometers and displacement sensors disagree",
        };
        out.push(format!("{what} ({}: {})", c.name, c.summary));
    }
    out
}

#[cfg(test)]
#[path = "adequacy_tests.rs"]
mod tests;
