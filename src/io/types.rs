//! In-memory form of a recorded test campaign (see `../shared/spec/recording-format.md`).

use crate::error::Result;
use crate::model::StructuralModel;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What a channel measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// Impact force at `floor` (hammer tests), N.
    Force,
    /// Absolute acceleration of the shake-table platform, m/s^2.
    GroundAcceleration,
    /// Absolute acceleration of `floor`, m/s^2.
    Acceleration,
    /// Displacement of `floor` relative to the ground / platform, m.
    Displacement,
}

impl Quantity {
    /// The SI unit the format requires for this quantity.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Force => "N",
            Quantity::GroundAcceleration | Quantity::Acceleration => "m/s^2",
            Quantity::Displacement => "m",
        }
    }
}

/// One channel of a test.
///
/// Its samples (in [`Test::data`]) are in the model's positive direction at its
/// location: the reader multiplies a column recorded with `sign = -1` by -1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Channel {
    /// Column name in `data.csv`.
    pub name: String,
    pub quantity: Quantity,
    /// Location, 0 = ground / shake-table platform; `k >= 1` is floor `k` of a shear
    /// frame, which is model DOF `k` (1-based), or DOF `k` (1-based) of a general model.
    /// See [`Channel::dof`].
    pub floor: usize,
    pub unit: String,
}

impl Channel {
    /// The model DOF the channel measures, 0-based (`floor - 1`); `None` on the ground.
    pub fn dof(&self) -> Option<usize> {
        self.floor.checked_sub(1)
    }
}

/// How a test was excited.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TestKind {
    /// Impact at one floor, base fixed. For a general model `excited_floor` is the
    /// impacted DOF, 1-based (`excited_dof` in `test.toml`).
    Hammer { excited_floor: usize },
    /// Base driven by a shake table.
    ShakeTable,
}

/// One test: its description and its samples.
#[derive(Debug, Clone)]
pub struct Test {
    /// Folder name under `tests/`.
    pub name: String,
    pub kind: TestKind,
    pub sample_rate_hz: f64,
    pub channels: Vec<Channel>,
    /// Samples per channel, in the order of `channels` (not of the CSV header).
    pub data: Vec<Vec<f64>>,
}

impl Test {
    /// Number of samples per channel.
    pub fn n_samples(&self) -> usize {
        self.data.first().map_or(0, Vec::len)
    }

    /// Index of the first channel measuring `quantity`.
    pub fn find(&self, quantity: Quantity) -> Option<usize> {
        self.channels.iter().position(|c| c.quantity == quantity)
    }

    /// Indices of the response channels (acceleration and displacement), in channel order.
    pub fn response_channels(&self) -> Vec<usize> {
        self.channels
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c.quantity, Quantity::Acceleration | Quantity::Displacement))
            .map(|(i, _)| i)
            .collect()
    }
}

/// The nominal model of `campaign.toml` (`[nominal]`): a shear frame (the shared
/// recording format) or a general linear model named by a manifest (the project's
/// extension, `docs/recording-format.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NominalModel {
    /// `"shear_frame"` or `"general"`.
    pub structure: String,
    /// Floor masses of a shear frame, floor 1 first (empty for a general model).
    pub floor_mass_kg: Vec<f64>,
    /// Story stiffnesses of a shear frame, story 1 first (empty for a general model).
    pub story_stiffness_n_per_m: Vec<f64>,
    /// The general model (`structure = "general"`); `None` for a shear frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<GeneralModel>,
}

/// A general linear model given by a model manifest ([`crate::model::ModelManifest`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GeneralModel {
    /// The manifest (`campaign.toml` gives it relative to the campaign folder; the reader
    /// stores it canonicalised).
    pub manifest: PathBuf,
    /// Number of DOFs; channels and impacts name DOFs `1..=n_dof`.
    pub n_dof: usize,
}

/// `structure` of a shear frame.
pub const SHEAR_FRAME: &str = "shear_frame";
/// `structure` of a general model.
pub const GENERAL: &str = "general";

impl NominalModel {
    /// A shear frame (`structure = "shear_frame"`).
    pub fn shear_frame(floor_mass_kg: Vec<f64>, story_stiffness_n_per_m: Vec<f64>) -> Self {
        NominalModel {
            structure: SHEAR_FRAME.into(),
            floor_mass_kg,
            story_stiffness_n_per_m,
            model: None,
        }
    }

    /// A general model of `n_dof` DOFs given by `manifest` (`structure = "general"`).
    pub fn general(manifest: PathBuf, n_dof: usize) -> Self {
        NominalModel {
            structure: GENERAL.into(),
            floor_mass_kg: Vec::new(),
            story_stiffness_n_per_m: Vec::new(),
            model: Some(GeneralModel { manifest, n_dof }),
        }
    }

    /// Number of locations above the ground: the floors of a shear frame, the DOFs of a
    /// general model (channel locations are `0..=n_floors()`).
    pub fn n_floors(&self) -> usize {
        match &self.model {
            Some(g) => g.n_dof,
            None => self.floor_mass_kg.len(),
        }
    }

    /// True for a shear frame (floors, stories and a base), false for a general model.
    pub fn is_shear_frame(&self) -> bool {
        self.model.is_none()
    }

    /// The parametrised model (Eqs. 20-21) at the nominal values: the shear frame, or the
    /// general model loaded from its manifest.
    pub fn structural_model(&self) -> Result<StructuralModel> {
        match &self.model {
            Some(g) => crate::model::ModelManifest::load(&g.manifest),
            None => {
                StructuralModel::shear_frame(&self.floor_mass_kg, &self.story_stiffness_n_per_m)
            }
        }
    }
}

/// A whole campaign: nominal model and tests sorted by name.
#[derive(Debug, Clone)]
pub struct Campaign {
    /// Folder the campaign was read from (empty when built in memory).
    pub root: PathBuf,
    pub title: String,
    pub nominal: NominalModel,
    pub tests: Vec<Test>,
    /// What the reader ignored (unknown keys, stray files), one message each, naming the
    /// file relative to `root`. Empty when built in memory.
    pub warnings: Vec<String>,
}
