//! Parametrised structural models, paper Eqs. (20)-(21):
//! `K(alpha) = K0 + sum_r alpha_r K0_r`, `M(beta) = M0 + sum_r beta_r M0_r`.
//!
//! A [`StructuralModel`] holds the constant matrices; updating variables `alpha` and
//! `beta` are dimensionless multipliers. For the shear frame built by
//! [`StructuralModel::shear_frame`], `K0_r` is story r's contribution at its nominal
//! stiffness, so story r has stiffness `k_r = k_r0 (1 + alpha_r)` and floor r has mass
//! `m_r = m_r0 (1 + beta_r)`; the paper's tables report `k_r` and `m_r`.

pub mod condense;
mod damping;
mod manifest;
pub mod mat;
mod mtx;
pub mod sparse;
mod validate;

pub use damping::{caughey_coefficients, caughey_damping_matrix, rayleigh_damping_matrix, Damping};
pub use manifest::{shared_root, InfluenceEntry, MatrixSpec, ModelManifest, VectorSpec};
pub use mtx::{read_matrix_market, read_matrix_market_triplets};

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};

/// Relative tolerance for the symmetry check of user-supplied matrices.
pub const SYMMETRY_RTOL: f64 = 1e-9;
/// Relative tolerance (against the largest eigenvalue) for positive semi-definiteness of K.
pub const PSD_RTOL: f64 = 1e-10;

/// What a model's updating variables mean physically, for reporting.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Short name, such as `k1` or `m3`.
    pub name: String,
    /// Unit of the physical value, such as `N/m` or `kg`.
    pub unit: String,
    /// Physical value when the multiplier is zero (`k_r0`, `m_r0`), or `None` when the
    /// multiplier has no single physical value (general models).
    pub nominal: Option<f64>,
}

/// A linear structural model with influence matrices for stiffness and mass updating.
#[derive(Debug, Clone, PartialEq)]
pub struct StructuralModel {
    k0: DMatrix<f64>,
    m0: DMatrix<f64>,
    k_influence: Vec<DMatrix<f64>>,
    m_influence: Vec<DMatrix<f64>>,
    alpha: Vec<Parameter>,
    beta: Vec<Parameter>,
    /// Rigid-body influence vector of ground motion (ones for a shear frame), paper Eq. (13).
    ground_influence: DVector<f64>,
    /// 0-based DOFs where the model's sensors sit, when the model file names them.
    measured_dofs: Vec<usize>,
}

