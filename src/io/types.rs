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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Channel {
    /// Column name in `data.csv`.
    pub name: String,
    pub quantity: Quantity,
    /// Floor index, 0 = ground / shake-table platform.
    pub floor: usize,
    pub unit: String,
}

/// How a test was excited.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TestKind {
    /// Impact at one floor, base fixed.
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

/// The nominal model of `campaign.toml` (`[nominal]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NominalModel {
    /// Only `"shear_frame"` is defined by the format.
    pub structure: String,
    pub floor_mass_kg: Vec<f64>,
    pub story_stiffness_n_per_m: Vec<f64>,
}

impl NominalModel {
    /// Number of floors.
    pub fn n_floors(&self) -> usize {
        self.floor_mass_kg.len()
    }

    /// The parametrised shear-frame model (Eqs. 20-21) at the nominal values.
    pub fn structural_model(&self) -> Result<StructuralModel> {
        StructuralModel::shear_frame(&self.floor_mass_kg, &self.story_stiffness_n_per_m)
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
