//! The model-updating objective, paper Eqs. (22a-f) and (24a-f): residuals between
//! analytical and measured FRF magnitudes over the long vector (Eqs. 18-19, 23), with
//! the eigen-constraint (22b) enforced by solving the modes at every evaluation.

use super::sensitivity::{magnitude_jacobian, RowScale, SensitivityWorkspace};
use super::variables::{DampingModel, Variables, VariablesConfig};
use crate::error::{Error, Result};
use crate::frf::{FrfBlock, ModalFrf};
use crate::modal::Modes;
use crate::model::StructuralModel;
use crate::update::lsq::LeastSquaresProblem;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// How a residual compares analytical and measured magnitudes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResidualForm {
    /// `|H^A_k| - |H^E_k|`, the paper's form (Eq. 22a). Without `sigma` the residuals
    /// are divided by the RMS of the measured magnitudes, a constant that leaves the
    /// minimiser unchanged and makes the cost dimensionless (so `gtol` means the same
    /// for receptance in m/N and accelerance in (m/s^2)/N).
    #[default]
    Magnitude,
    /// `ln |H^A_k| - ln |H^E_k|`: every decade of the FRF counts alike. Needs positive
    /// measured magnitudes.
    LogMagnitude,
}

/// Objective settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObjectiveOptions {
    pub residual: ResidualForm,
    /// Modes kept in the modal sums (`m` of Eq. 7); all when `None`.
    pub n_modes: Option<usize>,
}

/// Measured FRF magnitudes on the long vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurements {
    /// Frequency grids and pairs (one block per test), defining the long-vector order.
    pub blocks: Vec<FrfBlock>,
    /// `|H^E|` in long-vector order (Eqs. 17-19).
    pub magnitude: Vec<f64>,
    /// Optional standard deviation of each measured point, in the units of the chosen
    /// residual: of `|H^E_k|` for [`ResidualForm::Magnitude`], of `ln |H^E_k|` (about
    /// the relative error) for [`ResidualForm::LogMagnitude`]. Residuals are divided by
    /// it (weighted least squares). See [`crate::update::magnitude_sigma_from_coherence`].
    pub sigma: Option<Vec<f64>>,
}

/// One model-updating problem: model, variables, data and objective.
#[derive(Debug, Clone)]
pub struct Problem {
    model: StructuralModel,
    variables: Variables,
    frf: ModalFrf,
    target: Vec<f64>,
    weights: Vec<f64>,
    options: ObjectiveOptions,
    n_modes: usize,
    /// The caller's `|H^E|` and sigmas, kept so the problem can be written out
    /// exactly ([`Problem::spec`]).
    measured: Vec<f64>,
    sigma: Option<Vec<f64>>,
}

/// Per-thread scratch memory of a [`Problem`].
#[derive(Debug, Clone)]
pub struct ProblemWorkspace {
    theta: Vec<f64>,
    frf: ModalFrf,
    mag: Vec<f64>,
    columns: Vec<Option<usize>>,
    factors: Vec<f64>,
    sens: SensitivityWorkspace,
}

impl Problem {
    /// Validates and assembles a problem. Errors name what does not fit.
    pub fn new(
        model: StructuralModel,
        data: Measurements,
        damping: DampingModel,
        variables: &VariablesConfig,
        options: ObjectiveOptions,
    ) -> Result<Self> {
        let n_dof = model.n_dof();
        let n_modes = options.n_modes.unwrap_or(n_dof);
        if n_modes == 0 || n_modes > n_dof {
            return Err(Error::Usage(format!(
                "n_modes must be between 1 and {n_dof} (the model's DOFs), got {n_modes}"
            )));
        }
        let variables = Variables::new(&model, damping, n_modes, variables)?;
        check_blocks(&data.blocks, n_dof)?;
        let frf = ModalFrf::new(data.blocks);
        let len = frf.len();
        let log = options.residual == ResidualForm::LogMagnitude;
        check_magnitudes(&data.magnitude, len, log)?;
        let weights = residual_weights(&data.magnitude, data.sigma.as_deref(), log)?;
        let target = if log {
            data.magnitude.iter().map(|v| v.ln()).collect()
        } else {
            data.magnitude.clone()
        };
        Ok(Problem {
            model,
            variables,
            frf,
            target,
            weights,
            options,
            n_modes,
            measured: data.magnitude,
            sigma: data.sigma,
        })
    }

