//! Text labels of FRFs for figures and reports: the paper's pair notation (`H4,1`) and
//! the unit of each FRF kind.

use super::{Excitation, FrfKind, FrfPair};

/// Label of an FRF pair in the paper's notation: `H4,1`, `A2,ground`.
pub fn pair_label(pair: &FrfPair) -> String {
    let letter = match pair.kind {
        FrfKind::Receptance => "H",
        FrfKind::Mobility => "Y",
        FrfKind::Accelerance => "A",
    };
    match pair.excitation {
        Excitation::Dof(e) => format!("{letter}{},{}", pair.response + 1, e + 1),
        Excitation::Ground => format!("{letter}{},ground", pair.response + 1),
    }
}

/// Unit label of an FRF kind for ground or force input.
pub fn y_label(kind: FrfKind, ground: bool) -> &'static str {
    match (kind, ground) {
        (FrfKind::Receptance, false) => "|H| (m/N)",
        (FrfKind::Accelerance, false) => "|A| ((m/s^2)/N)",
        (FrfKind::Mobility, false) => "|Y| ((m/s)/N)",
        (FrfKind::Receptance, true) => "|H| (m/(m/s^2))",
        (FrfKind::Accelerance, true) => "|A| (-)",
        (FrfKind::Mobility, true) => "|Y| (s)",
    }
}
