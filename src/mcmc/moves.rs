//! Ensemble moves. A move only *proposes* a new position for one walker given the
//! complementary walkers; the sampler owns the red-blue split and the Metropolis-Hastings
//! accept step (`ln u < ln_factor + ln p(q) - ln p(x)`).
//!
//! | move | proposal `q` for walker `x` | `ln_factor` |
//! |---|---|---|
//! | [`Stretch`] (Goodman & Weare 2010) | `c + z (x - c)`, `g(z) ∝ 1/sqrt(z)` on `[1/a, a]` | `(d-1) ln z` |
//! | [`DifferentialEvolution`] (ter Braak 2006; Nelson et al. 2013) | `x + gamma (c1 - c2)` | 0 |
//! | [`Snooker`] (ter Braak & Vrugt 2008) | `x + gamma e e·(z1 - z2)`, `e = (x - z)/‖x - z‖` | `(d-1) ln(‖q - z‖/‖x - z‖)` |
//! | [`Walk`] (Goodman & Weare 2010) | `x + Σ_j w_j (c_j - c̄)/sqrt(s-1)`, `w_j ~ N(0,1)` | 0 |
//! | [`Independence`](super::Independence) | `m + L n / sqrt(w/nu)`, `(m, L L^T)` the complement's mean and covariance | `ln g(x) - ln g(q)` |
//!
//! `c`, `c1`, `c2`, `z`, `z1`, `z2`, `c_j` are distinct walkers of the complementary
//! set, so they do not depend on `x` and detailed balance holds for the product target.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The walkers a move may use to propose for one walker: all walkers outside its split,
/// in ascending walker order.
#[derive(Debug, Clone, Copy)]
pub struct Complement<'a> {
    walkers: &'a [&'a [f64]],
}

impl<'a> Complement<'a> {
    /// Wraps a list of walker positions.
    pub fn new(walkers: &'a [&'a [f64]]) -> Self {
        Complement { walkers }
    }
    /// Number of walkers.
    pub fn len(&self) -> usize {
        self.walkers.len()
    }
    /// True when there is no walker.
    pub fn is_empty(&self) -> bool {
        self.walkers.is_empty()
    }
    /// Position of walker `i` (`0 <= i < len()`).
    pub fn get(&self, i: usize) -> &'a [f64] {
        self.walkers[i]
    }
}

/// One ensemble proposal (see the module table).
pub trait Move: Send + Sync {
    /// A description with the parameters, e.g. `stretch(a=2)`; saved in checkpoints so a
    /// resumed run can check it uses the same moves.
    fn name(&self) -> String;

    /// Number of sub-ensembles the walkers are split into (emcee's `nsplits`); each is
    /// updated in turn with the others as complement. 2 = red-blue.
    fn n_splits(&self) -> usize {
        2
    }

    /// Fewest complementary walkers the move needs.
    fn min_complement(&self) -> usize {
        1
    }

