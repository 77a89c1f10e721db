//! Small fits behind the consistency checks: a complex ratio's phase slope and magnitude
//! trend, and a single-pole (SDOF) fit shared by several channels.
//!
//! ## Scale of the covariances
//! Every fit weights each point by its own noise (`segment` module docs) and reports the
//! covariance `s^2 (X^T W X)^-1` with `s^2 = max(1, chi^2_res / dof)` (the Birge ratio,
//! floored at 1). When the Bendat & Piersol errors are right, `s^2 ~ 1` and the estimates'
//! covariance is the textbook one; when the data scatter more than they say (estimator
//! bias, leakage, a model too simple for the band) the covariance grows accordingly, so a
//! check never rejects only because the noise was underestimated. Flooring at 1 makes the
//! tests conservative when the noise is overestimated (the calibration of
//! [`crate::signal::noise`] reports mean `z^2` of 0.6-0.9).

use crate::error::{Error, Result};
use crate::update::lsq::{fd_jacobian, Bounds, FdScheme};
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use num_complex::Complex64;

/// Weighted linear least squares `y ~ X beta` with standard deviations `sigma`.
#[derive(Debug, Clone, PartialEq)]
pub struct Wls {
    pub beta: Vec<f64>,
    /// Covariance `(X^T W X)^-1`, unscaled.
    pub cov: DMatrix<f64>,
    /// Residual `sum ((y - X beta) / sigma)^2`.
    pub chi2: f64,
    pub dof: usize,
}

/// Solves weighted least squares; rows are `x[i]` (all the same length).
pub fn wls(x: &[Vec<f64>], y: &[f64], sigma: &[f64]) -> Result<Wls> {
    let n = y.len();
    let p = x.first().map_or(0, Vec::len);
    if n <= p || p == 0 || x.len() != n || sigma.len() != n {
        return Err(Error::Numerical(format!(
            "weighted least squares needs more points ({n}) than parameters ({p})"
        )));
    }
    let a = DMatrix::from_fn(n, p, |i, j| x[i][j] / sigma[i]);
    let b = DVector::from_fn(n, |i, _| y[i] / sigma[i]);
    let ata = a.transpose() * &a;
    let cov = ata
        .try_inverse()
        .ok_or_else(|| Error::Numerical("singular least-squares design".into()))?;
    let beta = &cov * (a.transpose() * &b);
    let chi2 = (&b - &a * &beta).norm_squared();
    Ok(Wls {
        beta: beta.iter().cloned().collect(),
        cov,
        chi2,
        dof: n - p,
    })
}

/// Fit of a complex ratio `r(omega)` that should be 1:
/// `arg r = phase0 - omega delay` and `ln |r| = ln_gain0 + curvature omega^2`.
///
/// A pure time offset `d` gives `r = exp(-j omega d)`: `delay = d`, everything else 0. A
/// calibration factor gives a constant `ln_gain0`. A second-order sensor low-pass
/// `w^2 / (s^2 + 2 zeta w s + w^2)` well below its corner gives
/// `ln |r| ~ (1 - 2 zeta^2) (omega / w)^2` (curvature) and `arg r ~ -2 zeta omega / w`
/// (a delay of `2 zeta / w`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RatioFit {
    /// Fitted delay (positive: the numerator lags), s, and its standard error.
    pub delay_s: f64,
    pub delay_se_s: f64,
    /// Phase at zero frequency, rad.
    pub phase0_rad: f64,
    pub phase0_se_rad: f64,
    /// `ln |r|` at zero frequency.
    pub ln_gain0: f64,
    pub ln_gain0_se: f64,
    /// Change of `ln |r|` from 0 Hz to the highest frequency used (`curvature omega_max^2`).
    pub ln_gain_change: f64,
    pub ln_gain_change_se: f64,
    /// Wald statistic of all four coefficients against 0 (chi^2 with 4 dof under the null).
    pub wald_chi2: f64,
    /// Birge scale `s^2` applied to the covariance.
    pub scale: f64,
    pub n_points: usize,
    pub freq_min_hz: f64,
    pub freq_max_hz: f64,
}

