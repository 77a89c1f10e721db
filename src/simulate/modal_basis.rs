//! A truncated modal basis for simulating large linear models: the lowest `m` undamped
//! modes of the [`LinearSystem`] (one dense eigensolution), so that the state has `2 m`
//! entries instead of `2 n`.
//!
//! With `x = Phi_m q` (`Phi_m^T M Phi_m = I`), the equations of motion
//! `M x'' + C x' + K x = f - M iota a_g` become
//! `q'' + Phi_m^T C Phi_m q' + Omega^2 q = Phi_m^T f - Gamma a_g`, with the
//! participation `Gamma = Phi_m^T M iota` (paper Eq. 15). For proportional damping
//! (Rayleigh, Caughey, modal) `Phi_m^T C Phi_m` is diagonal and the basis only drops the
//! modes above the cutoff; with every mode kept it is exact. Read-outs at a physical DOF
//! `d` are row `d` of `Phi_m` applied to `q`, `q'` or `q''`.

use super::discrete::{Drive, OutputMap, Response, StateSpace};
use super::system::LinearSystem;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// The lowest modes of a system, up to a cutoff frequency.
#[derive(Debug, Clone)]
pub struct ModalBasis {
    /// Mass-normalised shapes of the kept modes (n_dof x m).
    pub phi: DMatrix<f64>,
    /// Their natural frequencies, rad/s, ascending.
    pub omega_rad_s: Vec<f64>,
    /// `Phi_m^T C Phi_m` (m x m), N s/m per unit modal mass.
    pub modal_damping: DMatrix<f64>,
    /// `Gamma = Phi_m^T M iota`.
    pub participation: DVector<f64>,
    /// The cutoff: every mode with a natural frequency up to it is kept, Hz.
    pub cutoff_hz: f64,
}

impl ModalBasis {
    /// The modes of `system` with natural frequencies up to `cutoff_hz` (at least one).
    pub fn new(system: &LinearSystem, cutoff_hz: f64) -> Result<Self> {
        let modes = system.modes()?;
        let m = modes
            .omega_rad_s
            .iter()
            .take_while(|w| **w / (2.0 * std::f64::consts::PI) <= cutoff_hz)
            .count();
        if m == 0 {
            return Err(Error::Usage(format!(
                "no mode below the modal cutoff {cutoff_hz} Hz (the lowest is {:.4} Hz); raise \
                 modal_cutoff_hz or the sampling rate",
                modes.omega_rad_s[0] / (2.0 * std::f64::consts::PI)
            )));
        }
        let phi = modes.phi.columns(0, m).into_owned();
        Ok(ModalBasis {
            modal_damping: phi.transpose() * &system.damping_n_s_per_m * &phi,
            participation: phi.transpose() * (&system.mass_kg * &system.ground_influence),
            omega_rad_s: modes.omega_rad_s[..m].to_vec(),
            phi,
            cutoff_hz,
        })
    }

    /// Number of modes kept.
    pub fn n_modes(&self) -> usize {
        self.omega_rad_s.len()
    }

    /// Row `dof` of `Phi_m`, checked.
    fn row(&self, dof: usize) -> Result<DVector<f64>> {
        if dof >= self.phi.nrows() {
            return Err(Error::Usage(format!("DOF {dof} of {}", self.phi.nrows())));
        }
        Ok(self.phi.row(dof).transpose())
    }

    /// Modal state space `z = [q; q']`: `A = [[0, I], [-Omega^2, -Phi^T C Phi]]`,
    /// `B = [[0], [Phi^T B_f]]` with the load pattern of each drive.
    pub fn state_space(&self, drives: &[Drive]) -> Result<StateSpace> {
        let m = self.n_modes();
        let mut a = DMatrix::zeros(2 * m, 2 * m);
        a.view_mut((0, m), (m, m)).fill_with_identity();
        for (i, w) in self.omega_rad_s.iter().enumerate() {
            a[(m + i, i)] = -w * w;
        }
        a.view_mut((m, m), (m, m))
            .copy_from(&(-&self.modal_damping));
        let mut b = DMatrix::zeros(2 * m, drives.len());
        for (j, d) in drives.iter().enumerate() {
            let load = match *d {
                Drive::Force { dof } => self.row(dof)?,
                Drive::Ground => -&self.participation,
                Drive::Pair {
                    plus_dof,
                    minus_dof,
                } => match minus_dof {
                    Some(minus) if minus == plus_dof => {
                        return Err(Error::Usage(format!(
                            "element force between DOF {plus_dof} and itself"
                        )))
                    }
                    Some(minus) => self.row(plus_dof)? - self.row(minus)?,
                    None => self.row(plus_dof)?,
                },
            };
            b.view_mut((m, j), (m, 1)).copy_from(&load);
        }
        Ok(StateSpace {
            a,
            b,
            drives: drives.to_vec(),
        })
    }