    /// This move specialised to one complement, built once per split before the split's
    /// proposals (e.g. a proposal density fitted to the complement, see
    /// [`super::Independence`]); `None` (the default): use the move itself. Must not
    /// draw randomness and must propose as [`Self::propose`] would.
    fn for_complement(&self, _complement: &Complement<'_>) -> Option<Box<dyn Move + '_>> {
        None
    }

    /// Writes the proposal for `walker` into `proposal` (same length) and returns the
    /// log of the factor that multiplies the density ratio in the acceptance probability
    /// (Hastings ratio times Jacobian). Must draw randomness only from `rng`.
    fn propose(
        &self,
        walker: &[f64],
        complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64;
}

/// Two distinct indices in `0..n` (n >= 2), uniformly over ordered pairs.
fn distinct_pair(n: usize, rng: &mut ChaCha8Rng) -> (usize, usize) {
    let a = rng.random_range(0..n);
    let mut b = rng.random_range(0..n - 1);
    if b >= a {
        b += 1;
    }
    (a, b)
}

/// Goodman & Weare's stretch move with scale `a` (emcee's `StretchMove`, default a = 2).
/// `z = ((a - 1) u + 1)^2 / a` with `u ~ U(0,1)` has density `∝ 1/sqrt(z)` on `[1/a, a]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stretch {
    /// Scale parameter `a > 1`.
    pub a: f64,
}

impl Default for Stretch {
    fn default() -> Self {
        Stretch { a: 2.0 }
    }
}

impl Stretch {
    /// Stretch move with scale `a` (> 1).
    pub fn new(a: f64) -> Result<Self> {
        if !(a > 1.0 && a.is_finite()) {
            return Err(Error::Usage(format!(
                "stretch scale a must be > 1, got {a}"
            )));
        }
        Ok(Stretch { a })
    }
}

impl Move for Stretch {
    fn name(&self) -> String {
        format!("stretch(a={})", self.a)
    }
    fn propose(
        &self,
        walker: &[f64],
        complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        let u: f64 = rng.random();
        let z = ((self.a - 1.0) * u + 1.0).powi(2) / self.a;
        let c = complement.get(rng.random_range(0..complement.len()));
        for ((q, &x), &c) in proposal.iter_mut().zip(walker).zip(c) {
            *q = c + z * (x - c);
        }
        (walker.len() as f64 - 1.0) * z.ln()
    }
}

/// Differential-evolution move as emcee's `DEMove` (ter Braak 2006; Nelson et al. 2013):
/// `q = x + gamma (c1 - c2)` for a random ordered pair of distinct complementary walkers,
/// `gamma = gamma0 (1 + sigma N(0,1))`, `gamma0 = 2.38 / sqrt(2 d)` by default.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DifferentialEvolution {
    /// Mean step factor; `None` = `2.38 / sqrt(2 d)`.
    pub gamma0: Option<f64>,
    /// Relative standard deviation of `gamma`.
    pub sigma: f64,
}

impl Default for DifferentialEvolution {
    fn default() -> Self {
        DifferentialEvolution {
            gamma0: None,
            sigma: 1e-5,
        }
    }
}

impl Move for DifferentialEvolution {
    fn name(&self) -> String {
        match self.gamma0 {
            Some(g) => format!("de(gamma0={g},sigma={})", self.sigma),
            None => format!("de(gamma0=2.38/sqrt(2d),sigma={})", self.sigma),
        }
    }
    fn min_complement(&self) -> usize {
        2
    }
    fn propose(
        &self,
        walker: &[f64],
        complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        let (a, b) = distinct_pair(complement.len(), rng);
        let gamma0 = self
            .gamma0
            .unwrap_or_else(|| 2.38 / (2.0 * walker.len() as f64).sqrt());
        let n: f64 = rng.sample(StandardNormal);
        let gamma = gamma0 * (1.0 + self.sigma * n);
        let (ca, cb) = (complement.get(a), complement.get(b));
        for i in 0..walker.len() {
            proposal[i] = walker[i] + gamma * (ca[i] - cb[i]);
        }
        0.0
    }
}

/// Differential-evolution snooker move (ter Braak & Vrugt 2008), fixed `gamma` = 1.7 as
/// emcee's `DESnookerMove`. Three distinct complementary walkers `z, z1, z2` are drawn in
/// random order; the walker moves along the line through `z` by the difference of the
/// orthogonal projections of `z1` and `z2` on it, and the acceptance factor is
/// `(‖q - z‖ / ‖x - z‖)^(d-1)`.
///
/// Differs from emcee 3.1 on purpose: emcee divides the direction by `sqrt(‖x - z‖)`
/// instead of `‖x - z‖` (so the step is multiplied by `‖x - z‖`, which breaks the
/// symmetry of the line proposal) and uses the factor `(‖q - z‖ / ‖x - z‖)^((d-1)/2)`.
/// That version does not sample its target: on a 10-D standard normal, emcee 3.1.6's
/// `DESnookerMove` gives variances of ~0.62 (see `tests/mcmc_thorough.rs`); the paper's
/// move is implemented here and passes the moment tests. emcee also
/// uses 4 splits and draws `z, z1, z2` one from each other split; here the three are
/// drawn without replacement from the whole complement (any number of splits).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Snooker {
    /// Step factor (1.7 in the paper and in emcee).
    pub gamma: f64,
}

impl Default for Snooker {
    fn default() -> Self {
        Snooker { gamma: 1.7 }
    }
}