/// The points of a ratio `r = num / den` of two estimates, and what their errors share.
///
/// Each estimate's relative error at bin `k` is `N_k / Y_k` (its response noise over the
/// response spectrum), so two bins `d` apart are correlated as `c(d) exp(-j (theta_k -
/// theta_l))`, `c` the window's bin correlation ([`crate::signal::correlation`]) and
/// `theta` the phase of the estimate (the force's phase is nearly the same at neighbouring
/// bins, as the impact sits at the block's start). `parts[k][i] = eps_i exp(-j theta_i)`
/// carries both for estimate `i`; the ratio's `ln r` errs by the difference of the two.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RatioPoints {
    pub omega_rad_s: Vec<f64>,
    pub ratio: Vec<Complex64>,
    /// Standard deviation of `ln |r|` and of `arg r` at each point, `sqrt(eps_1^2 + eps_2^2)`.
    pub sigma: Vec<f64>,
    /// Bin of each point on the estimates' grid, ascending.
    pub bin: Vec<usize>,
    pub parts: Vec<[Complex64; 2]>,
}

impl RatioPoints {
    /// Adds the point at `bin`: `num` and `den` are each the value divided and its `eps`.
    pub fn push(
        &mut self,
        omega_rad_s: f64,
        bin: usize,
        num: (Complex64, f64),
        den: (Complex64, f64),
    ) {
        let part = |(h, eps): (Complex64, f64)| Complex64::from_polar(eps, -h.arg());
        self.omega_rad_s.push(omega_rad_s);
        self.ratio.push(num.0 / den.0);
        self.sigma.push(num.1.hypot(den.1));
        self.bin.push(bin);
        self.parts.push([part(num), part(den)]);
    }

    pub fn len(&self) -> usize {
        self.ratio.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ratio.is_empty()
    }

    /// Correlation `rho_kl` of the complex `ln r` errors of points `k` and `l`, given the
    /// window's `corr[d] = c(d)` (zero beyond its end).
    fn correlation(&self, k: usize, l: usize, corr: &[Complex64]) -> Complex64 {
        let d = self.bin[k].abs_diff(self.bin[l]);
        let Some(&c) = corr.get(d) else {
            return Complex64::new(0.0, 0.0);
        };
        let c = if self.bin[k] >= self.bin[l] {
            c
        } else {
            c.conj()
        };
        let shared: Complex64 = (0..2)
            .map(|i| self.parts[k][i] * self.parts[l][i].conj())
            .sum();
        c * shared / (self.sigma[k] * self.sigma[l])
    }
}

