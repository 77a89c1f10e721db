//! The conclusions of the `tower-hmd` study, computed from the run: signs and ratios of
//! the channel gains, which measured resonances the shear model reproduces, which floors
//! stand out, what sits at a prior bound, how the fit to the first two modes predicts
//! the rest, and the frequency ratios against a shear chain and a cantilever.
//! [`super::tower_report`] only renders them; `findings.json` holds them.

use serde::Serialize;

use super::posterior::AtBound;
use super::tower_model::N;
use super::tower_residuals::{shear_modes, PeakResidual, ResidualAnalysis};
use super::tower_run::{TowerFit, TowerStudy};

/// A floor whose RMS standardised residual exceeds this multiple of the median floor's
/// stands out.
pub const FLOOR_OUTLIER_RATIO: f64 = 1.5;

/// `beta_n L` of a uniform cantilever (Euler-Bernoulli): roots of
/// `1 + cos(x) cosh(x) = 0`; frequencies scale as `(beta_n L)^2`.
const CANTILEVER_BETA_L: [f64; N] = [1.875104, 4.694091, 7.854757, 10.995541, 14.137168];

/// A measured resonance the model does not reproduce.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MissedPeak {
    pub freq_hz: f64,
    /// Nearest model mode, from 1.
    pub model_mode: usize,
    pub model_freq_hz: f64,
    pub mac: f64,
}

/// A model mode in the band that no measured peak is nearest to.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UnmatchedMode {
    /// From 1.
    pub mode: usize,
    pub freq_hz: f64,
}

/// A parameter of the whole-band fit at a prior bound.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bound {
    pub name: String,
    /// `"lower"` or `"upper"`.
    pub side: &'static str,
}

/// RMS |z| and reproduced count of a set of peaks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PeakGroup {
    pub rms_z: f64,
    pub n_peaks: usize,
    pub n_reproduced: usize,
}

/// `f_n / f_1` of the measured peaks, a uniform shear chain and a uniform cantilever.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrequencyRatios {
    pub measured: Vec<f64>,
    pub shear_chain: Vec<f64>,
    pub cantilever: Vec<f64>,
    /// Peaks (from 1) whose ratio lies between the shear chain's and the cantilever's.
    pub between_shear_and_flexure: Vec<usize>,
}

/// See the module docs. Floors are numbered from 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Findings {
    /// Floors whose gain's 95 % interval is negative (whole band).
    pub negative_gain_floors: Vec<usize>,
    /// Posterior-median gain magnitude relative to floor 1's.
    pub gain_ratio_to_floor1: Vec<f64>,
    pub reproduced_peaks_hz: Vec<f64>,
    pub missed_peaks: Vec<MissedPeak>,
    pub unmatched_modes: Vec<UnmatchedMode>,
    /// Posterior median of the noise scale `s` (whole band; 1 = estimator noise).
    pub noise_scale: f64,
    pub rms_z_total: f64,
    pub rms_z_floor: Vec<f64>,
    pub worst_floor: usize,
    pub best_floor: usize,
    /// Floors above [`FLOOR_OUTLIER_RATIO`] times the median floor.
    pub outlier_floors: Vec<usize>,
    pub at_bound: Vec<Bound>,
    /// The fit to the first two modes: its noise scale, and the peaks inside / above its
    /// band.
    pub low_noise_scale: f64,
    pub low_inside: PeakGroup,
    pub low_above: PeakGroup,
    pub frequency_ratios: Option<FrequencyRatios>,
}

fn gains(f: &TowerFit) -> (Vec<usize>, Vec<f64>) {
    let g = |c: usize| &f.rows[2 * N + 1 + c];
    let negative = (0..N)
        .filter(|&c| g(c).q97_5 < 0.0)
        .map(|c| c + 1)
        .collect();
    let ratio = (0..N).map(|c| g(c).q50 / g(0).q50).collect();
    (negative, ratio)
}

fn peaks(a: &ResidualAnalysis) -> (Vec<f64>, Vec<MissedPeak>) {
    let hit = a
        .peaks
        .iter()
        .filter(|p| p.reproduced())
        .map(|p| p.peak.freq_hz)
        .collect();
    let missed = a
        .peaks
        .iter()
        .filter(|p| !p.reproduced())
        .map(|p| MissedPeak {
            freq_hz: p.peak.freq_hz,
            model_mode: p.mode + 1,
            model_freq_hz: p.model_freq_hz,
            mac: p.mac,
        })
        .collect();
    (hit, missed)
}