impl Move for Snooker {
    fn name(&self) -> String {
        format!("snooker(gamma={})", self.gamma)
    }
    fn min_complement(&self) -> usize {
        3
    }
    fn propose(
        &self,
        walker: &[f64],
        complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        let n = complement.len();
        let iz = rng.random_range(0..n);
        let (mut i1, mut i2) = distinct_pair(n - 1, rng);
        // Map 0..n-1 onto 0..n without iz.
        if i1 >= iz {
            i1 += 1;
        }
        if i2 >= iz {
            i2 += 1;
        }
        let (z, z1, z2) = (complement.get(iz), complement.get(i1), complement.get(i2));
        let norm = walker
            .iter()
            .zip(z)
            .map(|(x, z)| (x - z) * (x - z))
            .sum::<f64>()
            .sqrt();
        if norm == 0.0 {
            // Walker on top of z: no direction; propose staying (accepted, harmless).
            proposal.copy_from_slice(walker);
            return 0.0;
        }
        let mut proj = 0.0; // e·(z1 - z2)
        for i in 0..walker.len() {
            proj += (walker[i] - z[i]) / norm * (z1[i] - z2[i]);
        }
        let step = self.gamma * proj / norm;
        let mut new_norm2 = 0.0;
        for i in 0..walker.len() {
            proposal[i] = walker[i] + step * (walker[i] - z[i]);
            new_norm2 += (proposal[i] - z[i]) * (proposal[i] - z[i]);
        }
        (walker.len() as f64 - 1.0) * (0.5 * new_norm2.ln() - norm.ln())
    }
}

/// Goodman & Weare's walk move (emcee's `WalkMove`): a Gaussian step with the sample
/// covariance of `subset` complementary walkers (all of them when `None`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Walk {
    /// Size of the random subset of the complement (>= 2); `None` = whole complement.
    pub subset: Option<usize>,
}

impl Move for Walk {
    fn name(&self) -> String {
        match self.subset {
            Some(s) => format!("walk(s={s})"),
            None => "walk(s=all)".into(),
        }
    }
    fn min_complement(&self) -> usize {
        self.subset.unwrap_or(2).max(2)
    }
    fn propose(
        &self,
        walker: &[f64],
        complement: &Complement<'_>,
        rng: &mut ChaCha8Rng,
        proposal: &mut [f64],
    ) -> f64 {
        let n = complement.len();
        let s = self.subset.unwrap_or(n).min(n);
        // Partial Fisher-Yates for a subset without replacement.
        let mut idx: Vec<usize> = (0..n).collect();
        for k in 0..s {
            let j = rng.random_range(k..n);
            idx.swap(k, j);
        }
        let idx = &idx[..s];
        let d = walker.len();
        let mut mean = vec![0.0; d];
        for &j in idx {
            for (m, c) in mean.iter_mut().zip(complement.get(j)) {
                *m += c / s as f64;
            }
        }
        proposal.copy_from_slice(walker);
        let scale = 1.0 / (s as f64 - 1.0).sqrt();
        for &j in idx {
            let w: f64 = rng.sample(StandardNormal);
            for ((q, c), m) in proposal.iter_mut().zip(complement.get(j)).zip(&mean) {
                *q += w * scale * (c - m);
            }
        }
        0.0
    }
}

/// A weighted mixture of moves: each step, each ensemble picks one move with probability
/// proportional to its weight (as emcee does).
pub struct Moves {
    entries: Vec<(Box<dyn Move>, f64)>,
    cumulative: Vec<f64>,
}

impl std::fmt::Debug for Moves {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl Default for Moves {
    /// The stretch move with `a = 2` alone.
    fn default() -> Self {
        Moves::single(Stretch::default())
    }
}

impl Moves {
    /// One move, always used.
    pub fn single(m: impl Move + 'static) -> Self {
        Moves {
            entries: vec![(Box::new(m), 1.0)],
            cumulative: vec![1.0],
        }
    }

    /// A mixture; weights must be positive and finite (they are normalised).
    pub fn mixture(entries: Vec<(Box<dyn Move>, f64)>) -> Result<Self> {
        if entries.is_empty() {
            return Err(Error::Usage(
                "a move mixture needs at least one move".into(),
            ));
        }
        let mut total = 0.0;
        for (m, w) in &entries {
            if !(w.is_finite() && *w > 0.0) {
                return Err(Error::Usage(format!(
                    "move {} has weight {w}; weights must be positive and finite",
                    m.name()
                )));
            }
            total += w;
        }
        let mut acc = 0.0;
        let cumulative = entries
            .iter()
            .map(|(_, w)| {
                acc += w / total;
                acc
            })
            .collect();
        Ok(Moves {
            entries,
            cumulative,
        })
    }

