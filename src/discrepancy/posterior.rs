//! The posterior of the nominal model or of one hypothesis at one location.
//!
//! # Parameters (`z`, uniform prior box)
//! `[ln (1 + alpha_1) .. ln (1 + alpha_a), ln (1 + beta_1) .. ln (1 + beta_b), ln xi_1 ..
//! ln xi_n, ln eta, effect...]` ([`FrameLayout`]): the scales of the model's stiffness and
//! mass groups (paper Eqs. 20-21; a shear frame's `ln k_r/k_r0` and `ln m_r/m_r0`) about
//! the campaign's nominal model, uniform on `ln 0.5 .. ln 2` ([`MULTIPLIER_BOUNDS`]);
//! modal damping ratios of the model's modes, `ln xi` uniform on `ln 1e-4 .. ln 0.2` ([`XI_BOUNDS`]); the
//! relative error floor `eta`, `ln eta` uniform on `ln 1e-4 .. ln 0.3`
//! ([`ETA_BOUNDS`]); then the hypothesis' effect coordinates with their own boxes.
//! [`ModelPosterior::ln_prior`] is the normalised log density of the box.
//!
//! # Likelihood
//! Each measured ratio `h_i` is complex circular Gaussian about the model `H_i` with
//! `var(Re) = var(Im) = sigma_i^2 = (eps_i^2 + eta^2) |h_i|^2`, `eps_i` the Bendat &
//! Piersol relative random error (`std(|H|)/|H|`, which is the per-component relative
//! standard deviation): `ln L = -sum_i [ |H_i - h_i|^2 / (2 sigma_i^2) + ln(2 pi
//! sigma_i^2) ]`. (DIAGNOSE.md writes `|r|^2 / sigma^2 + ln(pi sigma^2)`, the density
//! for `E|r|^2 = sigma^2`; with `sigma^2` the per-component variance the above is the
//! consistent form.)
//!
//! Single-impact hammer segments add the input channel's correlated relative error
//! ([`super::data::InputGainBasis`]): `h = H (1 + delta) + noise`, `delta ~ CN(0, U U^*)`
//! over the segment's frequencies, shared by its channels. With `H` replaced by the
//! measured `h` (plug-in, so the covariance does not depend on the parameters; or the
//! model's, [`super::data::GainCarrier`]: the measured plug-in's noise is correlated
//! with the residual it weighs, which biases effect sizes, see the README), the
//! residual `e = h - H` of a segment has the complex covariance `Sigma = D + V V^*`,
//! `D = diag(2 sigma_i^2)`, `V_i = h_i U_k(i)` (rank `r`, a few), and by Woodbury
//! `e^* Sigma^-1 e = e^* D^-1 e - b^* G^-1 b`, `ln det Sigma = ln det D + ln det G`
//! with `G = I + V^* D^-1 V = I + sum_k U_k^* U_k sum_(i at k) 1 / (2 (eps_i^2 +
//! eta^2))` and `b = V^* D^-1 e`: `O(N + M r^2)` per segment, `O(N + M r)` while `eta`
//! and the carrier stay (`G`'s factor is kept, [`super::gain_solve::GainCache`]).
//! `ln L = -e^* Sigma^-1 e - ln det (pi Sigma)`. `chi2 per dof` is `e^* Sigma^-1 e / N`:
//! 1 when the noise model is right.
//!
//! Shake-table records add the same kind of term bin by bin
//! ([`InputGainBasis::PerBin`]: the ground channel's noise, `delta_k = -N_x / X_k`,
//! independent between bins): `U = diag(sd)`, `G` diagonal, `O(N + M)`.
//! `D` takes each point's own error ([`InputGainBasis::own_rel_var`]): for a per-bin
//! basis its coherence's total less the shared part; for a single impact's smooth basis
//! the whole total, the force noise counted twice on purpose. Taking `eps_i` from the
//! output noise's coherence alone (the exact split were that noise the only other error)
//! gave a false alarm on null-22 (`sensor_timing`, delta ln Z 8.2) where the whole total
//! gives `none`.

