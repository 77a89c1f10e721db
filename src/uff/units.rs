//! Units of an FRF from the labels of records 9 and 10: what the numerator and the
//! denominator measure and their factors to SI.
//!
//! Analysers write the units of an FRF either split (record 9 `m/s^2`, record 10 `N`) or
//! whole in record 9 (`m/s^2/N`, `(m/s²)/N`, `(1/N)*(m/s²)`, `g/N`). Both are understood.
//! Known units: displacement `m mm um µm cm in`, velocity `m/s mm/s in/s`, acceleration
//! `m/s^2 mm/s^2 g in/s^2` (also `m/s2`, `m/s²`, `m/s**2`), force `N kN lbf lb`.

/// What a unit measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dimension {
    Displacement,
    Velocity,
    Acceleration,
    Force,
}

/// A unit: its dimension and the factor that turns its values into SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    pub dimension: Dimension,
    pub to_si: f64,
}

/// Standard gravity, m/s^2 (the unit `g`).
pub const STANDARD_GRAVITY_M_S2: f64 = 9.80665;

/// Labels normalised: blanks dropped, `²`, `s2`, `**2` written `^2`, `μ` as `u`.
fn normalise(label: &str) -> String {
    let s: String = label.chars().filter(|c| !c.is_whitespace()).collect();
    let s = s
        .replace('²', "^2")
        .replace("**", "^")
        .replace(['µ', 'μ'], "u");
    let s = strip_parens(&s);
    if s.ends_with("s2") && !s.ends_with("^2") {
        format!("{}^2", &s[..s.len() - 1])
    } else {
        s.to_string()
    }
}

/// `(x)` without its outer parentheses (when they enclose it all).
fn strip_parens(s: &str) -> &str {
    match s.strip_prefix('(').and_then(|r| r.strip_suffix(')')) {
        Some(inner) if depth_ok(inner) => inner,
        _ => s,
    }
}

/// True when the parentheses of `s` balance without going negative.
fn depth_ok(s: &str) -> bool {
    let mut d = 0i32;
    for c in s.chars() {
        match c {
            '(' => d += 1,
            ')' => d -= 1,
            _ => {}
        }
        if d < 0 {
            return false;
        }
    }
    d == 0
}

/// A simple unit (`m/s^2`, `N`, `g`, ...).
pub fn parse_unit(label: &str) -> Option<Unit> {
    use Dimension::*;
    let s = normalise(label);
    let (dimension, to_si) = match s.as_str() {
        "m" => (Displacement, 1.0),
        "mm" => (Displacement, 1e-3),
        "um" => (Displacement, 1e-6),
        "cm" => (Displacement, 1e-2),
        "in" => (Displacement, 0.0254),
        "m/s" => (Velocity, 1.0),
        "mm/s" => (Velocity, 1e-3),
        "in/s" => (Velocity, 0.0254),
        "m/s^2" => (Acceleration, 1.0),
        "mm/s^2" => (Acceleration, 1e-3),
        "in/s^2" => (Acceleration, 0.0254),
        "g" | "G" => (Acceleration, STANDARD_GRAVITY_M_S2),
        "N" => (Force, 1.0),
        "kN" => (Force, 1e3),
        "lbf" | "lb" | "lbF" => (Force, 4.448_221_615_260_5),
        _ => return None,
    };
    Some(Unit { dimension, to_si })
}

/// Numerator and denominator units of an FRF from record 9's and record 10's units
/// labels; `None` when they are not understood.
pub fn frf_units(ordinate: &str, denominator: &str) -> Option<(Unit, Unit)> {
    let unused = |s: &str| {
        let t = s.trim();
        t.is_empty() || t.eq_ignore_ascii_case("none")
    };
    if !unused(denominator) {
        return Some((parse_unit(ordinate)?, parse_unit(denominator)?));
    }
    let s = normalise(ordinate);
    // (1/B)*(A) or (1/B)*A
    if let Some(rest) = s.strip_prefix("(1/") {
        let (b, a) = rest.split_once(")*")?;
        return Some((parse_unit(a)?, parse_unit(b)?));
    }
    // A/B at the last '/' outside parentheses, trying every such split
    let cuts: Vec<usize> = s
        .char_indices()
        .filter(|&(i, c)| c == '/' && depth_ok(&s[..i]))
        .map(|(i, _)| i)
        .collect();
    cuts.iter()
        .rev()
        .find_map(|&i| Some((parse_unit(&s[..i])?, parse_unit(&s[i + 1..])?)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn analyser_labels() {
        let acc = |l: &str, d: &str| {
            frf_units(l, d).map(|(n, d)| (n.dimension, n.to_si, d.dimension, d.to_si))
        };
        use Dimension::*;
        assert_eq!(acc("m/s^2", "N"), Some((Acceleration, 1.0, Force, 1.0)));
        assert_eq!(
            acc("(1/N)*(m/s²)", "NONE"),
            Some((Acceleration, 1.0, Force, 1.0))
        );
        assert_eq!(acc("m/s²/N", ""), Some((Acceleration, 1.0, Force, 1.0)));
        assert_eq!(
            acc("(m/s2)/N", "NONE"),
            Some((Acceleration, 1.0, Force, 1.0))
        );
        assert_eq!(
            acc("g/N", "NONE"),
            Some((Acceleration, STANDARD_GRAVITY_M_S2, Force, 1.0))
        );
        assert_eq!(acc("mm/N", "NONE"), Some((Displacement, 1e-3, Force, 1.0)));
        assert_eq!(
            acc("(m/s^2)/(m/s^2)", "NONE"),
            Some((Acceleration, 1.0, Acceleration, 1.0))
        );
        assert_eq!(acc("m", "kN"), Some((Displacement, 1.0, Force, 1e3)));
        assert_eq!(acc("Pa", "NONE"), None);
        assert_eq!(acc("m/s^2", "furlong"), None);
        assert_eq!(acc("NONE", "NONE"), None);
    }
}