impl StructuralModel {
    /// A shear frame with lumped floor masses (kg) and story stiffnesses (N/m); floor 1 is
    /// DOF 0. Story r joins floor r-1 (0 = ground) and floor r. One alpha per story and one
    /// beta per floor.
    pub fn shear_frame(floor_mass_kg: &[f64], story_stiffness_n_per_m: &[f64]) -> Result<Self> {
        let n = floor_mass_kg.len();
        if n == 0 || story_stiffness_n_per_m.len() != n {
            return Err(Error::Model(format!(
                "a shear frame needs as many story stiffnesses as floor masses (got {} masses, {} stiffnesses)",
                n,
                story_stiffness_n_per_m.len()
            )));
        }
        for (i, &m) in floor_mass_kg.iter().enumerate() {
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::Model(format!(
                    "floor {} mass must be positive, got {m}",
                    i + 1
                )));
            }
        }
        for (i, &k) in story_stiffness_n_per_m.iter().enumerate() {
            if !(k.is_finite() && k > 0.0) {
                return Err(Error::Model(format!(
                    "story {} stiffness must be positive, got {k}",
                    i + 1
                )));
            }
        }
        let k_influence: Vec<_> = story_stiffness_n_per_m
            .iter()
            .enumerate()
            .map(|(r, &k)| story_matrix(n, r, k))
            .collect();
        let m_influence: Vec<_> = floor_mass_kg
            .iter()
            .enumerate()
            .map(|(r, &m)| {
                let mut mm = DMatrix::zeros(n, n);
                mm[(r, r)] = m;
                mm
            })
            .collect();
        let k0 = k_influence.iter().fold(DMatrix::zeros(n, n), |a, b| a + b);
        let m0 = m_influence.iter().fold(DMatrix::zeros(n, n), |a, b| a + b);
        let alpha = story_stiffness_n_per_m
            .iter()
            .enumerate()
            .map(|(r, &k)| Parameter {
                name: format!("k{}", r + 1),
                unit: "N/m".into(),
                nominal: Some(k),
            })
            .collect();
        let beta = floor_mass_kg
            .iter()
            .enumerate()
            .map(|(r, &m)| Parameter {
                name: format!("m{}", r + 1),
                unit: "kg".into(),
                nominal: Some(m),
            })
            .collect();
        Ok(StructuralModel {
            k0,
            m0,
            k_influence,
            m_influence,
            alpha,
            beta,
            ground_influence: DVector::from_element(n, 1.0),
            measured_dofs: Vec::new(),
        })
    }

    /// A general model from its matrices. Validates shapes, symmetry, M positive definite
    /// and K positive semi-definite.
    pub fn from_matrices(
        k0: DMatrix<f64>,
        m0: DMatrix<f64>,
        k_influence: Vec<(Parameter, DMatrix<f64>)>,
        m_influence: Vec<(Parameter, DMatrix<f64>)>,
        ground_influence: Option<DVector<f64>>,
    ) -> Result<Self> {
        let n = k0.nrows();
        let check_shape = |what: &str, m: &DMatrix<f64>| {
            if m.nrows() != n || m.ncols() != n {
                Err(Error::Model(format!(
                    "{what} is {}x{}, expected {n}x{n} like K0",
                    m.nrows(),
                    m.ncols()
                )))
            } else {
                Ok(())
            }
        };
        check_shape("K0", &k0)?;
        check_shape("M0", &m0)?;
        for (p, m) in k_influence.iter().chain(m_influence.iter()) {
            check_shape(&format!("influence matrix of {}", p.name), m)?;
            check_symmetric(&format!("influence matrix of {}", p.name), m)?;
        }
        let ground_influence = ground_influence.unwrap_or_else(|| DVector::from_element(n, 1.0));
        if ground_influence.len() != n {
            return Err(Error::Model(format!(
                "ground influence vector has {} entries, expected {n}",
                ground_influence.len()
            )));
        }
        let (alpha, k_influence) = k_influence.into_iter().unzip();
        let (beta, m_influence) = m_influence.into_iter().unzip();
        let model = StructuralModel {
            k0,
            m0,
            k_influence,
            m_influence,
            alpha,
            beta,
            ground_influence,
            measured_dofs: Vec::new(),
        };
        model.validate(&model.alpha_zero(), &model.beta_zero())?;
        Ok(model)
    }

    /// Number of degrees of freedom.
    pub fn n_dof(&self) -> usize {
        self.k0.nrows()
    }
    /// Number of stiffness multipliers alpha.
    pub fn n_alpha(&self) -> usize {
        self.k_influence.len()
    }
    /// Number of mass multipliers beta.
    pub fn n_beta(&self) -> usize {
        self.m_influence.len()
    }
    /// Physical meaning of each alpha.
    pub fn alpha_parameters(&self) -> &[Parameter] {
        &self.alpha
    }
    /// Physical meaning of each beta.
    pub fn beta_parameters(&self) -> &[Parameter] {
        &self.beta
    }
    /// Stiffness influence matrices `K0_r` (Eq. 20).
    pub fn stiffness_influence(&self) -> &[DMatrix<f64>] {
        &self.k_influence
    }
    /// Mass influence matrices `M0_r` (Eq. 21).
    pub fn mass_influence(&self) -> &[DMatrix<f64>] {
        &self.m_influence
    }
    /// The nominal stiffness `K(0) = K0` (Eq. 20 at alpha = 0), without a copy.
    pub fn nominal_stiffness(&self) -> &DMatrix<f64> {
        &self.k0
    }
    /// The nominal mass `M(0) = M0` (Eq. 21 at beta = 0), without a copy.
    pub fn nominal_mass(&self) -> &DMatrix<f64> {
        &self.m0
    }
    /// Ground-motion influence vector (Eq. 13; ones for a shear frame).
    pub fn ground_influence(&self) -> &DVector<f64> {
        &self.ground_influence
    }
    /// 0-based DOFs where the model file places its sensors (`measured_dofs` of a
    /// manifest); empty when it names none.
    pub fn measured_dofs(&self) -> &[usize] {
        &self.measured_dofs
    }
    /// The model with sensors at the 0-based `dofs`; errors when one is out of range.
    pub fn with_measured_dofs(mut self, dofs: Vec<usize>) -> Result<Self> {
        if let Some(&d) = dofs.iter().find(|&&d| d >= self.n_dof()) {
            return Err(Error::Model(format!(
                "measured DOF {} is outside 1..={}",
                d + 1,
                self.n_dof()
            )));
        }
        self.measured_dofs = dofs;
        Ok(self)
    }
    /// All-zero alpha (the nominal stiffness).
    pub fn alpha_zero(&self) -> Vec<f64> {
        vec![0.0; self.n_alpha()]
    }
    /// All-zero beta (the nominal mass).
    pub fn beta_zero(&self) -> Vec<f64> {
        vec![0.0; self.n_beta()]
    }

    /// `K(alpha)`, paper Eq. (20).
    pub fn stiffness(&self, alpha: &[f64]) -> DMatrix<f64> {
        let mut k = self.k0.clone();
        for (a, kr) in alpha.iter().zip(&self.k_influence) {
            k.zip_apply(kr, |x, y| *x += a * y);
        }
        k
    }

    /// `M(beta)`, paper Eq. (21).
    pub fn mass(&self, beta: &[f64]) -> DMatrix<f64> {
        let mut m = self.m0.clone();
        for (b, mr) in beta.iter().zip(&self.m_influence) {
            m.zip_apply(mr, |x, y| *x += b * y);
        }
        m
    }

    /// Checks that `K(alpha)` is positive semi-definite and `M(beta)` positive definite
    /// on its DOFs with mass, with `K` positive definite on the massless ones (zero rows
    /// of `M`, see [`condense`]).
    pub fn validate(&self, alpha: &[f64], beta: &[f64]) -> Result<()> {
        let (k, m) = (self.stiffness(alpha), self.mass(beta));
        check_symmetric("K", &k)?;
        check_symmetric("M", &m)?;
        condense::check_condensable(&k, &m)?;
        let eig = k.symmetric_eigenvalues();
        let max = eig.iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
        let min = eig.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        if min < -PSD_RTOL * max.max(f64::MIN_POSITIVE) {
            return Err(Error::Model(format!(
                "K is not positive semi-definite (smallest eigenvalue {min:.3e}, largest {max:.3e})"
            )));
        }
        Ok(())
    }

    /// Physical values of the shear-frame variables: story stiffnesses `k_r0 (1 + alpha_r)`
    /// then floor masses `m_r0 (1 + beta_r)`; `None` for variables without a nominal value.
    pub fn physical_values(
        &self,
        alpha: &[f64],
        beta: &[f64],
    ) -> (Vec<Option<f64>>, Vec<Option<f64>>) {
        let f = |ps: &[Parameter], x: &[f64]| -> Vec<Option<f64>> {
            ps.iter()
                .zip(x)
                .map(|(p, &v)| p.nominal.map(|n| n * (1.0 + v)))
                .collect()
        };
        (f(&self.alpha, alpha), f(&self.beta, beta))
    }
}

