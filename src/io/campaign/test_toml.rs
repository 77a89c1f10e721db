//! `tests/<name>/test.toml`: how a test was run and what each channel measures.

use super::location::{channel_location, excited_location, parse_sign};
use super::{parse_toml, read_text, warn_unknown};
use crate::error::{Error, Result};
use crate::io::{Channel, NominalModel, Quantity, Test, TestKind};
use serde::Deserialize;
use std::collections::HashSet;
use std::path::Path;

/// `test.toml` as written. Integers are read as `i64` so that a negative floor gets a
/// message of ours rather than a type error.
#[derive(Debug, Deserialize)]
struct RawTest {
    kind: Option<String>,
    sample_rate_hz: Option<f64>,
    excited_floor: Option<i64>,
    /// The impacted DOF of a general model (1-based; `docs/recording-format.md`).
    excited_dof: Option<toml::Value>,
    #[serde(default)]
    channel: Vec<RawChannel>,
    #[serde(flatten)]
    extra: toml::Table,
}

/// One `[[channel]]` as written.
#[derive(Debug, Deserialize)]
struct RawChannel {
    name: Option<String>,
    quantity: Option<String>,
    floor: Option<i64>,
    /// The model DOF (1-based; `docs/recording-format.md`).
    dof: Option<toml::Value>,
    /// +1 or -1 (`docs/recording-format.md`).
    sign: Option<toml::Value>,
    unit: Option<String>,
    #[serde(flatten)]
    extra: toml::Table,
}

/// A validated `test.toml`, waiting for its samples.
#[derive(Debug)]
pub(super) struct TestSpec {
    pub name: String,
    pub kind: TestKind,
    pub sample_rate_hz: f64,
    pub channels: Vec<Channel>,
    /// Sign of each channel's axis (+1 or -1), in channel order.
    pub signs: Vec<f64>,
}

impl TestSpec {
    /// The test with its samples, each channel's turned to the model's positive direction
    /// (multiplied by its sign).
    pub fn into_test(self, mut data: Vec<Vec<f64>>) -> Test {
        for (series, &sign) in data.iter_mut().zip(&self.signs) {
            if sign < 0.0 {
                series.iter_mut().for_each(|v| *v = -*v);
            }
        }
        Test {
            name: self.name,
            kind: self.kind,
            sample_rate_hz: self.sample_rate_hz,
            channels: self.channels,
            data,
        }
    }
}

fn parse_quantity(s: &str) -> Option<Quantity> {
    match s {
        "force" => Some(Quantity::Force),
        "ground_acceleration" => Some(Quantity::GroundAcceleration),
        "acceleration" => Some(Quantity::Acceleration),
        "displacement" => Some(Quantity::Displacement),
        _ => None,
    }
}

/// Reads and validates `root/tests/<name>/test.toml` against the nominal model.
pub(super) fn read_test_toml(
    root: &Path,
    name: &str,
    nominal: &NominalModel,
    warnings: &mut Vec<String>,
) -> Result<TestSpec> {
    let path = root.join("tests").join(name).join("test.toml");
    let place = format!("tests/{name}/test.toml");
    let text = read_text(
        &path,
        "each test folder needs test.toml with kind, sample_rate_hz and [[channel]] tables",
    )?;
    let raw: RawTest = parse_toml(&path, &text)?;
    warn_unknown(&raw.extra, &place, warnings);
    let bad = |what: String| Error::invalid(&path, what);

    let sample_rate_hz = raw.sample_rate_hz.ok_or_else(|| {
        bad("no `sample_rate_hz`; add sample_rate_hz = <samples per second>".into())
    })?;
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(bad(format!(
            "sample_rate_hz = {sample_rate_hz}; it must be a positive, finite rate in Hz"
        )));
    }

    let (channels, signs): (Vec<Channel>, Vec<f64>) = raw
        .channel
        .into_iter()
        .enumerate()
        .map(|(i, c)| validate_channel(&path, &place, i, c, nominal, warnings))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    if channels.is_empty() {
        return Err(bad(
            "no [[channel]] tables; describe each data.csv column with a [[channel]] table \
             (name, quantity, floor, unit)"
                .into(),
        ));
    }
    let mut seen = HashSet::new();
    for c in &channels {
        if !seen.insert(c.name.as_str()) {
            return Err(bad(format!(
                "channel name `{}` is used twice; every channel needs its own data.csv column name",
                c.name
            )));
        }
    }

    let kind_name = raw
        .kind
        .ok_or_else(|| bad("no `kind`; add kind = \"hammer\" or kind = \"shake_table\"".into()))?;
    let kind = match kind_name.as_str() {
        "hammer" => {
            let excited_floor =
                excited_location(raw.excited_floor, raw.excited_dof.as_ref(), nominal)
                    .map_err(bad)?;
            let force = only_one(&path, &channels, Quantity::Force, "a hammer test")?;
            if force.floor != excited_floor {
                let (what, key) = match nominal.model {
                    Some(_) => ("DOF", "excited_dof"),
                    None => ("floor", "excited_floor"),
                };
                return Err(bad(format!(
                    "force channel `{}` is at {what} {} but {key} = {excited_floor}; \
                     the hammer force is measured where it is applied",
                    force.name, force.floor
                )));
            }
            TestKind::Hammer { excited_floor }
        }
        "shake_table" => {
            for (key, given) in [
                ("excited_floor", raw.excited_floor.is_some()),
                ("excited_dof", raw.excited_dof.is_some()),
            ] {
                if given {
                    warnings.push(format!(
                        "{place}: `{key}` is ignored for a shake_table test"
                    ));
                }
            }
            let ground = only_one(
                &path,
                &channels,
                Quantity::GroundAcceleration,
                "a shake_table test",
            )?;
            if ground.floor != 0 {
                return Err(bad(format!(
                    "ground_acceleration channel `{}` is at floor {}; the shake-table platform \
                     is floor 0",
                    ground.name, ground.floor
                )));
            }
            TestKind::ShakeTable
        }
        other => {
            return Err(bad(format!(
                "kind = \"{other}\" is not known; use \"hammer\" or \"shake_table\""
            )))
        }
    };
    Ok(TestSpec {
        name: name.to_string(),
        kind,
        sample_rate_hz,
        channels,
        signs,
    })
}

