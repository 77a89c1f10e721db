//! The simulated linear system: general `M`, `K`, `C` matrices, a map from floors to
//! DOFs (extra DOFs allowed, for attached oscillators or a flexible base), and the
//! ground-motion influence vector. Effects that change the physics transform a
//! [`LinearSystem`] through [`SystemEffect`].

use super::config::{DampingSpec, StructureSpec};
use crate::error::{Error, Result};
use crate::modal::Modes;
use crate::model::condense::{check_condensable, massless_dofs};
use crate::model::{caughey_coefficients, caughey_damping_matrix, rayleigh_damping_matrix};
use nalgebra::{DMatrix, DVector};

/// `M x'' + C x' + K x = f(t) - M iota a_g(t)`, with `x` relative to the ground.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSystem {
    /// Mass matrix, kg (symmetric positive definite, or positive semi-definite with
    /// massless DOFs that can be condensed: [`crate::model::condense`]).
    pub mass_kg: DMatrix<f64>,
    /// Stiffness matrix, N/m (symmetric positive semi-definite).
    pub stiffness_n_per_m: DMatrix<f64>,
    /// Viscous damping matrix, N s/m (any; non-proportional allowed).
    pub damping_n_s_per_m: DMatrix<f64>,
    /// DOF (0-based) of floor f at index f-1.
    pub floor_dof: Vec<usize>,
    /// Rigid-body influence vector `iota` of ground motion (paper Eq. 13).
    pub ground_influence: DVector<f64>,
    /// DOF of a flexible base under story 1 (see [`super::BaseFlexibility`]); `None`
    /// when the structure stands on the rigid ground (or table).
    pub base_dof: Option<usize>,
}

/// One transformation of the simulated physics (an added damper, an attached
/// oscillator, a flexible base, ...). Effects are applied in order after the structure
/// and its damping are built.
pub trait SystemEffect: std::fmt::Debug + Send + Sync {
    /// Changes `system` in place; may add DOFs (then extends `ground_influence` too).
    fn apply(&self, system: &mut LinearSystem) -> Result<()>;
}

impl LinearSystem {
    /// Builds the structure with its damping.
    /// A general structure's floors are its DOFs (`floor_dof[k - 1] = k - 1`).
    pub fn from_spec(structure: &StructureSpec, damping: &DampingSpec) -> Result<Self> {
        let (model, alpha, beta) = match structure {
            StructureSpec::ShearFrame {
                floor_mass_kg,
                story_stiffness_n_per_m,
            } => {
                let model = crate::model::StructuralModel::shear_frame(
                    floor_mass_kg,
                    story_stiffness_n_per_m,
                )?;
                let (a, b) = (model.alpha_zero(), model.beta_zero());
                (model, a, b)
            }
            StructureSpec::General { .. } => {
                super::general::load(structure, std::path::Path::new("<model>"))?
            }
        };
        let m = model.mass(&beta);
        let k = model.stiffness(&alpha);
        let iota = model.ground_influence().clone();
        let c = damping_matrix(&m, &k, &iota, damping)?;
        let system = LinearSystem::on_rigid_ground(m, k, c, iota);
        system.validate()?;
        Ok(system)
    }

    /// The system of matrices `m`, `k`, `c` on the rigid ground: DOF `d` (0-based) is
    /// floor `d + 1`, ground motion enters through `iota`.
    pub fn on_rigid_ground(
        m: DMatrix<f64>,
        k: DMatrix<f64>,
        c: DMatrix<f64>,
        iota: DVector<f64>,
    ) -> Self {
        let n = m.nrows();
        LinearSystem {
            mass_kg: m,
            stiffness_n_per_m: k,
            damping_n_s_per_m: c,
            floor_dof: (0..n).collect(),
            ground_influence: iota,
            base_dof: None,
        }
    }

    /// Number of DOFs.
    pub fn n_dof(&self) -> usize {
        self.mass_kg.nrows()
    }

    /// Number of floors.
    pub fn n_floors(&self) -> usize {
        self.floor_dof.len()
    }

    /// DOF of floor `floor` (1-based).
    pub fn dof_of_floor(&self, floor: usize) -> Result<usize> {
        floor
            .checked_sub(1)
            .and_then(|i| self.floor_dof.get(i).copied())
            .ok_or_else(|| {
                Error::Usage(format!(
                    "floor {floor} is outside 1..={} of the simulated structure",
                    self.n_floors()
                ))
            })
    }

    /// DOF of level `level`: floor `level` for `level >= 1`; for `level = 0` the base,
    /// which is the base DOF when the base is flexible and the rigid ground (`None`)
    /// otherwise. Story `s` joins levels `s - 1` and `s`.
    pub fn dof_of_level(&self, level: usize) -> Result<Option<usize>> {
        if level == 0 {
            Ok(self.base_dof)
        } else {
            self.dof_of_floor(level).map(Some)
        }
    }

