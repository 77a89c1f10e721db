//! Priors on the sampled coordinates.
//!
//! The sampled vector `z` holds the free updating variables in their internal
//! coordinates (stiffness and mass multipliers `alpha`, `beta` as they are; damping
//! `a0`, `a1`, `xi_i` as logarithms) and, last, `ln s`, the log of the noise scale. Every
//! prior is confined to the variables' box (the paper's bounds, [`VariablesConfig`]);
//! outside it the log density is `-inf`.
//!
//! | [`PriorKind`] | multipliers (m, k) | damping | noise scale `s` |
//! |---|---|---|---|
//! | `Uniform` (default) | uniform in physical units | log-uniform (uniform in the sampled `ln`) | log-uniform |
//! | `UniformPhysical` | uniform | uniform in physical units (density `e^z` in `z = ln x`) | log-uniform |
//! | `LogNormal` | `ln x ~ N(ln x_nominal, ln(1 + cv^2))`, truncated | `ln x ~ N(ln x_start, damping_ln_sd^2)`, truncated | log-uniform |
//!
//! Log-uniform is the default for damping because its bounds span decades (Rayleigh's
//! `a1` from 1e-10 to 1e-3 s): a prior uniform in `a1` puts 99.9 % of its mass above
//! 1e-6 s. `x_start` is the variable's start value (the paper's initial values: `a0` =
//! 0.01 1/s, `a1` = 1e-6 s, `xi` = 0.01).
//!
//! [`VariablesConfig`]: crate::update::VariablesConfig

use crate::error::{Error, Result};
use crate::update::{Scale, VariableKind, Variables};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// Family of the prior on the structural and damping variables.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PriorKind {
    /// Uniform masses and stiffnesses, log-uniform damping (the default).
    #[default]
    Uniform,
    /// Uniform in physical units for every variable, damping included.
    UniformPhysical,
    /// Truncated lognormal: masses and stiffnesses with median at nominal and
    /// coefficient of variation `cv`; damping with median at its start value and log
    /// standard deviation `damping_ln_sd`.
    LogNormal { cv: f64, damping_ln_sd: f64 },
}

/// Default bounds of the noise scale `s` (log-uniform prior): 1e-2 to 1e4, from a
/// hundredth of the Bendat & Piersol error (data much better than their coherence says)
/// to 10^4 times it (model error far above measurement noise: a 0.1 % point
/// misfit by 10 %).
pub const DEFAULT_NOISE_SCALE_BOUNDS: [f64; 2] = [1e-2, 1e4];

/// The prior of one sampled coordinate.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Coord {
    /// Uniform on `[lo, hi]`.
    Flat,
    /// `ln p(z) = z` (uniform in `e^z`).
    ExpJacobian,
    /// `ln(1 + z) ~ N(0, sd^2)` (lognormal multiplier of a nominal value).
    LogNormalMultiplier { sd: f64 },
    /// `z ~ N(center, sd^2)` (`z` is already a logarithm).
    Normal { center: f64, sd: f64 },
}