mod gain;
mod scales;

use super::data::{weight_bias, DiagnosisData, InputGainBasis};
use super::forward::{BaseParams, ExtendedModel};
pub use super::frame_layout::FrameLayout;
use super::gain_solve::{GainCache, GainSegment};
use super::hypothesis::{EffectParam, Hypothesis};
use super::location::Location;
use super::time_domain::TimeDomainModel;
use crate::error::{Error, Result};
use crate::mcmc::LogDensity;
use num_complex::Complex64;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use scales::ScaleCache;
use std::ops::Range;
use std::sync::Arc;

/// Box of the `ln` stiffness and mass multipliers.
pub const MULTIPLIER_BOUNDS: (f64, f64) = (0.5, 2.0);
/// Box of the modal damping ratios.
pub const XI_BOUNDS: (f64, f64) = (1e-4, 0.2);
/// Box of the relative error floor.
pub const ETA_BOUNDS: (f64, f64) = (1e-4, 0.3);

/// A reported value.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalValue {
    pub name: String,
    pub value: f64,
    pub unit: String,
}

/// Posterior of one model (see the module docs).
#[derive(Debug, Clone)]
pub struct ModelPosterior {
    model: ExtendedModel,
    effect_params: Vec<EffectParam>,
    names: Vec<String>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    ln_volume: f64,
    /// Measured ratios (flat layout of the model).
    h: Vec<Complex64>,
    /// `eps_i^2` and `|h_i|^2`.
    eps2: Vec<f64>,
    abs2: Vec<f64>,
    frame: FrameLayout,
    /// Segments with a correlated input-noise gain error.
    gains: Vec<GainSegment>,
    /// Extra whitened residuals (2 per gain coefficient).
    n_gain_residuals: usize,
    /// When set, predictions replay the tests in the time domain instead of using
    /// `model`'s frequency-domain solution ([`Self::with_time_domain`]).
    time_domain: Option<Arc<TimeDomainModel>>,
    /// The model's prediction at its MAP, the gain carrier of
    /// [`super::data::GainCarrier::ModelAtMap`] ([`Self::at_map`]); the measured `h`
    /// until set.
    gain_plug_in: Option<Arc<Vec<Complex64>>>,
    /// Each thread's factors of the gain segments' `G` at its last error floor.
    gain_cache: GainCache,
    /// Each thread's per-point noise scales at its last error floor (the whitened
    /// residuals').
    scales: ScaleCache,
}

