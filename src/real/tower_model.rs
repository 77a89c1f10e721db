//! The 5-story shear model of the tower driven by the damper force, with uncertain
//! channel gains: likelihood, least-squares start, and standardised residuals.
//!
//! # Model
//! Floors of fixed mass [`FLOOR_MASS_KG`] (the author's value; frequencies and gains
//! cannot separate a mass scale from a gain scale, so the gains below are relative to
//! this mass), story stiffnesses `k_1..k_5`, Caughey (modal) damping `xi_1..xi_5`. The
//! damper force `F` acts on floor 5; the model accelerance of floor `c` is
//! `H_c(w) = g_c sum_r -w^2 phi_cr phi_5r / (w_r^2 - w^2 + 2 j xi_r w_r w)` with
//! mass-normalised modes and a real channel gain `g_c` relative to the author's
//! calibration (force and acceleration gains together; a sign error shows as a negative
//! gain).
//!
//! # Likelihood
//! `H1_ck` complex Gaussian around the model with variance
//! `s^2 |H1_ck|^2 (1 - gamma^2) / (n_d gamma^2)` (Bendat-Piersol with `n_d` segments;
//! `gamma^2` clamped to [0.02, 0.999]); `s = 1` when the estimator noise explains the
//! scatter, `s > 1` measures model error. Coordinates: `ln k_1..5`, `ln xi_1..5`,
//! `ln s`, uniform priors within [`TowerLikelihood::bounds`].
//!
//! The model is linear in each gain, so the gains are integrated out exactly under a
//! flat prior on the real line: per channel, with `A_c = sum |h_c|^2 / v`,
//! `b_c = sum Re(conj(h_c) y_c) / v` (`h_c` the unit-gain model), the integral of
//! `exp(-sum |y - g h|^2 / (s^2 v))` over `g` is `sqrt(pi s^2 / A_c) exp(-RSS_c / s^2)`
//! with `RSS_c = sum |y|^2 / v - b_c^2 / A_c`. Given the other coordinates, `g_c` is
//! Gaussian with mean `b_c / A_c` and variance `s^2 / (2 A_c)`; it is drawn so for every
//! posterior draw. This removes five dimensions from the sampler.

// Index loops over several parallel arrays (channels, bins, modes) read more clearly
// than zipped iterators here.
#![allow(clippy::needless_range_loop)]

use std::f64::consts::PI;
use std::sync::Arc;

use num_complex::Complex64;

use super::tower::{TowerFrf, FLOOR_MASS_KG};
use crate::error::{Error, Result};
use crate::frf::{Excitation, FrfBlock, FrfKind, FrfPair};
use crate::infer::{Block, NoiseScale, Posterior};
use crate::mcmc::LogDensity;
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::predict::{
    Coordinate, DenseModes, FrfDamping, FrfOptions, FrfOutput, FrfPredictor, Parametrisation,
    Predict, Scale, Variable,
};

/// Stories (and measured floors).
pub const N: usize = 5;
/// Centre of the stiffness prior (N/m): a uniform frame with a 0.52 Hz first mode.
pub const K_CENTRE_N_PER_M: f64 = 2.5e6;

/// Data of the fitted band.
#[derive(Debug, Clone)]
pub struct TowerData {
    pub freq_hz: Vec<f64>,
    /// `y[c][k]`, floor c+1.
    pub y: Vec<Vec<Complex64>>,
    /// Variance at `s = 1`.
    pub v: Vec<Vec<f64>>,
    /// `1 / v`.
    pub inv_v: Vec<Vec<f64>>,
    /// `sum_k |y_ck|^2 / v_ck` per channel.
    pub yy: Vec<f64>,
}

