//! Reading and writing: recorded test campaigns (`../shared/spec/recording-format.md`),
//! atomic output files, `run.json` records, and result tables.

pub mod atomic;
pub mod bundled;
mod campaign;
pub mod output;
pub mod runinfo;
pub mod scratch;
pub mod stages;
mod types;
mod writer;

pub use atomic::{write_atomic, write_atomic_with, StagedDir};
pub use bundled::resolve_data;
pub use campaign::{read_campaign, read_nominal};
pub use output::{partial_path_of, OutputClaim, MANIFEST};
pub use runinfo::RunInfo;
pub use scratch::{read_tree, write_tree, ScratchDir};
pub use types::{
    Campaign, Channel, GeneralModel, NominalModel, Quantity, Test, TestKind, GENERAL, SHEAR_FRAME,
};
pub use writer::{write_campaign, write_campaign_files};
