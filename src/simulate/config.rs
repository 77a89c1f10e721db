//! The simulation model file (TOML) and its parsing (validated in `validate.rs`). The
//! format is documented with an example in the [module docs](super).

use super::effects::EffectSpec;
use super::sensor_effects::SensorEffect;
use crate::error::{Error, Result};
use crate::io::NominalModel;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole simulation model: the true system, the tests to run, the instruments.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimModel {
    /// Campaign title written to `campaign.toml`.
    pub title: String,
    /// Seed of the sensor noise; `--seed` overrides it.
    #[serde(default)]
    pub seed: Option<u64>,
    /// The true structure.
    pub structure: StructureSpec,
    /// The true damping.
    pub damping: DampingSpec,
    /// What the engineer believes (written to `campaign.toml`); the true structure when
    /// absent.
    #[serde(default)]
    pub nominal: Option<NominalSpec>,
    /// Output rate and anti-aliasing.
    pub sampling: SamplingSpec,
    /// Sensor noise per quantity; zero when absent.
    #[serde(default)]
    pub noise: NoiseSpec,
    /// The tests, written in this order (the campaign sorts them by name).
    #[serde(rename = "test")]
    pub tests: Vec<TestSpec>,
    /// Changes of the physics, applied in order to the built structure.
    #[serde(default, rename = "effect", skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<EffectSpec>,
    /// Instrument effects on named channels, applied in order before anti-aliasing.
    #[serde(
        default,
        rename = "sensor_effect",
        skip_serializing_if = "Vec::is_empty"
    )]
    pub sensor_effects: Vec<SensorEffect>,
}

/// The true structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum StructureSpec {
    /// Lumped floor masses joined by story springs; floor f is DOF f-1.
    ShearFrame {
        floor_mass_kg: Vec<f64>,
        story_stiffness_n_per_m: Vec<f64>,
    },
    /// A general linear model from a manifest at the true `alpha`, `beta`, with sensors
    /// on DOFs (1-based); see [`super::general`].
    General {
        /// The model manifest (relative paths are resolved against the simulation model
        /// file's folder when it is read).
        manifest: PathBuf,
        /// True stiffness parameters (Eq. 20); zeros when empty.
        #[serde(default)]
        alpha: Vec<f64>,
        /// True mass parameters (Eq. 21); zeros when empty.
        #[serde(default)]
        beta: Vec<f64>,
        /// DOFs (1-based) with an accelerometer (channels `acc<k>`).
        #[serde(default)]
        acceleration_dofs: Vec<usize>,
        /// DOFs (1-based) with a displacement sensor (channels `disp<k>`).
        #[serde(default)]
        displacement_dofs: Vec<usize>,
        /// Highest natural frequency of the modal basis; the internal Nyquist frequency
        /// when absent.
        #[serde(default)]
        modal_cutoff_hz: Option<f64>,
    },
}

impl StructureSpec {
    /// Number of floors of a shear frame; `None` for a general model (its size is in
    /// its manifest).
    pub fn n_floors(&self) -> Option<usize> {
        match self {
            StructureSpec::ShearFrame { floor_mass_kg, .. } => Some(floor_mass_kg.len()),
            StructureSpec::General { .. } => None,
        }
    }

    /// Locations (1-based floors or DOFs) of the accelerometers and of the displacement
    /// sensors on a structure of `n` floors / DOFs: every floor of a shear frame, the
    /// listed DOFs of a general model.
    pub fn sensors(&self, n: usize) -> (Vec<usize>, Vec<usize>) {
        match self {
            StructureSpec::ShearFrame { .. } => ((1..=n).collect(), (1..=n).collect()),
            StructureSpec::General {
                acceleration_dofs,
                displacement_dofs,
                ..
            } => (acceleration_dofs.clone(), displacement_dofs.clone()),
        }
    }
}

/// The true damping of the structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum DampingSpec {
    /// `C = a0 M + a1 K` (paper Eq. 2).
    Rayleigh { a0_per_s: f64, a1_s: f64 },
    /// Caughey series (Eq. 8) with as many terms as ratios, fitted so that the first
    /// `xi.len()` modes have ratios `xi` (Eq. 9); higher modes follow the series.
    Caughey { xi: Vec<f64> },
    /// Modal damping, one ratio per mode: `C = M Phi diag(2 xi_i omega_i) Phi^T M`.
    Modal { xi: Vec<f64> },
}

/// The nominal model written to `campaign.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NominalSpec {
    pub floor_mass_kg: Vec<f64>,
    pub story_stiffness_n_per_m: Vec<f64>,
}

/// Output rate and the internal (simulation) rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SamplingSpec {
    /// Rate of the written samples.
    pub output_rate_hz: f64,
    /// Internal rate = `oversampling * output_rate_hz` (1..=100); 1 means no
    /// anti-aliasing filter.
    pub oversampling: usize,
    /// Anti-aliasing pass-band edge as a fraction of the output Nyquist frequency.
    #[serde(default = "default_passband_fraction")]
    pub passband_fraction: f64,
    /// Anti-aliasing stop-band attenuation (from the output Nyquist frequency up), dB.
    #[serde(default = "default_attenuation_db")]
    pub stopband_attenuation_db: f64,
}

fn default_passband_fraction() -> f64 {
    0.8
}
fn default_attenuation_db() -> f64 {
    100.0
}