impl ModelPosterior {
    /// The posterior of the nominal model (`hypothesis = None`) or of a hypothesis at a
    /// location.
    pub fn new(
        data: Arc<DiagnosisData>,
        hypothesis: Option<(Arc<dyn Hypothesis>, Location)>,
    ) -> Result<Self> {
        let frame = FrameLayout::of(&data);
        let effect_params = match &hypothesis {
            Some((h, loc)) => h.parameters(&data, loc)?,
            None => Vec::new(),
        };
        let mut names = Vec::new();
        let mut lower = Vec::new();
        let mut upper = Vec::new();
        let groups = data.model.alpha_parameters().iter();
        let groups = groups.chain(data.model.beta_parameters());
        for p in groups {
            names.push(format!("ln_{}", p.name));
            lower.push(MULTIPLIER_BOUNDS.0.ln());
            upper.push(MULTIPLIER_BOUNDS.1.ln());
        }
        for i in 1..=frame.n_xi {
            names.push(format!("ln_xi{i}"));
            lower.push(XI_BOUNDS.0.ln());
            upper.push(XI_BOUNDS.1.ln());
        }
        names.push("ln_eta".into());
        lower.push(ETA_BOUNDS.0.ln());
        upper.push(ETA_BOUNDS.1.ln());
        for p in &effect_params {
            if !(p.lower < p.upper && p.lower.is_finite() && p.upper.is_finite()) {
                return Err(Error::Model(format!(
                    "effect parameter {} has the empty prior box [{}, {}]",
                    p.name, p.lower, p.upper
                )));
            }
            names.push(p.coordinate_name.clone());
            lower.push(p.lower);
            upper.push(p.upper);
        }
        let ln_volume = lower.iter().zip(&upper).map(|(l, u)| (u - l).ln()).sum();
        let model = ExtendedModel::new(data.clone(), hypothesis)?;
        let mut h = Vec::with_capacity(model.len());
        let mut eps2 = Vec::with_capacity(model.len());
        let mut abs2 = Vec::with_capacity(model.len());
        let correct = data.options.weight_bias_correction;
        for seg in &data.segments {
            for ch in &seg.channels {
                match correct {
                    true => h.extend(
                        ch.h.iter()
                            .zip(&ch.rel_err)
                            .map(|(h, e)| h * (1.0 + weight_bias(*e))),
                    ),
                    false => h.extend_from_slice(&ch.h),
                }
                eps2.extend(ch.rel_err.iter().map(|e| e * e));
                abs2.extend(ch.h.iter().map(|v| v.norm_sqr()));
            }
        }
        let mut gains = Vec::new();
        for (seg, ranges) in data.segments.iter().zip(model.layout()) {
            let Some(basis) = &seg.input_gain else {
                continue;
            };
            if matches!(basis, InputGainBasis::Smooth { rank: 0, .. }) || ranges.is_empty() {
                continue;
            }
            let start = ranges[0].start;
            let mut freq_of = Vec::new();
            for (ch, r) in seg.channels.iter().zip(ranges) {
                debug_assert_eq!(r.start, start + freq_of.len());
                freq_of.extend(ch.freq_index.iter().map(|&k| k as u32));
            }
            // The points' own errors ([`InputGainBasis::own_rel_var`]).
            for (j, &k) in freq_of.iter().enumerate() {
                let e2 = &mut eps2[start + j];
                *e2 = basis.own_rel_var(k as usize, *e2);
            }
            let n_freq = seg.freq_hz.len();
            let (rank, u, per_bin) = match basis {
                InputGainBasis::Smooth { rank, u } => (*rank, u.clone(), false),
                InputGainBasis::PerBin { sd } => (
                    n_freq,
                    sd.iter().map(|&v| Complex64::new(v, 0.0)).collect(),
                    true,
                ),
            };
            gains.push(GainSegment {
                rank,
                u,
                per_bin,
                n_freq,
                start,
                freq_of,
            });
        }
        let n_gain_residuals = gains.iter().map(|g| 2 * g.rank).sum();
        Ok(ModelPosterior {
            gains,
            n_gain_residuals,
            time_domain: None,
            gain_plug_in: None,
            gain_cache: GainCache::default(),
            scales: ScaleCache::default(),
            model,
            effect_params,
            names,
            lower,
            upper,
            ln_volume,
            h,
            eps2,
            abs2,
            frame,
        })
    }

    /// The forward model.
    pub fn model(&self) -> &ExtendedModel {
        &self.model
    }

    /// The data.
    pub fn data(&self) -> &Arc<DiagnosisData> {
        self.model.data()
    }

    /// Number of parameters.
    pub fn dim(&self) -> usize {
        self.names.len()
    }

    /// Names of the sampled coordinates.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Units of the sampled coordinates (`1` for logarithms).
    pub fn units(&self) -> Vec<String> {
        let mut u = vec!["1".to_string(); self.eta_index() + 1];
        u.extend(self.effect_params.iter().map(|p| match p.coordinate {
            super::hypothesis::Coordinate::Log => "1".to_string(),
            super::hypothesis::Coordinate::Linear { factor: 1.0 } => p.unit.to_string(),
            super::hypothesis::Coordinate::Linear { .. } => "1".to_string(),
        }));
        u
    }

