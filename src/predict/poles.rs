//! A modal (pole-residue) model of measured FRFs, for data without a structural model:
//! the basis of
//!
//! `H(w) = sum_r A_r g_r(w) + B + D (w / w_0)^2`,
//!
//! accelerance mode terms `g_r(w) = -w^2 / (w_r^2 - w^2 + 2 j xi_r w_r w)` (the modal
//! sum of paper Eq. 17 in accelerance, one pole pair per mode) and two out-of-band
//! residual terms: `B` for modes below the band (accelerance's mass line) and `D` for
//! modes above (`-w^2` times a residual flexibility), `w_0` the band centre.
//!
//! The predictions are the basis, not an FRF: every complex unknown (`A_r`, `B`, `D`) of
//! a channel gives two real columns, `g` and `j g` (real and imaginary parts
//! interleaved, `2 n` entries each, column-major), so that complex residues (allowing
//! non-proportional damping and sensor phase) are integrated out by a
//! [`crate::infer::BlockKind::LinearMarginal`] block per channel. Coordinates:
//! `f_1, ln xi_1, ..., f_m, ln xi_m` (Hz, dimensionless).

use super::Predict;
use crate::error::{Error, Result};
use num_complex::Complex64;

/// Accelerance mode term `g(w) = -w^2 / (w_n^2 - w^2 + 2 j xi w_n w)`.
pub fn mode_term(omega: f64, omega_n: f64, xi: f64) -> Complex64 {
    -omega * omega
        / Complex64::new(
            omega_n * omega_n - omega * omega,
            2.0 * xi * omega_n * omega,
        )
}

/// See the module docs.
#[derive(Debug, Clone)]
pub struct PoleResidue {
    freq_hz: Vec<f64>,
    omega0_rad_s: f64,
    n_modes: usize,
    /// Natural frequencies must ascend (no label switching when sampling); a fit may
    /// leave them unordered and sort afterwards.
    ordered: bool,
}

impl PoleResidue {
    /// `n_modes` modes on the grid `freq_hz`, residual terms about `omega0_rad_s`.
    pub fn new(
        freq_hz: Vec<f64>,
        omega0_rad_s: f64,
        n_modes: usize,
        ordered: bool,
    ) -> Result<Self> {
        if freq_hz.len() < n_modes + 2 || freq_hz.iter().any(|f| !(f.is_finite() && *f > 0.0)) {
            return Err(Error::Usage(format!(
                "a pole-residue model of {n_modes} modes needs at least {} positive frequencies, \
                 got {}",
                n_modes + 2,
                freq_hz.len()
            )));
        }
        Ok(PoleResidue {
            freq_hz,
            omega0_rad_s,
            n_modes,
            ordered,
        })
    }

    /// The same model with or without the ordering constraint.
    pub fn with_ordering(&self, ordered: bool) -> Self {
        PoleResidue {
            ordered,
            ..self.clone()
        }
    }

    /// Complex unknowns per channel: the residues and the two residual terms.
    pub fn n_complex(&self) -> usize {
        self.n_modes + 2
    }

    /// Poles `(f_hz, xi)` of a coordinate vector (its first `2 n_modes` entries).
    pub fn poles(&self, theta: &[f64]) -> Vec<(f64, f64)> {
        (0..self.n_modes)
            .map(|r| (theta[2 * r], theta[2 * r + 1].exp()))
            .collect()
    }

    /// The complex basis at bin `k` for `poles`.
    pub fn basis_row(&self, k: usize, poles: &[(f64, f64)], row: &mut [Complex64]) {
        let w = std::f64::consts::TAU * self.freq_hz[k];
        for (r, &(f, xi)) in poles.iter().enumerate() {
            row[r] = mode_term(w, std::f64::consts::TAU * f, xi);
        }
        let m = poles.len();
        row[m] = Complex64::new(1.0, 0.0);
        row[m + 1] = Complex64::new((w / self.omega0_rad_s).powi(2), 0.0);
    }

    /// `sum_j row_j theta_j` at every bin: the FRF of complex unknowns `theta`.
    pub fn frf(&self, poles: &[(f64, f64)], theta: &[Complex64]) -> Vec<Complex64> {
        let mut row = vec![Complex64::new(0.0, 0.0); self.n_complex()];
        (0..self.freq_hz.len())
            .map(|k| {
                self.basis_row(k, poles, &mut row);
                row.iter().zip(theta).map(|(g, t)| g * t).sum()
            })
            .collect()
    }
}

impl Predict for PoleResidue {
    type Workspace = Vec<Complex64>;

    fn n_params(&self) -> usize {
        2 * self.n_modes
    }
    fn n_outputs(&self) -> usize {
        2 * self.n_complex() * 2 * self.freq_hz.len()
    }
    fn param_names(&self) -> Vec<String> {
        (1..=self.n_modes)
            .flat_map(|r| [format!("f{r}"), format!("ln_xi{r}")])
            .collect()
    }
    fn workspace(&self) -> Self::Workspace {
        vec![Complex64::new(0.0, 0.0); self.n_complex()]
    }
    fn predict(&self, theta: &[f64], row: &mut Self::Workspace, out: &mut [f64]) -> Result<()> {
        if self.ordered && (1..self.n_modes).any(|r| theta[2 * r] <= theta[2 * r - 2]) {
            return Err(Error::Model("natural frequencies out of order".into()));
        }
        let poles = self.poles(theta);
        let len = 2 * self.freq_hz.len();
        for k in 0..self.freq_hz.len() {
            self.basis_row(k, &poles, row);
            for (j, g) in row.iter().enumerate() {
                let (re, im) = (2 * j * len + 2 * k, (2 * j + 1) * len + 2 * k);
                out[re] = g.re;
                out[re + 1] = g.im;
                out[im] = -g.im;
                out[im + 1] = g.re;
            }
        }
        Ok(())
    }
}
