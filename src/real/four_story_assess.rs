//! The conclusions of the `four-story-modal` study, computed from the run: the rules of
//! the verdict, the comparisons with the paper's models, the effect of freeing the
//! masses. [`super::four_story_report`] only renders them; `findings.json` holds them.

use serde::Serialize;

use super::four_story::N_FLOORS;
use super::four_story_run::{FourStoryStudy, Variant};
use super::posterior::quantile_sorted;

/// Posterior-predictive p-values below this flag a misfit.
pub const P_FLAG: f64 = 0.05;

/// Index of Table 1's Caughey/accelerance model in [`FourStoryStudy::paper_models`], the
/// model this frame is compared against.
const TABLE1_REFERENCE: usize = 4;

/// Posterior medians of a variant's two noise scales.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseScales {
    /// Relative frequency error `sigma_f` (a fraction, not %).
    pub sigma_f: f64,
    /// Shape error per component of a unit-length shape, `sigma_s`.
    pub sigma_s: f64,
}

/// A posterior-predictive p-value below [`P_FLAG`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Flag {
    /// Mode, from 1.
    pub mode: usize,
    /// `"frequency"` or `"shape"`.
    pub quantity: &'static str,
    pub p: f64,
}

/// Where the measured mode-4 frequency falls in the predictive interval of the fit to
/// modes 1-3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Position {
    Below,
    Inside,
    Above,
}

/// A ratio minus 1 with its 95 % interval (fractions).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Relative {
    pub mean: f64,
    pub q2_5: f64,
    pub q97_5: f64,
}

/// See the module docs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Findings {
    /// Fixed masses, all four modes.
    pub noise_fixed_masses: NoiseScales,
    /// Free masses of floors 2-4.
    pub noise_free_masses: NoiseScales,
    /// Relative spread (max - min over mid-range) of the frequencies of the eight updated
    /// models of Tables 1-2, per mode.
    pub paper_spread: Vec<f64>,
    /// Mean frequency (Hz) of the four updated Table 1 models, per mode.
    pub table1_mean_freq_hz: Vec<f64>,
    /// Posterior-predictive p-values below [`P_FLAG`] (main variant).
    pub flagged: Vec<Flag>,
    /// Largest `|f_model / f_measured - 1|` of the posterior-median model.
    pub max_rel_freq_error: f64,
    pub min_mac: f64,
    /// The measured mode-4 frequency against the prediction from modes 1-3.
    pub holdout_position: Position,
    /// The rules: no flag, mode 4 inside its held-out interval, no frequency missed by
    /// more than the paper's own spread.
    pub adequate: bool,
    /// Posterior stiffness relative to Table 1 (Caughey, accelerance), per story.
    pub stiffness_vs_table1: Vec<Relative>,
    /// Stories (from 1) whose 95 % interval lies wholly below / above Table 1.
    pub stories_below_table1: Vec<usize>,
    pub stories_above_table1: Vec<usize>,
    /// Table 1's frequencies relative to the measured ones, minus 1, per mode.
    pub table1_freq_error: Vec<f64>,
    /// Smallest and largest chi-square p of the four Table 1 models.
    pub table1_chi2_p: (f64, f64),
    /// Freeing the masses halves both noise scales.
    pub free_masses_absorb_misfit: bool,
}

/// Posterior medians of a variant's noise scales (the coordinates after the structural
/// ones are their logarithms).
pub fn median_noise(v: &Variant) -> NoiseScales {
    let ns = v.lik.n_structural();
    let med = |p: usize| {
        let mut x: Vec<f64> = v.sampled.chains(p, f64::exp).concat();
        x.sort_by(f64::total_cmp);
        quantile_sorted(&x, 0.5)
    };
    NoiseScales {
        sigma_f: med(ns),
        sigma_s: med(ns + 1),
    }
}

/// Relative spread (max - min over mid-range) of the frequencies predicted by the eight
/// updated models of Tables 1-2, per mode.
fn paper_spread(s: &FourStoryStudy) -> Vec<f64> {
    (0..N_FLOORS)
        .map(|i| {
            let (lo, hi) = s.paper_models[1..]
                .iter()
                .map(|(_, p)| p.freq_hz[i])
                .fold((f64::MAX, f64::MIN), |a, x| (a.0.min(x), a.1.max(x)));
            (hi - lo) / (0.5 * (hi + lo))
        })
        .collect()
}

fn flags(s: &FourStoryStudy) -> Vec<Flag> {
    let mut out = vec![];
    for (i, m) in s.main_ppc.modes.iter().enumerate() {
        for (quantity, p) in [("frequency", m.p_freq), ("shape", m.p_shape)] {
            if p < P_FLAG {
                out.push(Flag {
                    mode: i + 1,
                    quantity,
                    p,
                });
            }
        }
    }
    out
}