    /// Applies effects in order.
    pub fn with_effects<E: SystemEffect>(mut self, effects: &[E]) -> Result<Self> {
        for e in effects {
            e.apply(&mut self)?;
            self.validate()?;
        }
        Ok(self)
    }

    /// Shapes agree, M is positive definite, all entries finite, floors map to DOFs.
    pub fn validate(&self) -> Result<()> {
        let n = self.n_dof();
        for (what, a) in [
            ("K", &self.stiffness_n_per_m),
            ("C", &self.damping_n_s_per_m),
            ("M", &self.mass_kg),
        ] {
            if a.nrows() != n || a.ncols() != n {
                return Err(Error::Model(format!(
                    "{what} is {}x{}, expected {n}x{n}",
                    a.nrows(),
                    a.ncols()
                )));
            }
            if a.iter().any(|v| !v.is_finite()) {
                return Err(Error::Model(format!("{what} has non-finite entries")));
            }
        }
        if self.ground_influence.len() != n {
            return Err(Error::Model(format!(
                "ground influence has {} entries for {n} DOFs",
                self.ground_influence.len()
            )));
        }
        if let Some(d) = self
            .floor_dof
            .iter()
            .chain(&self.base_dof)
            .find(|&&d| d >= n)
        {
            return Err(Error::Model(format!("floor mapped to DOF {d} of {n}")));
        }
        if self.mass_kg.clone().cholesky().is_none() {
            // lumped-mass FE models: massless DOFs, condensed by [`Self::modes`]
            if massless_dofs(&self.mass_kg).is_empty() {
                return Err(Error::Model("M is not positive definite".into()));
            }
            check_condensable(&self.stiffness_n_per_m, &self.mass_kg)?;
        }
        Ok(())
    }

    /// Undamped modes (ascending) of the system: every mode, or with massless DOFs
    /// (zero rows of `M`, e.g. an FE model's rotations) every finite mode by static
    /// condensation ([`Modes::solve_condensed`]).
    pub fn modes(&self) -> Result<Modes> {
        Modes::solve_condensed(
            &self.stiffness_n_per_m,
            &self.mass_kg,
            &self.ground_influence,
        )
    }

    /// Modal damping ratios `xi_i = (Phi^T C Phi)_ii / (2 omega_i)`; exact for
    /// proportional damping, the diagonal approximation otherwise.
    pub fn modal_damping_ratios(&self) -> Result<Vec<f64>> {
        let modes = self.modes()?;
        let cm = modes.phi.transpose() * &self.damping_n_s_per_m * &modes.phi;
        Ok(modes
            .omega_rad_s
            .iter()
            .enumerate()
            .map(|(i, w)| cm[(i, i)] / (2.0 * w))
            .collect())
    }
}