    /// The effect parameters (empty for the nominal model).
    pub fn effect_params(&self) -> &[EffectParam] {
        &self.effect_params
    }

    /// Prior box: lower and upper corners.
    pub fn bounds(&self) -> (&[f64], &[f64]) {
        (&self.lower, &self.upper)
    }

    /// Index of `ln eta` in `z`.
    pub fn eta_index(&self) -> usize {
        self.frame.xi().end
    }

    /// Where the stiffness scales, the mass scales and the damping ratios sit in `z`.
    pub fn frame_layout(&self) -> FrameLayout {
        self.frame
    }

    /// Number of complex data points.
    pub fn n_points(&self) -> usize {
        self.h.len()
    }

    /// Measured ratios as the likelihood compares them (flat layout): times `1 + v`
    /// with the weight-bias correction ([`super::data::weight_bias`]).
    pub fn measured(&self) -> &[Complex64] {
        &self.h
    }

    /// Normalised log prior density: `-ln(box volume)` inside, `-inf` outside.
    pub fn ln_prior(&self, z: &[f64]) -> f64 {
        if z.len() != self.dim() {
            return f64::NEG_INFINITY;
        }
        let inside = z
            .iter()
            .zip(self.lower.iter().zip(&self.upper))
            .all(|(v, (l, u))| v >= l && v <= u);
        if inside {
            -self.ln_volume
        } else {
            f64::NEG_INFINITY
        }
    }

    /// A draw from the prior.
    pub fn sample_prior(&self, rng: &mut ChaCha8Rng) -> Result<Vec<f64>> {
        Ok(self
            .lower
            .iter()
            .zip(&self.upper)
            .map(|(l, u)| l + (u - l) * rng.random::<f64>())
            .collect())
    }

    /// Frame parameters in physical units.
    pub fn base_params(&self, z: &[f64]) -> BaseParams {
        let exp = |r: Range<usize>| z[r].iter().map(|v| v.exp()).collect();
        BaseParams {
            stiffness_scale: exp(self.frame.stiffness()),
            mass_scale: exp(self.frame.mass()),
            xi: exp(self.frame.xi()),
        }
    }

    /// The hypothesis' physical effect values.
    pub fn effect_physical(&self, z: &[f64]) -> Result<Vec<f64>> {
        match self.model.hypothesis() {
            Some((h, loc)) => h.physical(self.data(), loc, &z[self.eta_index() + 1..]),
            None => Ok(Vec::new()),
        }
    }

    /// Every parameter in physical units: stiffnesses, masses, damping ratios, `eta`,
    /// then the effect's values.
    pub fn physical(&self, z: &[f64]) -> Result<Vec<PhysicalValue>> {
        let b = self.base_params(z);
        let mut out = Vec::new();
        let pv = |name: String, value: f64, unit: &str| PhysicalValue {
            name,
            value,
            unit: unit.into(),
        };
        let model = &self.data().model;
        let groups = [
            (model.alpha_parameters(), &b.stiffness_scale),
            (model.beta_parameters(), &b.mass_scale),
        ];
        for (params, scales) in groups {
            for (p, v) in params.iter().zip(scales.iter()) {
                out.push(match p.nominal {
                    Some(nominal) => pv(p.name.clone(), nominal * v, &p.unit),
                    None => pv(format!("{}_scale", p.name), *v, "1"),
                });
            }
        }
        for (i, v) in b.xi.iter().enumerate() {
            out.push(pv(format!("xi{}", i + 1), *v, "1"));
        }
        out.push(pv("eta".into(), z[self.eta_index()].exp(), "1"));
        for (p, v) in self.effect_params.iter().zip(self.effect_physical(z)?) {
            out.push(pv(p.name.clone(), v, p.unit));
        }
        Ok(out)
    }

