//! Campaign reader, per the shared recording format
//! (`../shared/spec/recording-format.md`) and the project's backward-compatible extension
//! to general models (`docs/recording-format.md`: `structure = "general"` with a model
//! manifest, channels and impacts on DOFs, a sign per channel):
//!
//! ```text
//! <campaign>/campaign.toml            title and [nominal] model
//! <campaign>/tests/<name>/test.toml   kind, sample_rate_hz, excited_floor, [[channel]]s
//! <campaign>/tests/<name>/data.csv    header `time_s,<channel names>`, one row per sample
//! ```
//!
//! Bad input never panics: every problem becomes an [`Error`] that names the file (and
//! the 1-based line and column for a bad cell) and says what to fix. Unknown TOML keys are
//! ignored with a warning (collected in [`Campaign::warnings`]), so later versions of the
//! format can add keys. Tests are read in parallel (one test per task); the first error
//! in test-folder order is returned, whatever the thread count.

mod data_csv;
mod location;
mod nominal;
mod test_toml;

use super::{Campaign, NominalModel};
use crate::error::{Error, Result};
use rayon::prelude::*;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// `campaign.toml` as written; fields are optional so that a missing one gets a message
/// that says what to add.
#[derive(Debug, Deserialize)]
struct RawCampaign {
    title: Option<String>,
    nominal: Option<RawNominal>,
    #[serde(flatten)]
    extra: toml::Table,
}

/// The `[nominal]` section as written.
#[derive(Debug, Deserialize)]
struct RawNominal {
    structure: Option<String>,
    floor_mass_kg: Option<Vec<f64>>,
    story_stiffness_n_per_m: Option<Vec<f64>>,
    /// Model manifest of a general model, relative to the campaign folder.
    manifest: Option<String>,
    #[serde(flatten)]
    extra: toml::Table,
}

/// Reads `campaign.toml` only (the nominal model). Warnings about unknown keys are
/// dropped; use [`read_campaign`] to see them.
pub fn read_nominal(root: &Path) -> Result<NominalModel> {
    let mut warnings = Vec::new();
    read_campaign_toml(root, &mut warnings).map(|(_, nominal)| nominal)
}

/// Reads a whole campaign: `campaign.toml`, then every `tests/<name>/` folder sorted by
/// folder name, validated against the nominal model (floor indices in 0..=n).
pub fn read_campaign(root: &Path) -> Result<Campaign> {
    let mut warnings = Vec::new();
    let (title, nominal) = read_campaign_toml(root, &mut warnings)?;
    let names = test_folders(root, &mut warnings)?;
    let specs = names
        .iter()
        .map(|name| test_toml::read_test_toml(root, name, &nominal, &mut warnings))
        .collect::<Result<Vec<_>>>()?;
    // Collect every result in order, then take the first error: deterministic.
    let results: Vec<Result<_>> = specs
        .into_par_iter()
        .map(|spec| {
            let path = root.join("tests").join(&spec.name).join("data.csv");
            let data = data_csv::read_data(&path, &spec.channels, spec.sample_rate_hz)?;
            Ok(spec.into_test(data))
        })
        .collect();
    let tests = results.into_iter().collect::<Result<Vec<_>>>()?;
    Ok(Campaign {
        root: root.to_path_buf(),
        title,
        nominal,
        tests,
        warnings,
    })
}

/// Reads a whole file, turning "not found" into a message that says what the campaign
/// layout needs.
fn read_text(path: &Path, what_it_is: &str) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::invalid(
            path,
            format!("file not found; {what_it_is} (see the recording format)"),
        ),
        _ => Error::io(path, e),
    })
}

/// Warns about every key of `extra` (keys the format does not define).
fn warn_unknown(extra: &toml::Table, place: &str, warnings: &mut Vec<String>) {
    for key in extra.keys() {
        warnings.push(format!("{place}: unknown key `{key}` ignored"));
    }
}

/// Parses `text` as TOML into `T`, naming `path` in the error.
fn parse_toml<T: serde::de::DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        Error::invalid(
            path,
            format!(
                "not valid for the recording format: {}",
                e.to_string().trim_end()
            ),
        )
    })
}

/// Title and validated nominal model of `root/campaign.toml`.
fn read_campaign_toml(root: &Path, warnings: &mut Vec<String>) -> Result<(String, NominalModel)> {
    let path = root.join("campaign.toml");
    let text = read_text(
        &path,
        "a campaign folder needs campaign.toml with a title and a [nominal] model",
    )?;
    let raw: RawCampaign = parse_toml(&path, &text)?;
    warn_unknown(&raw.extra, "campaign.toml", warnings);
    let title = match raw.title {
        Some(t) => t,
        None => {
            warnings.push("campaign.toml: no `title`; using the folder name".into());
            root.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        }
    };
    let nominal = raw.nominal.ok_or_else(|| {
        Error::invalid(
            &path,
            "no [nominal] section; add [nominal] with structure = \"shear_frame\", \
             floor_mass_kg = [...] and story_stiffness_n_per_m = [...]",
        )
    })?;
    warn_unknown(&nominal.extra, "campaign.toml [nominal]", warnings);
    Ok((title, nominal::validate(&path, root, nominal, warnings)?))
}

/// Names of the test folders under `root/tests`, sorted. Hidden entries are skipped;
/// other files are skipped with a warning.
fn test_folders(root: &Path, warnings: &mut Vec<String>) -> Result<Vec<String>> {
    let tests_dir = root.join("tests");
    let entries = std::fs::read_dir(&tests_dir).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Error::invalid(
            &tests_dir,
            "folder not found; a campaign keeps each test in tests/<test-name>/ \
             with test.toml and data.csv",
        ),
        _ => Error::io(&tests_dir, e),
    })?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(&tests_dir, e))?;
        let name = entry.file_name();
        let Some(name) = name.to_str().map(str::to_owned) else {
            return Err(Error::invalid(
                entry.path(),
                "test folder name is not valid UTF-8; rename the folder",
            ));
        };
        if name.starts_with('.') {
            continue;
        }
        let path: PathBuf = entry.path();
        if path.is_dir() {
            names.push(name);
        } else {
            warnings.push(format!("tests/{name}: not a test folder; ignored"));
        }
    }
    if names.is_empty() {
        return Err(Error::invalid(
            &tests_dir,
            "no test folders; add tests/<test-name>/ with test.toml and data.csv",
        ));
    }
    names.sort();
    Ok(names)
}
