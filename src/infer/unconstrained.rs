//! Sampling a box-bounded posterior in unconstrained coordinates.
//!
//! Every coordinate of a [`BoxPrior`] lies in `[lower, upper]`. The ensemble sampler's
//! moves know nothing of the box: near a wall most proposals fall outside and are
//! rejected, and a posterior that is flat over the box, or pushed against one bound, mixes
//! slowly. The logit map
//!
//! `z = lower + (upper - lower) s(u)`, `s(u) = 1 / (1 + e^-u)`,
//!
//! carries the box onto the whole real line, and the density of `u` is the density of `z`
//! times the Jacobian `dz/du = (upper - lower) s(u) (1 - s(u))`. A uniform prior becomes
//! a logistic density (tails `e^-|u|`), so every proposal is inside, and the walls are no
//! longer walls. Draws are mapped back, and their log densities are those of `z`: the
//! reparametrisation changes the sampler's path, not the posterior.

use super::prior::BoxPrior;
use super::sample::{sample_to_targets, Sampled, Sampling, Targets};
use crate::error::{Error, Result};
use crate::mcmc::{Draws, LogDensity, Start};

/// The logit map of a box, coordinate by coordinate.
#[derive(Debug, Clone, PartialEq)]
pub struct LogitMap {
    lower: Vec<f64>,
    width: Vec<f64>,
}

impl LogitMap {
    /// The map of `prior`'s box.
    pub fn new(prior: &BoxPrior) -> Self {
        LogitMap {
            lower: prior.lower().to_vec(),
            width: prior
                .upper()
                .iter()
                .zip(prior.lower())
                .map(|(u, l)| u - l)
                .collect(),
        }
    }

    /// The map of the box `bounds` (`(lower, upper)` per coordinate, finite, lower <
    /// upper).
    pub fn from_bounds(bounds: &[(f64, f64)]) -> Result<Self> {
        if let Some((i, b)) = bounds
            .iter()
            .enumerate()
            .find(|(_, (l, u))| !(l.is_finite() && u.is_finite() && l < u))
        {
            return Err(Error::Usage(format!(
                "logit map: bounds {b:?} of coordinate {i} must be finite with lower < upper"
            )));
        }
        Ok(LogitMap {
            lower: bounds.iter().map(|b| b.0).collect(),
            width: bounds.iter().map(|(l, u)| u - l).collect(),
        })
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// `z(u)` into `z`.
    pub fn to_box(&self, u: &[f64], z: &mut [f64]) {
        for (i, (zi, &ui)) in z.iter_mut().zip(u).enumerate() {
            *zi = self.lower[i] + self.width[i] * sigmoid(ui);
        }
    }

    /// `u(z)` for `z` strictly inside the box (a point on a bound maps to `+-inf`).
    pub fn from_box(&self, z: &[f64]) -> Vec<f64> {
        z.iter()
            .enumerate()
            .map(|(i, &zi)| {
                let s = (zi - self.lower[i]) / self.width[i];
                (s / (1.0 - s)).ln()
            })
            .collect()
    }

    /// `ln |dz/du|` at `u`.
    pub fn ln_jacobian(&self, u: &[f64]) -> f64 {
        u.iter()
            .zip(&self.width)
            .map(|(&ui, w)| w.ln() - softplus(ui) - softplus(-ui))
            .sum()
    }
}

/// `1 / (1 + e^-u)`, without overflow.
fn sigmoid(u: f64) -> f64 {
    if u >= 0.0 {
        1.0 / (1.0 + (-u).exp())
    } else {
        let e = u.exp();
        e / (1.0 + e)
    }
}

/// `ln(1 + e^u)`, without overflow; `ln s(u) = -softplus(-u)`.
fn softplus(u: f64) -> f64 {
    u.max(0.0) + (-u.abs()).exp().ln_1p()
}

/// The density of `u` when `z = map.to_box(u)` has density `inner`.
pub struct Unconstrained<'a, D: ?Sized> {
    inner: &'a D,
    map: LogitMap,
}

impl<'a, D: LogDensity + ?Sized> Unconstrained<'a, D> {
    /// `inner`'s density seen through `map` (dimensions must agree).
    pub fn new(inner: &'a D, map: LogitMap) -> Result<Self> {
        if map.dim() != inner.dim() {
            return Err(Error::Usage(format!(
                "a logit map of {} coordinates for a density of {}",
                map.dim(),
                inner.dim()
            )));
        }
        Ok(Unconstrained { inner, map })
    }
}

impl<D: LogDensity + ?Sized> LogDensity for Unconstrained<'_, D> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn ln_density(&self, u: &[f64]) -> Result<f64> {
        let mut z = vec![0.0; u.len()];
        self.map.to_box(u, &mut z);
        Ok(self.inner.ln_density(&z)? + self.map.ln_jacobian(u))
    }
    fn n_pointwise(&self) -> usize {
        self.inner.n_pointwise()
    }
    fn ln_density_with_pointwise(&self, u: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        let mut z = vec![0.0; u.len()];
        self.map.to_box(u, &mut z);
        Ok(self.inner.ln_density_with_pointwise(&z, pointwise)? + self.map.ln_jacobian(u))
    }
}

