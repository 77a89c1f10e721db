//! Where a hypothesis of missing physics acts: the whole structure, one story, one floor,
//! a connection between two DOFs of a general model, named channels, or every channel of
//! one quantity.
//!
//! Serialised exactly as `diagnosis.json` writes it (issue 5): `{}`, `{"story": 2}`,
//! `{"floor": 3}`, `{"dofs": [2, 5]}`, `{"channels": ["acc1", "acc3"]}`,
//! `{"quantity": "acceleration"}`. A general model's floor is its DOF (1-based, the
//! campaign format's convention); a connection joins two of them (0 = the ground).

use crate::io::Quantity;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// Location of a hypothesis' effect.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub enum Location {
    /// The whole structure (e.g. its base): `{}`.
    #[default]
    Whole,
    /// Story `s` (between floors `s - 1` and `s`, floor 0 the base): `{"story": s}`.
    Story(usize),
    /// Floor `f` (1-based): `{"floor": f}`.
    Floor(usize),
    /// The connection between DOFs `a < b` of a general model (1-based; 0 the ground):
    /// `{"dofs": [a, b]}`, a general model's counterpart of a story.
    Dofs([usize; 2]),
    /// Named channels (input channels included): `{"channels": [...]}`.
    Channels(Vec<String>),
    /// Every channel measuring one quantity: `{"quantity": "acceleration"}`.
    Quantity(Quantity),
}

/// The JSON object form: at most one key.
#[derive(Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Repr {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    story: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    floor: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    dofs: Option<[usize; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    channels: Option<Vec<String>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    quantity: Option<Quantity>,
}

impl Serialize for Location {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let mut r = Repr::default();
        match self {
            Location::Whole => {}
            Location::Story(v) => r.story = Some(*v),
            Location::Floor(v) => r.floor = Some(*v),
            Location::Dofs(v) => r.dofs = Some(*v),
            Location::Channels(v) => r.channels = Some(v.clone()),
            Location::Quantity(q) => r.quantity = Some(*q),
        }
        r.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Location {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let r = Repr::deserialize(d)?;
        match (r.story, r.floor, r.dofs, r.channels, r.quantity) {
            (None, None, None, None, None) => Ok(Location::Whole),
            (Some(s), None, None, None, None) => Ok(Location::Story(s)),
            (None, Some(f), None, None, None) => Ok(Location::Floor(f)),
            (None, None, Some(d), None, None) => Ok(Location::Dofs(d)),
            (None, None, None, Some(c), None) => Ok(Location::Channels(c)),
            (None, None, None, None, Some(q)) => Ok(Location::Quantity(q)),
            _ => Err(serde::de::Error::custom(
                "a location has at most one of `story`, `floor`, `dofs`, `channels`, `quantity`",
            )),
        }
    }
}

impl fmt::Display for Location {
    /// Plain words for reports: "the whole structure", "story 2", "floor 3",
    /// "channels acc1, acc3", "every acceleration channel".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Whole => write!(f, "the whole structure"),
            Location::Story(s) => write!(f, "story {s}"),
            Location::Floor(v) => write!(f, "floor {v}"),
            Location::Dofs([a, b]) => write!(f, "DOFs {a}-{b}"),
            Location::Channels(c) => write!(f, "channels {}", c.join(", ")),
            Location::Quantity(q) => {
                let name = serde_json::to_value(q)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_owned))
                    .unwrap_or_default();
                write!(f, "every {} channel", name.replace('_', " "))
            }
        }
    }
}

impl Location {
    /// True when a channel called `name` measuring `quantity` is at this location
    /// (always false for structural locations).
    pub fn covers_channel(&self, name: &str, quantity: Quantity) -> bool {
        match self {
            Location::Channels(c) => c.iter().any(|c| c == name),
            Location::Quantity(q) => *q == quantity,
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serialises_exactly_as_the_issue_json() {
        let cases = [
            (Location::Whole, r#"{}"#),
            (Location::Story(2), r#"{"story":2}"#),
            (Location::Floor(3), r#"{"floor":3}"#),
            (Location::Dofs([2, 5]), r#"{"dofs":[2,5]}"#),
            (
                Location::Channels(vec!["acc1".into(), "acc3".into()]),
                r#"{"channels":["acc1","acc3"]}"#,
            ),
            (
                Location::Quantity(Quantity::Acceleration),
                r#"{"quantity":"acceleration"}"#,
            ),
            (
                Location::Quantity(Quantity::Displacement),
                r#"{"quantity":"displacement"}"#,
            ),
        ];
        for (loc, json) in cases {
            assert_eq!(serde_json::to_string(&loc).unwrap(), json);
            let back: Location = serde_json::from_str(json).unwrap();
            assert_eq!(back, loc);
        }
    }

    #[test]
    fn rejects_two_keys_and_unknown_keys() {
        assert!(serde_json::from_str::<Location>(r#"{"story":1,"floor":2}"#).is_err());
        assert!(serde_json::from_str::<Location>(r#"{"storey":1}"#).is_err());
        assert!(serde_json::from_str::<Location>(r#"{"quantity":"speed"}"#).is_err());
        // TOML form of cases.toml reads the same way.
        let t: toml::Value = toml::from_str("location = { story = 3 }").unwrap();
        let loc: Location = t["location"].clone().try_into().unwrap();
        assert_eq!(loc, Location::Story(3));
    }

    #[test]
    fn covers_and_displays() {
        let q = Location::Quantity(Quantity::Acceleration);
        assert!(q.covers_channel("acc9", Quantity::Acceleration));
        assert!(!q.covers_channel("disp1", Quantity::Displacement));
        let c = Location::Channels(vec!["force".into()]);
        assert!(c.covers_channel("force", Quantity::Force));
        assert!(!Location::Story(1).covers_channel("acc1", Quantity::Acceleration));
        assert_eq!(q.to_string(), "every acceleration channel");
        assert_eq!(Location::Story(2).to_string(), "story 2");
    }
}
