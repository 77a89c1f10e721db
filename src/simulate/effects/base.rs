//! A flexible base: the structure stands on a base mass joined to the ground (or shake
//! table) by a spring and a dashpot, instead of on the rigid ground.
//!
//! Coordinates stay relative to the ground / table, with the base as one more DOF `b`.
//! Everything that was attached to the rigid base (story 1, and any dashpot to level 0
//! applied before) is re-attached to the base mass: with `u = x - iota x_b` the
//! deformations relative to the base, the structure's forces are unchanged functions of
//! `u, u'`, i.e. with `T = [I, -iota]`
//!
//! `K' = T^T K T + k_b e_b e_b^T`, `C' = T^T C T + c_b e_b e_b^T`, `M' = diag(M, m_b)`,
//! `iota' = [iota; 1]`.
//!
//! For a shear frame `K iota = k_1 e_1`, so `T^T K T` is the chain base-floor 1-...-floor n
//! with story 1 between the base and floor 1. The structure's own damping acts on its
//! deformation relative to the base; a rigid translation of structure and base meets only
//! `k_b` and `c_b`.
//!
//! In a hammer test the ground is fixed and the base moves; in a shake-table test the
//! table acceleration drives the base through `k_b` and `c_b` (load `-M' iota' a_g` on the
//! relative coordinates). Displacement channels read floor displacements relative to the
//! ground / table (`x_f`, base motion included), as for sensors on a fixed frame beside
//! the structure; acceleration channels are absolute.

use crate::error::{Error, Result};
use crate::simulate::system::{LinearSystem, SystemEffect};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Base mass `mass_kg` on a spring `stiffness_n_per_m` and a dashpot
/// `damping_n_s_per_m` to the ground, under story 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseFlexibility {
    pub mass_kg: f64,
    pub stiffness_n_per_m: f64,
    pub damping_n_s_per_m: f64,
}

impl BaseFlexibility {
    pub(super) fn check(&self) -> std::result::Result<(), String> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(ok(self.mass_kg) && ok(self.stiffness_n_per_m)) {
            return Err("base_flexibility mass_kg and stiffness_n_per_m must be positive".into());
        }
        if !(self.damping_n_s_per_m.is_finite() && self.damping_n_s_per_m >= 0.0) {
            return Err("base_flexibility damping_n_s_per_m must be finite and >= 0".into());
        }
        Ok(())
    }
}

