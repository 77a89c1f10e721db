//! A discrete viscous damper between two floors (or a floor and the ground), which makes
//! the damping non-proportional.

use crate::error::Result;
use crate::simulate::system::{LinearSystem, SystemEffect};
use serde::{Deserialize, Serialize};

/// Dashpot of `coefficient_n_s_per_m` between `floors[0]` and `floors[1]` (0 = ground):
/// adds `c (e_a - e_b)(e_a - e_b)^T` to `C` (only `c e_a e_a^T` when b is the ground).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dashpot {
    pub floors: [usize; 2],
    pub coefficient_n_s_per_m: f64,
}

impl Dashpot {
    pub(super) fn check(&self, n_floors: usize) -> std::result::Result<(), String> {
        let [a, b] = self.floors;
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
        let dof = |f: usize| -> Result<Option<usize>> {
            if f == 0 {
                Ok(None)
            } else {
                system.dof_of_floor(f).map(Some)
            }
        };
        let (a, b) = (dof(self.floors[0])?, dof(self.floors[1])?);
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
        Dashpot {
            floors: [3, 1],
            coefficient_n_s_per_m: 7.0,
        }
        .apply(&mut between)
        .unwrap();
        let expect =
            DMatrix::from_row_slice(3, 3, &[7.0, 0.0, -7.0, 0.0, 0.0, 0.0, -7.0, 0.0, 7.0]);
        assert_eq!(between.damping_n_s_per_m, expect);
        let mut ground = s.clone();
        Dashpot {
            floors: [0, 2],
            coefficient_n_s_per_m: 3.0,
        }
        .apply(&mut ground)
        .unwrap();
        let mut expect = DMatrix::zeros(3, 3);
        expect[(1, 1)] = 3.0;
        assert_eq!(ground.damping_n_s_per_m, expect);
        assert!(Dashpot {
            floors: [2, 2],
            coefficient_n_s_per_m: 1.0
        }
        .check(3)
        .is_err());
        assert!(Dashpot {
            floors: [1, 4],
            coefficient_n_s_per_m: 1.0
        }
        .check(3)
        .is_err());
    }
}
