//! The data of the likelihood: measured FRF magnitudes on the long vector, the
//! per-point standard deviation at noise scale 1, and each block's exponential window.

use crate::error::{Error, Result};
use crate::frf::{FrfBlock, FrfKind};
use crate::signal::correlation::{exp_window_bin_correlation_complex, magnitude_bin_correlation};
use crate::signal::TestFrf;
use crate::update::ResidualForm;
use num_complex::Complex64;
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

/// Bins either side over which `frfbayes sample` pools the output noise's auto-spectrum
/// behind each point's sd by default ([`crate::signal::pooled_rel_std`]). A single bin's
/// coherence has 5-14 complex degrees of freedom, so its noise estimate is uncertain by
/// 27-45 % and the likelihood leans on the points whose noise came out small; pooled over
/// +-8 bins, the six-DOF study's chi2 of its 7 alphas and betas fell from 24.4 to 10.4
/// (with [`BinCorrelation::Phase`]) against a calibrated 7 (docs/calibration.md).
pub const DEFAULT_NOISE_POOL_BINS: usize = 8;

/// How the noise of the force channel of hammer tests enters the likelihood.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputNoiseModel {
    /// Inside each point's Bendat & Piersol error, points independent: the force noise,
    /// one error common to all points of a test, is then counted once per point and the
    /// posterior is too narrow (`results/coverage/`).
    #[default]
    PerPoint,
    /// As a low-rank error shared by all points of a test
    /// ([`crate::signal::InputNoise`], [`CorrelatedNoise`]); each point's own error is
    /// the Bendat & Piersol error of the output noise alone.
    Shared,
}

/// Which magnitude scales the loadings of the shared force noise (magnitude residuals;
/// see [`FrfData::with_loading_magnitudes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoadingMagnitude {
    /// The measured `|H^E_k|`: carries the point's own response noise, which biases the
    /// mass-stiffness scale (six-DOF campaign +0.375 %, 2.65 posterior sd; README).
    #[default]
    Measured,
    /// Two-stage plug-in: the model's `|H^A_k(theta_ML)|` at the maximum-likelihood
    /// start ([`crate::bayes::plug_in_start`]), whose dependence on any one point is
    /// `O(1/n)`; fixed while sampling (no cost per evaluation).
    Model,
}

/// Whether the output noise of neighbouring bins of one response is correlated in the
/// likelihood (see [`FrfData::bin_correlation`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BinCorrelation {
    /// Every point independent: with a window that correlates neighbouring bins (the
    /// exponential window of hammer tests: `|c(1)| = 0.69`) the posterior is too narrow
    /// (ten-story campaign: maximum-likelihood errors 3.5 times their sd; README).
    #[default]
    Independent,
    /// Each response's points a Gauss-Markov chain along frequency, the correlation of
    /// consecutive points the window's `|c(d)|` at their bin distance `d`
    /// ([`crate::signal::correlation::exp_window_bin_correlation`]).
    Window,
    /// Each response's points a Gauss-Markov chain along frequency, the correlation of
    /// consecutive points `Re(c(d) g exp(-j (theta_k - theta_(k-1))))`: the window's
    /// complex `c(d)` turned by the estimate's phase `theta` between them and by the
    /// input's (`g`, [`crate::signal::TestFrf::input_turn`]). A magnitude's relative error
    /// is `Re(N_k / Y_k)`, the real part of the response noise over the response
    /// spectrum `Y = F H`, so its correlation between bins is the real part of the complex
    /// noise's correlation turned by the response's phase
    /// ([`crate::signal::correlation::magnitude_bin_correlation`]). The input's phase
    /// wobbles from bin to bin where a record holds two impacts. `|c(d)|`
    /// ([`Self::Window`]) is an upper bound, reached only where the turns cancel the
    /// window's own phase.
    Phase,
}

impl BinCorrelation {
    /// Relative eigenvalue below which components of the shared force noise are dropped
    /// from its low-rank term (their variance joins each point's own): with
    /// [`Self::Phase`] none that the eigen-solver resolves
    /// ([`SHARED_NOISE_REL_TOL_CHAINED`]); [`Self::Window`] keeps the tolerance its runs
    /// had, so that they resume unchanged.
    pub fn shared_noise_rel_tol(self) -> f64 {
        match self {
            BinCorrelation::Phase => SHARED_NOISE_REL_TOL_CHAINED,
            BinCorrelation::Independent | BinCorrelation::Window => SHARED_NOISE_REL_TOL,
        }
    }
}

/// Relative eigenvalue below which components of the shared force noise are dropped
/// (their variance is added to each point's own).
pub const SHARED_NOISE_REL_TOL: f64 = 1e-3;

