//! Light-rail wheel, measured accelerance (`wheel-frf`): data and the coherence-weighted
//! modal likelihood with the linear parameters integrated out.
//!
//! # Model (one frequency band, all channels)
//! `H_c(w) = sum_r A_cr g_r(w) + B_c + D_c (w / w_0)^2`, with the accelerance mode term
//! `g_r(w) = -w^2 / (w_r^2 - w^2 + 2 j xi_r w_r w)`, complex residues `A_cr` (modal
//! constants, complex to allow non-proportional damping and sensor phase), and complex
//! out-of-band residual terms: `B_c` (modes below the band: the mass line of accelerance)
//! and `D_c` (modes above: the stiffness line, `-w^2` times a residual flexibility).
//! `w_0` is the band centre.
//!
//! # Likelihood
//! Each measured `H_c(w_k)` is complex Gaussian (circular) around the model with variance
//! `s^2 v_ck`, `v_ck = |H_ck|^2 (1 - gamma_ck^2) / gamma_ck^2` from the coherence
//! `gamma^2` (the H1 estimate from `n_d` averages has `E|dH|^2 = |H|^2 (1 - gamma^2) /
//! (n_d gamma^2)`; `s^2` stands for `1 / n_d` and for model error, and is sampled as
//! `ln s`). `1 - gamma^2` is floored at [`COHERENCE_FLOOR`].
//!
//! Given the poles and `s`, the model is linear in `theta_c = (A_c1.., B_c, D_c)`
//! (`p` complex values per channel). With a flat prior they integrate out exactly: with
//! whitened `y~ = y / sqrt(v)`, `G~ = G / sqrt(v)`,
//! `ln L_c = -(N - p) ln(pi s^2) - ln det(G~^H G~) - RSS_c / s^2` (up to a constant),
//! `RSS_c` the weighted least-squares residual. The sampler then explores only the poles
//! and `s`; the residues given the poles are complex Gaussian with mean `theta^_c` and
//! covariance `s^2 (G~^H G~)^-1`, drawn exactly for every posterior draw.

use std::path::Path;

use num_complex::Complex64;

use super::mat::MatData;
use crate::error::{Error, Result};
use crate::mcmc::LogDensity;

/// File name in the dataset folder.
pub const FILE: &str = "LRV_wheel_FRF.mat";
/// Rim accelerometers.
pub const N_CHANNELS: usize = 12;
/// Floor on `1 - gamma^2` (coherences of 0.9999 occur at the strongest resonance).
pub const COHERENCE_FLOOR: f64 = 1e-4;

/// Measured accelerance: frequency grid, FRF and coherence per channel.
#[derive(Debug, Clone)]
pub struct WheelData {
    pub freq_hz: Vec<f64>,
    /// `frf[c][k]`, (m/s^2)/N.
    pub frf: Vec<Vec<Complex64>>,
    /// `coherence[c][k]` (magnitude-squared, 0..1).
    pub coherence: Vec<Vec<f64>>,
}

/// Reads `freq`, `frf` and `cohe` from `dir/LRV_wheel_FRF.mat` and checks their shapes,
/// the grid (ascending) and the coherence range.
pub fn load(dir: &Path) -> Result<WheelData> {
    let path = dir.join(FILE);
    let mat = MatData::open(&path)?;
    let freq_hz = mat.vector("freq", None)?;
    let n = freq_hz.len();
    if n < 10 || freq_hz.windows(2).any(|w| w[1] <= w[0]) {
        return Err(Error::invalid(
            &path,
            "variable `freq` must hold at least 10 ascending frequencies",
        ));
    }
    let frf = mat.complex("frf")?;
    let coh = mat.real("cohe")?;
    for (name, rows, cols) in [("frf", frf.rows, frf.cols), ("cohe", coh.rows, coh.cols)] {
        if (rows, cols) != (n, N_CHANNELS) {
            return Err(Error::invalid(
                &path,
                format!(
                    "variable `{name}` is {rows} x {cols}; expected {n} frequencies x \
                     {N_CHANNELS} channels (as `freq`)"
                ),
            ));
        }
    }
    if let Some(i) = coh
        .data
        .iter()
        .position(|g| !(0.0..=1.0 + 1e-9).contains(g))
    {
        return Err(Error::invalid(
            &path,
            format!(
                "variable `cohe`: value {} at frequency {} Hz, channel {} is outside [0, 1]",
                coh.data[i],
                freq_hz[i % n],
                i / n + 1
            ),
        ));
    }
    Ok(WheelData {
        frf: (0..N_CHANNELS).map(|c| frf.column(c).to_vec()).collect(),
        coherence: (0..N_CHANNELS).map(|c| coh.column(c).to_vec()).collect(),
        freq_hz,
    })
}

