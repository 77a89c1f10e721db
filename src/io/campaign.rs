//! Campaign reader (placeholder; the real reader follows the shared spec).

use super::{Campaign, NominalModel};
use crate::error::{Error, Result};
use std::path::Path;

/// Reads `campaign.toml` only (the nominal model).
pub fn read_nominal(root: &Path) -> Result<NominalModel> {
    Err(Error::invalid(
        root.join("campaign.toml"),
        "reader not built yet",
    ))
}

/// Reads a whole campaign.
pub fn read_campaign(root: &Path) -> Result<Campaign> {
    Err(Error::invalid(
        root.join("campaign.toml"),
        "reader not built yet",
    ))
}