    /// `name:weight` of every move, e.g. `stretch(a=2):0.8, de(...):0.2`.
    pub fn describe(&self) -> String {
        let total: f64 = self.entries.iter().map(|(_, w)| w).sum();
        self.entries
            .iter()
            .map(|(m, w)| format!("{}:{}", m.name(), w / total))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The moves.
    pub fn iter(&self) -> impl Iterator<Item = &dyn Move> {
        self.entries.iter().map(|(m, _)| m.as_ref())
    }

    /// Picks one move (one uniform draw from `rng`, even for a single move).
    pub(crate) fn select(&self, rng: &mut ChaCha8Rng) -> &dyn Move {
        let u: f64 = rng.random();
        let i = self
            .cumulative
            .iter()
            .position(|&c| u < c)
            .unwrap_or(self.entries.len() - 1);
        self.entries[i].0.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcmc::rng::{key_from_seed, walker_rng};

    fn ensemble() -> Vec<Vec<f64>> {
        (0..6)
            .map(|i| vec![i as f64, (i * i) as f64 * 0.3, 1.0 - i as f64])
            .collect()
    }

    #[test]
    fn stretch_proposal_lies_on_the_line_with_matching_factor() {
        let walkers = ensemble();
        let refs: Vec<&[f64]> = walkers.iter().map(|w| w.as_slice()).collect();
        let comp = Complement::new(&refs);
        let x = [0.5, -1.0, 2.0];
        let mut q = [0.0; 3];
        let mut rng = walker_rng(key_from_seed(3), 0, 0);
        for _ in 0..200 {
            let f = Stretch::default().propose(&x, &comp, &mut rng, &mut q);
            let z = (f / 2.0).exp(); // (d-1) ln z with d = 3
            assert!((0.5 - 1e-12..=2.0 + 1e-12).contains(&z));
            // q = c + z (x - c) for exactly one complement walker c.
            let hits = refs
                .iter()
                .filter(|c| (0..3).all(|i| (q[i] - (c[i] + z * (x[i] - c[i]))).abs() < 1e-9))
                .count();
            assert!(hits >= 1);
        }
    }

    #[test]
    fn snooker_is_an_involution_in_distribution_along_the_line() {
        // Reversibility of the line move: from q, the same (z, z1, z2) propose x back,
        // and the two factors are opposite.
        let walkers = ensemble();
        let refs: Vec<&[f64]> = walkers.iter().map(|w| w.as_slice()).collect();
        let comp = Complement::new(&refs);
        let x = [0.5, -1.0, 2.0];
        let mut q = [0.0; 3];
        let mut back = [0.0; 3];
        let mut rng = walker_rng(key_from_seed(5), 0, 0);
        for _ in 0..100 {
            let mut rng_back = rng.clone();
            let f = Snooker::default().propose(&x, &comp, &mut rng, &mut q);
            let g = Snooker { gamma: -1.7 }.propose(&q, &comp, &mut rng_back, &mut back);
            assert!((f + g).abs() < 1e-9, "{f} {g}");
            for i in 0..3 {
                assert!((back[i] - x[i]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn mixture_frequencies_follow_weights() {
        let moves = Moves::mixture(vec![
            (Box::new(Stretch::default()), 3.0),
            (Box::new(DifferentialEvolution::default()), 1.0),
        ])
        .unwrap();
        let mut rng = walker_rng(key_from_seed(9), 0, 0);
        let n = 40_000;
        let k = (0..n)
            .filter(|_| moves.select(&mut rng).name().starts_with("stretch"))
            .count();
        // Binomial(n, 0.75): sd = sqrt(n 0.25 0.75) ~ 87; allow 4 sd.
        assert!((k as f64 - 0.75 * n as f64).abs() < 4.0 * 86.7, "{k}");
        assert!(Moves::mixture(vec![(Box::new(Stretch::default()), 0.0)]).is_err());
    }
}
