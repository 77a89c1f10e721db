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
//!
//! This is the inference layer's posterior: the basis is [`PoleResidue`]'s prediction,
//! each channel a [`Block::complex_linear`] (each complex unknown as two real
//! coefficients, for which `ln det` of the real normal matrix is twice the complex one,
//! so the density above is the block's up to a constant), `ln s` its one sampled noise
//! scale.

use std::path::Path;

use num_complex::Complex64;

use super::mat::MatData;
use crate::error::{Error, Result};
use crate::infer::{Block, LinearFit, NoiseScale, Posterior};
use crate::predict::{PoleResidue, Predict};

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

pub use crate::predict::poles::mode_term;

/// The weighted least-squares solution of one channel at given poles.
#[derive(Debug, Clone)]
pub struct ChannelFit {
    /// `theta^ = (A_1.., B, D)`.
    pub theta: Vec<Complex64>,
    /// `sum_k |y_k - model_k|^2 / v_k`.
    pub rss: f64,
    /// The block's solution in its real coordinates (for conditional draws).
    pub linear: LinearFit,
}

/// The band posterior. Coordinates: `f_1, ln xi_1, ..., f_m, ln xi_m, ln s` (Hz,
/// dimensionless); prior uniform in them within [`BandLikelihood::bounds`], with the
/// natural frequencies in ascending order (no label switching within a close pair).
/// One [`Block::complex_linear`] per channel integrates its residues out.
#[derive(Debug, Clone)]
pub struct BandLikelihood {
    pub spec: BandSpec,
    pub data: BandData,
    pub posterior: Posterior<PoleResidue>,
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
        Self::from_band(spec, band)
    }

    fn from_band(spec: BandSpec, data: BandData) -> Result<Self> {
        let omega0 = std::f64::consts::PI * (spec.lo_hz + spec.hi_hz);
        let model = PoleResidue::new(data.freq_hz.clone(), omega0, spec.f_guess_hz.len(), true)?;
        let (n_out, k) = (model.n_outputs(), 2 * model.n_complex());
        let blocks = data
            .y
            .iter()
            .zip(&data.v)
            .enumerate()
            .map(|(c, (y, v))| {
                let observed: Vec<f64> = y.iter().flat_map(|h| [h.re, h.im]).collect();
                let sd: Vec<f64> = v.iter().map(|x| x.sqrt()).collect();
                let name = format!("ch{}", c + 1);
                Block::complex_linear(&name, 0..n_out, &observed, &sd, k, NoiseScale::Sampled(0))
            })
            .collect::<Result<Vec<_>>>()?;
        let mut bounds = Vec::new();
        for _ in &spec.f_guess_hz {
            bounds.push((spec.lo_hz, spec.hi_hz));
            bounds.push((XI_RANGE.0.ln(), XI_RANGE.1.ln()));
        }
        let scale = ("ln_s".to_string(), (S_RANGE.0.ln(), S_RANGE.1.ln()));
        let posterior = Posterior::new(model, &bounds, &[scale], blocks)?;
        Ok(BandLikelihood {
            spec,
            data,
            posterior,
        })
    }

    /// The same band restricted to the given channels (0-based).
    pub fn with_channels(&self, channels: &[usize]) -> Result<BandLikelihood> {
        let mut data = self.data.clone();
        data.y = channels.iter().map(|&c| self.data.y[c].clone()).collect();
        data.v = channels.iter().map(|&c| self.data.v[c].clone()).collect();
        Self::from_band(self.spec.clone(), data)
    }

    /// Modes in the band.
    pub fn n_modes(&self) -> usize {
        self.spec.f_guess_hz.len()
    }

    /// Complex unknowns per channel: residues and the two residual terms.
    pub fn n_linear(&self) -> usize {
        self.n_modes() + 2
    }

    /// Sampled coordinates.
    pub fn dim(&self) -> usize {
        2 * self.n_modes() + 1
    }

    /// Prior box of the coordinates.
    pub fn bounds(&self) -> Vec<(f64, f64)> {
        (0..self.dim())
            .map(|i| self.posterior.prior().bound(i))
            .collect()
    }

    /// The basis at bin `k` for poles `(f_hz, xi)`.
    pub fn basis_row(&self, k: usize, poles: &[(f64, f64)], row: &mut [Complex64]) {
        self.posterior.predictor().basis_row(k, poles, row)
    }

    /// Poles `(f_hz, xi)` of a coordinate vector.
    pub fn poles(&self, theta: &[f64]) -> Vec<(f64, f64)> {
        self.posterior.predictor().poles(theta)
    }

    /// Weighted least squares of every channel at the poles of `theta` (in any order);
    /// `None` when the basis is rank-deficient.
    pub fn fit_channels(&self, theta: &[f64]) -> Option<Vec<ChannelFit>> {
        let model = self.posterior.predictor().with_ordering(false);
        let mut pred = vec![0.0; model.n_outputs()];
        model
            .predict(
                &theta[..model.n_params()],
                &mut model.workspace(),
                &mut pred,
            )
            .ok()?;
        self.posterior
            .blocks()
            .iter()
            .map(|b| {
                let linear = b.linear_fit(&pred)?;
                let theta = linear
                    .coefficients
                    .chunks(2)
                    .map(|c| Complex64::new(c[0], c[1]))
                    .collect();
                // Whitened by sqrt(2 / v): the real residual norm is twice the complex one.
                let rss = 0.5 * linear.rss;
                Some(ChannelFit { theta, rss, linear })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