    /// Predicted ratios at `z` (flat layout; see [`ExtendedModel::layout`]).
    pub fn predict(&self, z: &[f64]) -> Result<Vec<Complex64>> {
        self.check_len(z)?;
        let (base, effect) = (self.base_params(z), self.effect_physical(z)?);
        match &self.time_domain {
            Some(td) => {
                let hyp = self.model.hypothesis();
                td.predict(&base, hyp.map(|(h, l)| (h.as_ref(), l)), &effect)
            }
            None => self.model.predict(&base, &effect),
        }
    }

    /// The same posterior with predictions from a time-domain replay of the tests
    /// ([`super::time_domain`]); `td` must be built on this posterior's data.
    pub fn with_time_domain(mut self, td: Arc<TimeDomainModel>) -> Result<Self> {
        if !Arc::ptr_eq(td.data(), self.data()) && **td.data() != **self.data() {
            return Err(Error::Usage(
                "time-domain model built on other data than the posterior".into(),
            ));
        }
        self.time_domain = Some(td);
        Ok(self)
    }

    /// True when predictions come from a time-domain replay of the tests.
    pub fn is_time_domain(&self) -> bool {
        self.time_domain.is_some()
    }

    fn check_len(&self, z: &[f64]) -> Result<()> {
        if z.len() != self.dim() {
            return Err(Error::Usage(format!(
                "parameter vector of {} entries for {} parameters",
                z.len(),
                self.dim()
            )));
        }
        Ok(())
    }

    /// Log-likelihood at `z` (see the module docs).
    pub fn ln_likelihood(&self, z: &[f64]) -> Result<f64> {
        let pred = self.predict(z)?;
        Ok(self.ln_likelihood_of(&pred, z[self.eta_index()].exp()))
    }

    /// Log-likelihood of a prediction at error floor `eta`.
    pub fn ln_likelihood_of(&self, pred: &[Complex64], eta: f64) -> f64 {
        let (quad, ln_det) = self.quadratic_and_ln_det(pred, eta, None);
        -quad - ln_det - pred.len() as f64 * std::f64::consts::PI.ln()
    }

    /// `e^* Sigma^-1 e` and `ln det Sigma` of the residual `e = h - pred` (complex
    /// covariance `Sigma = D + V V^*`, `D = diag(2 sigma_i^2)`, see the module docs);
    /// `gains` receives each gain segment's `g`.
    fn quadratic_and_ln_det(
        &self,
        pred: &[Complex64],
        eta: f64,
        gains: Option<&mut Vec<Vec<Complex64>>>,
    ) -> (f64, f64) {
        let eta2 = eta * eta;
        let mut quad = 0.0;
        let mut ln_det = 0.0;
        for (((p, h), e2), a2) in pred.iter().zip(&self.h).zip(&self.eps2).zip(&self.abs2) {
            let d = 2.0 * (e2 + eta2) * a2;
            quad += (p - h).norm_sqr() / d;
            ln_det += d.ln();
        }
        let inv_d = |i: usize| 1.0 / (2.0 * (self.eps2[i] + eta2) * self.abs2[i]);
        let (q, ld) = self.gain_terms(pred, eta, inv_d, gains);
        (quad - q, ln_det + ld)
    }

    /// `e^* Sigma^-1 e / N` of a prediction at error floor `eta` (the chi2 per real
    /// degree of freedom: 1 when the noise model is right), correlated gain errors
    /// included.
    pub fn chi2_per_dof_of(&self, pred: &[Complex64], eta: f64) -> f64 {
        self.quadratic_and_ln_det(pred, eta, None).0 / pred.len().max(1) as f64
    }

    /// Chi2 per dof of the points `range` (flat layout) of a full prediction, without
    /// the correlated gain errors (a per-channel diagnostic).
    pub fn chi2_per_dof_of_range(
        &self,
        pred: &[Complex64],
        eta: f64,
        range: std::ops::Range<usize>,
    ) -> f64 {
        let eta2 = eta * eta;
        let n = range.len();
        let q: f64 = range
            .map(|i| (pred[i] - self.h[i]).norm_sqr() / ((self.eps2[i] + eta2) * self.abs2[i]))
            .sum();
        q / (2.0 * n.max(1) as f64)
    }

