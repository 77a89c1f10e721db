//! The FRF columns of one test from its file: UFF 58/58b, `.mat`, or CSV.

use super::{ChannelSpec, TestSpec};
use crate::error::{Error, Result};
use crate::io::Quantity;
use crate::model::mat::MatData;
use crate::signal::frf_csv::read_frf_csv;
use crate::uff::units::{frf_units, Dimension, Unit};
use crate::uff::{parse_direction, read_uff, Function58, FunctionType, NodeDof};
use num_complex::Complex64;
use std::path::Path;

/// One response's FRF as the file gives it, with what turns it into the model's.
#[derive(Debug, Clone)]
pub(super) struct Column {
    /// Names the column in messages: `file: response 2+X / reference 1+X`.
    pub label: String,
    /// Short name of the response (the channel name unless the manifest gives one).
    pub name: String,
    pub freq_hz: Vec<f64>,
    pub h: Vec<Complex64>,
    pub coherence: Option<Vec<f64>>,
    /// Numerator and denominator units.
    pub units: (Unit, Unit),
    /// +1, or -1 when the file's directions are opposite to the manifest's.
    pub sign: f64,
}

/// The columns of `spec`'s channels, in channel order.
pub(super) fn read_columns(
    spec: &TestSpec,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Vec<Column>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match ext.as_str() {
        "uff" | "unv" | "uf" => uff_columns(spec, path, warnings),
        "mat" => mat_columns(spec, path),
        "csv" => csv_columns(spec, path),
        _ => Err(Error::invalid(
            path,
            "unknown FRF file type: give a .uff/.unv (dataset 58 or 58b), .mat or .csv file",
        )),
    }
}

/// Units from the manifest: `unit` (an FRF unit) or `quantity` (SI).
fn manifest_units(c: &ChannelSpec, spec: &TestSpec) -> Result<Option<(Unit, Unit)>> {
    if let Some(u) = &c.unit {
        return frf_units(u, "NONE").map(Some).ok_or_else(|| {
            Error::Usage(format!(
                "channel dof = {}: unit = {u:?} is not an FRF unit this reader knows \
                 (e.g. \"m/s^2/N\", \"g/N\", \"mm/N\", \"(m/s^2)/(m/s^2)\")",
                c.dof
            ))
        });
    }
    let num = match c.quantity {
        Some(Quantity::Acceleration) => Dimension::Acceleration,
        Some(Quantity::Displacement) => Dimension::Displacement,
        Some(q) => {
            return Err(Error::Usage(format!(
                "channel dof = {}: quantity {q:?} is not a response",
                c.dof
            )))
        }
        None => return Ok(None),
    };
    let den = match spec.excitation {
        super::Excitation::Force => Dimension::Force,
        super::Excitation::Ground => Dimension::Acceleration,
    };
    let si = |dimension| Unit {
        dimension,
        to_si: 1.0,
    };
    Ok(Some((si(num), si(den))))
}

/// Node and direction of a manifest's `node = "2+X"` (or `reference`).
fn node_dir(text: &str, what: &str) -> Result<(i64, i32)> {
    let t = text.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let node = t[..split].parse::<i64>().ok();
    let dir = parse_direction(&t[split..]).filter(|d| *d != 0);
    match (node, dir) {
        (Some(n), Some(d)) => Ok((n, d)),
        _ => Err(Error::Usage(format!(
            "{what} = {text:?}: write the node and direction, e.g. \"2+X\", \"14-Z\""
        ))),
    }
}

/// The sign of `file` against `want` on the same axis; `None` on another axis or node.
fn matches(file: &NodeDof, (node, dir): (i64, i32)) -> Option<f64> {
    (file.node == node && file.direction.abs() == dir.abs()).then(|| {
        if file.direction.signum() == dir.signum() {
            1.0
        } else {
            -1.0
        }
    })
}

