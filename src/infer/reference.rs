//! Generalised stepping-stone (Fan, Wu, Chen, Kuo & Lewis 2011, Syst. Biol. 60:150):
//! the tempered ensembles of [`super::evidence`] run from a reference distribution `g`
//! fitted at the posterior instead of from the prior,
//! `p_beta ∝ g^(1 - beta) q^beta`, `ln Z = sum_k ln mean_j (q/g)_j^(beta_{k+1} - beta_k)`.
//! The walkers start where the posterior is, the ladder is short (the information from
//! `g` to the posterior, not from the prior: a few nats instead of thousands), and the
//! estimator keeps the stepping-stone's unbiasedness for `Z` and its replicate error.
//!
//! ## The reference, using the nesting
//! In the logit coordinates `u` of the box ([`InUnconstrained`]), with the mode `u*` and
//! covariance `C` of Laplace's approximation there ([`super::nested::laplace_in_u`]), `g`
//! is the mixture
//! `g = (1 - a) t_nu(u; u*, C) + a t_nu(u_base; u*_base, C_base) prod_e logistic(u_e)`:
//! a Student t (`nu =` [`NU`]) on the Laplace Gaussian, and, when effect coordinates are
//! named, the same t on the base coordinates times the effect coordinates' prior (a box
//! prior is logistic in `u`). The second part puts walkers on an effect's plateau below
//! detection, where the posterior of a null has mass that no Gaussian at the mode
//! covers (measured on the log-uniform null of [`super::validation`]: a bridge from an
//! ensemble at the posterior, which must cross from the peak to the plateau, is 0.2
//! nats low there). Mixture weight `a =` [`EFFECT_PRIOR_WEIGHT`].

use nalgebra::{DMatrix, DVector};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use statrs::function::gamma::ln_gamma;

use super::evidence::{
    stepping_stone, Evidence, EvidenceOptions, EvidenceProgress, PosteriorDraws, TemperedTarget,
};
use super::laplace::LaplaceEvidence;
use super::nested::{laplace_in_u, InUnconstrained};
use super::tempering::log_sum_exp;
use super::unconstrained::LogitMap;
use crate::error::{Error, Result};

/// Degrees of freedom of the reference's t parts.
pub const NU: f64 = 4.0;
/// Weight of the part that draws the effect coordinates from their prior.
pub const EFFECT_PRIOR_WEIGHT: f64 = 0.5;

/// A multivariate Student t with a Cholesky factor.
struct StudentT {
    mu: DVector<f64>,
    l: DMatrix<f64>,
    /// Normalising constant: `ln Gamma((nu+d)/2) - ln Gamma(nu/2) - d/2 ln(nu pi) - ln|L|`.
    ln_c: f64,
}

impl StudentT {
    fn new(mu: DVector<f64>, cov: DMatrix<f64>) -> Result<Self> {
        let d = mu.len() as f64;
        let l = nalgebra::Cholesky::new(cov)
            .ok_or_else(|| Error::Numerical("reference: covariance not PD".into()))?
            .l();
        let ln_det_l: f64 = l.diagonal().iter().map(|v| v.ln()).sum();
        let ln_c = ln_gamma(0.5 * (NU + d))
            - ln_gamma(0.5 * NU)
            - 0.5 * d * (NU * std::f64::consts::PI).ln()
            - ln_det_l;
        Ok(StudentT { mu, l, ln_c })
    }
    fn ln_pdf(&self, x: &[f64]) -> f64 {
        let d = self.mu.len() as f64;
        let r = DVector::from_column_slice(x) - &self.mu;
        let m = self
            .l
            .solve_lower_triangular(&r)
            .map_or(f64::INFINITY, |v| v.norm_squared());
        self.ln_c - 0.5 * (NU + d) * (m / NU).ln_1p()
    }
    fn sample(&self, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let xi = DVector::from_fn(self.mu.len(), |_, _| rng.sample::<f64, _>(StandardNormal));
        // chi2_nu / nu from nu standard normals would need an integer nu: use the
        // Gamma(nu/2, 2) draw of rand_distr.
        let chi2: f64 = rng.sample(rand_distr::ChiSquared::new(NU).expect("nu > 0"));
        (&self.mu + &self.l * xi / (chi2 / NU).sqrt())
            .iter()
            .copied()
            .collect()
    }
}

