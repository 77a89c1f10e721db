//! Writes a campaign in the shared recording format (the simulator's output); a campaign
//! on a general model in the project's extension (`docs/recording-format.md`).

use super::atomic::{write_atomic, write_atomic_with, StagedDir};
use super::{Campaign, Quantity, TestKind, GENERAL};
use crate::error::{Error, Result};
use std::path::{Component, Path, PathBuf};

fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

fn float_list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

fn quantity_name(q: Quantity) -> &'static str {
    match q {
        Quantity::Force => "force",
        Quantity::GroundAcceleration => "ground_acceleration",
        Quantity::Acceleration => "acceleration",
        Quantity::Displacement => "displacement",
    }
}

/// `target` as a path relative to the folder `base` (both made absolute; `..` where
/// they part), so that a campaign can name a model manifest outside it.
fn relative_path(target: &Path, base: &Path) -> Result<PathBuf> {
    let target = target.canonicalize().map_err(|e| Error::io(target, e))?;
    // `base` may not exist yet: canonicalise its deepest existing ancestor.
    let absolute = std::path::absolute(base).map_err(|e| Error::io(base, e))?;
    let existing = absolute
        .ancestors()
        .find(|a| a.exists())
        .unwrap_or(Path::new("/"));
    let rest = absolute.strip_prefix(existing).unwrap_or(Path::new(""));
    let base = existing
        .canonicalize()
        .map_err(|e| Error::io(existing, e))?
        .join(rest);
    let (t, b): (Vec<_>, Vec<_>) = (target.components().collect(), base.components().collect());
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut rel: PathBuf = b[common..].iter().map(|_| Component::ParentDir).collect();
    rel.extend(&t[common..]);
    Ok(rel)
}

/// `campaign.toml` of `campaign`, to be written in `root`.
fn campaign_toml(campaign: &Campaign, root: &Path) -> Result<String> {
    let n = &campaign.nominal;
    let title = toml_string(&campaign.title);
    Ok(match &n.model {
        None => format!(
            "title = {title}\n\n[nominal]\nstructure = {}\nfloor_mass_kg = {}\nstory_stiffness_n_per_m = {}\n",
            toml_string(&n.structure),
            float_list(&n.floor_mass_kg),
            float_list(&n.story_stiffness_n_per_m)
        ),
        Some(g) => {
            let manifest = relative_path(&g.manifest, root)?;
            let manifest = manifest.to_str().ok_or_else(|| {
                Error::invalid(&g.manifest, "the manifest path is not valid UTF-8; rename it")
            })?;
            format!(
                "title = {title}\n\n[nominal]\nstructure = {}\nmanifest = {}\n",
                toml_string(GENERAL),
                toml_string(&manifest.replace('\\', "/"))
            )
        }
    })
}

/// Writes `campaign` to `root` (replacing any existing folder only once the whole campaign
/// is written). Samples are written with the shortest representation that reads back
/// exactly, and `time_s` is `i / sample_rate_hz`. On a general model, the manifest is
/// named relative to `root`, impacts and channels by their DOF (`excited_dof`, `dof`).
pub fn write_campaign(campaign: &Campaign, root: &Path) -> Result<PathBuf> {
    let staged = StagedDir::new(root)?;
    write_campaign_files(campaign, staged.path(), root)?;
    staged.commit()
}

/// Writes the files of `campaign` into the folder `dir` that will become `root` (a
/// staging folder beside it: the manifest path is made relative to `root`).
pub fn write_campaign_files(campaign: &Campaign, dir: &Path, root: &Path) -> Result<()> {
    let toml = campaign_toml(campaign, root)?;
    write_atomic(&dir.join("campaign.toml"), toml.as_bytes())?;
    let general = campaign.nominal.model.is_some();
    for test in &campaign.tests {
        let dir = dir.join("tests").join(&test.name);
        let mut t = String::new();
        match test.kind {
            TestKind::Hammer { excited_floor } => {
                let key = if general {
                    "excited_dof"
                } else {
                    "excited_floor"
                };
                t += &format!(
                    "kind = \"hammer\"\nsample_rate_hz = {:?}\n{key} = {excited_floor}\n",
                    test.sample_rate_hz
                );
            }
            TestKind::ShakeTable => {
                t += &format!(
                    "kind = \"shake_table\"\nsample_rate_hz = {:?}\n",
                    test.sample_rate_hz
                );
            }
        }
        for c in &test.channels {
            let key = if general && c.floor > 0 {
                "dof"
            } else {
                "floor"
            };
            t += &format!(
                "\n[[channel]]\nname = {}\nquantity = \"{}\"\n{key} = {}\nunit = {}\n",
                toml_string(&c.name),
                quantity_name(c.quantity),
                c.floor,
                toml_string(&c.unit)
            );
        }
        write_atomic(&dir.join("test.toml"), t.as_bytes())?;
        if test.data.len() != test.channels.len()
            || test.data.iter().any(|d| d.len() != test.n_samples())
        {
            return Err(Error::Usage(format!(
                "test {}: one equal-length series per channel needed",
                test.name
            )));
        }
        write_atomic_with(&dir.join("data.csv"), |w| {
            write!(w, "time_s")?;
            for c in &test.channels {
                write!(w, ",{}", c.name)?;
            }
            writeln!(w)?;
            for i in 0..test.n_samples() {
                write!(w, "{:?}", i as f64 / test.sample_rate_hz)?;
                for d in &test.data {
                    write!(w, ",{:e}", d[i])?;
                }
                writeln!(w)?;
            }
            Ok(())
        })?;
    }
    Ok(())
}
