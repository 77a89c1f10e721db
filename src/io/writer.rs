//! Writes a campaign in the shared recording format (the simulator's output).

use super::atomic::{write_atomic, write_atomic_with, StagedDir};
use super::{Campaign, Quantity, TestKind};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

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

/// Writes `campaign` to `root` (replacing any existing folder only once the whole campaign
/// is written). Samples are written with the shortest representation that reads back
/// exactly, and `time_s` is `i / sample_rate_hz`.
pub fn write_campaign(campaign: &Campaign, root: &Path) -> Result<PathBuf> {
    let staged = StagedDir::new(root)?;
    let n = &campaign.nominal;
    let toml = format!(
        "title = {}\n\n[nominal]\nstructure = {}\nfloor_mass_kg = {}\nstory_stiffness_n_per_m = {}\n",
        toml_string(&campaign.title),
        toml_string(&n.structure),
        float_list(&n.floor_mass_kg),
        float_list(&n.story_stiffness_n_per_m)
    );
    write_atomic(&staged.path().join("campaign.toml"), toml.as_bytes())?;
    for test in &campaign.tests {
        let dir = staged.path().join("tests").join(&test.name);
        let mut t = String::new();
        match test.kind {
            TestKind::Hammer { excited_floor } => {
                t += &format!(
                    "kind = \"hammer\"\nsample_rate_hz = {:?}\nexcited_floor = {excited_floor}\n",
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
            t += &format!(
                "\n[[channel]]\nname = {}\nquantity = \"{}\"\nfloor = {}\nunit = {}\n",
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
    staged.commit()
}