fn uff_columns(spec: &TestSpec, path: &Path, warnings: &mut Vec<String>) -> Result<Vec<Column>> {
    let file = read_uff(path)?;
    let disp = path.display();
    let is_frf = |f: &Function58| {
        matches!(
            f.function_type,
            FunctionType::Frf | FunctionType::Transmissibility
        )
    };
    let frfs: Vec<&Function58> = file
        .functions
        .iter()
        .map(|f| &f.0)
        .filter(|f| is_frf(f))
        .collect();
    let mut refs: Vec<String> = frfs.iter().map(|f| f.reference.label()).collect();
    refs.sort();
    refs.dedup();
    let reference = match &spec.reference {
        Some(r) => node_dir(r, "reference")?,
        // one reference: its axis, positive, is the model's direction
        None if refs.len() == 1 => (frfs[0].reference.node, frfs[0].reference.direction.abs()),
        None => {
            return Err(Error::Usage(format!(
                "{disp} holds FRFs for references [{}]; say which with reference = \"...\"",
                refs.join(", ")
            )))
        }
    };
    let ours: Vec<(&Function58, f64)> = frfs
        .iter()
        .filter_map(|f| matches(&f.reference, reference).map(|s| (*f, s)))
        .collect();
    if ours.is_empty() {
        return Err(Error::Usage(format!(
            "{disp} has no FRF (function type 4 or 5) for reference {}{}; it has [{}]",
            reference.0,
            crate::uff::direction_label(reference.1),
            refs.join(", ")
        )));
    }
    let mut used = vec![false; ours.len()];
    let mut columns = Vec::new();
    for c in &spec.channels {
        let node = c.node.as_deref().ok_or_else(|| {
            Error::Usage(format!(
                "channel dof = {}: add node = \"<node><direction>\", e.g. \"{}+X\"",
                c.dof, c.dof
            ))
        })?;
        let want = node_dir(node, "node")?;
        let mut hits: Vec<usize> = (0..ours.len())
            .filter(|&k| matches(&ours[k].0.response, want).is_some())
            .collect();
        // several at one node and direction (an accelerometer and a displacement sensor):
        // the response entity name (record 6) chooses
        if let (true, Some(name)) = (hits.len() > 1, &c.name) {
            let clipped: String = name.chars().take(10).collect();
            hits.retain(|&k| ours[k].0.response.entity == clipped);
        }
        let &[k] = hits.as_slice() else {
            return Err(Error::Usage(format!(
                "{disp}: {} FRFs for response {node} and reference {}{} (need exactly one)",
                hits.len(),
                reference.0,
                crate::uff::direction_label(reference.1)
            )));
        };
        used[k] = true;
        let (f, ref_sign) = ours[k];
        let sign = ref_sign * matches(&f.response, want).unwrap_or(1.0);
        columns.push(uff_column(c, spec, f, sign, &file.functions, path)?);
    }
    for (k, (f, _)) in ours.iter().enumerate() {
        if !used[k] {
            warnings.push(format!(
                "{disp}: FRF {} / {} is not mapped to a model DOF; not used",
                f.response.label(),
                f.reference.label()
            ));
        }
    }
    Ok(columns)
}

fn uff_column(
    c: &ChannelSpec,
    spec: &TestSpec,
    f: &Function58,
    sign: f64,
    all: &[(Function58, crate::uff::Location, crate::uff::Encoding)],
    path: &Path,
) -> Result<Column> {
    let label = format!(
        "{}: response {} / reference {}",
        path.display(),
        f.response.label(),
        f.reference.label()
    );
    let x = &f.axes[0];
    let hz = x.units.trim().eq_ignore_ascii_case("hz")
        || (x.data_type == 18 && x.units.trim().eq_ignore_ascii_case("none"));
    if !hz {
        return Err(Error::Usage(format!(
            "{label}: the abscissa is {:?} in {:?} (specific data type {}); FRFs need frequency in Hz",
            x.label, x.units, x.data_type
        )));
    }
    let units = match manifest_units(c, spec)? {
        Some(u) => u,
        None => {
            frf_units(&f.ordinate_axis().units, &f.denominator_axis().units).ok_or_else(|| {
                Error::Usage(format!(
                "{label}: units {:?} / {:?} not understood; give unit = \"...\" (e.g. \"m/s^2/N\") \
                 in this [[test.channel]]",
                f.ordinate_axis().units,
                f.denominator_axis().units
            ))
            })?
        }
    };
    let same =
        |d: &NodeDof, e: &NodeDof| d.node == e.node && d.direction.abs() == e.direction.abs();
    let mut coherence: Vec<&Function58> = all
        .iter()
        .map(|a| &a.0)
        .filter(|g| {
            g.function_type == FunctionType::Coherence
                && same(&g.response, &f.response)
                && same(&g.reference, &f.reference)
        })
        .collect();
    if coherence.len() > 1 {
        coherence.retain(|g| g.response.entity == f.response.entity);
    }
    let coherence = match coherence.as_slice() {
        [] => None,
        [g] if g.abscissa_values() == f.abscissa_values() => {
            Some(g.ordinate.to_complex().iter().map(|v| v.re).collect())
        }
        [_] => {
            return Err(Error::Usage(format!(
                "{label}: its coherence is on another frequency grid"
            )))
        }
        _ => {
            return Err(Error::Usage(format!(
                "{label}: {} coherences for it; keep one",
                coherence.len()
            )))
        }
    };
    let entity = f.response.entity.trim();
    let name = if entity.is_empty() || entity.eq_ignore_ascii_case("none") {
        f.response.label()
    } else {
        entity.to_string()
    };
    Ok(Column {
        label,
        name,
        freq_hz: f.abscissa_values(),
        h: f.ordinate.to_complex(),
        coherence,
        units,
        sign,
    })
}

