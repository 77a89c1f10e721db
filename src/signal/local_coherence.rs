//! The local-model coherence of one test's responses ([`CoherenceMethod::LocalRational`]
//! in [`super::estimate`]): the window, bin spacing, window correlation and degrees of
//! freedom are set up once per test, then each response's coherence is computed from its
//! block spectra ([`super::noise`]).

use super::correlation::{NoiseWindow, WindowDof};
use super::noise::{add_smooth_input_noise, local_rational_noise};
use super::spectra::CrossSpectra;
use super::windows::exponential_window;
use crate::error::Result;
use num_complex::Complex64;

#[cfg(doc)]
use super::noise::CoherenceMethod;

/// The local models of one test: bins spaced so that the noise of neighbours is at most
/// 50 % correlated (exponential window, zero padding), the rest normalised exactly
/// ([`super::correlation`]).
pub(super) struct LocalModel {
    /// Neighbours on each side of a bin.
    pub half_width_bins: usize,
    /// Spacing of the neighbours, bins.
    pub step: usize,
    /// Noise correlation of the window at the neighbours' offsets.
    pub corr: Vec<Complex64>,
    pub dof: WindowDof,
    /// Bins the windows of the kept bins reach.
    pub n_local: usize,
}

impl LocalModel {
    /// Sets up the local models of a test with blocks of `block_len` samples at `fs_hz`,
    /// exponential window time constant `tau_s` (s; `None`: rectangular), `n_fft`-point
    /// spectra of which `n_keep` bins are kept, and `n_blocks` blocks.
    pub fn new(
        half_width_bins: usize,
        tau_s: Option<f64>,
        block_len: usize,
        fs_hz: f64,
        n_fft: usize,
        n_keep: usize,
        n_blocks: usize,
    ) -> Result<Self> {
        let expw = tau_s.map(|t| exponential_window(block_len, 1.0 / fs_hz, t));
        let window = NoiseWindow::new(expw.as_deref(), block_len, n_fft)?;
        let step = window.decorrelating_step();
        let corr = window.window_correlation(half_width_bins, step);
        let dof = WindowDof::new(Some(&corr), half_width_bins, n_blocks)?;
        // bins the windows of the kept bins reach
        let n_local = (n_keep + 2 * half_width_bins * step).min(n_fft / 2 + 1);
        Ok(LocalModel {
            half_width_bins,
            step,
            corr,
            dof,
            n_local,
        })
    }

    /// The coherence of one response (with the smooth input noise `input_noise`, per
    /// block) and that of its output noise alone, on the first `n_local` bins; both 0
    /// where the input has no power. `f_blocks`, `y_blocks`: input and response spectra
    /// per block; `h1` and `spectra` their H1 and cross spectra.
    pub fn coherences(
        &self,
        f_blocks: &[Vec<Complex64>],
        y_blocks: &[Vec<Complex64>],
        h1: &[Complex64],
        spectra: &CrossSpectra,
        input_noise: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        let n_local = self.n_local;
        let cut = |b: &[Vec<Complex64>]| -> Vec<Vec<Complex64>> {
            b.iter().map(|v| v[..n_local].to_vec()).collect()
        };
        let fb = cut(f_blocks);
        let mut noise = local_rational_noise(
            &fb,
            &cut(y_blocks),
            &h1[..n_local],
            self.half_width_bins,
            self.step,
            Some(&self.corr),
        )?;
        let mut out = noise.coherence.clone();
        add_smooth_input_noise(&mut noise, h1, &fb, input_noise)?;
        let mut c = noise.coherence;
        for ((v, o), null) in c.iter_mut().zip(&mut out).zip(spectra.null_input()) {
            if null {
                *v = 0.0;
                *o = 0.0;
            }
        }
        Ok((c, out))
    }
}