/// One analysis band and its starting guesses.
#[derive(Debug, Clone, PartialEq)]
pub struct BandSpec {
    pub label: &'static str,
    pub lo_hz: f64,
    pub hi_hz: f64,
    /// Initial natural frequencies (Hz), ascending; one per mode in the band.
    pub f_guess_hz: Vec<f64>,
    /// Initial damping ratio of every mode.
    pub xi_guess: f64,
}

/// The measured data of one band, with the variance weights.
#[derive(Debug, Clone)]
pub struct BandData {
    pub freq_hz: Vec<f64>,
    /// `y[c][k]`.
    pub y: Vec<Vec<Complex64>>,
    /// `v[c][k] = |y|^2 max(1 - gamma^2, floor) / gamma^2`.
    pub v: Vec<Vec<f64>>,
}

impl BandData {
    /// The bins of `data` in `[lo_hz, hi_hz]`.
    pub fn extract(data: &WheelData, lo_hz: f64, hi_hz: f64) -> Result<Self> {
        let idx: Vec<usize> = (0..data.freq_hz.len())
            .filter(|&k| data.freq_hz[k] >= lo_hz && data.freq_hz[k] <= hi_hz)
            .collect();
        if idx.len() < 10 {
            return Err(Error::Usage(format!(
                "band {lo_hz}-{hi_hz} Hz holds {} frequency bins; need at least 10",
                idx.len()
            )));
        }
        let mut v = vec![Vec::with_capacity(idx.len()); data.frf.len()];
        for (c, vc) in v.iter_mut().enumerate() {
            for &k in &idx {
                let g = data.coherence[c][k].clamp(1e-6, 1.0);
                let y2 = data.frf[c][k].norm_sqr().max(1e-300);
                vc.push(y2 * (1.0 - g).max(COHERENCE_FLOOR) / g);
            }
        }
        Ok(BandData {
            freq_hz: idx.iter().map(|&k| data.freq_hz[k]).collect(),
            y: data
                .frf
                .iter()
                .map(|h| idx.iter().map(|&k| h[k]).collect())
                .collect(),
            v,
        })
    }

    /// Complex data points (bins x channels).
    pub fn n_points(&self) -> usize {
        self.freq_hz.len() * self.y.len()
    }
}

/// Accelerance mode term `g(w) = -w^2 / (w_n^2 - w^2 + 2 j xi w_n w)`.
pub fn mode_term(omega: f64, omega_n: f64, xi: f64) -> Complex64 {
    -omega * omega
        / Complex64::new(
            omega_n * omega_n - omega * omega,
            2.0 * xi * omega_n * omega,
        )
}

/// The weighted least-squares solution of one channel.
#[derive(Debug, Clone)]
pub struct ChannelFit {
    /// `theta^ = (A_1.., B, D)`.
    pub theta: Vec<Complex64>,
    /// Lower Cholesky factor `L` of `G~^H G~ = L L^H` (row-major, p x p).
    pub chol: Vec<Complex64>,
    pub rss: f64,
    /// `ln det(G~^H G~) = 2 sum ln L_ii`.
    pub ln_det: f64,
}

/// Complex Cholesky `A = L L^H` of a Hermitian positive definite `p x p` (row-major).
pub fn cholesky(a: &[Complex64], p: usize) -> Option<Vec<Complex64>> {
    let mut l = vec![Complex64::new(0.0, 0.0); p * p];
    for i in 0..p {
        for j in 0..=i {
            let mut s = a[i * p + j];
            for k in 0..j {
                s -= l[i * p + k] * l[j * p + k].conj();
            }
            if i == j {
                if !(s.re > 0.0 && s.re.is_finite()) {
                    return None;
                }
                l[i * p + i] = Complex64::new(s.re.sqrt(), 0.0);
            } else {
                l[i * p + j] = s / l[j * p + j].re;
            }
        }
    }
    Some(l)
}

/// Solves `L L^H x = b`.
pub fn chol_solve(l: &[Complex64], p: usize, b: &[Complex64]) -> Vec<Complex64> {
    let mut z = b.to_vec();
    for i in 0..p {
        for k in 0..i {
            let t = l[i * p + k] * z[k];
            z[i] -= t;
        }
        z[i] /= l[i * p + i].re;
    }
    for i in (0..p).rev() {
        for k in i + 1..p {
            let t = l[k * p + i].conj() * z[k];
            z[i] -= t;
        }
        z[i] /= l[i * p + i].re;
    }
    z
}