/// Priors of all sampled coordinates with their box.
#[derive(Debug, Clone, PartialEq)]
pub struct Prior {
    coords: Vec<Coord>,
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl Prior {
    /// The prior of `kind` on the free variables of `vars` (damping on a log scale) and a
    /// log-uniform noise scale on `noise_scale_bounds`.
    pub fn new(kind: PriorKind, vars: &Variables, noise_scale_bounds: [f64; 2]) -> Result<Self> {
        let [s_lo, s_hi] = noise_scale_bounds;
        if !(s_lo.is_finite() && s_hi.is_finite() && s_lo > 0.0 && s_lo < s_hi) {
            return Err(Error::Usage(format!(
                "noise scale bounds must satisfy 0 < lower < upper, got [{s_lo}, {s_hi}]"
            )));
        }
        if let PriorKind::LogNormal { cv, damping_ln_sd } = kind {
            if !(cv.is_finite() && cv > 0.0 && damping_ln_sd.is_finite() && damping_ln_sd > 0.0) {
                return Err(Error::Usage(format!(
                    "lognormal prior: cv ({cv}) and damping_ln_sd ({damping_ln_sd}) must be positive"
                )));
            }
        }
        let bounds = vars.internal_bounds();
        let mut coords = Vec::new();
        for (j, &i) in vars.free().iter().enumerate() {
            let v = &vars.variables()[i];
            let structural = matches!(v.kind, VariableKind::Alpha(_) | VariableKind::Beta(_));
            if structural && bounds.lower()[j] <= -1.0 {
                return Err(Error::Usage(format!(
                    "the lower bound of {} is {}: multipliers must stay above -1 (positive \
                     stiffness and mass)",
                    v.name,
                    bounds.lower()[j]
                )));
            }
            if !structural && v.scale != Scale::Log {
                return Err(Error::Usage(format!(
                    "{} must be sampled on a log scale (log_damping = true)",
                    v.name
                )));
            }
            coords.push(match (kind, structural) {
                (PriorKind::Uniform, _) | (PriorKind::UniformPhysical, true) => Coord::Flat,
                (PriorKind::UniformPhysical, false) => Coord::ExpJacobian,
                (PriorKind::LogNormal { cv, .. }, true) => Coord::LogNormalMultiplier {
                    sd: (1.0 + cv * cv).ln().sqrt(),
                },
                (PriorKind::LogNormal { damping_ln_sd, .. }, false) => Coord::Normal {
                    center: v.initial.ln(),
                    sd: damping_ln_sd,
                },
            });
        }
        coords.push(Coord::Flat);
        let mut lower = bounds.lower().to_vec();
        let mut upper = bounds.upper().to_vec();
        lower.push(s_lo.ln());
        upper.push(s_hi.ln());
        Ok(Prior {
            coords,
            lower,
            upper,
        })
    }

    /// Number of coordinates (free variables + noise scale).
    pub fn dim(&self) -> usize {
        self.coords.len()
    }
    /// Lower corner of the box in sampled coordinates.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// Upper corner of the box in sampled coordinates.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }

    /// Log prior density at `z` up to a constant; `-inf` outside the box.
    pub fn ln_density(&self, z: &[f64]) -> f64 {
        let mut lp = 0.0;
        for (((c, &x), &lo), &hi) in self.coords.iter().zip(z).zip(&self.lower).zip(&self.upper) {
            if !(x >= lo && x <= hi) {
                return f64::NEG_INFINITY;
            }
            lp += match *c {
                Coord::Flat => 0.0,
                Coord::ExpJacobian => x,
                Coord::LogNormalMultiplier { sd } => {
                    let l = x.ln_1p();
                    -0.5 * (l / sd).powi(2) - l
                }
                Coord::Normal { center, sd } => -0.5 * ((x - center) / sd).powi(2),
            };
        }
        lp
    }

    /// One exact draw from the prior (inverse CDF for the uniform kinds, rejection from
    /// the untruncated law for the lognormal ones).
    pub fn sample(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        const MAX_TRIES: usize = 100_000;
        self.coords
            .iter()
            .zip(self.lower.iter().zip(&self.upper))
            .map(|(c, (&lo, &hi))| {
                let u: f64 = rng.random();
                match *c {
                    Coord::Flat => return Ok(lo + (hi - lo) * u),
                    // p(z) ∝ e^z on [lo, hi]: z = ln(e^lo + u (e^hi - e^lo)).
                    Coord::ExpJacobian => return Ok((lo.exp() + u * (hi.exp() - lo.exp())).ln()),
                    _ => {}
                }
                for _ in 0..MAX_TRIES {
                    let n: f64 = rng.sample(StandardNormal);
                    let x = match *c {
                        Coord::LogNormalMultiplier { sd } => (sd * n).exp() - 1.0,
                        Coord::Normal { center, sd } => center + sd * n,
                        _ => unreachable!("handled above"),
                    };
                    if x >= lo && x <= hi {
                        return Ok(x);
                    }
                }
                Err(Error::Usage(format!(
                    "the truncated prior keeps less than 1/{MAX_TRIES} of its mass in [{lo}, {hi}]"
                )))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::StructuralModel;
    use crate::update::{DampingModel, VariablesConfig};
    use rand::SeedableRng;

    fn vars() -> Variables {
        let model = StructuralModel::shear_frame(&[4.64; 2], &[1000.0, 1200.0]).unwrap();
        let mut c = VariablesConfig::default();
        c.fixed.insert("m1".into(), 0.0);
        Variables::new(&model, DampingModel::Rayleigh, 2, &c).unwrap()
    }

    #[test]
    fn layout_bounds_and_support() {
        let p = Prior::new(PriorKind::Uniform, &vars(), [0.1, 10.0]).unwrap();
        // k1 k2 m2 a0 a1 ln s
        assert_eq!(p.dim(), 6);
        assert!((p.lower()[3] - 1e-4_f64.ln()).abs() < 1e-12);
        assert!((p.upper()[5] - 10f64.ln()).abs() < 1e-12);
        let mid: Vec<f64> = p
            .lower()
            .iter()
            .zip(p.upper())
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        assert_eq!(p.ln_density(&mid), 0.0);
        let mut out = mid.clone();
        out[2] = 0.2;
        assert_eq!(p.ln_density(&out), f64::NEG_INFINITY);
        let mut nan = mid;
        nan[0] = f64::NAN;
        assert_eq!(p.ln_density(&nan), f64::NEG_INFINITY);
        assert!(Prior::new(PriorKind::Uniform, &vars(), [1.0, 1.0]).is_err());
        let bad = PriorKind::LogNormal {
            cv: 0.0,
            damping_ln_sd: 1.0,
        };
        assert!(Prior::new(bad, &vars(), [0.1, 10.0]).is_err());
    }

    #[test]
    fn densities_are_the_stated_laws() {
        let v = vars();
        let p = Prior::new(PriorKind::UniformPhysical, &v, [0.1, 10.0]).unwrap();
        let mut z: Vec<f64> = p
            .lower()
            .iter()
            .zip(p.upper())
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
        let base = p.ln_density(&z);
        z[3] += 0.5;
        assert!((p.ln_density(&z) - base - 0.5).abs() < 1e-12);
        let ln = PriorKind::LogNormal {
            cv: 0.1,
            damping_ln_sd: 2.0,
        };
        let p = Prior::new(ln, &v, [0.1, 10.0]).unwrap();
        let sd = 1.01f64.ln().sqrt();
        let mut z = vec![0.0, 0.05, 0.0, 0.01f64.ln(), 1e-6f64.ln(), 0.0];
        let at0 = p.ln_density(&z);
        z[1] = 0.0;
        assert!(
            at0.is_finite()
                && (p.ln_density(&z) - at0 - (0.5 * (1.05f64.ln() / sd).powi(2) + 1.05f64.ln()))
                    .abs()
                    < 1e-12
        );
        // ln a1 two log-sds above its centre ln 1e-6: 0.5 (2 / 2)^2 lower.
        let centre = p.ln_density(&z);
        z[4] += 2.0;
        assert!((p.ln_density(&z) - centre + 0.5).abs() < 1e-12);
    }

    /// Draws follow the density: for a log-uniform-physical damping coordinate on
    /// `[ln a, ln b]`, `P(z < ln m) = (m - a)/(b - a)`. With n = 20000 draws the binomial
    /// standard error of a fraction is at most 0.0036; tolerance 5 se.
    #[test]
    fn samples_match_the_laws() {
        let v = vars();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 20_000;
        for kind in [
            PriorKind::Uniform,
            PriorKind::UniformPhysical,
            PriorKind::LogNormal {
                cv: 0.1,
                damping_ln_sd: 1.0,
            },
        ] {
            let p = Prior::new(kind, &v, [0.1, 10.0]).unwrap();
            let draws: Vec<Vec<f64>> = (0..n).map(|_| p.sample(&mut rng).unwrap()).collect();
            assert!(draws.iter().all(|z| p.ln_density(z).is_finite()));
            let frac =
                |j: usize, t: f64| draws.iter().filter(|z| z[j] < t).count() as f64 / n as f64;
            let tol = 5.0 * 0.5 / (n as f64).sqrt();
            // a0 in [1e-4, 1]: below 0.1
            let expect = match kind {
                PriorKind::Uniform => (0.1f64.ln() - 1e-4f64.ln()) / (-(1e-4f64.ln())),
                PriorKind::UniformPhysical => (0.1 - 1e-4) / (1.0 - 1e-4),
                // ln a0 ~ N(ln 0.01, 1) truncated to [ln 1e-4, 0]
                PriorKind::LogNormal { .. } => {
                    use statrs::distribution::{ContinuousCDF, Normal};
                    let nd = Normal::new(0.0, 1.0).unwrap();
                    let c = |x: f64| nd.cdf(x - 0.01f64.ln());
                    (c(0.1f64.ln()) - c(1e-4f64.ln())) / (c(0.0) - c(1e-4f64.ln()))
                }
            };
            assert!((frac(3, 0.1f64.ln()) - expect).abs() < tol, "{kind:?}");
            // noise scale log-uniform on [0.1, 10]: half below ln 1
            assert!((frac(5, 0.0) - 0.5).abs() < tol);
        }
    }
}