    /// The structural model.
    pub fn model(&self) -> &StructuralModel {
        &self.model
    }
    /// The variables and their bounds.
    pub fn variables(&self) -> &Variables {
        &self.variables
    }
    /// The FRF blocks (long-vector layout).
    pub fn blocks(&self) -> &[FrfBlock] {
        self.frf.blocks()
    }
    /// Objective settings.
    pub fn options(&self) -> &ObjectiveOptions {
        &self.options
    }
    /// Modes kept in the modal sums.
    pub fn n_modes(&self) -> usize {
        self.n_modes
    }
    /// True when the caller gave per-point sigmas (residuals are then standardised).
    pub fn is_weighted(&self) -> bool {
        self.sigma.is_some()
    }
    /// The measured magnitudes `|H^E|` as given (long-vector order).
    pub fn measured(&self) -> &[f64] {
        &self.measured
    }
    /// The per-point sigmas as given, if any.
    pub fn sigma(&self) -> Option<&[f64]> {
        self.sigma.as_deref()
    }
    /// Per-point factor the raw difference is multiplied by (`1/sigma_k`, or
    /// `1/RMS(|H^E|)` for unweighted magnitude residuals, or 1).
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    fn check_theta(&self, theta: &[f64]) -> Result<()> {
        if theta.len() != self.variables.len() {
            return Err(Error::Usage(format!(
                "theta has {} entries, the problem has {} variables ({})",
                theta.len(),
                self.variables.len(),
                self.variables.names().join(", ")
            )));
        }
        Ok(())
    }

    /// All modes at `theta` and `M(beta)`.
    fn modes(&self, theta: &[f64]) -> Result<(Modes, DMatrix<f64>)> {
        let (alpha, beta, _) = self.variables.split(theta);
        let (k, m) = (self.model.stiffness(alpha), self.model.mass(beta));
        let modes = Modes::solve(&k, &m, self.model.ground_influence(), None)?;
        Ok((modes, m))
    }

    /// The first `n_modes` of `modes`.
    fn truncated(&self, modes: &Modes) -> Modes {
        let m = self.n_modes;
        Modes {
            omega_rad_s: modes.omega_rad_s[..m].to_vec(),
            phi: modes.phi.columns(0, m).into_owned(),
            participation: modes.participation[..m].to_vec(),
        }
    }

    /// Analytical magnitudes `|H^A|` at `theta` into `frf`'s layout.
    fn magnitudes_into(&self, theta: &[f64], frf: &mut ModalFrf, out: &mut [f64]) -> Result<()> {
        let (modes, _) = self.modes(theta)?;
        let modes = if self.n_modes < modes.n_modes() {
            self.truncated(&modes)
        } else {
            modes
        };
        let (_, _, damping) = self.variables.split(theta);
        let mut c = vec![0.0; self.n_modes];
        damping.modal_coefficients(&modes.omega_rad_s, &mut c)?;
        frf.magnitudes(&modes, &c, out)
    }

    /// Analytical complex FRFs `H^A(theta)` in long-vector order (for plots and FDAC).
    pub fn complex_frf(&self, theta: &[f64]) -> Result<Vec<Complex64>> {
        self.check_theta(theta)?;
        let (modes, _) = self.modes(theta)?;
        let modes = self.truncated(&modes);
        let (_, _, damping) = self.variables.split(theta);
        let mut c = vec![0.0; self.n_modes];
        damping.modal_coefficients(&modes.omega_rad_s, &mut c)?;
        let mut out = vec![Complex64::new(0.0, 0.0); self.frf.len()];
        self.frf.clone().complex(&modes, &c, &mut out)?;
        Ok(out)
    }