/// [`SHARED_NOISE_REL_TOL`] with [`BinCorrelation::Phase`]: every component the
/// eigen-solver resolves is kept. Dropped components join each point's own variance, which
/// the chain then correlates as the window correlates the output noise, while the force
/// noise is smooth across the whole test: on the 20 four-story coverage campaigns with
/// force noise alone (campaigns 0-5) the phase chain with the 1e-3 tolerance covered 45 of
/// 72 parameters (max |z| 27.5), with this one 72 of 72 (rms z 0.80;
/// docs/calibration.md).
pub const SHARED_NOISE_REL_TOL_CHAINED: f64 = 1e-9;

/// Noise shared by a run of consecutive points (one test's): `cov = L L^T` in the
/// residual's units at noise scale 1, on top of the independent `sigma_k^2`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CorrelatedNoise {
    /// First point (long-vector index).
    pub start: usize,
    /// Number of points.
    pub len: usize,
    /// Columns of `L`.
    pub rank: usize,
    /// `L`, `len x rank`, row-major.
    pub loadings: Vec<f64>,
    /// The magnitude `|H_k|` that row `k` of `loadings` is scaled by (magnitude
    /// residuals: the row is `|H_k| a_k`, `a_k` the relative loadings); as built, the
    /// measured `|H^E_k|`, after [`FrfData::with_loading_magnitudes`] the model's. Empty
    /// when the loadings scale with no magnitude (log residuals, or loadings given
    /// directly).
    #[serde(default)]
    pub magnitude: Vec<f64>,
}

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
    /// Selected bins left out because a used response had zero coherence there (no
    /// finite error; see [`FrfData::with_input_noise`]).
    #[serde(default)]
    pub n_dropped_bins: usize,
    /// Noise shared between points, on top of `sigma` (empty: independent points).
    #[serde(default)]
    pub correlated: Vec<CorrelatedNoise>,
    /// Correlation of each point's own noise with the previous point's (0 for the first
    /// point of a response's run; empty: all independent): the points of a run are a
    /// Gauss-Markov chain, `e_k = rho_k e_(k-1) + sqrt(1 - rho_k^2) u_k` in units of
    /// `sigma`, `u` independent ([`BinCorrelation::Window`]).
    #[serde(default)]
    pub bin_correlation: Vec<f64>,
}

impl FrfData {
    /// The responses of `kind` of every test in `frfs` at their selected points, with
    /// `sigma_k = max(r_k, rel_sigma_floor)` (log residuals) or `|H^E_k|` times that
    /// (magnitude residuals), `r_k` the Bendat & Piersol relative random error of
    /// [`TestFrf::selected_rel_std`], the force noise of hammer tests modelled as
    /// `input_noise` says ([`InputNoiseModel::PerPoint`]: inside `r_k`). [`InputNoiseModel::Shared`]: `sigma_k` from the output noise
    /// alone (floored as before) plus the dropped components of the force noise, and one
    /// [`CorrelatedNoise`] per test with force noise, its loadings `|H^E_k| a_k`
    /// (magnitude residuals) or `a_k` (log residuals), `a` the low-rank relative loadings
    /// of [`crate::signal::InputNoise::low_rank`] at the test's selected bins (the same
    /// for every response).
    ///
    /// A selected bin where the coherence of one of the used responses is zero (or not
    /// a number) has no finite Bendat & Piersol error: the estimator says the response
    /// there is noise. Such bins are left out of the test's block (for all of its
    /// responses) and counted in [`Self::n_dropped_bins`]. This happens on noisy
    /// simulated campaigns of general models (a displacement sensor's band edges); a
    /// test whose every selected bin is dropped is an error naming it.
    pub fn with_input_noise(
        frfs: &[&TestFrf],
        kind: FrfKind,
        residual: ResidualForm,
        rel_sigma_floor: f64,
        input_noise: InputNoiseModel,
    ) -> Result<Self> {
        Self::with_noise_model(
            frfs,
            kind,
            residual,
            rel_sigma_floor,
            input_noise,
            BinCorrelation::Independent,
            0,
        )
    }

