//! Writing datasets 58 (ASCII, the formats of the dataset description) and 58b
//! (IEEE 754 binary).

use super::{Abscissa, Axis, Encoding, Function58, NodeDof, Ordinate, Precision};
use crate::error::{Error, Result};
use crate::io::write_atomic;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `functions` to `path` atomically, each as `encoding` says.
pub fn write_uff(path: &Path, functions: &[Function58], encoding: Encoding) -> Result<()> {
    let bytes = write_uff_bytes(functions, encoding)?;
    write_atomic(path, &bytes)
}

/// The bytes of [`write_uff`]. ASCII: 12 significant digits in double precision
/// (E20.12), 6 in single (E13.5); the abscissa minimum and increment, and an uneven
/// abscissa in ASCII, have 6 (E13.5, as the format prescribes). Binary: exact.
pub fn write_uff_bytes(functions: &[Function58], encoding: Encoding) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    for (k, f) in functions.iter().enumerate() {
        check(f).map_err(|e| Error::Usage(format!("UFF dataset {}: {e}", k + 1)))?;
        write_one(&mut out, f, encoding)?;
    }
    Ok(out)
}

fn check(f: &Function58) -> std::result::Result<(), String> {
    if let Abscissa::Uneven(x) = &f.abscissa {
        if x.len() != f.len() {
            return Err(format!(
                "{} abscissa values for {} points",
                x.len(),
                f.len()
            ));
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err("an abscissa value is not finite".into());
        }
    }
    if let Abscissa::Even { min, step } = f.abscissa {
        if !(min.is_finite() && step.is_finite() && (step > 0.0 || f.len() <= 1)) {
            return Err(format!(
                "even abscissa {min} + k {step}: needs a positive increment"
            ));
        }
    }
    let finite = match &f.ordinate {
        Ordinate::Real(v) => v.iter().all(|x| x.is_finite()),
        Ordinate::Complex(v) => v.iter().all(|x| x.re.is_finite() && x.im.is_finite()),
    };
    if !finite {
        return Err("an ordinate value is not finite".into());
    }
    let texts = f
        .id_lines
        .iter()
        .chain(f.axes.iter().flat_map(|a| [&a.label, &a.units]));
    if texts
        .chain([&f.response.entity, &f.reference.entity])
        .any(|s| s.contains(['\n', '\r']))
    {
        return Err("a label or ID line contains a line break".into());
    }
    for d in [&f.response, &f.reference] {
        if !(-6..=6).contains(&d.direction) || d.node.to_string().len() > 10 {
            return Err(format!(
                "node {} direction {} does not fit record 6",
                d.node, d.direction
            ));
        }
    }
    Ok(())
}