fn holdout_position(s: &FourStoryStudy) -> Position {
    let h4 = &s.holdout_ppc.modes[3];
    let f4 = s.data.freq_hz[3];
    if f4 < h4.f_rep[0] {
        Position::Below
    } else if f4 > h4.f_rep[2] {
        Position::Above
    } else {
        Position::Inside
    }
}

/// The posterior's stiffnesses against Table 1's, and the stories wholly below / above.
fn stiffness_vs_table1(s: &FourStoryStudy) -> (Vec<Relative>, Vec<usize>, Vec<usize>) {
    let t1 = &s.paper_models[TABLE1_REFERENCE].0;
    let (mut below, mut above) = (vec![], vec![]);
    let rel = (0..N_FLOORS)
        .map(|r| {
            let row = &s.main.rows[r];
            let k = t1.stiffness_n_per_m[r];
            if row.q97_5 < k {
                below.push(r + 1);
            }
            if row.q2_5 > k {
                above.push(r + 1);
            }
            Relative {
                mean: row.mean / k - 1.0,
                q2_5: row.q2_5 / k - 1.0,
                q97_5: row.q97_5 / k - 1.0,
            }
        })
        .collect();
    (rel, below, above)
}

/// Computes the findings of a run.
pub fn assess(s: &FourStoryStudy) -> Findings {
    let d = &s.data;
    let flagged = flags(s);
    let max_rel_freq_error = (0..N_FLOORS)
        .map(|i| (s.main_median.freq_hz[i] / d.freq_hz[i] - 1.0).abs())
        .fold(0.0, f64::max);
    let paper_spread = paper_spread(s);
    let max_spread = paper_spread.iter().copied().fold(f64::MIN, f64::max);
    let holdout_position = holdout_position(s);
    let table1 = &s.paper_models[1..5];
    let (stiffness_vs_table1, stories_below_table1, stories_above_table1) = stiffness_vs_table1(s);
    let noise_fixed_masses = median_noise(&s.main);
    let noise_free_masses = median_noise(&s.free_mass);
    let p = s.chi2[1..5].iter().map(|c| c.p);
    Findings {
        adequate: flagged.is_empty()
            && holdout_position == Position::Inside
            && max_rel_freq_error <= max_spread,
        flagged,
        max_rel_freq_error,
        min_mac: s.main_median.mac.iter().copied().fold(1.0, f64::min),
        holdout_position,
        table1_mean_freq_hz: (0..N_FLOORS)
            .map(|i| table1.iter().map(|(_, p)| p.freq_hz[i]).sum::<f64>() / 4.0)
            .collect(),
        paper_spread,
        stiffness_vs_table1,
        stories_below_table1,
        stories_above_table1,
        table1_freq_error: (0..N_FLOORS)
            .map(|i| s.paper_models[TABLE1_REFERENCE].1.freq_hz[i] / d.freq_hz[i] - 1.0)
            .collect(),
        table1_chi2_p: (p.clone().fold(f64::MAX, f64::min), p.fold(0.0, f64::max)),
        free_masses_absorb_misfit: noise_free_masses.sigma_f < 0.5 * noise_fixed_masses.sigma_f
            && noise_free_masses.sigma_s < 0.5 * noise_fixed_masses.sigma_s,
        noise_fixed_masses,
        noise_free_masses,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::real::posterior::Sampling;
    use crate::real::{shared_dataset, Dataset};

    /// The rules on a short run of the real study (skipped without ../shared): each rule
    /// alone turns the verdict, and the findings follow the run's own numbers.
    #[test]
    fn each_rule_of_the_verdict_decides_on_a_real_run() {
        let Some(dir) = shared_dataset(Dataset::FourStoryModal) else {
            return;
        };
        let study = super::super::four_story_run::run(&dir, 3, &mut Sampling::capped(200))
            .expect("four-story run");
        let base = assess(&study);
        assert_eq!(base.stiffness_vs_table1.len(), N_FLOORS);
        assert!(base.max_rel_freq_error > 0.0 && base.min_mac <= 1.0);

        let mut low = study.clone();
        low.data.freq_hz[3] = 0.5 * low.holdout_ppc.modes[3].f_rep[0];
        let f = assess(&low);
        assert_eq!(f.holdout_position, Position::Below);
        assert!(!f.adequate);

        let mut flagged = study.clone();
        flagged.main_ppc.modes[1].p_shape = 0.5 * P_FLAG;
        let f = assess(&flagged);
        assert!(f
            .flagged
            .iter()
            .any(|g| g.mode == 2 && g.quantity == "shape"));
        assert!(!f.adequate);

        let mut far = study.clone();
        let spread = base.paper_spread.iter().copied().fold(0.0, f64::max);
        far.main_median.freq_hz[0] = far.data.freq_hz[0] * (1.0 + 2.0 * spread);
        let f = assess(&far);
        assert!(f.max_rel_freq_error > spread);
        assert!(!f.adequate);
    }
}