/// The single channel measuring `quantity`; an error if there is none or more than one.
fn only_one<'a>(
    path: &Path,
    channels: &'a [Channel],
    quantity: Quantity,
    test: &str,
) -> Result<&'a Channel> {
    let q = quantity_key(quantity);
    let mut found = channels.iter().filter(|c| c.quantity == quantity);
    let first = found.next().ok_or_else(|| {
        Error::invalid(
            path,
            format!(
                "{test} needs a channel with quantity = \"{q}\"; add one and its data.csv column"
            ),
        )
    })?;
    if let Some(second) = found.next() {
        return Err(Error::invalid(
            path,
            format!(
                "{test} needs exactly one \"{q}\" channel, found `{}` and `{}`; keep one",
                first.name, second.name
            ),
        ));
    }
    Ok(first)
}

fn quantity_key(q: Quantity) -> &'static str {
    match q {
        Quantity::Force => "force",
        Quantity::GroundAcceleration => "ground_acceleration",
        Quantity::Acceleration => "acceleration",
        Quantity::Displacement => "displacement",
    }
}

/// Checks one `[[channel]]` (the `index`-th, 0-based); returns it with its sign.
fn validate_channel(
    path: &Path,
    place: &str,
    index: usize,
    raw: RawChannel,
    nominal: &NominalModel,
    warnings: &mut Vec<String>,
) -> Result<(Channel, f64)> {
    let number = index + 1;
    let bad = |what: String| Error::invalid(path, format!("[[channel]] #{number}: {what}"));
    let name = raw
        .name
        .ok_or_else(|| bad("no `name`; add name = \"<data.csv column name>\"".into()))?;
    let name_trimmed = name.trim();
    if name_trimmed.is_empty() {
        return Err(bad("empty `name`; give the data.csv column name".into()));
    }
    if name_trimmed == "time_s" {
        return Err(bad(
            "name = \"time_s\" is reserved for the time column; rename the channel".into(),
        ));
    }
    let bad = |what: String| {
        Error::invalid(
            path,
            format!("[[channel]] #{number} (`{name_trimmed}`): {what}"),
        )
    };
    warn_unknown(
        &raw.extra,
        &format!("{place} channel `{name_trimmed}`"),
        warnings,
    );
    let q_name = raw.quantity.ok_or_else(|| {
        bad("no `quantity`; add quantity = force | ground_acceleration | acceleration | displacement".into())
    })?;
    let quantity = parse_quantity(&q_name).ok_or_else(|| {
        bad(format!(
            "quantity = \"{q_name}\" is not known; use force, ground_acceleration, \
             acceleration or displacement"
        ))
    })?;
    let floor = channel_location(raw.floor, raw.dof.as_ref(), quantity, nominal).map_err(bad)?;
    let sign = parse_sign(raw.sign.as_ref()).map_err(bad)?;
    let unit = raw
        .unit
        .ok_or_else(|| bad(format!("no `unit`; add unit = \"{}\"", quantity.unit())))?;
    if unit != quantity.unit() {
        return Err(bad(format!(
            "unit = \"{unit}\" does not match quantity = \"{q_name}\"; the format requires \
             \"{}\" (convert the data to SI units)",
            quantity.unit()
        )));
    }
    Ok((
        Channel {
            name: name_trimmed.to_string(),
            quantity,
            floor,
            unit,
        },
        sign,
    ))
}
