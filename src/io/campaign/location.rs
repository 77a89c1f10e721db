//! Where a channel or an impact is, and the sign of its axis: a floor of a shear frame
//! (the shared recording format) or a model DOF, 1-based (the extension of
//! `docs/recording-format.md`). Errors are returned as the text of what to fix; the
//! caller adds the file and the table they concern.

use crate::io::{NominalModel, Quantity};

/// How the nominal model is named in messages.
fn model_desc(nominal: &NominalModel) -> String {
    match &nominal.model {
        Some(g) => format!(
            "the model of {}",
            g.manifest.file_name().map_or_else(
                || g.manifest.display().to_string(),
                |n| n.to_string_lossy().into_owned()
            )
        ),
        None => "the shear frame of campaign.toml (DOF k is floor k)".into(),
    }
}

/// A DOF value of `key`: an integer `1..=n` (1-based, as in Matrix Market files and
/// MATLAB index lists).
pub(super) fn parse_dof(
    key: &str,
    value: &toml::Value,
    nominal: &NominalModel,
) -> Result<usize, String> {
    let n = nominal.n_floors();
    match value {
        toml::Value::Integer(i) if *i >= 1 && *i as u64 <= n as u64 => Ok(*i as usize),
        toml::Value::Integer(i) if *i <= 0 => Err(format!(
            "{key} = {i} is not a DOF: DOFs are numbered 1..={n} (1-based, as in Matrix Market \
             files); the ground is not a DOF"
        )),
        toml::Value::Integer(i) => Err(format!(
            "{key} = {i} is outside 1..={n}: {} has {n} DOFs (1-based); write {key} = <1..={n}>",
            model_desc(nominal)
        )),
        toml::Value::String(s) => Err(format!(
            "{key} = \"{s}\" is not a known DOF: {} names no DOFs; write the DOF number, an \
             integer 1..={n} (1-based)",
            model_desc(nominal)
        )),
        other => Err(format!(
            "{key} = {other} is not a DOF number; write an integer 1..={n} (1-based)"
        )),
    }
}

/// The location of a channel (0 = ground, `k` = floor / DOF `k`) from its `floor` and
/// `dof` keys.
pub(super) fn channel_location(
    floor: Option<i64>,
    dof: Option<&toml::Value>,
    quantity: Quantity,
    nominal: &NominalModel,
) -> Result<usize, String> {
    let n = nominal.n_floors();
    let general = nominal.model.is_some();
    let ground = quantity == Quantity::GroundAcceleration;
    match (floor, dof) {
        (Some(_), Some(_)) => Err(format!(
            "has both `floor` and `dof`; a channel has one location: keep dof = <1..={n}> \
             (the model DOF) or floor = <0..={n}> (a shear-frame floor), not both"
        )),
        (None, Some(_)) if ground => Err(
            "a ground_acceleration channel measures the ground / shake-table platform, not a \
             model DOF; remove `dof` (or write floor = 0)"
                .into(),
        ),
        (None, Some(d)) => parse_dof("dof", d, nominal),
        (Some(0), None) => Ok(0),
        (Some(f), None) if general => Err(format!(
            "floor = {f}: floors belong to shear frames, and the nominal model of this campaign \
             is general ({}); write dof = <1..={n}> instead",
            model_desc(nominal)
        )),
        (Some(f), None) => {
            if f < 0 || f as u64 > n as u64 {
                return Err(format!(
                    "floor = {f} is outside 0..={n} (0 = ground; the nominal model in \
                     campaign.toml has {n} floors)"
                ));
            }
            Ok(f as usize)
        }
        (None, None) if general && ground => Ok(0),
        (None, None) if general => Err(format!(
            "no `dof`; add dof = <1..={n}> (the model DOF the sensor measures, 1-based)"
        )),
        (None, None) => Err(format!("no `floor`; add floor = <0..={n}> (0 = ground)")),
    }
}

/// The impacted location of a hammer test from `excited_floor` and `excited_dof`.
pub(super) fn excited_location(
    floor: Option<i64>,
    dof: Option<&toml::Value>,
    nominal: &NominalModel,
) -> Result<usize, String> {
    let n = nominal.n_floors();
    let general = nominal.model.is_some();
    match (floor, dof) {
        (Some(_), Some(_)) => Err(format!(
            "has both `excited_floor` and `excited_dof`; keep one (excited_dof = <1..={n}> for \
             the model DOF)"
        )),
        (None, Some(d)) => parse_dof("excited_dof", d, nominal),
        (Some(_), None) if general => Err(format!(
            "excited_floor belongs to shear frames, and the nominal model of this campaign is \
             general ({}); write excited_dof = <1..={n}> instead",
            model_desc(nominal)
        )),
        (None, None) if general => Err(format!(
            "a hammer test needs `excited_dof` (the impacted DOF, 1..={n})"
        )),
        (None, None) => Err(format!(
            "a hammer test needs `excited_floor` (the impacted floor, 1..={n})"
        )),
        (Some(f), None) if f < 0 || f as u64 > n as u64 => Err(format!(
            "excited_floor = {f} is outside 0..={n} (the nominal model in campaign.toml has {n} \
             floors)"
        )),
        (Some(0), None) => Err(format!(
            "excited_floor = 0 is the ground; a hammer test impacts a floor 1..={n}"
        )),
        (Some(f), None) => Ok(f as usize),
    }
}

/// The `sign` of a channel: +1 when absent; -1 when the sensor's positive axis points
/// against the model's positive direction at its location.
pub(super) fn parse_sign(value: Option<&toml::Value>) -> Result<f64, String> {
    match value {
        None => Ok(1.0),
        Some(toml::Value::Integer(1)) => Ok(1.0),
        Some(toml::Value::Integer(-1)) => Ok(-1.0),
        Some(toml::Value::Float(x)) if *x == 1.0 || *x == -1.0 => Ok(*x),
        Some(other) => Err(format!(
            "sign = {other} must be +1 or -1 (write sign = -1 when the sensor's positive axis \
             points against the model's positive direction at its location, else leave it out)"
        )),
    }
}