    /// Number of whitened residuals: `2 N` plus 2 per correlated gain coefficient.
    pub fn n_whitened_residuals(&self) -> usize {
        2 * self.h.len() + self.n_gain_residuals
    }

    /// Whitened residuals at `z` with the error floor `eta` (not `z`'s), so that half
    /// their squared norm is the likelihood's quadratic term `e^* Sigma^-1 e`: per point
    /// `Re`, `Im` of `(H_i - h_i + v_i g) / sigma_i` with each gain segment's `g` at its
    /// conditional optimum, then `sqrt(2) g` (variable projection of the latent gains;
    /// `min_g |D^-1/2 (e - V g)|^2 + |g|^2 = e^* Sigma^-1 e`).
    pub fn whitened_residuals(&self, z: &[f64], eta: f64, out: &mut [f64]) -> Result<()> {
        let pred = self.predict(z)?;
        self.whitened_residuals_of(&pred, eta, out);
        Ok(())
    }

    /// [`Self::whitened_residuals`] of a given prediction (flat layout).
    pub fn whitened_residuals_of(&self, pred: &[Complex64], eta: f64, out: &mut [f64]) {
        let scales = self.scales.at(eta, &self.eps2, &self.abs2);
        let mut gains = Vec::with_capacity(self.gains.len());
        self.gain_terms(pred, eta, |i| scales.inv_d[i], Some(&mut gains));
        let carrier = self.gain_carrier(pred);
        let mut corr = vec![Complex64::new(0.0, 0.0); pred.len()];
        for (gs, g) in self.gains.iter().zip(&gains) {
            // `U_k g` once per frequency: the segment's channels share it.
            let terms: Vec<Complex64> = (0..gs.n_freq).map(|k| gs.term(k, g)).collect();
            for (j, &k) in gs.freq_of.iter().enumerate() {
                let i = gs.start + j;
                corr[i] = carrier[i] * terms[k as usize];
            }
        }
        for (i, p) in pred.iter().enumerate() {
            let r = (p - self.h[i] + corr[i]) / scales.sd[i];
            out[2 * i] = r.re;
            out[2 * i + 1] = r.im;
        }
        let mut j = 2 * pred.len();
        for g in &gains {
            for v in g {
                out[j] = std::f64::consts::SQRT_2 * v.re;
                out[j + 1] = std::f64::consts::SQRT_2 * v.im;
                j += 2;
            }
        }
    }

    /// `z` of physical frame parameters and effect values (for truths and starts);
    /// `effect` in the units of [`Self::effect_params`] (physical), converted through
    /// each parameter's coordinate. Hypotheses whose [`Hypothesis::physical`] is not
    /// per-parameter (base damping) take the coordinate values directly in
    /// `effect_coordinates`.
    pub fn z_of(&self, base: &BaseParams, eta: f64, effect_coordinates: &[f64]) -> Vec<f64> {
        let mut z = Vec::with_capacity(self.dim());
        z.extend(base.stiffness_scale.iter().map(|s| s.ln()));
        z.extend(base.mass_scale.iter().map(|s| s.ln()));
        z.extend(base.xi.iter().map(|x| x.ln()));
        z.push(eta.ln());
        z.extend_from_slice(effect_coordinates);
        z
    }
}

impl LogDensity for ModelPosterior {
    fn dim(&self) -> usize {
        self.names.len()
    }

    fn ln_density(&self, z: &[f64]) -> Result<f64> {
        let p = self.ln_prior(z);
        if p == f64::NEG_INFINITY {
            return Ok(p);
        }
        Ok(p + self.ln_likelihood(z)?)
    }
}