impl TowerData {
    /// The bins of `frf` in `[lo_hz, hi_hz]` with their variances.
    pub fn from_frf(frf: &TowerFrf, lo_hz: f64, hi_hz: f64) -> Result<Self> {
        let idx: Vec<usize> = (0..frf.freq_hz.len())
            .filter(|&k| frf.freq_hz[k] >= lo_hz && frf.freq_hz[k] <= hi_hz)
            .collect();
        if idx.len() < 20 {
            return Err(Error::Usage(format!(
                "band {lo_hz}-{hi_hz} Hz holds {} bins",
                idx.len()
            )));
        }
        let nd = frf.n_segments as f64;
        let y: Vec<Vec<Complex64>> = frf
            .h1
            .iter()
            .map(|h| idx.iter().map(|&k| h[k]).collect())
            .collect();
        let v: Vec<Vec<f64>> = frf
            .h1
            .iter()
            .zip(&frf.coherence)
            .map(|(h, g)| {
                idx.iter()
                    .map(|&k| {
                        let g2 = g[k].clamp(0.02, 0.999);
                        h[k].norm_sqr().max(1e-300) * (1.0 - g2) / (nd * g2)
                    })
                    .collect()
            })
            .collect();
        let inv_v: Vec<Vec<f64>> = v
            .iter()
            .map(|c| c.iter().map(|x| 1.0 / x).collect())
            .collect();
        let yy = y
            .iter()
            .zip(&inv_v)
            .map(|(y, w)| y.iter().zip(w).map(|(y, w)| y.norm_sqr() * w).sum())
            .collect();
        Ok(TowerData {
            freq_hz: idx.iter().map(|&k| frf.freq_hz[k]).collect(),
            y,
            v,
            inv_v,
            yy,
        })
    }

    pub fn n_points(&self) -> usize {
        self.freq_hz.len() * self.y.len()
    }
}

/// The likelihood; see the module docs. A thin adapter on the one posterior layer: an
/// [`FrfPredictor`] of the shear model (complex accelerances of the five floors to the
/// damper force at floor 5, modal damping) and one [`Block::complex_gain`] per channel,
/// all with the sampled scale `s`.
#[derive(Debug, Clone)]
pub struct TowerLikelihood {
    pub data: TowerData,
    post: Posterior<FrfPredictor<DenseModes>>,
}

/// The gains given the other coordinates: `(A_c, b_c, RSS_c)` per channel.
#[derive(Debug, Clone, PartialEq)]
pub struct GainFit {
    pub a: [f64; N],
    pub b: [f64; N],
    pub rss: [f64; N],
}

impl GainFit {
    /// Conditional mean of the gains.
    pub fn mean(&self) -> [f64; N] {
        let mut g = [0.0; N];
        for c in 0..N {
            g[c] = self.b[c] / self.a[c];
        }
        g
    }
}

/// The unit-gain predictor of the accelerances at `freq_hz` (coordinates `ln k`, `ln xi`).
fn predictor(freq_hz: &[f64]) -> Result<FrfPredictor<DenseModes>> {
    let model = Arc::new(StructuralModel::shear_frame(
        &[FLOOR_MASS_KG; N],
        &[K_CENTRE_N_PER_M; N],
    )?);
    let coords = (0..N)
        .map(|r| Coordinate {
            name: format!("ln_k{}", r + 1),
            variable: Variable::Alpha(r),
            scale: Scale::Log {
                ln_offset: K_CENTRE_N_PER_M.ln(),
            },
        })
        .collect();
    let params = Parametrisation::new(&model, coords)?;
    let pairs = (0..N)
        .map(|c| FrfPair {
            response: c,
            excitation: Excitation::Dof(N - 1),
            kind: FrfKind::Accelerance,
        })
        .collect();
    let block = FrfBlock {
        omega_rad_s: freq_hz.iter().map(|f| 2.0 * PI * f).collect(),
        pairs,
    };
    FrfPredictor::new(
        DenseModes::new(model.clone()),
        model,
        params,
        FrfOptions {
            damping: FrfDamping::Modal,
            output: FrfOutput::Complex,
            n_modes: N,
        },
        &[block],
        &[None],
    )
}

/// Model accelerances `[channel][bin]` at stiffnesses, damping ratios and gains.
pub fn model_frf(
    freq_hz: &[f64],
    k: &[f64],
    xi: &[f64],
    gains: &[f64],
) -> Result<Vec<Vec<Complex64>>> {
    let p = predictor(freq_hz)?;
    let theta: Vec<f64> = k.iter().chain(xi).map(|v| v.ln()).collect();
    let mut out = vec![0.0; p.n_outputs()];
    p.predict(&theta, &mut p.workspace(), &mut out)?;
    let nb = freq_hz.len();
    Ok((0..N)
        .map(|c| {
            (0..nb)
                .map(|i| {
                    gains[c] * Complex64::new(out[2 * (c * nb + i)], out[2 * (c * nb + i) + 1])
                })
                .collect()
        })
        .collect())
}

/// Natural frequencies (Hz) of the shear model.
pub fn natural_freq_hz(k: &[f64]) -> Result<Vec<f64>> {
    let model = StructuralModel::shear_frame(&[FLOOR_MASS_KG; N], k)?;
    Ok(Modes::solve(
        &model.stiffness(&model.alpha_zero()),
        &model.mass(&model.beta_zero()),
        model.ground_influence(),
        None,
    )?
    .freq_hz())
}

