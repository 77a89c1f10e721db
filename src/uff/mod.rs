//! Universal File Format dataset 58, "Function at Nodal DOF": the form in which modal
//! analysers (Simcenter Testlab, B&K, HBM catman, m+p, ARTeMIS, I-DEAS) export measured
//! FRFs, coherences and time histories. Both forms are read and written:
//!
//! - **58** (ASCII): records 1-11 of the header, then record 12, the data, in fixed
//!   Fortran formats (6E13.5 single precision; 4E20.12, 2(E13.5,E20.12) or
//!   E13.5,2E20.12 double precision);
//! - **58b** (binary): an extra header line `    58b  BO  FP  NL  NB  0 0 0 0` (Format
//!   `I6,A1,I6,I6,I12,I12,I6,I6,I12,I12`: byte order 1 little-endian / 2 big-endian,
//!   floating-point format 2 = IEEE 754, the number of ASCII header lines (11), the
//!   number of data bytes), the same 11 ASCII records, then the data as raw numbers.
//!
//! A file is a sequence of datasets, each between two lines `    -1`. Datasets other
//! than 58 (geometry 15/2411, units 164, ...) are skipped and listed in
//! [`UffFile::skipped`].
//!
//! # Robustness
//! Every error names the file and the line (ASCII) or byte offset (binary) and what is
//! wrong; no input panics (`tests/uff_reader.rs` reads every truncation and many
//! corruptions of valid files). What the reader tolerates, because analysers write it:
//! lines shorter than 80 columns, `\r\n` line ends, non-ASCII labels (`m/s²`, decoded
//! lossily), Fortran `D` exponents and three-digit exponents, numbers that touch
//! (`-1.0E+00-2.0E+00`), a last data line not filled. In 58b the data length is taken
//! from the number of points and the data type (record 7); the header's byte count is
//! checked against it, and a byte count that disagrees is accepted only when the
//! dataset's end marker sits exactly where the points say (some writers, pyuff among
//! them, put `num_pts x 8` there for complex data); a binary block is never searched
//! for `-1`, which its bytes may contain.
//!
//! # Units
//! Records 8-11 give each axis a specific data type (8 displacement, 11 velocity, 12
//! acceleration, 13 excitation force, 18 frequency, ...), unit exponents and labels.
//! [`units`] turns the labels of an FRF's numerator and denominator into an SI factor
//! (`m/s^2`, `g`, `mm`, `N`, `kN`, `lbf`, `(1/N)*(m/s²)`, ...); labels it does not know
//! are an error asking for the unit in the manifest.
//!
//! Reference: the dataset 58 description of the Structural Dynamics Research Lab
//! (University of Cincinnati, `ceas3.uc.edu/sdrluff`), revision 30-Jun-1999.

mod binary;
mod read;
#[cfg(test)]
mod tests;
pub mod units;
mod write;

pub use read::{read_uff, read_uff_bytes};
pub use write::{write_uff, write_uff_bytes};

use num_complex::Complex64;

/// Function type, record 6 field 1 (the kinds frfbayes uses by name).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FunctionType {
    /// 1: time response.
    TimeResponse,
    /// 4: frequency response function.
    Frf,
    /// 5: transmissibility.
    Transmissibility,
    /// 6: (ordinary) coherence.
    Coherence,
    /// Any other code (auto spectrum 2, PSD 9, ...).
    Other(i32),
}

impl FunctionType {
    /// From the file's code.
    pub fn from_code(code: i32) -> Self {
        match code {
            1 => FunctionType::TimeResponse,
            4 => FunctionType::Frf,
            5 => FunctionType::Transmissibility,
            6 => FunctionType::Coherence,
            c => FunctionType::Other(c),
        }
    }
    /// The file's code.
    pub fn code(self) -> i32 {
        match self {
            FunctionType::TimeResponse => 1,
            FunctionType::Frf => 4,
            FunctionType::Transmissibility => 5,
            FunctionType::Coherence => 6,
            FunctionType::Other(c) => c,
        }
    }
}

/// A node and direction of record 6 (response or reference).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeDof {
    /// Entity name (`NONE` if unused), trimmed.
    pub entity: String,
    pub node: i64,
    /// 0 scalar, 1/2/3 +X/+Y/+Z translation, 4/5/6 +X/+Y/+Z rotation, negative: the
    /// opposite direction.
    pub direction: i32,
}

impl NodeDof {
    /// `"11+X"`, `"3-Z"`, `"5RY"`-style label of the node and direction.
    pub fn label(&self) -> String {
        format!("{}{}", self.node, direction_label(self.direction))
    }
}