fn write_one(out: &mut Vec<u8>, f: &Function58, encoding: Encoding) -> Result<()> {
    let even = matches!(f.abscissa, Abscissa::Even { .. });
    let complex = matches!(f.ordinate, Ordinate::Complex(_));
    let values = data_values(f);
    let width = match f.precision {
        Precision::Single => 4,
        Precision::Double => 8,
    };
    let mut head = String::from("    -1\n");
    match encoding {
        Encoding::Ascii => head.push_str("    58\n"),
        Encoding::Binary { little_endian } => {
            let order = if little_endian { 1 } else { 2 };
            let n_bytes = values.len() * width;
            let _ = writeln!(
                head,
                "{:6}b{order:6}{:6}{:12}{n_bytes:12}{:6}{:6}{:12}{:12}",
                58, 2, 11, 0, 0, 0, 0
            );
        }
    }
    for id in &f.id_lines {
        let id = if id.trim().is_empty() { "NONE" } else { id };
        let _ = writeln!(head, "{}", clip(id, 80));
    }
    let dof = |d: &NodeDof| {
        let e = if d.entity.trim().is_empty() {
            "NONE"
        } else {
            &d.entity
        };
        format!(" {:<10}{:10}{:4}", clip(e, 10), d.node, d.direction)
    };
    let _ = writeln!(
        head,
        "{:5}{:10}{:5}{:10}{}{}",
        f.function_type.code(),
        f.function_id,
        f.version,
        f.load_case,
        dof(&f.response),
        dof(&f.reference)
    );
    let data_type = match (complex, f.precision) {
        (false, Precision::Single) => 2,
        (false, Precision::Double) => 4,
        (true, Precision::Single) => 5,
        (true, Precision::Double) => 6,
    };
    let (min, step) = match f.abscissa {
        Abscissa::Even { min, step } => (min, step),
        Abscissa::Uneven(_) => (0.0, 0.0),
    };
    let _ = writeln!(
        head,
        "{:10}{:10}{:10}{}{}{}",
        data_type,
        f.len(),
        u8::from(even),
        fortran_e(min, 13, 5),
        fortran_e(step, 13, 5),
        fortran_e(f.z_axis_value, 13, 5)
    );
    for a in &f.axes {
        head.push_str(&axis_line(a));
    }
    out.extend_from_slice(head.as_bytes());
    match encoding {
        Encoding::Ascii => {
            out.extend_from_slice(ascii_data(&values, f.precision, even, complex).as_bytes())
        }
        Encoding::Binary { little_endian } => {
            for v in &values {
                match (f.precision, little_endian) {
                    (Precision::Single, true) => out.extend_from_slice(&(*v as f32).to_le_bytes()),
                    (Precision::Single, false) => out.extend_from_slice(&(*v as f32).to_be_bytes()),
                    (Precision::Double, true) => out.extend_from_slice(&v.to_le_bytes()),
                    (Precision::Double, false) => out.extend_from_slice(&v.to_be_bytes()),
                }
            }
        }
    }
    out.extend_from_slice(b"    -1\n");
    Ok(())
}

/// Record 12's numbers in file order: per point the abscissa (uneven), then the real
/// part, then the imaginary part (complex).
fn data_values(f: &Function58) -> Vec<f64> {
    let x = match &f.abscissa {
        Abscissa::Uneven(x) => Some(x),
        Abscissa::Even { .. } => None,
    };
    let mut v = Vec::new();
    for k in 0..f.len() {
        if let Some(x) = x {
            v.push(x[k]);
        }
        match &f.ordinate {
            Ordinate::Real(y) => v.push(y[k]),
            Ordinate::Complex(y) => v.extend([y[k].re, y[k].im]),
        }
    }
    v
}

/// Record 12 in ASCII: 6E13.5 (single precision), 4E20.12 (double, even),
/// 2(E13.5,E20.12) (real double, uneven), E13.5,2E20.12 (complex double, uneven).
fn ascii_data(values: &[f64], precision: Precision, even: bool, complex: bool) -> String {
    let fields: &[(usize, usize)] = match (precision, even, complex) {
        (Precision::Single, ..) => &[(13, 5); 6],
        (Precision::Double, true, _) => &[(20, 11); 4],
        (Precision::Double, false, false) => &[(13, 5), (20, 11), (13, 5), (20, 11)],
        (Precision::Double, false, true) => &[(13, 5), (20, 11), (20, 11)],
    };
    let mut s = String::new();
    for line in values.chunks(fields.len()) {
        for (v, &(w, d)) in line.iter().zip(fields) {
            s.push_str(&fortran_e(*v, w, d));
        }
        s.push('\n');
    }
    s
}

fn axis_line(a: &Axis) -> String {
    let text = |s: &str| {
        if s.trim().is_empty() {
            "NONE".to_string()
        } else {
            clip(s, 20)
        }
    };
    format!(
        "{:10}{:5}{:5}{:5} {:<20} {:<20}\n",
        a.data_type,
        a.length_exp,
        a.force_exp,
        a.temperature_exp,
        text(&a.label),
        text(&a.units)
    )
}

/// At most `n` characters of `s`.
fn clip(s: &str, n: usize) -> String {
    s.chars().take(n).collect()
}

/// `v` as Fortran `Ew.d` with `decimals` digits after the point of a mantissa in
/// [1, 10) (C's `%w.de`): `-1.23456E+02`, right-aligned in `width` columns.
pub(super) fn fortran_e(v: f64, width: usize, decimals: usize) -> String {
    let s = format!("{v:.decimals$e}");
    let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let sign = if exp < 0 { '-' } else { '+' };
    format!("{:>width$}", format!("{mantissa}E{sign}{:02}", exp.abs()))
}