/// [`sample_to_targets`] of `density` (whose support is `prior`'s box) in the
/// unconstrained coordinates of [`LogitMap`]. `start` is in box coordinates (explicit
/// positions strictly inside the box); the returned draws are in box coordinates with the
/// log density of `density` (the Jacobian removed). Autocorrelation times are those of the
/// unconstrained chains, which are the ones that decide convergence.
#[allow(clippy::too_many_arguments)]
pub fn sample_in_unconstrained<D: LogDensity + ?Sized>(
    density: &D,
    prior: &BoxPrior,
    start: Start,
    n_walkers: usize,
    seed: u64,
    targets: &Targets,
    label: &str,
    sampling: &mut Sampling<'_>,
) -> Result<Sampled> {
    let map = LogitMap::new(prior);
    let Start::Positions(positions) = start else {
        return Err(Error::Usage(
            "sampling in unconstrained coordinates needs explicit start positions".into(),
        ));
    };
    let mut u_start = Vec::with_capacity(positions.len());
    for z in &positions {
        if !prior.contains(z) || z.iter().zip(prior.lower()).any(|(v, l)| v == l) {
            return Err(Error::Usage(
                "a start position on or outside the prior's box: the logit map needs \
                 points strictly inside"
                    .into(),
            ));
        }
        let u = map.from_box(z);
        if u.iter().any(|v| !v.is_finite()) {
            return Err(Error::Usage(
                "a start position on the prior's upper bound: the logit map needs \
                 points strictly inside"
                    .into(),
            ));
        }
        u_start.push(u);
    }
    let target = Unconstrained::new(density, map.clone())?;
    let mut sampled = sample_to_targets(
        &target,
        Start::Positions(u_start),
        n_walkers,
        seed,
        targets,
        label,
        sampling,
    )?;
    to_box_draws(&map, &mut sampled.draws);
    to_box_draws(&map, &mut sampled.full);
    Ok(sampled)
}

/// Maps draws of `u` to draws of `z`, removing the Jacobian from their log densities.
fn to_box_draws(map: &LogitMap, draws: &mut Draws) {
    let dim = draws.dim;
    let mut z = vec![0.0; dim];
    for (u, lnp) in draws.values.chunks_mut(dim).zip(&mut draws.ln_density) {
        *lnp -= map.ln_jacobian(u);
        map.to_box(u, &mut z);
        u.copy_from_slice(&z);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcmc::DensityFn;

    fn prior() -> BoxPrior {
        BoxPrior::new(vec!["a".into(), "b".into()], &[(-1.0, 2.0), (0.0, 1.0)]).unwrap()
    }

    #[test]
    fn map_round_trips_and_jacobian_matches_finite_difference() {
        let map = LogitMap::new(&prior());
        let z = [0.37, 0.999];
        let u = map.from_box(&z);
        let mut back = [0.0; 2];
        map.to_box(&u, &mut back);
        assert!((back[0] - z[0]).abs() < 1e-14 && (back[1] - z[1]).abs() < 1e-14);
        for i in 0..2 {
            let h = 1e-6;
            let (mut up, mut dn) = (u.clone(), u.clone());
            up[i] += h;
            dn[i] -= h;
            let (mut zu, mut zd) = ([0.0; 2], [0.0; 2]);
            map.to_box(&up, &mut zu);
            map.to_box(&dn, &mut zd);
            let dz = (zu[i] - zd[i]) / (2.0 * h);
            let single = map.width[i].ln() - softplus(u[i]) - softplus(-u[i]);
            assert!((single - dz.ln()).abs() < 1e-7, "coordinate {i}");
        }
        // far tails stay finite
        assert!(map.ln_jacobian(&[800.0, -800.0]).is_finite());
    }

    /// A density flat in `a` over its box and, in `b`, proportional to `e^{4 b}` on
    /// [0, 1] (pushed against the upper bound): exact moments
    /// `E a = 0.5`, `sd a = 3/sqrt 12`; `E b = 1/(1 - e^-4) - 1/4`.
    #[test]
    fn sampled_moments_match_the_box_density() {
        let p = prior();
        let density = DensityFn::new(2, |z: &[f64]| {
            Ok(if p.contains(z) {
                4.0 * z[1]
            } else {
                f64::NEG_INFINITY
            })
        });
        let start: Vec<Vec<f64>> = (0..128)
            .map(|k| vec![-0.9 + 0.02 * k as f64, 0.05 + 0.007 * k as f64])
            .collect();
        let targets = Targets {
            first_cap_steps: 3000,
            hard_cap_steps: 3000,
            ..Targets::default()
        };
        let s = sample_in_unconstrained(
            &density,
            &p,
            Start::Positions(start),
            32,
            7,
            &targets,
            "test",
            &mut Sampling::new(|_, _| {}),
        )
        .unwrap();
        let summary = s.draws.summary();
        let (mean_a, sd_a, mean_b) = (summary[0].mean, summary[0].sd, summary[1].mean);
        let eb = 1.0 / (1.0 - (-4.0f64).exp()) - 0.25;
        // 4 sigma of the Monte Carlo error (mean: its MCSE; sd: sd / sqrt(2 ESS))
        let ess_a = (sd_a / summary[0].mcse_mean).powi(2);
        assert!(
            (mean_a - 0.5).abs() < 4.0 * summary[0].mcse_mean,
            "E a {mean_a}"
        );
        let sd_exact = 3.0 / 12f64.sqrt();
        assert!(
            (sd_a - sd_exact).abs() < 4.0 * sd_exact / (2.0 * ess_a).sqrt(),
            "sd a {sd_a}"
        );
        assert!(
            (mean_b - eb).abs() < 4.0 * summary[1].mcse_mean,
            "E b {mean_b} vs {eb}"
        );
        assert!(s.draws.values.iter().all(|v| (-1.0..=2.0).contains(v)));
        // log densities are those of z: 4 b
        for (row, lnp) in s.draws.values.chunks(2).zip(&s.draws.ln_density) {
            assert!((lnp - 4.0 * row[1]).abs() < 1e-9);
        }
    }
}