/// Stiffness matrix of story `r` (0-based) of an n-floor shear frame with stiffness `k`.
fn story_matrix(n: usize, r: usize, k: f64) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(n, n);
    m[(r, r)] += k;
    if r > 0 {
        m[(r - 1, r - 1)] += k;
        m[(r - 1, r)] -= k;
        m[(r, r - 1)] -= k;
    }
    m
}

fn check_symmetric(what: &str, m: &DMatrix<f64>) -> Result<()> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Model(format!("{what} has non-finite entries")));
    }
    let scale = m.amax().max(f64::MIN_POSITIVE);
    for i in 0..m.nrows() {
        for j in 0..i {
            let d = (m[(i, j)] - m[(j, i)]).abs();
            if d > SYMMETRY_RTOL * scale {
                return Err(Error::Model(format!(
                    "{what} is not symmetric: entry ({},{}) = {} but ({},{}) = {}",
                    i + 1,
                    j + 1,
                    m[(i, j)],
                    j + 1,
                    i + 1,
                    m[(j, i)]
                )));
            }
        }
    }
    Ok(())
}

/// For tests: `$FRFBAYES_SHARED_DIR/<rel>` or `<repo>/../shared/<rel>` when present, else
/// `None` after printing a skip message.
#[cfg(test)]
pub(crate) fn shared_dir(rel: &str) -> Option<std::path::PathBuf> {
    let mut roots = vec![std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")];
    roots.extend(std::env::var_os("FRFBAYES_SHARED_DIR").map(std::path::PathBuf::from));
    let found = roots.into_iter().map(|r| r.join(rel)).find(|p| p.exists());
    if found.is_none() {
        println!("skipped: {rel} not found (no ../shared beside the repository and no FRFBAYES_SHARED_DIR)");
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shear_frame_matrices() {
        let m = StructuralModel::shear_frame(&[1.0, 2.0], &[10.0, 20.0]).unwrap();
        let k = m.stiffness(&[0.0, 0.0]);
        assert_eq!(
            k,
            DMatrix::from_row_slice(2, 2, &[30.0, -20.0, -20.0, 20.0])
        );
        let k = m.stiffness(&[1.0, 0.5]);
        assert_eq!(
            k,
            DMatrix::from_row_slice(2, 2, &[50.0, -30.0, -30.0, 30.0])
        );
        let mm = m.mass(&[0.5, 0.0]);
        assert_eq!(mm, DMatrix::from_row_slice(2, 2, &[1.5, 0.0, 0.0, 2.0]));
        let (k, ms) = m.physical_values(&[0.1, 0.0], &[0.0, -0.5]);
        assert!((k[0].unwrap() - 11.0).abs() < 1e-12 && (ms[1].unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_models() {
        assert!(StructuralModel::shear_frame(&[1.0, -2.0], &[10.0, 20.0]).is_err());
        assert!(StructuralModel::shear_frame(&[1.0], &[10.0, 20.0]).is_err());
        let k = DMatrix::from_row_slice(2, 2, &[1.0, 0.5, 0.4, 1.0]);
        let m = DMatrix::identity(2, 2);
        let e = StructuralModel::from_matrices(k, m.clone(), vec![], vec![], None).unwrap_err();
        assert!(e.to_string().contains("not symmetric"), "{e}");
        let k = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        let e = StructuralModel::from_matrices(k, m, vec![], vec![], None).unwrap_err();
        assert!(e.to_string().contains("semi-definite"), "{e}");
        let k = DMatrix::identity(2, 2);
        let m = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, -1.0]);
        let e = StructuralModel::from_matrices(k.clone(), m, vec![], vec![], None).unwrap_err();
        assert!(e.to_string().contains("M is not positive definite"), "{e}");
        // A massless DOF is fine when K holds it, not when it is free.
        let m = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 0.0]);
        assert!(StructuralModel::from_matrices(k, m.clone(), vec![], vec![], None).is_ok());
        let k = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 0.0]);
        let e = StructuralModel::from_matrices(k, m, vec![], vec![], None).unwrap_err();
        assert!(e.to_string().contains("massless DOFs"), "{e}");
    }
}