    /// Analytical magnitudes `|H^A(theta)|` (Eq. 17) in long-vector order.
    pub fn magnitudes(&self, theta: &[f64]) -> Result<Vec<f64>> {
        self.check_theta(theta)?;
        let mut out = vec![0.0; self.frf.len()];
        self.magnitudes_into(theta, &mut self.frf.clone(), &mut out)?;
        Ok(out)
    }

    /// Turns magnitudes into residuals in place.
    fn residuals_from_magnitudes(&self, r: &mut [f64]) {
        let log = self.options.residual == ResidualForm::LogMagnitude;
        for ((x, t), w) in r.iter_mut().zip(&self.target).zip(&self.weights) {
            let a = if log { x.ln() } else { *x };
            *x = w * (a - t);
        }
    }

    /// Residuals at `theta` (full layout, physical units; the solver's
    /// [`LeastSquaresProblem::residuals`] takes the internal vector instead).
    pub fn residuals_at(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let mut r = self.magnitudes(theta)?;
        self.residuals_from_magnitudes(&mut r);
        Ok(r)
    }

    /// Cost `0.5 ||r(theta)||^2`.
    pub fn cost_at(&self, theta: &[f64]) -> Result<f64> {
        Ok(0.5 * self.residuals_at(theta)?.iter().map(|v| v * v).sum::<f64>())
    }

    /// Jacobian `dr_k / d theta_v` at `theta` over *all* variables (fixed ones too),
    /// in physical units (analytical; see [`crate::update`] for the formulas).
    pub fn jacobian_at(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        self.check_theta(theta)?;
        let columns: Vec<Option<usize>> = (0..self.variables.len()).map(Some).collect();
        let mut jac = DMatrix::zeros(self.frf.len(), self.variables.len());
        let mut mag = vec![0.0; self.frf.len()];
        let mut sens = SensitivityWorkspace::default();
        self.jacobian_into(theta, &columns, &mut sens, &mut mag, &mut jac)?;
        Ok(jac)
    }

    /// Residual Jacobian into the mapped columns of `jac` (physical units).
    fn jacobian_into(
        &self,
        theta: &[f64],
        columns: &[Option<usize>],
        sens: &mut SensitivityWorkspace,
        mag: &mut [f64],
        jac: &mut DMatrix<f64>,
    ) -> Result<()> {
        let (modes, mass) = self.modes(theta)?;
        let (_, _, damping) = self.variables.split(theta);
        let rows = RowScale {
            weights: &self.weights,
            log: self.options.residual == ResidualForm::LogMagnitude,
        };
        magnitude_jacobian(
            &self.model,
            &mass,
            &modes,
            self.n_modes,
            &damping,
            self.frf.blocks(),
            rows,
            columns,
            sens,
            mag,
            jac,
        )?;
        Ok(())
    }

    /// The internal vector (solver coordinates) of `theta`.
    pub fn to_internal(&self, theta: &[f64]) -> Vec<f64> {
        self.variables.to_internal(theta)
    }
}

/// Every FRF pair lies inside the `n_dof`-DOF model and every frequency is finite and
/// positive.
fn check_blocks(blocks: &[FrfBlock], n_dof: usize) -> Result<()> {
    for b in blocks {
        for p in &b.pairs {
            let e_ok = match p.excitation {
                crate::frf::Excitation::Dof(e) => e < n_dof,
                crate::frf::Excitation::Ground => true,
            };
            if p.response >= n_dof || !e_ok {
                return Err(Error::Usage(format!(
                    "FRF pair {p:?} refers to a DOF outside the {n_dof}-DOF model"
                )));
            }
        }
        if b.omega_rad_s.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(Error::Usage(
                "frequencies must be finite and positive".into(),
            ));
        }
    }
    Ok(())
}

