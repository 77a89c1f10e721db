//! A discrete viscous damper between two floors (or a floor and the base), which makes
//! the damping non-proportional.

use crate::error::Result;
use crate::simulate::system::{LinearSystem, SystemEffect};
use serde::{Deserialize, Serialize};

/// Dashpot of `coefficient_n_s_per_m` placed either across story `story` (between floors
/// `story - 1` and `story`) or between `floors[0]` and `floors[1]`; give exactly one.
/// Level 0 is the base: the rigid ground, or the base mass when a
/// [`super::BaseFlexibility`] is present (in either order of the effects). Adds
/// `c (e_a - e_b)(e_a - e_b)^T` to `C` (only `c e_a e_a^T` when b is the rigid ground).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dashpot {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub story: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floors: Option<[usize; 2]>,
    pub coefficient_n_s_per_m: f64,
}

impl Dashpot {
    /// Across story `story`.
    pub fn story(story: usize, coefficient_n_s_per_m: f64) -> Self {
        Dashpot {
            story: Some(story),
            floors: None,
            coefficient_n_s_per_m,
        }
    }

    /// Between two floors (0 = base).
    pub fn between(floors: [usize; 2], coefficient_n_s_per_m: f64) -> Self {
        Dashpot {
            story: None,
            floors: Some(floors),
            coefficient_n_s_per_m,
        }
    }

    /// The two levels it joins (0 = base), once checked.
    fn levels(&self) -> std::result::Result<[usize; 2], String> {
        match (self.story, self.floors) {
            (Some(s), None) if s >= 1 => Ok([s - 1, s]),
            (Some(s), None) => Err(format!("dashpot story must be >= 1 (got {s})")),
            (None, Some(f)) => Ok(f),
            _ => Err("dashpot: give exactly one of `story` or `floors`".into()),
        }
    }

    pub(super) fn check(&self, n_floors: usize) -> std::result::Result<(), String> {
        let [a, b] = self.levels()?;
        if a == b || a > n_floors || b > n_floors {
            return Err(format!(
                "dashpot floors must be two different floors in 0..={n_floors} (got {a}, {b})"
            ));
        }
        if !(self.coefficient_n_s_per_m.is_finite() && self.coefficient_n_s_per_m >= 0.0) {
            return Err(format!(
                "dashpot coefficient_n_s_per_m must be finite and >= 0 (got {})",
                self.coefficient_n_s_per_m
            ));
        }
        Ok(())
    }
}

impl SystemEffect for Dashpot {
    fn apply(&self, system: &mut LinearSystem) -> Result<()> {
        let c = self.coefficient_n_s_per_m;
        let [a, b] = self.levels().map_err(crate::error::Error::Usage)?;
        let (a, b) = (system.dof_of_level(a)?, system.dof_of_level(b)?);
        let cm = &mut system.damping_n_s_per_m;
        for d in [a, b].into_iter().flatten() {
            cm[(d, d)] += c;
        }
        if let (Some(a), Some(b)) = (a, b) {
            cm[(a, b)] -= c;
            cm[(b, a)] -= c;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::config::{DampingSpec, StructureSpec};
    use nalgebra::DMatrix;

    #[test]
    fn adds_the_dashpot_pattern() {
        let s = LinearSystem::from_spec(
            &StructureSpec::ShearFrame {
                floor_mass_kg: vec![1.0; 3],
                story_stiffness_n_per_m: vec![100.0; 3],
            },
            &DampingSpec::Rayleigh {
                a0_per_s: 0.0,
                a1_s: 0.0,
            },
        )
        .unwrap();
        let mut between = s.clone();
        Dashpot::between([3, 1], 7.0).apply(&mut between).unwrap();
        let expect =
            DMatrix::from_row_slice(3, 3, &[7.0, 0.0, -7.0, 0.0, 0.0, 0.0, -7.0, 0.0, 7.0]);
        assert_eq!(between.damping_n_s_per_m, expect);
        let mut ground = s.clone();
        Dashpot::between([0, 2], 3.0).apply(&mut ground).unwrap();
        let mut expect = DMatrix::zeros(3, 3);
        expect[(1, 1)] = 3.0;
        assert_eq!(ground.damping_n_s_per_m, expect);
        // Story placement: story 3 joins floors 2 and 3, story 1 the ground and floor 1.
        let mut story = s.clone();
        Dashpot::story(3, 2.0).apply(&mut story).unwrap();
        let expect =
            DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 0.0, 0.0, 2.0, -2.0, 0.0, -2.0, 2.0]);
        assert_eq!(story.damping_n_s_per_m, expect);
        let mut first = s.clone();
        Dashpot::story(1, 5.0).apply(&mut first).unwrap();
        assert_eq!(first.damping_n_s_per_m[(0, 0)], 5.0);
        assert_eq!(first.damping_n_s_per_m.sum(), 5.0);
        for bad in [
            Dashpot::between([2, 2], 1.0),
            Dashpot::between([1, 4], 1.0),
            Dashpot::story(0, 1.0),
            Dashpot::story(4, 1.0),
            Dashpot {
                story: Some(1),
                floors: Some([0, 1]),
                coefficient_n_s_per_m: 1.0,
            },
            Dashpot {
                story: None,
                floors: None,
                coefficient_n_s_per_m: 1.0,
            },
            Dashpot::story(2, -1.0),
        ] {
            assert!(bad.check(3).is_err(), "{bad:?}");
        }
    }
}
