//! A secondary oscillator (a mass on a spring and dashpot) attached to a floor: one extra
//! DOF that the floor sensors do not see.

use crate::error::Result;
use crate::simulate::system::{LinearSystem, SystemEffect};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Mass `mass_kg` joined to `floor` by a spring `stiffness_n_per_m` and a dashpot
/// `2 damping_ratio sqrt(k m)` (its damping ratio when the floor is held still).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Oscillator {
    pub floor: usize,
    pub mass_kg: f64,
    pub stiffness_n_per_m: f64,
    pub damping_ratio: f64,
}

impl Oscillator {
    /// Natural frequency on a fixed floor.
    pub fn freq_hz(&self) -> f64 {
        (self.stiffness_n_per_m / self.mass_kg).sqrt() / (2.0 * std::f64::consts::PI)
    }

    pub(super) fn check(&self, n_floors: usize) -> std::result::Result<(), String> {
        if self.floor == 0 || self.floor > n_floors {
            return Err(format!(
                "oscillator floor must be in 1..={n_floors} (got {})",
                self.floor
            ));
        }
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(ok(self.mass_kg) && ok(self.stiffness_n_per_m)) {
            return Err("oscillator mass_kg and stiffness_n_per_m must be positive".into());
        }
        if !(self.damping_ratio.is_finite() && self.damping_ratio >= 0.0) {
            return Err("oscillator damping_ratio must be finite and >= 0".into());
        }
        Ok(())
    }
}

impl SystemEffect for Oscillator {
    fn apply(&self, system: &mut LinearSystem) -> Result<()> {
        let f = system.dof_of_floor(self.floor)?;
        let n = system.n_dof();
        let grow = |a: &DMatrix<f64>| a.clone().resize(n + 1, n + 1, 0.0);
        let (k, m) = (self.stiffness_n_per_m, self.mass_kg);
        let c = 2.0 * self.damping_ratio * (k * m).sqrt();
        let mut mm = grow(&system.mass_kg);
        let mut kk = grow(&system.stiffness_n_per_m);
        let mut cc = grow(&system.damping_n_s_per_m);
        mm[(n, n)] = m;
        for (mat, v) in [(&mut kk, k), (&mut cc, c)] {
            mat[(f, f)] += v;
            mat[(n, n)] += v;
            mat[(f, n)] -= v;
            mat[(n, f)] -= v;
        }
        let mut iota = DVector::from_element(n + 1, 1.0);
        iota.rows_mut(0, n).copy_from(&system.ground_influence);
        system.mass_kg = mm;
        system.stiffness_n_per_m = kk;
        system.damping_n_s_per_m = cc;
        system.ground_influence = iota;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::config::{DampingSpec, StructureSpec};

    #[test]
    fn two_dof_frequencies_match_the_closed_form() {
        // One floor (M, K) with an attached (m, k): omega^2 are the roots of
        // M m w^4 - (K m + k m + k M) w^2 + K k = 0.
        let (big_m, big_k, m, k) = (5.0, 2000.0, 0.5, 150.0);
        let mut s = LinearSystem::from_spec(
            &StructureSpec::ShearFrame {
                floor_mass_kg: vec![big_m],
                story_stiffness_n_per_m: vec![big_k],
            },
            &DampingSpec::Rayleigh {
                a0_per_s: 0.0,
                a1_s: 0.0,
            },
        )
        .unwrap();
        let osc = Oscillator {
            floor: 1,
            mass_kg: m,
            stiffness_n_per_m: k,
            damping_ratio: 0.02,
        };
        osc.apply(&mut s).unwrap();
        s.validate().unwrap();
        assert_eq!(s.n_dof(), 2);
        assert_eq!(s.floor_dof, vec![0]);
        assert_eq!(s.ground_influence.as_slice(), &[1.0, 1.0]);
        let (a, b, c) = (big_m * m, -(big_k * m + k * m + k * big_m), big_k * k);
        let disc = (b * b - 4.0 * a * c).sqrt();
        let w2 = [(-b - disc) / (2.0 * a), (-b + disc) / (2.0 * a)];
        let modes = s.modes().unwrap();
        for (w, e) in modes.omega_rad_s.iter().zip(w2) {
            assert!((w * w - e).abs() < 1e-10 * e, "{w} vs {}", e.sqrt());
        }
        let c = 2.0 * 0.02 * (k * m).sqrt();
        assert!((s.damping_n_s_per_m[(1, 1)] - c).abs() < 1e-15);
        assert!((s.damping_n_s_per_m[(0, 1)] + c).abs() < 1e-15);
        assert!((osc.freq_hz() - (k / m).sqrt() / (2.0 * std::f64::consts::PI)).abs() < 1e-15);
    }
}