/// The band likelihood. Coordinates: `f_1, ln xi_1, ..., f_m, ln xi_m, ln s` (Hz,
/// dimensionless); prior uniform in them within [`BandLikelihood::bounds`], with the
/// natural frequencies in ascending order (no label switching within a close pair).
#[derive(Debug, Clone)]
pub struct BandLikelihood {
    pub spec: BandSpec,
    pub data: BandData,
    omega0: f64,
    bounds: Vec<(f64, f64)>,
}

/// Prior range of the damping ratio.
pub const XI_RANGE: (f64, f64) = (1e-4, 0.2);
/// Prior range of the noise scale `s`.
pub const S_RANGE: (f64, f64) = (1e-3, 1e4);

impl BandLikelihood {
    /// The likelihood of `spec`'s band of `data`. Natural frequencies may range over the
    /// band.
    pub fn new(data: &WheelData, spec: BandSpec) -> Result<Self> {
        let band = BandData::extract(data, spec.lo_hz, spec.hi_hz)?;
        let mut bounds = Vec::new();
        for _ in &spec.f_guess_hz {
            bounds.push((spec.lo_hz, spec.hi_hz));
            bounds.push((XI_RANGE.0.ln(), XI_RANGE.1.ln()));
        }
        bounds.push((S_RANGE.0.ln(), S_RANGE.1.ln()));
        Ok(BandLikelihood {
            omega0: std::f64::consts::PI * (spec.lo_hz + spec.hi_hz),
            spec,
            data: band,
            bounds,
        })
    }

    /// The same band restricted to the given channels (0-based).
    pub fn with_channels(&self, channels: &[usize]) -> BandLikelihood {
        let mut out = self.clone();
        out.data.y = channels.iter().map(|&c| self.data.y[c].clone()).collect();
        out.data.v = channels.iter().map(|&c| self.data.v[c].clone()).collect();
        out
    }

    /// Modes in the band.
    pub fn n_modes(&self) -> usize {
        self.spec.f_guess_hz.len()
    }

    /// Complex unknowns per channel: residues and the two residual terms.
    pub fn n_linear(&self) -> usize {
        self.n_modes() + 2
    }

    /// Prior box of the coordinates.
    pub fn bounds(&self) -> &[(f64, f64)] {
        &self.bounds
    }

    /// The basis at bin `k` for poles `(f_hz, xi)`.
    pub fn basis_row(&self, k: usize, poles: &[(f64, f64)], row: &mut [Complex64]) {
        let two_pi = 2.0 * std::f64::consts::PI;
        let w = two_pi * self.data.freq_hz[k];
        for (r, &(f, xi)) in poles.iter().enumerate() {
            row[r] = mode_term(w, two_pi * f, xi);
        }
        let m = poles.len();
        row[m] = Complex64::new(1.0, 0.0);
        row[m + 1] = Complex64::new((w / self.omega0).powi(2), 0.0);
    }

    /// Weighted least squares of every channel at the given poles; `None` when the
    /// basis is rank-deficient.
    pub fn fit_channels(&self, poles: &[(f64, f64)]) -> Option<Vec<ChannelFit>> {
        let p = poles.len() + 2;
        let n = self.data.freq_hz.len();
        let mut rows = vec![Complex64::new(0.0, 0.0); n * p];
        for k in 0..n {
            self.basis_row(k, poles, &mut rows[k * p..(k + 1) * p]);
        }
        let mut fits = Vec::with_capacity(self.data.y.len());
        for (y, v) in self.data.y.iter().zip(&self.data.v) {
            let mut a = vec![Complex64::new(0.0, 0.0); p * p];
            let mut b = vec![Complex64::new(0.0, 0.0); p];
            for k in 0..n {
                let w = 1.0 / v[k];
                let g = &rows[k * p..(k + 1) * p];
                for i in 0..p {
                    let gi = g[i].conj() * w;
                    b[i] += gi * y[k];
                    for j in 0..=i {
                        a[i * p + j] += gi * g[j];
                    }
                }
            }
            for i in 0..p {
                for j in 0..i {
                    a[j * p + i] = a[i * p + j].conj();
                }
            }
            let l = cholesky(&a, p)?;
            let theta = chol_solve(&l, p, &b);
            let mut rss = 0.0;
            for k in 0..n {
                let g = &rows[k * p..(k + 1) * p];
                let model: Complex64 = g.iter().zip(&theta).map(|(g, t)| g * t).sum();
                rss += (y[k] - model).norm_sqr() / v[k];
            }
            let ln_det = (0..p).map(|i| 2.0 * l[i * p + i].re.ln()).sum();
            fits.push(ChannelFit {
                theta,
                chol: l,
                rss,
                ln_det,
            });
        }
        Some(fits)
    }