impl TowerLikelihood {
    /// The posterior of `data` on the layer.
    pub fn new(data: TowerData) -> Result<Self> {
        let p = predictor(&data.freq_hz)?;
        let nb = data.freq_hz.len();
        let blocks = (0..N)
            .map(|c| {
                let observed: Vec<f64> = data.y[c].iter().flat_map(|y| [y.re, y.im]).collect();
                let sd: Vec<f64> = data.v[c].iter().map(|v| v.sqrt()).collect();
                let range = 2 * c * nb..2 * (c + 1) * nb;
                Block::complex_gain(
                    &format!("floor {}", c + 1),
                    range,
                    &observed,
                    &sd,
                    NoiseScale::Sampled(0),
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let bounds = Self::bounds();
        let scale = [("ln_s".to_string(), bounds[2 * N])];
        let post = Posterior::new(p, &bounds[..2 * N], &scale, blocks)?;
        Ok(TowerLikelihood { data, post })
    }

    /// The layer's posterior (coordinates `ln k`, `ln xi`, `ln s`).
    pub fn posterior(&self) -> &Posterior<FrfPredictor<DenseModes>> {
        &self.post
    }

    /// Prior box: `k` within a factor 10 of [`K_CENTRE_N_PER_M`], `xi` in [0.002, 0.3],
    /// `s` in [0.1, 1000].
    pub fn bounds() -> Vec<(f64, f64)> {
        let mut b = vec![
            (
                (K_CENTRE_N_PER_M / 10.0).ln(),
                (K_CENTRE_N_PER_M * 10.0).ln()
            );
            N
        ];
        b.extend([(0.002f64.ln(), 0.3f64.ln()); N]);
        b.push((0.1f64.ln(), 1000.0f64.ln()));
        b
    }

    /// `(k, xi, s)` of a coordinate vector (`s = 1` when `t` holds only `ln k, ln xi`).
    pub fn unpack(t: &[f64]) -> ([f64; N], [f64; N], f64) {
        let mut k = [0.0; N];
        let mut xi = [0.0; N];
        for i in 0..N {
            k[i] = t[i].exp();
            xi[i] = t[N + i].exp();
        }
        (k, xi, t.get(2 * N).map_or(1.0, |v| v.exp()))
    }

    /// The gain fit at `t` (unit-gain model, then per-channel sums).
    pub fn gain_fit(&self, t: &[f64]) -> Result<GainFit> {
        let h = self.post.predict(&t[..2 * N])?;
        let nb = self.data.freq_hz.len();
        let mut fit = GainFit {
            a: [0.0; N],
            b: [0.0; N],
            rss: [0.0; N],
        };
        for c in 0..N {
            let (mut a, mut b) = (0.0, 0.0);
            for (i, (y, w)) in self.data.y[c].iter().zip(&self.data.inv_v[c]).enumerate() {
                let h = Complex64::new(h[2 * (c * nb + i)], h[2 * (c * nb + i) + 1]);
                a += h.norm_sqr() * w;
                b += (h.conj() * y).re * w;
            }
            fit.a[c] = a;
            fit.b[c] = b;
            fit.rss[c] = (self.data.yy[c] - b * b / a).max(0.0);
        }
        Ok(fit)
    }

    /// Standardised residuals `(y - g h) / sqrt(v)` (complex; `s = 1`) at `t` with
    /// gains `g`.
    pub fn residuals(&self, t: &[f64], g: &[f64; N]) -> Result<Vec<Vec<Complex64>>> {
        let (k, xi, _) = Self::unpack(t);
        let h = model_frf(&self.data.freq_hz, &k, &xi, g)?;
        Ok((0..N)
            .map(|c| {
                (0..self.data.freq_hz.len())
                    .map(|i| (self.data.y[c][i] - h[c][i]) / self.data.v[c][i].sqrt())
                    .collect()
            })
            .collect())
    }
}

impl LogDensity for TowerLikelihood {
    fn dim(&self) -> usize {
        2 * N + 1
    }

    fn ln_density(&self, t: &[f64]) -> Result<f64> {
        self.post.ln_density(t)
    }

    /// One term per channel (its gain integrated out).
    fn n_pointwise(&self) -> usize {
        self.post.n_pointwise()
    }

    fn ln_density_with_pointwise(&self, t: &[f64], pointwise: &mut [f64]) -> Result<f64> {
        self.post.ln_density_with_pointwise(t, pointwise)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::direct;
    use nalgebra::DMatrix;

    /// Synthetic data from the same forward model (signed gains, complex noise of the
    /// modelled variance with s = 1): the log-likelihood peaks at the true stiffnesses
    /// and damping (each perturbed by +-3% lowers it), the conditional mean gains are
    /// within 4 conditional sds of the truth, and the analytic gain integral matches
    /// a numerical one. (The damping of modes above the band is not identified and is
    /// skipped.)
    #[test]
    fn gain_marginal_likelihood_on_synthetic_data() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let k = [4.0e6, 5.5e6, 1.0e6, 2.0e7, 2.0e7];
        let xi = [0.05, 0.03, 0.05, 0.1, 0.02];
        let g = [-1.0, -1.2, -0.5, -0.5, -0.4];
        let freq_hz: Vec<f64> = (0..200).map(|i| 0.4 + 0.025 * i as f64).collect();
        let h = model_frf(&freq_hz, &k, &xi, &g).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let v: Vec<Vec<f64>> = h
            .iter()
            .map(|c| c.iter().map(|x| 0.01 * x.norm_sqr()).collect())
            .collect();
        let y: Vec<Vec<Complex64>> = h
            .iter()
            .zip(&v)
            .map(|(c, vc)| {
                c.iter()
                    .zip(vc)
                    .map(|(x, var)| {
                        let (a, b): (f64, f64) = (
                            StandardNormal.sample(&mut rng),
                            StandardNormal.sample(&mut rng),
                        );
                        x + Complex64::new(a, b) * (var / 2.0).sqrt()
                    })
                    .collect()
            })
            .collect();
        let inv_v: Vec<Vec<f64>> = v
            .iter()
            .map(|c| c.iter().map(|x| 1.0 / x).collect())
            .collect();
        let yy = y
            .iter()
            .zip(&inv_v)
            .map(|(y, w)| y.iter().zip(w).map(|(y, w)| y.norm_sqr() * w).sum())
            .collect();
        let lik = TowerLikelihood::new(TowerData {
            freq_hz,
            y,
            v,
            inv_v,
            yy,
        })
        .unwrap();
        let mut t: Vec<f64> = k.iter().chain(&xi).map(|x| x.ln()).collect();
        t.push(0.0);
        let l0 = lik.ln_density(&t).unwrap();
        let f_n = natural_freq_hz(&k).unwrap();
        let top = lik.data.freq_hz[lik.data.freq_hz.len() - 1];
        for i in (0..2 * N).filter(|&i| i < N || f_n[i - N] < top) {
            for d in [-0.03, 0.03] {
                let mut u = t.clone();
                u[i] += d;
                assert!(lik.ln_density(&u).unwrap() < l0, "coordinate {i} {d:+}");
            }
        }
        let fit = lik.gain_fit(&t).unwrap();
        for c in 0..N {
            let sd = (1.0 / (2.0 * fit.a[c])).sqrt();
            assert!(
                (fit.mean()[c] - g[c]).abs() < 4.0 * sd,
                "gain {c}: {} vs {}",
                fit.mean()[c],
                g[c]
            );
        }
        // Numerical integral over g of exp(-sum |y - g h|^2 / v) for channel 0
        // (trapezoid over +-10 sd) against sqrt(pi / A) exp(-RSS).
        let h1 = model_frf(&lik.data.freq_hz, &k, &xi, &[1.0; N]).unwrap();
        let (a, b, rss) = (fit.a[0], fit.b[0], fit.rss[0]);
        let (m, sd) = (b / a, (1.0 / (2.0 * a)).sqrt());
        let q = |gg: f64| -> f64 {
            let chi: f64 = (0..lik.data.freq_hz.len())
                .map(|i| (lik.data.y[0][i] - gg * h1[0][i]).norm_sqr() * lik.data.inv_v[0][i])
                .sum();
            (-(chi - rss)).exp()
        };
        let n = 4000;
        let step = 20.0 * sd / n as f64;
        let num: f64 = (0..=n)
            .map(|i| {
                let w = if i == 0 || i == n { 0.5 } else { 1.0 };
                w * q(m - 10.0 * sd + i as f64 * step)
            })
            .sum::<f64>()
            * step;
        assert!((num / (std::f64::consts::PI / a).sqrt() - 1.0).abs() < 1e-6);
    }

    /// The layer's density is the hand-written gain-marginal likelihood of the module
    /// docs, `-(2n - N) ln s - sum RSS_c / s^2 - 1/2 sum ln A_c`, up to a constant: their
    /// differences between points agree.
    #[test]
    fn layer_density_is_the_gain_marginal_likelihood() {
        let k = [3.0e6, 2.8e6, 2.5e6, 2.2e6, 2.0e6];
        let xi = [0.02, 0.015, 0.01, 0.012, 0.03];
        let freq_hz: Vec<f64> = (0..120).map(|i| 0.4 + 0.04 * i as f64).collect();
        let h = model_frf(&freq_hz, &k, &xi, &[0.9, -1.1, 1.0, 0.8, 1.2]).unwrap();
        let y: Vec<Vec<Complex64>> = h
            .iter()
            .map(|c| {
                c.iter()
                    .enumerate()
                    .map(|(i, x)| x * Complex64::new(1.0, 0.02 * (i % 7) as f64))
                    .collect()
            })
            .collect();
        let v: Vec<Vec<f64>> = y
            .iter()
            .map(|c| c.iter().map(|x| 1e-3 * x.norm_sqr()).collect())
            .collect();
        let inv_v: Vec<Vec<f64>> = v
            .iter()
            .map(|c| c.iter().map(|x| 1.0 / x).collect())
            .collect();
        let yy = y
            .iter()
            .zip(&inv_v)
            .map(|(y, w)| y.iter().zip(w).map(|(y, w)| y.norm_sqr() * w).sum())
            .collect();
        let lik = TowerLikelihood::new(TowerData {
            freq_hz,
            y,
            v,
            inv_v,
            yy,
        })
        .unwrap();
        let hand = |t: &[f64]| -> f64 {
            let fit = lik.gain_fit(t).unwrap();
            let s = t[2 * N].exp();
            let n = lik.data.n_points() as f64;
            -(2.0 * n - N as f64) * s.ln()
                - fit.rss.iter().sum::<f64>() / (s * s)
                - 0.5 * fit.a.iter().map(|a| a.ln()).sum::<f64>()
        };
        let mut t0: Vec<f64> = k.iter().chain(&xi).map(|x| x.ln()).collect();
        t0.push(0.3);
        let mut t1 = t0.clone();
        t1[1] += 0.02;
        t1[7] -= 0.1;
        t1[10] = 0.9;
        let d_layer = lik.ln_density(&t1).unwrap() - lik.ln_density(&t0).unwrap();
        let d_hand = hand(&t1) - hand(&t0);
        assert!(
            (d_layer - d_hand).abs() < 1e-8 * d_hand.abs().max(1.0),
            "{d_layer} vs {d_hand}"
        );
    }

    /// Oracle: the modal sum against the direct solve `-w^2 (K - w^2 M + j w C)^-1` with
    /// the modal damping matrix `C = M Phi diag(2 xi_r w_r) Phi^T M` of the same ratios.
    #[test]
    fn modal_accelerance_matches_the_direct_solve() {
        let k = [3.0e6, 2.8e6, 2.5e6, 2.2e6, 2.0e6];
        let xi = [0.02, 0.015, 0.01, 0.012, 0.03];
        let f = [0.4, 0.9, 1.7, 3.3];
        let h = model_frf(&f, &k, &xi, &[1.0; N]).unwrap();
        let model = StructuralModel::shear_frame(&[FLOOR_MASS_KG; N], &k).unwrap();
        let (kk, mm) = (
            model.stiffness(&model.alpha_zero()),
            model.mass(&model.beta_zero()),
        );
        let modes = Modes::solve(&kk, &mm, model.ground_influence(), None).unwrap();
        let diag = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            N,
            (0..N).map(|r| 2.0 * xi[r] * modes.omega_rad_s[r]),
        ));
        let cc = &mm * &modes.phi * diag * modes.phi.transpose() * &mm;
        for (i, &fh) in f.iter().enumerate() {
            let w = 2.0 * std::f64::consts::PI * fh;
            let rec = direct::receptance_matrix(&mm, &kk, &cc, w).unwrap();
            for c in 0..N {
                let d = -w * w * rec[(c, N - 1)];
                assert!(
                    (h[c][i] - d).norm() < 1e-9 * d.norm().max(1e-12),
                    "floor {c} f {fh}: {} vs {d}",
                    h[c][i]
                );
            }
        }
    }
}