fn si_units(c: &ChannelSpec, spec: &TestSpec) -> Result<(Unit, Unit)> {
    manifest_units(c, spec)?.ok_or_else(|| {
        Error::Usage(format!(
            "channel dof = {}: give quantity = \"acceleration\" or \"displacement\" (values in SI) \
             or unit = \"...\"",
            c.dof
        ))
    })
}

fn csv_columns(spec: &TestSpec, path: &Path) -> Result<Vec<Column>> {
    let table = read_frf_csv(path)?;
    let names: Vec<&str> = table.columns.iter().map(|c| c.name.as_str()).collect();
    spec.channels
        .iter()
        .map(|c| {
            let name = c.name.as_deref().ok_or_else(|| {
                Error::Usage(format!(
                    "channel dof = {}: add name = \"<column prefix>\" (have {})",
                    c.dof,
                    names.join(", ")
                ))
            })?;
            let col = table
                .columns
                .iter()
                .find(|t| t.name == name)
                .ok_or_else(|| {
                    Error::Usage(format!(
                        "{}: no columns {name}_re/_im/_coherence (have {})",
                        path.display(),
                        names.join(", ")
                    ))
                })?;
            Ok(Column {
                label: format!("{}: {name}", path.display()),
                name: name.to_string(),
                freq_hz: table.freq_hz.clone(),
                h: col.h1.clone(),
                coherence: Some(col.coherence.clone()),
                units: si_units(c, spec)?,
                sign: 1.0,
            })
        })
        .collect()
}

fn mat_columns(spec: &TestSpec, path: &Path) -> Result<Vec<Column>> {
    let mat = MatData::open(path)?;
    let freq = mat.vector(&spec.mat.freq, None)?;
    let frf = mat.complex(&spec.mat.frf)?;
    let has_coh = mat.names().iter().any(|n| n == &spec.mat.coherence);
    let coh = has_coh.then(|| mat.real(&spec.mat.coherence)).transpose()?;
    let nf = freq.len();
    // frequency along rows (one column per response) or along columns
    let by_column = frf.rows == nf;
    if !by_column && frf.cols != nf {
        return Err(Error::invalid(
            path,
            format!(
                "`{}` is {} x {}; one of its sizes must be the {nf} frequencies of `{}`",
                spec.mat.frf, frf.rows, frf.cols, spec.mat.freq
            ),
        ));
    }
    if let Some(g) = &coh {
        if (g.rows, g.cols) != (frf.rows, frf.cols) {
            return Err(Error::invalid(
                path,
                format!(
                    "`{}` and `{}` differ in shape",
                    spec.mat.coherence, spec.mat.frf
                ),
            ));
        }
    }
    let n_resp = if by_column { frf.cols } else { frf.rows };
    let pick = |k: usize, j: usize| {
        if by_column {
            k + frf.rows * j
        } else {
            j + frf.rows * k
        }
    };
    spec.channels
        .iter()
        .map(|c| {
            let j = match c.column {
                Some(j) if (1..=n_resp).contains(&j) => j - 1,
                other => {
                    return Err(Error::Usage(format!(
                        "channel dof = {}: column = {other:?}; `{}` has responses 1..={n_resp}",
                        c.dof, spec.mat.frf
                    )))
                }
            };
            Ok(Column {
                label: format!("{}: {} response {}", path.display(), spec.mat.frf, j + 1),
                name: format!("{}{}", spec.mat.frf, j + 1),
                freq_hz: freq.clone(),
                h: (0..nf).map(|k| frf.data[pick(k, j)]).collect(),
                coherence: coh
                    .as_ref()
                    .map(|g| (0..nf).map(|k| g.data[pick(k, j)]).collect()),
                units: si_units(c, spec)?,
                sign: 1.0,
            })
        })
        .collect()
}