impl SystemEffect for BaseFlexibility {
    fn apply(&self, system: &mut LinearSystem) -> Result<()> {
        if system.base_dof.is_some() {
            return Err(Error::Usage(
                "the base is already flexible (give base_flexibility once)".into(),
            ));
        }
        let n = system.n_dof();
        let mut t = DMatrix::zeros(n, n + 1);
        t.view_mut((0, 0), (n, n)).fill_with_identity();
        t.set_column(n, &(-&system.ground_influence));
        let transform = |a: &DMatrix<f64>, ground: f64| {
            let mut out = t.transpose() * a * &t;
            out[(n, n)] += ground;
            // Exact symmetry (the products round differently on each side).
            (&out + out.transpose()) * 0.5
        };
        let k = transform(&system.stiffness_n_per_m, self.stiffness_n_per_m);
        let c = transform(&system.damping_n_s_per_m, self.damping_n_s_per_m);
        let mut m = system.mass_kg.clone().resize(n + 1, n + 1, 0.0);
        m[(n, n)] = self.mass_kg;
        let mut iota = DVector::from_element(n + 1, 1.0);
        iota.rows_mut(0, n).copy_from(&system.ground_influence);
        system.mass_kg = m;
        system.stiffness_n_per_m = k;
        system.damping_n_s_per_m = c;
        system.ground_influence = iota;
        system.base_dof = Some(n);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::config::{DampingSpec, StructureSpec};
    use crate::simulate::effects::Dashpot;

    fn frame(damping: DampingSpec) -> LinearSystem {
        LinearSystem::from_spec(
            &StructureSpec::ShearFrame {
                floor_mass_kg: vec![5.0, 4.0, 4.5],
                story_stiffness_n_per_m: vec![1200.0, 1300.0, 2500.0],
            },
            &damping,
        )
        .unwrap()
    }

    const BASE: BaseFlexibility = BaseFlexibility {
        mass_kg: 6.0,
        stiffness_n_per_m: 30_000.0,
        damping_n_s_per_m: 4.0,
    };

    #[test]
    fn stiffness_proportional_frame_becomes_the_chain_on_the_base() {
        // Oracle assembled independently: a 4-"floor" shear frame whose first floor is
        // the base (masses [m_b, m...], stories [k_b, k...]); damping a1 K of the frame
        // itself plus c_b between base and ground.
        let a1 = 2e-3;
        let mut s = frame(DampingSpec::Rayleigh {
            a0_per_s: 0.0,
            a1_s: a1,
        });
        BASE.apply(&mut s).unwrap();
        s.validate().unwrap();
        // The oracle's DOFs are [base, 1, 2, 3]; ours are [1, 2, 3, base].
        let perm = [1, 2, 3, 0];
        let k_chain = {
            // Spring i joins DOF i-1 (the ground for i = 0) and DOF i.
            let k = [30_000.0, 1200.0, 1300.0, 2500.0];
            let mut kk = DMatrix::zeros(4, 4);
            for (i, ki) in k.iter().enumerate() {
                kk[(i, i)] += ki;
                if i > 0 {
                    kk[(i - 1, i - 1)] += ki;
                    kk[(i - 1, i)] -= ki;
                    kk[(i, i - 1)] -= ki;
                }
            }
            kk
        };
        let mut c_chain = &k_chain * a1;
        c_chain[(0, 0)] += 4.0 - a1 * 30_000.0;
        for i in 0..4 {
            for j in 0..4 {
                let (p, q) = (perm[i], perm[j]);
                assert!((s.stiffness_n_per_m[(i, j)] - k_chain[(p, q)]).abs() < 1e-9);
                assert!((s.damping_n_s_per_m[(i, j)] - c_chain[(p, q)]).abs() < 1e-12);
            }
        }
        assert_eq!(
            s.mass_kg,
            DMatrix::from_diagonal(&DVector::from_row_slice(&[5.0, 4.0, 4.5, 6.0]))
        );
        assert_eq!(s.ground_influence.as_slice(), &[1.0; 4]);
        assert_eq!(s.base_dof, Some(3));
        assert_eq!(s.floor_dof, vec![0, 1, 2]);
        assert!(BASE.apply(&mut s).is_err(), "a second base is refused");
    }

    #[test]
    fn rigid_translation_meets_only_the_base_spring_and_a_stiff_base_is_rigid() {
        let xi = vec![0.02, 0.01, 0.005];
        let fixed = frame(DampingSpec::Modal { xi: xi.clone() });
        let mut s = fixed.clone();
        BASE.apply(&mut s).unwrap();
        let ones = DVector::from_element(4, 1.0);
        let (kf, cf) = (&s.stiffness_n_per_m * &ones, &s.damping_n_s_per_m * &ones);
        for i in 0..3 {
            assert!(kf[i].abs() < 1e-9 && cf[i].abs() < 1e-12, "{kf} {cf}");
        }
        assert!((kf[3] - 30_000.0).abs() < 1e-9 && (cf[3] - 4.0).abs() < 1e-12);
        // Base stiffness 1e6 x the stories: the fixed-base modes come back to
        // O(k / k_b) = 1e-6 relative (first-order perturbation of a stiff support).
        let mut stiff = fixed.clone();
        BaseFlexibility {
            stiffness_n_per_m: 1.2e9,
            ..BASE
        }
        .apply(&mut stiff)
        .unwrap();
        let (f0, f1) = (fixed.modes().unwrap(), stiff.modes().unwrap());
        for i in 0..3 {
            let rel = f1.omega_rad_s[i] / f0.omega_rad_s[i] - 1.0;
            assert!(rel < 0.0 && rel > -1e-5, "mode {i}: {rel}");
        }
        // The structure's damping moves with it: same ratios to 1e-5.
        let (x0, x1) = (
            fixed.modal_damping_ratios().unwrap(),
            stiff.modal_damping_ratios().unwrap(),
        );
        for i in 0..3 {
            assert!((x1[i] / x0[i] - 1.0).abs() < 1e-5, "{x0:?} {x1:?}");
        }
        // A dashpot to level 0 lands between floor 1 and the base in either order.
        let mut before = fixed.clone();
        Dashpot::story(1, 9.0).apply(&mut before).unwrap();
        BASE.apply(&mut before).unwrap();
        let mut after = fixed.clone();
        BASE.apply(&mut after).unwrap();
        Dashpot::story(1, 9.0).apply(&mut after).unwrap();
        let diff = (&before.damping_n_s_per_m - &after.damping_n_s_per_m).amax();
        assert!(diff < 1e-12, "{diff}");
        assert!(
            (after.damping_n_s_per_m[(0, 3)] - s.damping_n_s_per_m[(0, 3)] + 9.0).abs() < 1e-12
        );
    }
}