/// `len` (> 0) measured magnitudes, finite and >= 0, and positive when `log`.
fn check_magnitudes(magnitude: &[f64], len: usize, log: bool) -> Result<()> {
    if len == 0 {
        return Err(Error::Usage("no measured FRF points".into()));
    }
    if magnitude.len() != len {
        return Err(Error::Usage(format!(
            "{} measured magnitudes for {len} FRF points (blocks x pairs x frequencies)",
            magnitude.len()
        )));
    }
    if let Some(k) = magnitude.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
        return Err(Error::Usage(format!(
            "measured magnitude {k} is {}; magnitudes must be finite and >= 0",
            magnitude[k]
        )));
    }
    if log {
        if let Some(k) = magnitude.iter().position(|&v| v <= 0.0) {
            return Err(Error::Usage(format!(
                "log-magnitude residuals need positive magnitudes; point {k} is zero"
            )));
        }
    }
    Ok(())
}

/// Residual weights `w_k`: `1 / sigma_k` when sigmas are given, else 1 for
/// log-magnitude residuals and `1 / RMS(|H^E|)` for magnitude residuals (Eq. 22a).
fn residual_weights(magnitude: &[f64], sigma: Option<&[f64]>, log: bool) -> Result<Vec<f64>> {
    let len = magnitude.len();
    Ok(match sigma {
        Some(sigma) => {
            if sigma.len() != len {
                return Err(Error::Usage(format!(
                    "{} sigmas for {len} FRF points",
                    sigma.len()
                )));
            }
            if let Some(k) = sigma.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
                return Err(Error::Usage(format!(
                    "sigma {k} is {}; every sigma must be finite and positive",
                    sigma[k]
                )));
            }
            sigma.iter().map(|s| 1.0 / s).collect()
        }
        None if log => vec![1.0; len],
        None => {
            let rms = (magnitude.iter().map(|v| v * v).sum::<f64>() / len as f64).sqrt();
            if rms == 0.0 {
                return Err(Error::Usage("every measured magnitude is zero".into()));
            }
            vec![1.0 / rms; len]
        }
    })
}

impl LeastSquaresProblem for Problem {
    type Workspace = ProblemWorkspace;

    fn n_params(&self) -> usize {
        self.variables.free().len()
    }

    fn n_residuals(&self) -> usize {
        self.frf.len()
    }

    fn workspace(&self) -> ProblemWorkspace {
        let mut columns = vec![None; self.variables.len()];
        for (c, &v) in self.variables.free().iter().enumerate() {
            columns[v] = Some(c);
        }
        ProblemWorkspace {
            theta: self.variables.initial(),
            frf: self.frf.clone(),
            mag: vec![0.0; self.frf.len()],
            columns,
            factors: vec![0.0; self.variables.free().len()],
            sens: SensitivityWorkspace::default(),
        }
    }

    fn residuals(&self, z: &[f64], ws: &mut ProblemWorkspace, r: &mut [f64]) -> Result<()> {
        self.variables.from_internal(z, &mut ws.theta);
        self.magnitudes_into(&ws.theta, &mut ws.frf, r)?;
        self.residuals_from_magnitudes(r);
        Ok(())
    }