impl SamplingSpec {
    /// Internal simulation rate.
    pub fn internal_rate_hz(&self) -> f64 {
        self.output_rate_hz * self.oversampling as f64
    }
}

/// Standard deviation of the Gaussian sensor noise per quantity, at the output rate.
/// White by default; `ar1_coefficient = phi > 0` makes every channel's noise a
/// stationary first-order autoregression at the output rate (red noise),
/// `n_t = phi n_(t-1) + sqrt(1 - phi^2) sigma e_t`, whose standard deviation is still
/// `sigma` but whose power spectral density `(1 - phi^2) / (1 - 2 phi cos(2 pi f / fs) + phi^2)`
/// falls with frequency: the noise of neighbouring frequencies is alike, unlike the
/// flat spectrum the estimator's error model is usually checked on.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseSpec {
    #[serde(default)]
    pub force_n: f64,
    #[serde(default)]
    pub ground_acceleration_m_per_s2: f64,
    #[serde(default)]
    pub acceleration_m_per_s2: f64,
    #[serde(default)]
    pub displacement_m: f64,
    /// Lag-one autocorrelation `phi` of every channel's noise at the output rate, in
    /// `[0, 1)`; 0 (the default) is white noise.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub ar1_coefficient: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// One test to simulate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TestSpec {
    /// Impacts at one floor (or DOF of a general model), base fixed.
    Hammer {
        name: String,
        /// The impacted floor, or the DOF (1-based) of a general model (`excited_dof`).
        #[serde(alias = "excited_dof")]
        excited_floor: usize,
        /// Record length.
        duration_s: f64,
        /// Duration of each half-sine force pulse.
        pulse_duration_s: f64,
        impacts: Vec<ImpactSpec>,
    },
    /// Base driven by a shake table with a tapered linear chirp, then left to ring down.
    ShakeTable {
        name: String,
        chirp: ChirpSpec,
        /// Zero-input record after the sweep.
        ring_down_s: f64,
    },
}

impl TestSpec {
    /// Folder name of the test.
    pub fn name(&self) -> &str {
        match self {
            TestSpec::Hammer { name, .. } | TestSpec::ShakeTable { name, .. } => name,
        }
    }

    /// Record length.
    pub fn duration_s(&self) -> f64 {
        match self {
            TestSpec::Hammer { duration_s, .. } => *duration_s,
            TestSpec::ShakeTable {
                chirp, ring_down_s, ..
            } => chirp.start_s + chirp.sweep_duration_s + ring_down_s,
        }
    }
}

/// One hammer impact: a half-sine pulse starting at `time_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImpactSpec {
    pub time_s: f64,
    pub peak_force_n: f64,
}

/// A linear chirp of ground acceleration with raised-cosine tapers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChirpSpec {
    pub f0_hz: f64,
    pub f1_hz: f64,
    /// Start of the sweep in the record (zero input before).
    #[serde(default)]
    pub start_s: f64,
    pub sweep_duration_s: f64,
    /// Length of each raised-cosine taper at the start and end of the sweep.
    pub taper_s: f64,
    pub amplitude_m_per_s2: f64,
}

impl SimModel {
    /// Reads and validates a model file.
    pub fn from_path(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::from_toml(&text, path)
    }

    /// Parses and validates model text; `path` names the file in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        let mut model: SimModel =
            toml::from_str(text).map_err(|e| Error::invalid(path, e.to_string()))?;
        let dir = path.parent().unwrap_or(Path::new(""));
        super::general::resolve_manifest(&mut model.structure, dir);
        model.validate(path)?;
        Ok(model)
    }

    /// The nominal model for `campaign.toml`: the given one, else the true shear frame;
    /// for a general structure, its manifest (a model of `n_dof` DOFs).
    pub fn nominal_model(&self, n_dof: usize) -> Result<NominalModel> {
        let (m, k) = match (&self.nominal, &self.structure) {
            (_, StructureSpec::General { manifest, .. }) => {
                let manifest = manifest
                    .canonicalize()
                    .map_err(|e| Error::io(manifest, e))?;
                return Ok(NominalModel::general(manifest, n_dof));
            }
            (Some(n), _) => (&n.floor_mass_kg, &n.story_stiffness_n_per_m),
            (
                None,
                StructureSpec::ShearFrame {
                    floor_mass_kg,
                    story_stiffness_n_per_m,
                },
            ) => (floor_mass_kg, story_stiffness_n_per_m),
        };
        Ok(NominalModel::shear_frame(m.clone(), k.clone()))
    }
}

/// Names of the channels a test records with accelerometers at `acc` and displacement
/// sensors at `disp` (floors or DOFs, 1-based; see [`StructureSpec::sensors`]): the
/// input (`force` or `ground_acc`), then `acc<k>`, then `disp<k>`.
pub fn channel_names(test: &TestSpec, acc: &[usize], disp: &[usize]) -> Vec<String> {
    let mut names = vec![match test {
        TestSpec::Hammer { .. } => "force".to_string(),
        TestSpec::ShakeTable { .. } => "ground_acc".to_string(),
    }];
    names.extend(acc.iter().map(|f| format!("acc{f}")));
    names.extend(disp.iter().map(|f| format!("disp{f}")));
    names
}