    /// Poles `(f_hz, xi)` of a coordinate vector.
    pub fn poles(&self, theta: &[f64]) -> Vec<(f64, f64)> {
        (0..self.n_modes())
            .map(|r| (theta[2 * r], theta[2 * r + 1].exp()))
            .collect()
    }

    fn in_support(&self, theta: &[f64]) -> bool {
        let inside = theta
            .iter()
            .zip(&self.bounds)
            .all(|(t, (lo, hi))| *t >= *lo && *t <= *hi);
        let ordered = (1..self.n_modes()).all(|r| theta[2 * r] > theta[2 * r - 2]);
        inside && ordered
    }

    /// Log marginal likelihood from channel fits and `s`.
    pub fn ln_marginal(&self, fits: &[ChannelFit], s: f64) -> f64 {
        let n = self.data.freq_hz.len() as f64;
        let p = self.n_linear() as f64;
        let ln_pi_s2 = (std::f64::consts::PI * s * s).ln();
        fits.iter()
            .map(|f| -(n - p) * ln_pi_s2 - f.ln_det - f.rss / (s * s))
            .sum()
    }
}

impl LogDensity for BandLikelihood {
    fn dim(&self) -> usize {
        2 * self.n_modes() + 1
    }

    fn ln_density(&self, theta: &[f64]) -> Result<f64> {
        if !self.in_support(theta) {
            return Ok(f64::NEG_INFINITY);
        }
        let s = theta[2 * self.n_modes()].exp();
        match self.fit_channels(&self.poles(theta)) {
            Some(fits) => Ok(self.ln_marginal(&fits, s)),
            None => Ok(f64::NEG_INFINITY),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn complex_cholesky_solves_a_hermitian_system() {
        let c = |re, im| Complex64::new(re, im);
        let a = vec![c(4.0, 0.0), c(1.0, -1.0), c(1.0, 1.0), c(3.0, 0.0)];
        let l = cholesky(&a, 2).unwrap();
        let x = [c(1.0, 2.0), c(-0.5, 0.25)];
        let b = [a[0] * x[0] + a[1] * x[1], a[2] * x[0] + a[3] * x[1]];
        let y = chol_solve(&l, 2, &b);
        for (u, v) in y.iter().zip(&x) {
            assert!((u - v).norm() < 1e-14);
        }
        assert!(cholesky(&[c(-1.0, 0.0)], 1).is_none());
    }

    /// The real file (skipped without ../shared): shapes, grid, and the strongest
    /// resonance near 667 Hz with its n = 2 node at channel 4 (45 degrees).
    #[test]
    fn reads_the_real_wheel_file() {
        let Some(dir) = crate::real::shared_dataset(crate::real::Dataset::WheelFrf) else {
            return;
        };
        let d = load(&dir).unwrap();
        assert_eq!(d.freq_hz.len(), 15001);
        assert!((d.freq_hz[1] - 1.0 / 3.0).abs() < 1e-3);
        let k = (1900..2100)
            .max_by(|&a, &b| d.frf[0][a].norm().total_cmp(&d.frf[0][b].norm()))
            .unwrap();
        assert!((d.freq_hz[k] - 667.3).abs() < 1.0, "{}", d.freq_hz[k]);
        assert!(d.frf[3][k].norm() < 0.1 * d.frf[0][k].norm());
    }

    #[test]
    fn load_rejects_wrong_shapes() {
        let dir = tempfile::tempdir().unwrap();
        let freq: Vec<f64> = (0..12).map(f64::from).collect();
        let bytes = crate::real::mat::write_test_mat(&[
            ("freq", 6, 12, 1, &freq),
            ("frf", 6, 12, 2, &[0.0; 24]),
            ("cohe", 6, 12, 12, &[0.5; 144]),
        ]);
        std::fs::write(dir.path().join(FILE), bytes).unwrap();
        let e = load(dir.path()).unwrap_err().to_string();
        assert!(e.contains(FILE) && e.contains("`frf` is 12 x 2"), "{e}");
    }

    /// The mode term is the accelerance of a unit-residue SDOF: at resonance it is
    /// `-w_n^2 / (2 j xi w_n^2) = j / (2 xi)`.
    #[test]
    fn mode_term_at_resonance() {
        let g = mode_term(100.0, 100.0, 0.01);
        assert!((g - Complex64::new(0.0, 50.0)).norm() < 1e-12);
    }
}