    /// [`Self::with_input_noise`] with the correlation of neighbouring bins of
    /// `bins` ([`Self::bin_correlation`]) and the output noise's auto-spectrum pooled over
    /// `+-noise_pool_bins` bins ([`crate::signal::pooled_rel_std`]; 0: each bin's own).
    pub fn with_noise_model(
        frfs: &[&TestFrf],
        kind: FrfKind,
        residual: ResidualForm,
        rel_sigma_floor: f64,
        input_noise: InputNoiseModel,
        bins: BinCorrelation,
        noise_pool_bins: usize,
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
            n_dropped_bins: 0,
            correlated: Vec::new(),
            bin_correlation: Vec::new(),
        };
        for frf in frfs {
            data.push_test(
                frf,
                kind,
                rel_sigma_floor,
                input_noise,
                noise_pool_bins,
                bins,
            )?;
        }
        if data.blocks.is_empty() {
            return Err(Error::Usage(format!(
                "no {kind:?} FRFs with selected points in these tests"
            )));
        }
        data.validate()?;
        Ok(data)
    }

    /// Appends the `kind` responses of one test at its selected bins with finite errors
    /// (see [`Self::with_input_noise`]).
    fn push_test(
        &mut self,
        frf: &TestFrf,
        kind: FrfKind,
        rel_sigma_floor: f64,
        input_noise: InputNoiseModel,
        noise_pool_bins: usize,
        bins: BinCorrelation,
    ) -> Result<()> {
        let full = frf.frf_block()?;
        let mags = frf.selected_magnitudes();
        let noise = frf
            .input_noise
            .as_ref()
            .filter(|_| input_noise == InputNoiseModel::Shared);
        let rel = frf.selected_pooled_rel_std(noise.is_some(), noise_pool_bins);
        let nw = full.omega_rad_s.len();
        let used: Vec<usize> = (0..full.pairs.len())
            .filter(|&j| full.pairs[j].kind == kind && nw > 0)
            .collect();
        // positions (into `selected`) of the bins kept: every used response has a
        // finite error there
        let keep: Vec<usize> = (0..nw)
            .filter(|&i| used.iter().all(|&j| rel[j * nw + i].is_finite()))
            .collect();
        if !used.is_empty() && keep.is_empty() {
            return Err(Error::Usage(format!(
                "test {}: every selected bin has a {kind:?} response with zero coherence \
                 (no finite error); the test carries no usable {kind:?} points",
                frf.test
            )));
        }
        self.n_dropped_bins += (nw - keep.len()) * usize::from(!used.is_empty());
        let kept_bins: Vec<usize> = keep.iter().map(|&i| frf.selected[i]).collect();
        let shared = noise
            .map(|n| n.low_rank(&kept_bins, bins.shared_noise_rel_tol()))
            .transpose()?;
        let start = self.magnitude.len();
        let (mut loadings, mut scale) = (Vec::new(), Vec::new());
        for &j in &used {
            for (q, &i) in keep.iter().enumerate() {
                let (m, r) = (mags[j * nw + i], rel[j * nw + i]);
                if !(m.is_finite() && m > 0.0) {
                    return Err(Error::Usage(format!(
                        "test {}: measured magnitude {m} at a selected point; \
                         magnitudes must be positive",
                        frf.test
                    )));
                }
                if r < rel_sigma_floor {
                    self.n_floored += 1;
                }
                let mut r = r.max(rel_sigma_floor);
                if let Some(lr) = &shared {
                    r = (r * r + lr.dropped_var[q]).sqrt();
                    let unit = match self.residual {
                        ResidualForm::Magnitude => {
                            scale.push(m);
                            m
                        }
                        ResidualForm::LogMagnitude => 1.0,
                    };
                    let row = &lr.loadings[q * lr.rank..(q + 1) * lr.rank];
                    loadings.extend(row.iter().map(|a| a * unit));
                }
                self.magnitude.push(m);
                self.sigma.push(match self.residual {
                    ResidualForm::Magnitude => m * r,
                    ResidualForm::LogMagnitude => r,
                });
            }
        }
        if used.is_empty() {
            return Ok(());
        }
        if let Some(lr) = shared.filter(|lr| lr.rank > 0) {
            self.correlated.push(CorrelatedNoise {
                start,
                len: self.magnitude.len() - start,
                rank: lr.rank,
                loadings,
                magnitude: scale,
            });
        }
        self.blocks.push(FrfBlock {
            omega_rad_s: keep.iter().map(|&i| full.omega_rad_s[i]).collect(),
            pairs: used.iter().map(|&j| full.pairs[j]).collect(),
        });
        self.tests.push(frf.test.clone());
        self.window_tau_s.push(frf.exp_window_tau_s);
        if bins != BinCorrelation::Independent {
            self.push_bin_correlation(frf, &used, &kept_bins, bins);
        }
        Ok(())
    }

    /// Appends [`Self::bin_correlation`] of the test just pushed, whose `used` responses
    /// (indices into its responses) were pushed at its bins `kept_bins`: per response, 0
    /// at its first bin, then the correlation of each bin with the previous one that
    /// `correlation` says. The window's `c(d)`, turned by the input's phase for
    /// [`BinCorrelation::Phase`], is common to the test's responses and computed once.
    fn push_bin_correlation(
        &mut self,
        frf: &TestFrf,
        used: &[usize],
        kept_bins: &[usize],
        correlation: BinCorrelation,
    ) {
        let df = match frf.freq_hz.as_slice() {
            [f0, f1, ..] if f1 > f0 => f1 - f0,
            _ => 0.0,
        };
        let zero = Complex64::new(0.0, 0.0);
        let common: Vec<Complex64> = (0..kept_bins.len())
            .map(|q| {
                if q == 0 || df <= 0.0 {
                    return zero;
                }
                let (k, l) = (kept_bins[q], kept_bins[q - 1]);
                let c = exp_window_bin_correlation_complex(
                    frf.exp_window_tau_s,
                    frf.block_s,
                    df,
                    k.abs_diff(l),
                );
                match correlation {
                    BinCorrelation::Phase => c * frf.input_turn(k, l),
                    _ => c,
                }
            })
            .collect();
        for &j in used {
            let h1 = &frf.responses[j].h1;
            let per_point = common.iter().enumerate().map(|(q, &c)| match q {
                0 => 0.0,
                _ if correlation == BinCorrelation::Phase => {
                    let (k, l) = (kept_bins[q], kept_bins[q - 1]);
                    magnitude_bin_correlation(c, h1[k].arg() - h1[l].arg())
                }
                _ => c.norm(),
            });
            self.bin_correlation.extend(per_point);
        }
    }

    /// [`Self::bin_correlation`]: empty or one value per point, each in `[0, 1)`.
    fn validate_bin_correlation(&self, n: usize) -> Result<()> {
        let rho = &self.bin_correlation;
        if !(rho.is_empty() || rho.len() == n)
            || rho.iter().any(|r| !(r.is_finite() && r.abs() < 1.0))
        {
            return Err(Error::Usage(format!(
                "{} bin correlations for {n} points, each in (-1, 1)",
                rho.len()
            )));
        }
        Ok(())
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.magnitude.len()
    }
    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.magnitude.is_empty()
    }

    /// The same data with every shared-noise row that scales with a magnitude rescaled
    /// to `h[k]` (long-vector order, e.g. the model's `|H^A_k|` at a point estimate):
    /// row `k` becomes `h_k a_k` in place of `|H^E_k| a_k`, and
    /// [`CorrelatedNoise::magnitude`] records `h`. Everything else is unchanged. Why:
    /// the force noise of a test moves its measured FRF by a common relative error
    /// `sum_r a_kr eta_r`, so its loadings are `|H_k| a_k` with `|H_k|` the FRF itself;
    /// the measured `|H^E_k|` carries point `k`'s own response noise, so loadings built
    /// from it correlate with the residual `y_k - |H^A_k|` they weight
    /// (`E[L^T D^-1 (y - h)]` holds `var(y_k)`, not 0) and the Woodbury correction
    /// biases the mass-stiffness scale (README, "Recovery of a simulated truth").
    /// See [`LoadingMagnitude::Model`].
    pub fn with_loading_magnitudes(&self, h: &[f64]) -> Result<FrfData> {
        if h.len() != self.len() {
            return Err(Error::Usage(format!(
                "{} loading magnitudes for {} points",
                h.len(),
                self.len()
            )));
        }
        let mut data = self.clone();
        for c in data
            .correlated
            .iter_mut()
            .filter(|c| !c.magnitude.is_empty())
        {
            for k in 0..c.len {
                let to = h[c.start + k];
                if !(to.is_finite() && to > 0.0) {
                    return Err(Error::Numerical(format!(
                        "loading magnitude {to} at point {}; it must be positive",
                        c.start + k
                    )));
                }
                let f = to / c.magnitude[k];
                c.loadings[k * c.rank..(k + 1) * c.rank]
                    .iter_mut()
                    .for_each(|v| *v *= f);
                c.magnitude[k] = to;
            }
        }
        data.validate()?;
        Ok(data)
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
        let mut end = 0;
        for c in &self.correlated {
            if c.start < end
                || c.start + c.len > n
                || c.loadings.len() != c.len * c.rank
                || c.loadings.iter().any(|v| !v.is_finite())
                || !(c.magnitude.is_empty() || c.magnitude.len() == c.len)
                || c.magnitude.iter().any(|v| !(v.is_finite() && *v > 0.0))
            {
                return Err(Error::Usage(format!(
                    "correlated noise over points {}..{} (rank {}, {} loadings) does not fit \
                     {n} points in order, or has non-finite loadings or loading magnitudes",
                    c.start,
                    c.start + c.len,
                    c.rank,
                    c.loadings.len()
                )));
            }
            end = c.start + c.len;
        }
        self.validate_bin_correlation(n)?;
        if let Some(k) = self.sigma.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::Usage(format!(
                "sigma {k} is {}; every sigma must be finite and positive",
                self.sigma[k]
            )));
        }
        Ok(())
    }
}