    /// Read-outs at physical DOFs from the modal state space `ss` of [`Self::state_space`]:
    /// displacement `phi_d^T q`, velocity `phi_d^T q'`, absolute acceleration
    /// `phi_d^T q'' (+ a_g)` with `q''` from the state equation.
    pub fn output_map(&self, ss: &StateSpace, responses: &[Response]) -> Result<OutputMap> {
        let m = self.n_modes();
        let ni = ss.n_inputs();
        let mut c = DMatrix::zeros(responses.len(), 2 * m);
        let mut d = DMatrix::zeros(responses.len(), ni);
        for (r, resp) in responses.iter().enumerate() {
            match *resp {
                Response::Input(j) if j < ni => d[(r, j)] = 1.0,
                Response::Input(j) => return Err(Error::Usage(format!("input {j} of {ni}"))),
                Response::Displacement { dof } => {
                    c.view_mut((r, 0), (1, m))
                        .copy_from(&self.row(dof)?.transpose());
                }
                Response::Velocity { dof } => {
                    c.view_mut((r, m), (1, m))
                        .copy_from(&self.row(dof)?.transpose());
                }
                Response::Acceleration { dof } => {
                    let row = self.row(dof)?.transpose();
                    c.set_row(r, &(&row * ss.a.rows(m, m)));
                    d.set_row(r, &(&row * ss.b.rows(m, m)));
                    for (j, drive) in ss.drives.iter().enumerate() {
                        if *drive == Drive::Ground {
                            d[(r, j)] += 1.0;
                        }
                    }
                }
            }
        }
        Ok(OutputMap { c, d })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::config::DampingSpec;
    use crate::simulate::discrete::Foh;
    use crate::simulate::system::damping_matrix;

    /// A 6-DOF system that is not a shear frame (springs between non-adjacent DOFs, full
    /// mass matrix), Rayleigh damping, a non-uniform ground influence.
    fn system() -> LinearSystem {
        let n = 6;
        let mut k = DMatrix::<f64>::zeros(n, n);
        let mut spring = |i: Option<usize>, j: usize, kv: f64| {
            k[(j, j)] += kv;
            if let Some(i) = i {
                k[(i, i)] += kv;
                k[(i, j)] -= kv;
                k[(j, i)] -= kv;
            }
        };
        spring(None, 0, 4000.0);
        spring(None, 3, 2500.0);
        for (i, j, kv) in [
            (0, 1, 3000.0),
            (1, 2, 2000.0),
            (2, 5, 1500.0),
            (0, 4, 1800.0),
            (3, 4, 2200.0),
            (4, 5, 900.0),
            (1, 3, 700.0),
        ] {
            spring(Some(i), j, kv);
        }
        let mut m = DMatrix::from_diagonal(&DVector::from_vec(vec![2.0, 1.5, 1.2, 1.8, 1.0, 0.8]));
        m[(0, 1)] = 0.2;
        m[(1, 0)] = 0.2;
        let iota = DVector::from_vec(vec![1.0, 1.0, 0.5, 1.0, 0.8, 1.0]);
        let c = damping_matrix(
            &m,
            &k,
            &iota,
            &DampingSpec::Rayleigh {
                a0_per_s: 0.4,
                a1_s: 2e-4,
            },
        )
        .unwrap();
        LinearSystem::on_rigid_ground(m, k, c, iota)
    }

    /// Oracle: with every mode kept, the modal simulation equals the physical one
    /// (both exact FOH discretisations of the same system; they differ by rounding only).
    #[test]
    fn full_basis_simulation_equals_the_physical_one() {
        let sys = system();
        let basis = ModalBasis::new(&sys, 1e6).unwrap();
        assert_eq!(basis.n_modes(), 6);
        let drives = [
            Drive::Force { dof: 2 },
            Drive::Ground,
            Drive::Pair {
                plus_dof: 4,
                minus_dof: Some(1),
            },
        ];
        let responses = [
            Response::Input(1),
            Response::Displacement { dof: 5 },
            Response::Velocity { dof: 0 },
            Response::Acceleration { dof: 3 },
            Response::Acceleration { dof: 2 },
        ];
        let h = 1e-3;
        let n_steps = 4000;
        let inputs: Vec<Vec<f64>> = (0..3)
            .map(|j| {
                (0..n_steps)
                    .map(|k| ((k as f64 * 0.013 * (j + 1) as f64).sin() * (1.0 + j as f64)).powi(3))
                    .collect()
            })
            .collect();
        let run = |ss: &StateSpace, out: &OutputMap| {
            Foh::new(ss, h)
                .unwrap()
                .simulate(out, &inputs, None, &|_| {})
                .unwrap()
        };
        let phys = StateSpace::new(&sys, &drives).unwrap();
        let y_phys = run(&phys, &phys.output_map(&responses).unwrap());
        let modal = basis.state_space(&drives).unwrap();
        let y_modal = run(&modal, &basis.output_map(&modal, &responses).unwrap());
        for (r, (a, b)) in y_phys.iter().zip(&y_modal).enumerate() {
            let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
            let err = a
                .iter()
                .zip(b)
                .fold(0.0f64, |s, (x, y)| s.max((x - y).abs()));
            assert!(err <= 1e-9 * scale, "response {r}: {err:e} of {scale:e}");
        }
    }

    #[test]
    fn cutoff_keeps_the_modes_below_it() {
        let sys = system();
        let f_hz: Vec<f64> = sys.modes().unwrap().freq_hz();
        let basis = ModalBasis::new(&sys, 0.5 * (f_hz[2] + f_hz[3])).unwrap();
        assert_eq!(basis.n_modes(), 3);
        let t = basis.phi.transpose() * &sys.mass_kg * &basis.phi;
        assert!((t - DMatrix::identity(3, 3)).amax() < 1e-12);
        let e = ModalBasis::new(&sys, 0.5 * f_hz[0]).unwrap_err();
        assert!(e.to_string().contains("raise modal_cutoff_hz"), "{e}");
    }
}
