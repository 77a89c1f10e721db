//! A single pole (SDOF) fitted to several channels in one band, for the pole checks
//! ([`super::poles`]). Covariances are scaled as in [`super::fit`] (the Birge ratio,
//! floored at 1).

use crate::error::{Error, Result};
use crate::update::lsq::{fd_jacobian, Bounds, FdScheme};
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use num_complex::Complex64;

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