/// Fits [`RatioFit`] to `ln r` of `points` (phase unwrapped about the mean direction),
/// whose errors are correlated between bins as the window's `corr[d] = c(d)` says
/// (`[1]`: independent points).
///
/// The coefficients are the weighted least-squares estimates; their covariance is the
/// sandwich `A^-1 B A^-1` with `A = X^T W X` and `B = X^T W^(1/2) R W^(1/2) X`, `R` the
/// correlation of the stacked real errors `(ln|r|, arg r)`: for complex circular errors
/// with correlation `rho_kl`, `cov(ln|r|_k, ln|r|_l) = cov(arg_k, arg_l) = Re rho_kl` and
/// `cov(ln|r|_k, arg_l) = -Im rho_kl` (in units of `sigma_k sigma_l`). Independent points
/// give `B = A`, the textbook `(X^T W X)^-1`. The Wald statistic uses the joint 4 x 4
/// covariance.
///
/// `smooth_rel_error` is the standard deviation `delta` of a smooth (slowly varying over
/// the fitted range) relative error of the ratio that the per-point noise does not
/// describe: estimator bias. It adds `delta^2` to the variance of `phase0` and
/// `ln_gain0`, `(delta / omega_max)^2` to that of the slope and
/// `(delta / omega_max^2)^2` to that of the curvature: a relative error of size `delta`
/// in gain and phase anywhere in `[0, omega_max]` moves each coefficient by about that.
pub fn fit_ratio(
    points: &RatioPoints,
    corr: &[Complex64],
    smooth_rel_error: f64,
) -> Result<RatioFit> {
    let n = points.len();
    let (omega_rad_s, ratio, sigma) = (&points.omega_rad_s, &points.ratio, &points.sigma);
    let lengths = [
        omega_rad_s.len(),
        sigma.len(),
        points.bin.len(),
        points.parts.len(),
    ];
    if n < 4 || lengths.iter().any(|&l| l != n) {
        return Err(Error::Numerical(format!(
            "ratio fit needs at least 4 points, each with its frequency, sigma, bin and parts; got {n} ratios and {lengths:?}"
        )));
    }
    // mean direction, then phases relative to it (no wrap for spreads below pi)
    let mean: Complex64 = ratio
        .iter()
        .zip(sigma)
        .map(|(r, s)| r / r.norm() / (s * s))
        .sum();
    let m = mean.arg();
    let rot = Complex64::from_polar(1.0, -m);
    let phase: Vec<f64> = ratio.iter().map(|r| m + (r * rot).arg()).collect();
    let lnmag: Vec<f64> = ratio.iter().map(|r| r.norm().ln()).collect();
    let xp: Vec<Vec<f64>> = omega_rad_s.iter().map(|&w| vec![1.0, w]).collect();
    let xm: Vec<Vec<f64>> = omega_rad_s.iter().map(|&w| vec![1.0, w * w]).collect();
    let fp = wls(&xp, &phase, sigma)?;
    let fm = wls(&xm, &lnmag, sigma)?;
    let scale = ((fp.chi2 + fm.chi2) / (fp.dof + fm.dof) as f64).max(1.0);
    let w_max = omega_rad_s.iter().cloned().fold(0.0, f64::max);
    let w_min = omega_rad_s.iter().cloned().fold(f64::INFINITY, f64::min);
    // coefficients (g0, g2, p0, p1)
    let meat = sandwich_meat(points, corr, &xm, &xp);
    let mut a_inv = DMatrix::zeros(4, 4);
    a_inv.view_mut((0, 0), (2, 2)).copy_from(&fm.cov);
    a_inv.view_mut((2, 2), (2, 2)).copy_from(&fp.cov);
    let d2 = smooth_rel_error * smooth_rel_error;
    let smooth = DVector::from_vec(vec![d2, d2 / w_max.powi(4), d2, d2 / w_max.powi(2)]);
    let cov = &a_inv * meat * &a_inv * scale + DMatrix::from_diagonal(&smooth);
    let beta = DVector::from_vec(vec![fm.beta[0], fm.beta[1], fp.beta[0], fp.beta[1]]);
    let inv = cov
        .clone()
        .try_inverse()
        .ok_or_else(|| Error::Numerical("singular ratio-fit covariance".into()))?;
    let two_pi = 2.0 * std::f64::consts::PI;
    Ok(RatioFit {
        delay_s: -fp.beta[1],
        delay_se_s: cov[(3, 3)].sqrt(),
        phase0_rad: fp.beta[0],
        phase0_se_rad: cov[(2, 2)].sqrt(),
        ln_gain0: fm.beta[0],
        ln_gain0_se: cov[(0, 0)].sqrt(),
        ln_gain_change: fm.beta[1] * w_max * w_max,
        ln_gain_change_se: cov[(1, 1)].sqrt() * w_max * w_max,
        wald_chi2: (beta.transpose() * inv * &beta)[(0, 0)],
        scale,
        n_points: n,
        freq_min_hz: w_min / two_pi,
        freq_max_hz: w_max / two_pi,
    })
}