/// `ln` of the standard logistic density (a uniform box coordinate in logit `u`).
fn ln_logistic(u: f64) -> f64 {
    let sp = |x: f64| x.max(0.0) + (-x.abs()).exp().ln_1p();
    -sp(u) - sp(-u)
}

/// A box-prior target referenced to `g` (module docs): as a [`TemperedTarget`] its
/// "prior" is `g` and its "likelihood" `q / g`, so its evidence is the target's and its
/// tempered path is the generalised stepping-stone's.
pub struct Referenced<'a, T: TemperedTarget> {
    inner: InUnconstrained<'a, T>,
    full: StudentT,
    /// Base coordinates, their t, and the effect coordinates.
    base: Vec<usize>,
    base_t: Option<StudentT>,
    effect: Vec<usize>,
}

impl<'a, T: TemperedTarget> Referenced<'a, T> {
    /// `inner` referenced to the t on `N(mode, cov)`, mixed with the effect-prior part
    /// when `effect` (coordinate indices) is not empty.
    pub fn new(
        inner: InUnconstrained<'a, T>,
        mode: &[f64],
        cov: &DMatrix<f64>,
        effect: &[usize],
    ) -> Result<Self> {
        let d = inner.dim();
        if effect.iter().any(|&i| i >= d) || effect.len() >= d {
            return Err(Error::Usage(format!(
                "reference: effect coordinates {effect:?} of a {d}-parameter target"
            )));
        }
        let base: Vec<usize> = (0..d).filter(|i| !effect.contains(i)).collect();
        let base_t = if effect.is_empty() {
            None
        } else {
            let mu = DVector::from_iterator(base.len(), base.iter().map(|&i| mode[i]));
            let c = DMatrix::from_fn(base.len(), base.len(), |a, b| cov[(base[a], base[b])]);
            Some(StudentT::new(mu, c)?)
        };
        Ok(Referenced {
            full: StudentT::new(DVector::from_column_slice(mode), cov.clone())?,
            inner,
            base,
            base_t,
            effect: effect.to_vec(),
        })
    }

    fn ln_g(&self, u: &[f64]) -> f64 {
        let a = self.full.ln_pdf(u);
        match &self.base_t {
            None => a,
            Some(bt) => {
                let ub: Vec<f64> = self.base.iter().map(|&i| u[i]).collect();
                let b =
                    bt.ln_pdf(&ub) + self.effect.iter().map(|&i| ln_logistic(u[i])).sum::<f64>();
                log_sum_exp(&[
                    (1.0 - EFFECT_PRIOR_WEIGHT).ln() + a,
                    EFFECT_PRIOR_WEIGHT.ln() + b,
                ])
            }
        }
    }

    /// `z(u)` of the referenced target.
    pub fn to_box(&self, u: &[f64]) -> Vec<f64> {
        self.inner.to_box(u)
    }
}

impl<T: TemperedTarget> TemperedTarget for Referenced<'_, T> {
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn ln_prior(&self, u: &[f64]) -> f64 {
        self.ln_g(u)
    }
    fn ln_likelihood(&self, u: &[f64]) -> Result<f64> {
        let ln_q = self.inner.ln_prior(u) + self.inner.ln_likelihood(u)?;
        let v = ln_q - self.ln_g(u);
        if v.is_nan() {
            return Err(Error::Numerical(format!(
                "reference: ln q/g is NaN at {u:?}"
            )));
        }
        Ok(v)
    }
    fn sample_prior(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        match &self.base_t {
            Some(bt) if rng.random::<f64>() < EFFECT_PRIOR_WEIGHT => {
                let ub = bt.sample(rng);
                let mut u = vec![0.0; self.dim()];
                for (k, &i) in self.base.iter().enumerate() {
                    u[i] = ub[k];
                }
                for &i in &self.effect {
                    let p: f64 = rng.random_range(1e-300..1.0);
                    u[i] = (p / (1.0 - p)).ln();
                }
                Ok(u)
            }
            _ => Ok(self.full.sample(rng)),
        }
    }
}

