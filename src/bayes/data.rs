//! The data of the likelihood: measured FRF magnitudes on the long vector, the
//! per-point standard deviation at noise scale 1, and each block's exponential window.

use crate::error::{Error, Result};
use crate::frf::{FrfBlock, FrfKind};
use crate::signal::TestFrf;
use crate::update::ResidualForm;
use serde::{Deserialize, Serialize};

/// Default floor on the relative standard deviation of a measured magnitude (0.1 %).
///
/// The Bendat & Piersol error `sqrt((1 - g^2) / (2 g^2 n))` goes to 0 as the coherence
/// goes to 1, which would give a few points unbounded weight. It is floored at 0.1 %:
/// the coherence behind it comes from a local model with only 5-14 complex degrees of
/// freedom (`TestFrf::coherence_dof`), so a single estimate of the noise variance is
/// uncertain by `1/sqrt(dof)` = 27-45 %, and the smallest of a few hundred such
/// estimates is several times too small; and other errors of a magnitude estimate (the
/// frequency-grid and window effects of a 58-s block on a 0.2 %-damped peak, sensor
/// calibration) are not below a few tenths of a percent. On the four-story campaign the
/// floor lifts about 40 % of the hammer points (their B&P values are 0.03-0.1 %) and none
/// of the shake-table points (0.34 % and up).
pub const DEFAULT_REL_SIGMA_FLOOR: f64 = 1e-3;

/// Measured magnitudes and their noise model at noise scale 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrfData {
    /// Frequency grids and pairs, one block per test (the long-vector layout).
    #[serde(skip)]
    pub blocks: Vec<FrfBlock>,
    /// Test of each block.
    pub tests: Vec<String>,
    /// Exponential window time constant of each block, s (`None`: no window).
    pub window_tau_s: Vec<Option<f64>>,
    /// `|H^E|` in long-vector order.
    pub magnitude: Vec<f64>,
    /// How residuals are formed.
    pub residual: ResidualForm,
    /// Standard deviation of each point at noise scale 1, in the residual's units: of
    /// `|H^E_k|` for [`ResidualForm::Magnitude`], of `ln |H^E_k|` (the relative error)
    /// for [`ResidualForm::LogMagnitude`].
    pub sigma: Vec<f64>,
    /// Points whose relative standard deviation was raised to the floor.
    pub n_floored: usize,
}

impl FrfData {
    /// The responses of `kind` of every test in `frfs` at their selected points, with
    /// `sigma_k = max(r_k, rel_sigma_floor)` (log residuals) or `|H^E_k|` times that
    /// (magnitude residuals), `r_k` the Bendat & Piersol relative random error of
    /// [`TestFrf::selected_rel_std`].
    pub fn from_test_frfs(
        frfs: &[&TestFrf],
        kind: FrfKind,
        residual: ResidualForm,
        rel_sigma_floor: f64,
    ) -> Result<Self> {
        if !(rel_sigma_floor.is_finite() && rel_sigma_floor > 0.0) {
            return Err(Error::Usage(format!(
                "the relative sigma floor must be positive, got {rel_sigma_floor}"
            )));
        }
        let mut data = FrfData {
            blocks: Vec::new(),
            tests: Vec::new(),
            window_tau_s: Vec::new(),
            magnitude: Vec::new(),
            residual,
            sigma: Vec::new(),
            n_floored: 0,
        };
        for frf in frfs {
            let full = frf.frf_block()?;
            let mags = frf.selected_magnitudes();
            let rel = frf.selected_rel_std();
            let nw = full.omega_rad_s.len();
            let mut pairs = Vec::new();
            for (j, p) in full.pairs.iter().enumerate() {
                if p.kind != kind || nw == 0 {
                    continue;
                }
                pairs.push(*p);
                for (&m, &r) in mags[j * nw..(j + 1) * nw]
                    .iter()
                    .zip(&rel[j * nw..(j + 1) * nw])
                {
                    if !(m.is_finite() && m > 0.0) {
                        return Err(Error::Usage(format!(
                            "test {}: measured magnitude {m} at a selected point; \
                             magnitudes must be positive",
                            frf.test
                        )));
                    }
                    let r = if r.is_nan() { f64::INFINITY } else { r };
                    if r < rel_sigma_floor {
                        data.n_floored += 1;
                    }
                    let r = r.max(rel_sigma_floor);
                    data.magnitude.push(m);
                    data.sigma.push(match residual {
                        ResidualForm::Magnitude => m * r,
                        ResidualForm::LogMagnitude => r,
                    });
                }
            }
            if !pairs.is_empty() {
                data.blocks.push(FrfBlock {
                    omega_rad_s: full.omega_rad_s.clone(),
                    pairs,
                });
                data.tests.push(frf.test.clone());
                data.window_tau_s.push(frf.exp_window_tau_s);
            }
        }
        if data.blocks.is_empty() {
            return Err(Error::Usage(format!(
                "no {kind:?} FRFs with selected points in these tests"
            )));
        }
        data.validate()?;
        Ok(data)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.magnitude.len()
    }
    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.magnitude.is_empty()
    }

    /// Checks lengths and values: one magnitude and one sigma per point, magnitudes
    /// positive (zero allowed for magnitude residuals), sigmas positive and finite.
    pub fn validate(&self) -> Result<()> {
        let n: usize = self
            .blocks
            .iter()
            .map(|b| b.omega_rad_s.len() * b.pairs.len())
            .sum();
        if n == 0 {
            return Err(Error::Usage("no measured FRF points".into()));
        }
        if self.magnitude.len() != n || self.sigma.len() != n {
            return Err(Error::Usage(format!(
                "{} magnitudes and {} sigmas for {n} FRF points (blocks x pairs x frequencies)",
                self.magnitude.len(),
                self.sigma.len()
            )));
        }
        if self.window_tau_s.len() != self.blocks.len() || self.tests.len() != self.blocks.len() {
            return Err(Error::Usage(format!(
                "{} blocks but {} window entries and {} test names",
                self.blocks.len(),
                self.window_tau_s.len(),
                self.tests.len()
            )));
        }
        let log = self.residual == ResidualForm::LogMagnitude;
        if let Some(k) = self
            .magnitude
            .iter()
            .position(|&v| !(v.is_finite() && (v > 0.0 || (!log && v == 0.0))))
        {
            return Err(Error::Usage(format!(
                "measured magnitude {k} is {}; magnitudes must be finite and {}",
                self.magnitude[k],
                if log {
                    "positive for log residuals"
                } else {
                    ">= 0"
                }
            )));
        }
        if let Some(k) = self.sigma.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::Usage(format!(
                "sigma {k} is {}; every sigma must be finite and positive",
                self.sigma[k]
            )));
        }
        Ok(())
    }
}