    fn jacobian(&self, z: &[f64], ws: &mut ProblemWorkspace, jac: &mut DMatrix<f64>) -> Result<()> {
        self.variables.from_internal(z, &mut ws.theta);
        self.jacobian_into(&ws.theta, &ws.columns, &mut ws.sens, &mut ws.mag, jac)?;
        self.variables.chain_factors(&ws.theta, &mut ws.factors);
        let n_rows = jac.nrows();
        for (c, &f) in ws.factors.iter().enumerate() {
            if f != 1.0 {
                for x in &mut jac.as_mut_slice()[c * n_rows..(c + 1) * n_rows] {
                    *x *= f;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::{Excitation, FrfKind, FrfPair};

    fn setup() -> (StructuralModel, Vec<FrfBlock>) {
        let model = StructuralModel::shear_frame(&[2.0, 3.0], &[500.0, 800.0]).unwrap();
        let pairs = vec![
            FrfPair {
                response: 1,
                excitation: Excitation::Dof(0),
                kind: FrfKind::Accelerance,
            },
            FrfPair {
                response: 0,
                excitation: Excitation::Ground,
                kind: FrfKind::Receptance,
            },
        ];
        let omega_rad_s = (1..=30).map(|i| i as f64).collect();
        (model, vec![FrfBlock { omega_rad_s, pairs }])
    }

    fn make(
        magnitude: Vec<f64>,
        sigma: Option<Vec<f64>>,
        residual: ResidualForm,
    ) -> Result<Problem> {
        let (model, blocks) = setup();
        let data = Measurements {
            blocks,
            magnitude,
            sigma,
        };
        let options = ObjectiveOptions {
            residual,
            n_modes: None,
        };
        Problem::new(
            model,
            data,
            DampingModel::Caughey,
            &VariablesConfig::default(),
            options,
        )
    }

    #[test]
    fn rejects_inconsistent_data() {
        let e = make(vec![1.0; 59], None, ResidualForm::Magnitude).unwrap_err();
        assert!(
            e.to_string().contains("59 measured magnitudes for 60"),
            "{e}"
        );
        let mut m = vec![1.0; 60];
        m[7] = -1.0;
        let e = make(m, None, ResidualForm::Magnitude).unwrap_err();
        assert!(e.to_string().contains("measured magnitude 7"), "{e}");
        let mut m = vec![1.0; 60];
        m[3] = 0.0;
        assert!(make(m.clone(), None, ResidualForm::Magnitude).is_ok());
        let e = make(m, None, ResidualForm::LogMagnitude).unwrap_err();
        assert!(e.to_string().contains("point 3"), "{e}");
        let e = make(vec![1.0; 60], Some(vec![0.0; 60]), ResidualForm::Magnitude).unwrap_err();
        assert!(e.to_string().contains("sigma 0"), "{e}");
        let (model, blocks) = setup();
        let data = Measurements {
            blocks,
            magnitude: vec![1.0; 60],
            sigma: None,
        };
        let options = ObjectiveOptions {
            residual: ResidualForm::Magnitude,
            n_modes: Some(3),
        };
        let e = Problem::new(
            model,
            data,
            DampingModel::Rayleigh,
            &VariablesConfig::default(),
            options,
        )
        .unwrap_err();
        assert!(e.to_string().contains("n_modes"), "{e}");
    }

    #[test]
    fn residual_forms_and_frfs_agree() {
        let measured: Vec<f64> = (0..60).map(|i| 1e-3 * (1.0 + 0.01 * i as f64)).collect();
        let p = make(measured.clone(), None, ResidualForm::Magnitude).unwrap();
        let theta = p.variables().initial();
        let mag = p.magnitudes(&theta).unwrap();
        let h = p.complex_frf(&theta).unwrap();
        for (a, b) in mag.iter().zip(&h) {
            assert!((a - b.norm()).abs() <= 1e-14 * a);
        }
        // Plain residuals are divided by the RMS of the measurements.
        let rms = (measured.iter().map(|v| v * v).sum::<f64>() / 60.0).sqrt();
        let r = p.residuals_at(&theta).unwrap();
        assert!((r[5] - (mag[5] - measured[5]) / rms).abs() < 1e-12 * r[5].abs().max(1.0));
        let sigma: Vec<f64> = (0..60).map(|i| 1e-5 * (1.0 + i as f64)).collect();
        let pw = make(
            measured.clone(),
            Some(sigma.clone()),
            ResidualForm::Magnitude,
        )
        .unwrap();
        let rw = pw.residuals_at(&theta).unwrap();
        assert!((rw[9] - (mag[9] - measured[9]) / sigma[9]).abs() < 1e-9 * rw[9].abs().max(1.0));
        let pl = make(measured.clone(), None, ResidualForm::LogMagnitude).unwrap();
        let rl = pl.residuals_at(&theta).unwrap();
        assert!((rl[2] - (mag[2] / measured[2]).ln()).abs() < 1e-12);
        assert!(
            (pl.cost_at(&theta).unwrap() - 0.5 * rl.iter().map(|v| v * v).sum::<f64>()).abs()
                < 1e-12
        );
        assert!(p.residuals_at(&theta[1..]).is_err());
    }
}
