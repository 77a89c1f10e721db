//! The `[nominal]` section of `campaign.toml`: a shear frame (the shared recording
//! format) or a general model named by its manifest (`docs/recording-format.md`).

use super::RawNominal;
use crate::error::{Error, Result};
use crate::io::{NominalModel, GENERAL, SHEAR_FRAME};
use crate::model::ModelManifest;
use std::path::Path;

/// Checks the `[nominal]` section of `path` (in the campaign folder `root`).
pub(super) fn validate(
    path: &Path,
    root: &Path,
    raw: RawNominal,
    warnings: &mut Vec<String>,
) -> Result<NominalModel> {
    let structure = raw.structure.clone().ok_or_else(|| {
        Error::invalid(
            path,
            "[nominal] has no `structure`; add structure = \"shear_frame\"",
        )
    })?;
    match structure.as_str() {
        SHEAR_FRAME => {
            if raw.manifest.is_some() {
                // As the original format: a key it does not define.
                warnings.push("campaign.toml [nominal]: unknown key `manifest` ignored".into());
            }
            shear_frame(path, raw)
        }
        GENERAL => general(path, root, raw),
        _ => Err(Error::invalid(
            path,
            format!(
                "[nominal] structure = \"{structure}\" is not supported; use \"shear_frame\" \
                 (floor masses and story stiffnesses) or \"general\" with \
                 manifest = \"<model manifest>\" (docs/recording-format.md)"
            ),
        )),
    }
}

/// A general model: `manifest` (relative to the campaign folder) is loaded once, to check
/// it and count its DOFs.
fn general(path: &Path, root: &Path, raw: RawNominal) -> Result<NominalModel> {
    for (key, given) in [
        ("floor_mass_kg", raw.floor_mass_kg.is_some()),
        (
            "story_stiffness_n_per_m",
            raw.story_stiffness_n_per_m.is_some(),
        ),
    ] {
        if given {
            return Err(Error::invalid(
                path,
                format!(
                    "[nominal] {key} belongs to a shear frame; a general model takes its \
                     matrices from its manifest: remove {key}"
                ),
            ));
        }
    }
    let manifest = raw.manifest.ok_or_else(|| {
        Error::invalid(
            path,
            "[nominal] structure = \"general\" needs the model: add manifest = \
             \"<path of the model's TOML manifest (k0, m0, [[alpha]], [[beta]]), relative to \
             the campaign folder>\"",
        )
    })?;
    let resolved = root.join(&manifest);
    let canonical = resolved
        .canonicalize()
        .ok()
        .filter(|p| p.is_file())
        .ok_or_else(|| {
            Error::invalid(
                path,
                format!(
                    "[nominal] manifest = \"{manifest}\": {} not found; give the model's TOML \
                     manifest as a path relative to the campaign folder",
                    resolved.display()
                ),
            )
        })?;
    let model = ModelManifest::load(&canonical)
        .map_err(|e| Error::invalid(path, format!("[nominal] manifest = \"{manifest}\": {e}")))?;
    Ok(NominalModel::general(canonical, model.n_dof()))
}

/// A shear frame: one mass per floor and one stiffness per story, all positive and
/// finite.
fn shear_frame(path: &Path, raw: RawNominal) -> Result<NominalModel> {
    let floor_mass_kg = raw.floor_mass_kg.ok_or_else(|| {
        Error::invalid(
            path,
            "[nominal] has no `floor_mass_kg`; add one mass in kg per floor, floor 1 first",
        )
    })?;
    let story_stiffness_n_per_m = raw.story_stiffness_n_per_m.ok_or_else(|| {
        Error::invalid(
            path,
            "[nominal] has no `story_stiffness_n_per_m`; add one stiffness in N/m per story, \
             story 1 (ground to floor 1) first",
        )
    })?;
    if floor_mass_kg.is_empty() {
        return Err(Error::invalid(
            path,
            "[nominal] floor_mass_kg is empty; give one mass in kg per floor",
        ));
    }
    if floor_mass_kg.len() != story_stiffness_n_per_m.len() {
        return Err(Error::invalid(
            path,
            format!(
                "[nominal] floor_mass_kg has {} values but story_stiffness_n_per_m has {}; \
                 a shear frame needs one mass per floor and one stiffness per story \
                 (story i joins floor i-1 and floor i)",
                floor_mass_kg.len(),
                story_stiffness_n_per_m.len()
            ),
        ));
    }
    check_positive(path, "floor_mass_kg", "floor", "kg", &floor_mass_kg)?;
    check_positive(
        path,
        "story_stiffness_n_per_m",
        "story",
        "N/m",
        &story_stiffness_n_per_m,
    )?;
    Ok(NominalModel::shear_frame(
        floor_mass_kg,
        story_stiffness_n_per_m,
    ))
}

fn check_positive(path: &Path, key: &str, item: &str, unit: &str, values: &[f64]) -> Result<()> {
    for (i, &v) in values.iter().enumerate() {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(
                path,
                format!(
                    "[nominal] {key}[{i}] ({item} {}) is {v}; it must be a positive, finite \
                     value in {unit}",
                    i + 1
                ),
            ));
        }
    }
    Ok(())
}