/// Worst floor, best floor and the floors standing out (all from 1).
fn floors(a: &ResidualAnalysis) -> (usize, usize, Vec<usize>) {
    let mut order: Vec<usize> = (0..N).collect();
    order.sort_by(|&x, &y| a.rms_z_floor[y].total_cmp(&a.rms_z_floor[x]));
    let mut sorted = a.rms_z_floor.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[N / 2];
    let outliers = (0..N)
        .filter(|&c| a.rms_z_floor[c] > FLOOR_OUTLIER_RATIO * median)
        .map(|c| c + 1)
        .collect();
    (order[0] + 1, order[N - 1] + 1, outliers)
}

fn at_bound(f: &TowerFit) -> Vec<Bound> {
    f.rows
        .iter()
        .filter_map(|r| {
            r.at_bound.map(|b| Bound {
                name: r.name.clone(),
                side: match b {
                    AtBound::Lower => "lower",
                    AtBound::Upper => "upper",
                },
            })
        })
        .collect()
}

fn group(v: &[&PeakResidual]) -> PeakGroup {
    let all: Vec<f64> = v.iter().flat_map(|p| p.rms_z.iter().copied()).collect();
    PeakGroup {
        rms_z: (all.iter().map(|x| x * x).sum::<f64>() / all.len().max(1) as f64).sqrt(),
        n_peaks: v.len(),
        n_reproduced: v.iter().filter(|p| p.reproduced()).count(),
    }
}

/// Measured peak frequencies over the first against a uniform 5-story shear chain and a
/// uniform flexural cantilever; `None` without measured peaks.
fn frequency_ratios(a: &ResidualAnalysis) -> Option<FrequencyRatios> {
    let first = a.peaks.first()?;
    let measured: Vec<f64> = a
        .peaks
        .iter()
        .map(|p| p.peak.freq_hz / first.peak.freq_hz)
        .collect();
    let shear_chain = shear_modes(&[1.0e6; N])
        .map(|m| {
            let f = m.freq_hz();
            f.iter().map(|x| x / f[0]).collect::<Vec<_>>()
        })
        .unwrap_or_default();
    let cantilever: Vec<f64> = CANTILEVER_BETA_L
        .iter()
        .map(|b| (b / CANTILEVER_BETA_L[0]).powi(2))
        .collect();
    let between_shear_and_flexure = (1..measured.len().min(shear_chain.len()))
        .filter(|&n| measured[n] > shear_chain[n] && measured[n] < cantilever[n])
        .map(|n| n + 1)
        .collect();
    Some(FrequencyRatios {
        measured,
        shear_chain,
        cantilever,
        between_shear_and_flexure,
    })
}

/// Computes the findings of a run.
pub fn assess(s: &TowerStudy) -> Findings {
    let a = &s.residuals;
    let (negative_gain_floors, gain_ratio_to_floor1) = gains(&s.full);
    let (reproduced_peaks_hz, missed_peaks) = peaks(a);
    let (worst_floor, best_floor, outlier_floors) = floors(a);
    let (inside, above): (Vec<&PeakResidual>, Vec<&PeakResidual>) = s
        .residuals_low
        .peaks
        .iter()
        .partition(|p| p.peak.freq_hz <= s.low.band_hz.1);
    Findings {
        negative_gain_floors,
        gain_ratio_to_floor1,
        reproduced_peaks_hz,
        missed_peaks,
        unmatched_modes: a
            .unmatched_modes
            .iter()
            .map(|&r| UnmatchedMode {
                mode: r + 1,
                freq_hz: a.model_freq_hz[r],
            })
            .collect(),
        noise_scale: s.full.rows[2 * N].q50,
        rms_z_total: a.rms_z_total,
        rms_z_floor: a.rms_z_floor.to_vec(),
        worst_floor,
        best_floor,
        outlier_floors,
        at_bound: at_bound(&s.full),
        low_noise_scale: s.low.rows[2 * N].q50,
        low_inside: group(&inside),
        low_above: group(&above),
        frequency_ratios: frequency_ratios(a),
    }
}
