//! Reading and writing: recorded test campaigns (`../shared/spec/recording-format.md`),
//! atomic output files, and result tables.

mod types;

pub use types::{Campaign, Channel, NominalModel, Quantity, Test, TestKind};