/// Result of [`referenced_evidence`].
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct ReferencedEvidence {
    /// The generalised stepping-stone run (its `ln_z`, replicate `ln_z_se`, ladders;
    /// posterior draws, if any, in box coordinates with the target's `ln L` and `ln pi`).
    pub evidence: Evidence,
    /// Laplace's `ln Z` at the mode in `u`.
    pub ln_z_laplace: f64,
    /// The mode in `u`, mapped to the box.
    pub mode: Vec<f64>,
    /// Posterior draws in box coordinates, rows (empty without final steps).
    pub draws: Vec<Vec<f64>>,
    /// Likelihood evaluations in all (Newton and Laplace included).
    pub n_likelihood_evaluations: u64,
}

/// `ln Z` of `target` (box prior on `bounds`) by the generalised stepping-stone from the
/// reference of the module docs, built at the mode in logit coordinates found from
/// `start` (e.g. the MAP); `effect` names the coordinates that the base model fixes.
/// `opts` as for [`stepping_stone`] (its defaults need far fewer temperatures here).
pub fn referenced_evidence<T: TemperedTarget>(
    target: &T,
    bounds: &[(f64, f64)],
    start: &[f64],
    effect: &[usize],
    opts: &EvidenceOptions,
) -> Result<ReferencedEvidence> {
    let inner = InUnconstrained::new(target, bounds)?;
    let (u_mode, lap, n_newton) = laplace_in_u(&inner, start)?;
    let mode = inner.to_box(&u_mode);
    let evidence = referenced_evidence_at_mode(target, bounds, &u_mode, &lap, effect, opts, None)?;
    let draws = evidence.posterior.as_ref().map_or_else(Vec::new, |p| {
        p.draws
            .values
            .chunks_exact(p.draws.dim)
            .map(<[f64]>::to_vec)
            .collect()
    });
    Ok(ReferencedEvidence {
        ln_z_laplace: lap.ln_z,
        mode,
        draws,
        n_likelihood_evaluations: evidence.n_likelihood_evaluations + n_newton,
        evidence,
    })
}

/// The generalised stepping-stone of [`referenced_evidence`] from a mode in logit
/// coordinates `u_mode` and Laplace's approximation `lap` there, already found (by
/// [`laplace_in_u`]); `progress` as for [`stepping_stone`]. The posterior draws, if any,
/// are returned in box coordinates, with the target's own `ln L` and `ln pi` (not the
/// referenced path's `ln q/g` and `ln g`). The count of likelihood evaluations leaves out
/// those that found the mode.
pub fn referenced_evidence_at_mode<T: TemperedTarget>(
    target: &T,
    bounds: &[(f64, f64)],
    u_mode: &[f64],
    lap: &LaplaceEvidence,
    effect: &[usize],
    opts: &EvidenceOptions,
    progress: Option<&mut dyn FnMut(EvidenceProgress)>,
) -> Result<Evidence> {
    let inner = InUnconstrained::new(target, bounds)?;
    let map = inner.map().clone();
    let r = Referenced::new(inner, u_mode, &lap.covariance, effect)?;
    let mut evidence = stepping_stone(&r, opts, progress)?;
    if let Some(p) = evidence.posterior.as_mut() {
        draws_to_box(target, &map, p);
    }
    Ok(evidence)
}

/// Posterior draws of the referenced path (logit `u`; terms `ln q/g` and `ln g`) moved to
/// box coordinates with the target's `ln L` and `ln pi`: `ln q = ln pi(z) + ln |dz/du| +
/// ln L(z)` in `u`, so `ln L = (ln q/g + ln g) - ln pi(z) - ln |dz/du|`.
fn draws_to_box<T: TemperedTarget>(target: &T, map: &LogitMap, p: &mut PosteriorDraws) {
    let dim = p.draws.dim;
    let mut z = vec![0.0; dim];
    for (k, u) in p.draws.values.chunks_exact_mut(dim).enumerate() {
        map.to_box(u, &mut z);
        let ln_prior = target.ln_prior(&z);
        let ln_q = p.ln_likelihood[k] + p.ln_prior[k];
        let ln_l = ln_q - ln_prior - map.ln_jacobian(u);
        p.ln_likelihood[k] = ln_l;
        p.ln_prior[k] = ln_prior;
        p.draws.ln_density[k] = ln_l + ln_prior;
        u.copy_from_slice(&z);
    }
}
