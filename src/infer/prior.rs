//! The prior of the inference layer: independent uniform coordinates in a box.
//!
//! Coordinates are the sampled ones (a log-uniform prior on a positive quantity is a
//! uniform prior on its logarithm), so the density is `1 / volume` inside the box and
//! zero outside, normalised as evidence computations need.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use crate::error::{Error, Result};
use crate::update::lsq::Bounds;

/// Uniform prior on `lower <= z <= upper` (normalised).
#[derive(Debug, Clone, PartialEq)]
pub struct BoxPrior {
    names: Vec<String>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    ln_volume: f64,
}

impl BoxPrior {
    /// `bounds[i] = (lower, upper)` of coordinate `names[i]`; finite, lower < upper.
    pub fn new(names: Vec<String>, bounds: &[(f64, f64)]) -> Result<Self> {
        if names.len() != bounds.len() {
            return Err(Error::Usage(format!(
                "{} coordinate names for {} bounds",
                names.len(),
                bounds.len()
            )));
        }
        for (n, &(l, u)) in names.iter().zip(bounds) {
            if !(l.is_finite() && u.is_finite() && l < u) {
                return Err(Error::Usage(format!(
                    "prior of `{n}`: bounds [{l}, {u}] must be finite with lower < upper"
                )));
            }
        }
        Ok(BoxPrior {
            ln_volume: bounds.iter().map(|(l, u)| (u - l).ln()).sum(),
            lower: bounds.iter().map(|b| b.0).collect(),
            upper: bounds.iter().map(|b| b.1).collect(),
            names,
        })
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
    }
    pub fn names(&self) -> &[String] {
        &self.names
    }
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }
    /// `(lower, upper)` of coordinate `i`.
    pub fn bound(&self, i: usize) -> (f64, f64) {
        (self.lower[i], self.upper[i])
    }

    /// The box of the first `n` coordinates, for the least-squares solver.
    pub fn bounds_of_first(&self, n: usize) -> Result<Bounds> {
        Bounds::new(self.lower[..n].to_vec(), self.upper[..n].to_vec())
    }

    /// True when `z` is inside the box (bounds included).
    pub fn contains(&self, z: &[f64]) -> bool {
        z.len() == self.dim()
            && z.iter()
                .zip(self.lower.iter().zip(&self.upper))
                .all(|(v, (l, u))| *v >= *l && *v <= *u)
    }

    /// `-ln volume` inside the box, `-inf` outside.
    pub fn ln_density(&self, z: &[f64]) -> f64 {
        if self.contains(z) {
            -self.ln_volume
        } else {
            f64::NEG_INFINITY
        }
    }

    /// One uniform draw.
    pub fn sample(&self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        self.lower
            .iter()
            .zip(&self.upper)
            .map(|(l, u)| l + (u - l) * rng.random::<f64>())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn normalised_inside_zero_outside_and_draws_stay_inside() {
        let p = BoxPrior::new(vec!["a".into(), "b".into()], &[(0.0, 2.0), (-1.0, 3.0)]).unwrap();
        assert!((p.ln_density(&[1.0, 0.0]) + 8f64.ln()).abs() < 1e-15);
        assert_eq!(p.ln_density(&[2.5, 0.0]), f64::NEG_INFINITY);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        // Mean of 4000 uniform draws on [0, 2]: sd 2/sqrt(12)/sqrt(4000) = 0.0091.
        let mean = (0..4000).map(|_| p.sample(&mut rng)[0]).sum::<f64>() / 4000.0;
        assert!((mean - 1.0).abs() < 4.0 * 0.0092, "{mean}");
        let err = BoxPrior::new(vec!["c".into()], &[(1.0, 1.0)]).unwrap_err();
        assert!(err.to_string().contains("`c`"));
    }
}