/// Damping matrix of a structure with mass `m`, stiffness `k`.
pub fn damping_matrix(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    iota: &DVector<f64>,
    spec: &DampingSpec,
) -> Result<DMatrix<f64>> {
    let c = match spec {
        DampingSpec::Rayleigh { a0_per_s, a1_s } => rayleigh_damping_matrix(m, k, *a0_per_s, *a1_s),
        DampingSpec::Caughey { xi } => {
            let modes = Modes::solve(k, m, iota, None)?;
            let a = caughey_coefficients(&modes.omega_rad_s[..xi.len()], xi)?;
            let c = caughey_damping_matrix(m, k, &a)?;
            // Modes beyond xi.len() follow the series, which may make them negative.
            let cm = modes.phi.transpose() * &c * &modes.phi;
            for (i, w) in modes.omega_rad_s.iter().enumerate() {
                if cm[(i, i)] < -1e-12 * c.amax() {
                    return Err(Error::Model(format!(
                        "Caughey damping with {} ratios gives mode {} the negative ratio {:.3e}; give more ratios",
                        xi.len(),
                        i + 1,
                        cm[(i, i)] / (2.0 * w)
                    )));
                }
            }
            c
        }
        DampingSpec::Modal { xi } => {
            let modes = Modes::solve(k, m, iota, None)?;
            if xi.len() != modes.n_modes() {
                return Err(Error::Model(format!(
                    "modal damping needs {} ratios, got {}",
                    modes.n_modes(),
                    xi.len()
                )));
            }
            // Phi^T M Phi = I, so M Phi diagonalises back: C = (M Phi) D (M Phi)^T.
            let m_phi = m * &modes.phi;
            let d = DMatrix::from_diagonal(&DVector::from_iterator(
                xi.len(),
                xi.iter().zip(&modes.omega_rad_s).map(|(x, w)| 2.0 * x * w),
            ));
            &m_phi * d * m_phi.transpose()
        }
    };
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> StructureSpec {
        StructureSpec::ShearFrame {
            floor_mass_kg: vec![5.0, 4.0, 4.5],
            story_stiffness_n_per_m: vec![1200.0, 1300.0, 2500.0],
        }
    }

    #[test]
    fn every_damping_model_gives_its_ratios() {
        let xi = vec![0.02, 0.01, 0.005];
        for spec in [
            DampingSpec::Modal { xi: xi.clone() },
            DampingSpec::Caughey { xi: xi.clone() },
        ] {
            let s = LinearSystem::from_spec(&frame(), &spec).unwrap();
            let got = s.modal_damping_ratios().unwrap();
            for (g, x) in got.iter().zip(&xi) {
                assert!((g - x).abs() < 1e-12, "{spec:?}: {got:?}");
            }
            // Proportional: Phi^T C Phi is diagonal.
            let modes = s.modes().unwrap();
            let cm = modes.phi.transpose() * &s.damping_n_s_per_m * &modes.phi;
            for i in 0..3 {
                for j in 0..3 {
                    if i != j {
                        assert!(cm[(i, j)].abs() < 1e-12 * cm.amax());
                    }
                }
            }
        }
        let s = LinearSystem::from_spec(
            &frame(),
            &DampingSpec::Rayleigh {
                a0_per_s: 0.3,
                a1_s: 1e-4,
            },
        )
        .unwrap();
        let modes = s.modes().unwrap();
        for (g, w) in s
            .modal_damping_ratios()
            .unwrap()
            .iter()
            .zip(&modes.omega_rad_s)
        {
            assert!((g - (0.3 + 1e-4 * w * w) / (2.0 * w)).abs() < 1e-12);
        }
    }

    /// Oracle: a system with massless DOFs (every second DOF of a chain, as an FE
    /// model's rotations) validates, and its modes are the condensed pencil's: each
    /// solves `K phi = lambda M phi` on every DOF, `Phi^T M Phi = I`, ascending, the
    /// participation is `Phi^T M iota`, and the modal basis of the simulator keeps the
    /// modes below its cutoff with a diagonal `Phi^T C Phi` under Rayleigh damping.
    #[test]
    fn massless_dofs_are_condensed() {
        let model = crate::predict::reduced::test_models::chain_model(6);
        let (k, m) = (model.stiffness(&model.alpha_zero()), model.mass(&[]));
        let iota = DVector::from_element(12, 1.0);
        let c = damping_matrix(
            &m,
            &k,
            &iota,
            &DampingSpec::Rayleigh {
                a0_per_s: 0.2,
                a1_s: 1e-4,
            },
        )
        .unwrap();
        let s = LinearSystem::on_rigid_ground(m.clone(), k.clone(), c, iota.clone());
        s.validate().unwrap();
        let modes = s.modes().unwrap();
        assert_eq!(modes.n_modes(), 6);
        for (j, w) in modes.omega_rad_s.iter().enumerate() {
            let phi = modes.phi.column(j);
            let r = &k * phi - &m * phi * (w * w);
            assert!(r.amax() < 1e-9 * k.amax(), "mode {j}: {}", r.amax());
            let gamma = phi.dot(&(&m * &iota));
            assert!((gamma - modes.participation[j]).abs() < 1e-12);
        }
        let g = modes.phi.transpose() * &m * &modes.phi;
        assert!((g - DMatrix::identity(6, 6)).amax() < 1e-12);
        assert!(modes.omega_rad_s.windows(2).all(|w| w[0] < w[1]));
        let cutoff_hz = 0.5 * (modes.omega_rad_s[2] + modes.omega_rad_s[3]) / std::f64::consts::TAU;
        let basis = super::super::ModalBasis::new(&s, cutoff_hz).unwrap();
        assert_eq!(basis.n_modes(), 3);
        let cm = &basis.modal_damping;
        assert!(cm[(0, 1)].abs() < 1e-12 * cm.amax() && cm[(1, 2)].abs() < 1e-12 * cm.amax());
        let mut singular = s.clone();
        singular.stiffness_n_per_m[(1, 1)] = 0.0;
        singular.stiffness_n_per_m[(1, 0)] = 0.0;
        singular.stiffness_n_per_m[(0, 1)] = 0.0;
        singular.stiffness_n_per_m[(1, 2)] = 0.0;
        singular.stiffness_n_per_m[(2, 1)] = 0.0;
        assert!(singular.validate().is_err());
    }

    #[test]
    fn caughey_with_few_ratios_rejects_negative_damping() {
        // Two ratios decreasing with frequency: the series a0 M + a1 K has a1 < 0, so the
        // third mode would get negative damping.
        let e = LinearSystem::from_spec(
            &frame(),
            &DampingSpec::Caughey {
                xi: vec![0.05, 0.001],
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("negative ratio"), "{e}");
    }
}