/// `+X`, `-Y`, `+RZ`, ... of a record 6 direction code (`S` for scalar, `?` otherwise).
pub fn direction_label(direction: i32) -> &'static str {
    const POS: [&str; 7] = ["S", "+X", "+Y", "+Z", "+RX", "+RY", "+RZ"];
    const NEG: [&str; 7] = ["S", "-X", "-Y", "-Z", "-RX", "-RY", "-RZ"];
    match direction {
        0..=6 => POS[direction as usize],
        -6..=-1 => NEG[(-direction) as usize],
        _ => "?",
    }
}

/// The direction code of a label written as in [`direction_label`] (also `X`, `x`,
/// `+x`, `1`, `-3`).
pub fn parse_direction(label: &str) -> Option<i32> {
    let s = label.trim().to_ascii_uppercase();
    if let Ok(v) = s.parse::<i32>() {
        return (-6..=6).contains(&v).then_some(v);
    }
    let (sign, rest) = match s.strip_prefix('-') {
        Some(r) => (-1, r),
        None => (1, s.strip_prefix('+').unwrap_or(&s)),
    };
    let code = match rest {
        "X" => 1,
        "Y" => 2,
        "Z" => 3,
        "RX" => 4,
        "RY" => 5,
        "RZ" => 6,
        _ => return None,
    };
    Some(sign * code)
}

/// One axis of records 8-11.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Axis {
    /// Specific data type (0 unknown, 1 general, 8 displacement, 11 velocity, 12
    /// acceleration, 13 excitation force, 15 pressure, 17 time, 18 frequency, ...).
    pub data_type: i32,
    pub length_exp: i32,
    pub force_exp: i32,
    pub temperature_exp: i32,
    /// Axis label, trimmed (`NONE` if unused).
    pub label: String,
    /// Units label, trimmed (`NONE` if unused).
    pub units: String,
}

/// Abscissa of record 7.
#[derive(Debug, Clone, PartialEq)]
pub enum Abscissa {
    /// `min + k step`.
    Even { min: f64, step: f64 },
    /// One value per point.
    Uneven(Vec<f64>),
}

/// Ordinates of record 12.
#[derive(Debug, Clone, PartialEq)]
pub enum Ordinate {
    Real(Vec<f64>),
    Complex(Vec<Complex64>),
}

impl Ordinate {
    /// Number of points.
    pub fn len(&self) -> usize {
        match self {
            Ordinate::Real(v) => v.len(),
            Ordinate::Complex(v) => v.len(),
        }
    }
    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The values as complex numbers (real ones with zero imaginary part).
    pub fn to_complex(&self) -> Vec<Complex64> {
        match self {
            Ordinate::Real(v) => v.iter().map(|&x| Complex64::new(x, 0.0)).collect(),
            Ordinate::Complex(v) => v.clone(),
        }
    }
}

/// Precision of the stored numbers (record 7 field 1: 2/5 single, 4/6 double).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Precision {
    Single,
    Double,
}

/// How a dataset is (to be) stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// Dataset 58, ASCII.
    Ascii,
    /// Dataset 58b, IEEE 754, in the given byte order.
    Binary { little_endian: bool },
}

/// One dataset 58: a function of frequency or time at a response DOF, for a reference
/// DOF.
#[derive(Debug, Clone, PartialEq)]
pub struct Function58 {
    /// ID lines 1-5 (records 1-5), right-trimmed.
    pub id_lines: [String; 5],
    pub function_type: FunctionType,
    pub function_id: i32,
    pub version: i32,
    pub load_case: i32,
    pub response: NodeDof,
    pub reference: NodeDof,
    pub abscissa: Abscissa,
    pub z_axis_value: f64,
    /// Abscissa, ordinate (numerator), ordinate denominator, z axis (records 8-11).
    pub axes: [Axis; 4],
    pub ordinate: Ordinate,
    /// As stored in the file (writing: single precision rounds the values).
    pub precision: Precision,
}

impl Function58 {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.ordinate.len()
    }
    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.ordinate.is_empty()
    }
    /// The abscissa value of every point.
    pub fn abscissa_values(&self) -> Vec<f64> {
        match &self.abscissa {
            Abscissa::Even { min, step } => {
                (0..self.len()).map(|k| min + k as f64 * step).collect()
            }
            Abscissa::Uneven(x) => x.clone(),
        }
    }
    /// Ordinate numerator axis (record 9).
    pub fn ordinate_axis(&self) -> &Axis {
        &self.axes[1]
    }
    /// Ordinate denominator axis (record 10).
    pub fn denominator_axis(&self) -> &Axis {
        &self.axes[2]
    }
}

/// Where a dataset was found: its first line (the `    -1` before it), 1-based, and its
/// byte offset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Location {
    pub line: usize,
    pub byte: usize,
}

/// A read file: its datasets 58 in file order, with where each starts and how it was
/// stored, and the other datasets skipped.
#[derive(Debug, Clone, PartialEq)]
pub struct UffFile {
    pub functions: Vec<(Function58, Location, Encoding)>,
    /// Dataset numbers skipped, with their locations.
    pub skipped: Vec<(String, Location)>,
}