/// `B = X^T W^(1/2) R W^(1/2) X` of [`fit_ratio`] for the stacked design
/// `(ln|r|: xm, arg r: xp)`, over the pairs of points within `corr`'s reach.
fn sandwich_meat(
    points: &RatioPoints,
    corr: &[Complex64],
    xm: &[Vec<f64>],
    xp: &[Vec<f64>],
) -> DMatrix<f64> {
    let n = points.len();
    let row = |k: usize| -> [f64; 4] {
        let s = points.sigma[k];
        [xm[k][0] / s, xm[k][1] / s, xp[k][0] / s, xp[k][1] / s]
    };
    let mut b = DMatrix::zeros(4, 4);
    for k in 0..n {
        let ak = row(k);
        for l in 0..n {
            if points.bin[k].abs_diff(points.bin[l]) >= corr.len() {
                continue;
            }
            let rho = if k == l {
                Complex64::new(1.0, 0.0)
            } else {
                points.correlation(k, l, corr)
            };
            let al = row(l);
            for i in 0..2 {
                for j in 0..2 {
                    b[(i, j)] += ak[i] * al[j] * rho.re;
                    b[(2 + i, 2 + j)] += ak[2 + i] * al[2 + j] * rho.re;
                    b[(i, 2 + j)] -= ak[i] * al[2 + j] * rho.im;
                    b[(2 + j, i)] -= ak[i] * al[2 + j] * rho.im;
                }
            }
        }
    }
    b
}

/// One channel's data for [`fit_pole`]: receptance-like values (see
/// [`super::SegmentFrf::receptance_like`]) and the standard deviation of their real and
/// imaginary parts.
#[derive(Debug, Clone, PartialEq)]
pub struct PoleData {
    pub omega_rad_s: Vec<f64>,
    pub h: Vec<Complex64>,
    pub sigma: Vec<f64>,
}

/// A pole shared by several channels in one band.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PoleFit {
    pub omega_n_rad_s: f64,
    pub omega_n_se_rad_s: f64,
    pub xi: f64,
    pub xi_se: f64,
    /// Correlation of the two estimates.
    pub corr: f64,
    pub chi2: f64,
    pub dof: usize,
    /// Birge scale `s^2` applied to the covariance.
    pub scale: f64,
}

impl PoleFit {
    /// Adds a smooth relative error `delta` of the FRF over the band (estimator bias) to
    /// the standard errors: such an error moves the pole by about `delta` times the
    /// half-power half-width in frequency (`delta xi omega_n`) and by `delta xi` in damping,
    /// `xi` the damping of the fitted (windowed) pole.
    pub fn with_smooth_error(&self, delta: f64) -> PoleFit {
        let fw = delta * self.xi * self.omega_n_rad_s;
        let fx = delta * self.xi;
        let sw = (self.omega_n_se_rad_s.powi(2) + fw * fw).sqrt();
        let sx = (self.xi_se.powi(2) + fx * fx).sqrt();
        PoleFit {
            omega_n_se_rad_s: sw,
            xi_se: sx,
            corr: self.corr * self.omega_n_se_rad_s * self.xi_se / (sw * sx),
            ..*self
        }
    }

    /// The pole without the exponential window (the window adds `1/tau` to the decay
    /// rate; [`crate::signal::unwindowed_pole`]), standard errors propagated to first order
    /// by central differences.
    pub fn unwindowed(&self, tau_s: Option<f64>) -> PoleFit {
        let Some(tau) = tau_s else { return *self };
        let f = |w: f64, x: f64| crate::signal::unwindowed_pole(w, x, tau);
        let (w0, x0) = f(self.omega_n_rad_s, self.xi);
        let hw = 1e-6 * self.omega_n_rad_s;
        let hx = 1e-6 * self.xi.max(1e-6);
        let (a, b) = f(self.omega_n_rad_s + hw, self.xi);
        let (c, d) = f(self.omega_n_rad_s - hw, self.xi);
        let (e, g) = f(self.omega_n_rad_s, self.xi + hx);
        let (h, i) = f(self.omega_n_rad_s, self.xi - hx);
        let j = Matrix2::new(
            (a - c) / (2.0 * hw),
            (e - h) / (2.0 * hx),
            (b - d) / (2.0 * hw),
            (g - i) / (2.0 * hx),
        );
        let cov_in = Matrix2::new(
            self.omega_n_se_rad_s.powi(2),
            self.corr * self.omega_n_se_rad_s * self.xi_se,
            self.corr * self.omega_n_se_rad_s * self.xi_se,
            self.xi_se.powi(2),
        );
        let cov = j * cov_in * j.transpose();
        let (sw, sx) = (cov[(0, 0)].sqrt(), cov[(1, 1)].sqrt());
        PoleFit {
            omega_n_rad_s: w0,
            omega_n_se_rad_s: sw,
            xi: x0,
            xi_se: sx,
            corr: if sw > 0.0 && sx > 0.0 {
                cov[(0, 1)] / (sw * sx)
            } else {
                0.0
            },
            ..*self
        }
    }
}

/// Projected residuals of the model `A_c g(omega) + B_c + C_c x` per channel, with
/// `g = 1 / (omega_n^2 - omega^2 + 2 j xi omega_n omega)`, `x = omega / omega_ref - 1`;
/// the complex `A_c, B_c, C_c` are solved by weighted linear least squares (variable
/// projection: Golub & Pereyra 1973). Real and imaginary parts, each divided by sigma.
fn projected_residuals(
    data: &[PoleData],
    omega_n: f64,
    xi: f64,
    omega_ref: f64,
) -> Option<Vec<f64>> {
    let mut out = Vec::new();
    for ch in data {
        let n = ch.h.len();
        let rows: Vec<[Complex64; 3]> = ch
            .omega_rad_s
            .iter()
            .zip(&ch.sigma)
            .map(|(&w, &s)| {
                let g = Complex64::new(omega_n * omega_n - w * w, 2.0 * xi * omega_n * w).inv();
                [
                    g / s,
                    Complex64::new(1.0 / s, 0.0),
                    Complex64::new((w / omega_ref - 1.0) / s, 0.0),
                ]
            })
            .collect();
        // column scaling for conditioning
        let mut norms = [0.0f64; 3];
        for r in &rows {
            for j in 0..3 {
                norms[j] += r[j].norm_sqr();
            }
        }
        let norms = norms.map(|v| if v > 0.0 { v.sqrt() } else { 1.0 });
        let a = DMatrix::from_fn(n, 3, |i, j| rows[i][j] / norms[j]);
        let b = DVector::from_fn(n, |i, _| ch.h[i] / ch.sigma[i]);
        let coef = a.clone().svd(true, true).solve(&b, 1e-12).ok()?;
        let res = &b - &a * coef;
        for v in res.iter() {
            out.push(v.re);
            out.push(v.im);
        }
    }
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Fits one pole (natural frequency, damping ratio) shared by all channels, each channel
/// with its own complex residue and linear complex background, by Levenberg-Marquardt on
/// the projected residuals over `(ln omega_n, ln xi)`. The covariance of the two comes from
/// the projected Jacobian (which equals the Schur complement of the full Gauss-Newton
/// information, i.e. the linear parameters are marginalised), scaled as in the module docs.
pub fn fit_pole(data: &[PoleData], omega_n0_rad_s: f64, xi0: f64) -> Result<PoleFit> {
    let n_real: usize = data.iter().map(|c| 2 * c.h.len()).sum();
    let n_par = 2 + 6 * data.len();
    if data.is_empty() || n_real <= n_par + 2 {
        return Err(Error::Numerical(format!(
            "pole fit: {n_real} real data for {n_par} parameters"
        )));
    }
    let omega_ref = omega_n0_rad_s;
    let resid = |q: Vector2<f64>| projected_residuals(data, q[0].exp(), q[1].exp(), omega_ref);
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let jac = |q: Vector2<f64>, r0: &[f64]| -> Option<DMatrix<f64>> {
        let mut j = DMatrix::zeros(r0.len(), 2);
        let f = |q: &[f64], r: &mut [f64]| {
            let v = resid(Vector2::new(q[0], q[1]))
                .ok_or_else(|| Error::Numerical("pole fit: non-finite residuals".into()))?;
            r.copy_from_slice(&v);
            Ok(())
        };
        fd_jacobian(
            FdScheme::Central,
            q.as_slice(),
            &Bounds::unbounded(2),
            f,
            &mut j,
        )
        .ok()?;
        Some(j)
    };
    let mut q = Vector2::new(omega_n0_rad_s.ln(), xi0.clamp(1e-4, 0.3).ln());
    let mut r = resid(q).ok_or_else(|| Error::Numerical("pole fit: non-finite start".into()))?;
    let mut c = cost(&r);
    let mut mu = 1e-3;
    for _ in 0..100 {
        let j =
            jac(q, &r).ok_or_else(|| Error::Numerical("pole fit: non-finite Jacobian".into()))?;
        let jtj = j.transpose() * &j;
        let g = j.transpose() * DVector::from_column_slice(&r);
        let mut improved = false;
        let mut step_small = false;
        for _ in 0..20 {
            let mut m = jtj.clone();
            for d in 0..2 {
                m[(d, d)] *= 1.0 + mu;
            }
            let Some(delta) = m.try_inverse().map(|inv| -(inv * &g)) else {
                mu *= 10.0;
                continue;
            };
            // keep steps modest in log space
            let step = Vector2::new(delta[0].clamp(-0.05, 0.05), delta[1].clamp(-0.5, 0.5));
            let qn = q + step;
            if let Some(rn) = resid(qn) {
                let cn = cost(&rn);
                if cn < c {
                    step_small = step.norm() < 1e-10 || (c - cn) < 1e-12 * c;
                    q = qn;
                    r = rn;
                    c = cn;
                    mu = (mu * 0.3).max(1e-12);
                    improved = true;
                    break;
                }
            }
            mu *= 10.0;
        }
        if !improved || step_small {
            break;
        }
    }
    let j = jac(q, &r).ok_or_else(|| Error::Numerical("pole fit: non-finite Jacobian".into()))?;
    let cov_q = (j.transpose() * &j)
        .try_inverse()
        .ok_or_else(|| Error::Numerical("pole fit: singular information".into()))?;
    let dof = n_real - n_par;
    let scale = (c / dof as f64).max(1.0);
    let (wn, xi) = (q[0].exp(), q[1].exp());
    let (sq0, sq1) = (
        (cov_q[(0, 0)] * scale).sqrt(),
        (cov_q[(1, 1)] * scale).sqrt(),
    );
    Ok(PoleFit {
        omega_n_rad_s: wn,
        omega_n_se_rad_s: wn * sq0,
        xi,
        xi_se: xi * sq1,
        corr: cov_q[(0, 1)] * scale / (sq0 * sq1),
        chi2: c,
        dof,
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    fn ratio_points(omega_rad_s: &[f64], ratio: &[Complex64], sigma: &[f64]) -> RatioPoints {
        let mut pts = RatioPoints::default();
        for (k, ((&w, &r), &s)) in omega_rad_s.iter().zip(ratio).zip(sigma).enumerate() {
            let e = s / std::f64::consts::SQRT_2;
            pts.push(w, k, (r, e), (Complex64::new(1.0, 0.0), e));
        }
        pts
    }

    #[test]
    fn ratio_fit_recovers_delay_and_gain() {
        let w: Vec<f64> = (0..60).map(|i| 5.0 + 0.5 * i as f64).collect();
        let r: Vec<Complex64> = w
            .iter()
            .map(|&w| Complex64::from_polar((0.02 + 1e-4 * w * w).exp(), 0.1 - 0.012 * w))
            .collect();
        let pts = ratio_points(&w, &r, &[1e-3; 60]);
        let one = [Complex64::new(1.0, 0.0)];
        let f = fit_ratio(&pts, &one, 0.0).unwrap();
        assert!((f.delay_s - 0.012).abs() < 1e-12, "{f:?}");
        assert!((f.phase0_rad - 0.1).abs() < 1e-10);
        assert!((f.ln_gain0 - 0.02).abs() < 1e-10);
        assert!((f.ln_gain_change - 1e-4 * w[59] * w[59]).abs() < 1e-9);
        assert!(f.wald_chi2 > 1e4);
        // Independent points: the textbook covariance (X^T W X)^-1 of the slope.
        let xp: Vec<Vec<f64>> = w.iter().map(|&w| vec![1.0, w]).collect();
        let phase: Vec<f64> = r.iter().map(|r| r.arg()).collect();
        let plain = wls(&xp, &phase, &[1e-3; 60]).unwrap();
        assert!(
            (f.delay_se_s - plain.cov[(1, 1)].sqrt()).abs()
                < 1e-12 * f.delay_se_s.max(1e-30) + 1e-18
        );
        // Fully correlated neighbours inflate it.
        let half = [Complex64::new(1.0, 0.0), Complex64::new(0.5, 0.0)];
        let g = fit_ratio(&pts, &half, 0.0).unwrap();
        assert!(
            g.delay_se_s > 1.3 * f.delay_se_s,
            "{} {}",
            g.delay_se_s,
            f.delay_se_s
        );
    }

    /// Oracle: white noise through the default hammer window (`T / tau = ln 20`),
    /// transformed directly at 60 bins across a resonance whose windowed pole spans about a
    /// bin (the estimate's phase turns by pi there), for the numerator and denominator
    /// estimates of a ratio whose truth is 1. 400 seeded draws: the Wald test with the
    /// window's bin correlation rejects at 5 % in 20 +- 4.4 draws (the Birge scale,
    /// floored at 1, can only lower it; bound 7-33; 22 measured); with the points taken as
    /// independent it rejects in 235 (asserted above 150). Without the estimate's phase in
    /// the correlation (`parts` real) it rejects in 221: near the peak, where the points
    /// weigh most, the phase turns between neighbouring bins and `Re rho` follows it.
    #[test]
    fn ratio_wald_test_holds_its_level_over_windowed_noise() {
        use crate::signal::correlation::{exp_window_bin_correlation_complex, WindowedNoise};
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        let (first_bin, n) = (20, 60);
        let noise = WindowedNoise::new(250.0, 4.0, first_bin, n);
        let (tau_s, df_hz) = (noise.tau_s, noise.df_hz);
        let corr: Vec<Complex64> = (0..=256)
            .map(|d| exp_window_bin_correlation_complex(Some(tau_s), 1.0 / df_hz, df_hz, d))
            .collect();
        let two_pi = 2.0 * std::f64::consts::PI;
        let (wn, xi) = (two_pi * 12.5, 0.01);
        let omega: Vec<f64> = (0..n)
            .map(|k| two_pi * df_hz * (first_bin + k) as f64)
            .collect();
        // the windowed estimate samples H at omega - j / tau
        let y: Vec<Complex64> = omega
            .iter()
            .map(|&om| {
                let s = Complex64::new(om, -1.0 / tau_s);
                Complex64::new(wn * wn, 0.0)
                    / (wn * wn - s * s + Complex64::new(0.0, 2.0 * xi * wn) * s)
            })
            .collect();
        let mut rng = ChaCha8Rng::seed_from_u64(20261202);
        // each part's sd is 0.01 / |y| of the relative error
        let gain = 0.01;
        let critical = ChiSquared::new(4.0).unwrap().inverse_cdf(0.95);
        let one = [Complex64::new(1.0, 0.0)];
        let (mut rejected, mut rejected_independent) = (0, 0);
        let draws = 400;
        for _ in 0..draws {
            let (n1, n2) = (noise.draw(&mut rng), noise.draw(&mut rng));
            let mut pts = RatioPoints::default();
            for k in 0..n {
                let (a, b) = (y[k] + gain * n1[k], y[k] + gain * n2[k]);
                let eps = gain / y[k].norm();
                pts.omega_rad_s.push(omega[k]);
                pts.ratio.push(a / b);
                pts.sigma.push(eps * std::f64::consts::SQRT_2);
                pts.bin.push(first_bin + k);
                let part = Complex64::from_polar(eps, -y[k].arg());
                pts.parts.push([part, part]);
            }
            rejected += usize::from(fit_ratio(&pts, &corr, 0.0).unwrap().wald_chi2 > critical);
            rejected_independent +=
                usize::from(fit_ratio(&pts, &one, 0.0).unwrap().wald_chi2 > critical);
        }
        eprintln!("rejected {rejected}, as independent {rejected_independent} of {draws}");
        assert!((7..=33).contains(&rejected), "{rejected} of {draws}");
        assert!(
            rejected_independent > 150,
            "{rejected_independent} of {draws}"
        );
    }

    #[test]
    fn pole_fit_recovers_pole_within_its_standard_error() {
        // two channels, residues of different sign and phase, linear background, noise 1 %
        let (wn, xi) = (2.0 * std::f64::consts::PI * 2.7, 0.012);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let nd = Normal::new(0.0, 1.0).unwrap();
        let mut z_w = Vec::new();
        for _ in 0..30 {
            let data: Vec<PoleData> = [(1.0, 0.01), (-0.4, 0.02)]
                .iter()
                .map(|&(a, bg)| {
                    let om: Vec<f64> = (0..25).map(|i| wn * (0.94 + 0.005 * i as f64)).collect();
                    let h0: Vec<Complex64> = om
                        .iter()
                        .map(|&w| {
                            Complex64::new(a, 0.1 * a)
                                / Complex64::new(wn * wn - w * w, 2.0 * xi * wn * w)
                                + bg * (1.0 + w / wn)
                        })
                        .collect();
                    let sigma: Vec<f64> = h0.iter().map(|h| 0.01 * h.norm()).collect();
                    let h = h0
                        .iter()
                        .zip(&sigma)
                        .map(|(h, s)| {
                            h + Complex64::new(s * nd.sample(&mut rng), s * nd.sample(&mut rng))
                        })
                        .collect();
                    PoleData {
                        omega_rad_s: om,
                        h,
                        sigma,
                    }
                })
                .collect();
            let fit = fit_pole(&data, wn * 1.01, 0.02).unwrap();
            z_w.push((fit.omega_n_rad_s - wn) / fit.omega_n_se_rad_s);
            assert!(((fit.xi - xi) / fit.xi_se).abs() < 4.5, "{fit:?}");
        }
        // mean of z^2 over 30 fits: chi^2_30 / 30, 99.9 % interval about [0.39, 2.0]
        // (scale floored at 1 can only lower it)
        let mz2 = z_w.iter().map(|z| z * z).sum::<f64>() / 30.0;
        assert!((0.3..2.0).contains(&mz2), "mean z^2 {mz2}");
    }

    #[test]
    fn unwindowed_pole_moves_decay_rate() {
        let p = PoleFit {
            omega_n_rad_s: 10.0,
            omega_n_se_rad_s: 0.01,
            xi: 0.02,
            xi_se: 0.001,
            corr: 0.0,
            chi2: 0.0,
            dof: 1,
            scale: 1.0,
        };
        let u = p.unwindowed(Some(20.0));
        // sigma = 0.2 - 0.05 = 0.15; omega_d^2 = 100 (1 - 4e-4)
        let wn = (0.15f64.powi(2) + 100.0 * (1.0 - 4e-4)).sqrt();
        assert!((u.omega_n_rad_s - wn).abs() < 1e-12);
        assert!((u.xi - 0.15 / wn).abs() < 1e-12);
        assert!((u.xi_se - 0.001 * 10.0 / wn).abs() < 1e-6);
        assert_eq!(p.unwindowed(None), p);
    }
}
