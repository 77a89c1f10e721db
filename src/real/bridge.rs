//! The steel pedestrian bridge (`bridge-fe`): a 946-DOF FE model with 17 stiffness
//! groups and 5 identified modes, updated as SMU (Wang's Structural Model Updating
//! toolbox) updates it, then sampled. The formulation is written down in
//! `docs/bridge-smu.md` (read from SMU's source, not copied).
//!
//! This module loads the data and states the two posteriors on the one inference layer
//! ([`crate::infer::Posterior`]): SMU's weighted least squares (eigenvalue differences
//! over their measured scatter, eigenvector differences with a reference entry of 1) and
//! a Bayesian posterior on the same residuals with sampled noise scales.

use std::path::Path;
use std::sync::Arc;

use nalgebra::DMatrix;

use crate::error::{Error, Result};
use crate::infer::likelihood::Transform;
use crate::infer::{Block, NoiseScale, Posterior};
use crate::model::mat::MatData;
use crate::model::{ModelManifest, StructuralModel};
use crate::predict::modal::{ModalPredictor, ModeSolver};
use crate::predict::Parametrisation;

/// The model manifest, shipped with the repository; `{shared}` is replaced by the data
/// folder's shared root when loaded.
const MANIFEST: &str = include_str!("../../experiments/models/bridge-fe.toml");

/// SMU's published optimum (`PostProcess.m`, 4 decimals), SMU's order.
pub const SMU_PUBLISHED_ALPHA: [f64; 17] = [
    -0.1, -0.045, 0.4, -0.2, -0.2, -0.2, -0.2, -0.2, -0.2, -0.2, -0.2, 0.4, 0.4, -0.7168, 3.9951,
    -0.1633, 10.0,
];
/// SMU's published objective `f = sum r^2` at its optimum.
pub const SMU_PUBLISHED_OBJECTIVE: f64 = 2.8474;
/// SMU's measured DOF count, in its shape weights `1 / std / 58`.
const N_MEAS: f64 = 58.0;

/// The model and the identified modes.
#[derive(Debug, Clone)]
pub struct BridgeData {
    pub model: Arc<StructuralModel>,
    /// Identified eigenvalues `(2 pi f)^2` (rad^2/s^2) and their scatter over tests.
    pub lambda_exp: Vec<f64>,
    pub std_lambda: Vec<f64>,
    /// Identified shapes at the measured DOFs (58 x 5, rows in `measDOFs` order) and
    /// their scatter.
    pub psi_exp: DMatrix<f64>,
    pub std_psi: DMatrix<f64>,
    /// 0-based model DOF of each shape row.
    pub meas_dofs: Vec<usize>,
    /// Row of each mode's reference entry (the entry equal to 1, SMU's `q(i)`).
    pub reference: Vec<usize>,
    /// Tests that identified each mode.
    pub num_test: Vec<f64>,
}

impl BridgeData {
    pub fn n_modes(&self) -> usize {
        self.lambda_exp.len()
    }
    /// Measured natural frequencies, Hz.
    pub fn freq_exp_hz(&self) -> Vec<f64> {
        self.lambda_exp
            .iter()
            .map(|l| l.sqrt() / (2.0 * std::f64::consts::PI))
            .collect()
    }
}

/// `<shared>/data/real/bridge-fe` -> `<shared>`.
fn shared_of(data_dir: &Path) -> &Path {
    data_dir
        .parent()
        .and_then(Path::parent)
        .and_then(Path::parent)
        .unwrap_or(Path::new("."))
}

/// Reads the model (through the shipped manifest) and the identified modes from
/// `data_dir` (`<shared>/data/real/bridge-fe`).
pub fn load(data_dir: &Path) -> Result<BridgeData> {
    let shared = shared_of(data_dir).display().to_string();
    let text = MANIFEST.replace(
        "{shared}",
        &shared.replace('\\', "\\\\").replace('"', "\\\""),
    );
    let label = Path::new("experiments/models/bridge-fe.toml");
    let model = ModelManifest::load_text(&text, label, data_dir)?;
    let meas_dofs = model.measured_dofs().to_vec();
    let path = data_dir.join("ExpModeInfo_FEM.mat");
    let mat = MatData::open(&path)?;
    let lambda_exp = mat.vector("lambdaExp", None)?;
    let n_modes = lambda_exp.len();
    let std_lambda = mat.vector("std_lambdaExp", Some(n_modes))?;
    let num_test = mat.vector("numTest", Some(n_modes))?;
    let grid = |name: &str| -> Result<DMatrix<f64>> {
        let a = mat.real(name)?;
        if a.rows != meas_dofs.len() || a.cols != n_modes {
            return Err(Error::invalid(
                &path,
                format!(
                    "`{name}` is {} x {}; expected {} x {n_modes} (measured DOFs x modes)",
                    a.rows,
                    a.cols,
                    meas_dofs.len()
                ),
            ));
        }
        Ok(DMatrix::from_fn(a.rows, a.cols, |r, c| a.get(r, c)))
    };
    let (psi_exp, std_psi) = (grid("psiExp_m")?, grid("std_psiExp")?);
    let reference = (0..n_modes)
        .map(|i| reference_row(psi_exp.column(i).as_slice()))
        .collect();
    Ok(BridgeData {
        model: Arc::new(model),
        lambda_exp,
        std_lambda,
        psi_exp,
        std_psi,
        meas_dofs,
        reference,
        num_test,
    })
}

/// SMU's `q(i)`: the entry exactly equal to 1, else the largest in magnitude.
pub fn reference_row(shape: &[f64]) -> usize {
    shape.iter().position(|&v| v == 1.0).unwrap_or_else(|| {
        (0..shape.len())
            .max_by(|&a, &b| shape[a].abs().total_cmp(&shape[b].abs()))
            .unwrap_or(0)
    })
}

/// SMU's bounds: -0.1..0.1 (Frame, Truss), -0.2..0.4 (Conc1..11), -1..10 (supports).
pub fn smu_bounds() -> Vec<(f64, f64)> {
    (0..17)
        .map(|j| match j {
            0 | 1 => (-0.1, 0.1),
            2..=12 => (-0.2, 0.4),
            _ => (-1.0, 10.0),
        })
        .collect()
}

/// How shape residuals are weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// As SMU computes it: mode i's shape residuals all get `psiWeights(i)`, a linear
    /// index into the 58 x 5 matrix `1 / std_psiExp / 58`, so entry i of column 1.
    SmuLinearIndex,
    /// What it probably meant: entry k of mode i gets `1 / std_psiExp(k, i) / 58`.
    PerEntry,
}

/// The modal predictor of the bridge: all 17 alphas (linear, SMU's order), the 5 lowest
/// modes paired by index (SMU's "forced matching"), shapes at `measDOFs`.
pub fn predictor<S: ModeSolver>(data: &BridgeData, solver: S) -> Result<ModalPredictor<S>> {
    let params = Parametrisation::all_alphas(&data.model)?;
    let modes = (0..data.n_modes()).collect();
    ModalPredictor::new(solver, params, data.meas_dofs.clone(), modes)
}

fn shape_weights(data: &BridgeData, i: usize, weighting: Weighting) -> Vec<f64> {
    let q = data.reference[i];
    (0..data.meas_dofs.len())
        .map(|k| match weighting {
            Weighting::SmuLinearIndex => 1.0 / data.std_psi[(i, 0)] / N_MEAS,
            Weighting::PerEntry if k == q => 1.0,
            Weighting::PerEntry => 1.0 / data.std_psi[(k, i)] / N_MEAS,
        })
        .collect()
}

/// The eigenvalue block and one shape-difference block per mode, shape weights scaled
/// by `shape_factor`, with the noise scales `eig_scale` and `shape_scale`.
fn modal_blocks<S: ModeSolver>(
    data: &BridgeData,
    p: &ModalPredictor<S>,
    weighting: Weighting,
    shape_factor: f64,
    (eig_scale, shape_scale): (NoiseScale, NoiseScale),
) -> Result<Vec<Block>> {
    let mut blocks = vec![Block::values(
        "eigenvalues",
        p.freq_range(),
        &data.freq_exp_hz(),
        &data.std_lambda,
        Transform::EigenvalueOfHz,
        eig_scale,
    )?];
    for i in 0..data.n_modes() {
        let w: Vec<f64> = shape_weights(data, i, weighting)
            .iter()
            .map(|w| w * shape_factor)
            .collect();
        blocks.push(Block::shape_difference(
            &format!("shape {}", i + 1),
            p.shape_range(i),
            data.psi_exp.column(i).as_slice(),
            data.reference[i],
            &w,
            shape_scale,
        )?);
    }
    Ok(blocks)
}

/// SMU's objective as a posterior with every noise scale fixed at 1: its cost
/// `0.5 ||r||^2` is half of SMU's `f = sum r^2` (docs/bridge-smu.md, sections 5-6).
pub fn smu_posterior<S: ModeSolver>(
    data: &BridgeData,
    solver: S,
    weighting: Weighting,
) -> Result<Posterior<ModalPredictor<S>>> {
    let p = predictor(data, solver)?;
    let fixed = NoiseScale::Fixed(1.0);
    let blocks = modal_blocks(data, &p, weighting, 1.0, (fixed, fixed))?;
    Posterior::new(p, &smu_bounds(), &[], blocks)
}

/// Prior box of the two sampled noise scales, `ln sigma`.
pub const LN_SIGMA_BOUNDS: (f64, f64) = (-5.0, 5.0);

/// The Bayesian posterior: uniform prior on SMU's box; eigenvalue residuals over their
/// measured scatter and shape residuals over theirs (per entry, without SMU's 1/58),
/// Gaussian, each kind with its own sampled noise scale `sigma` (log-uniform): a
/// `sigma` well above 1 says the misfit is more than the test-to-test scatter.
pub fn bayes_posterior<S: ModeSolver>(
    data: &BridgeData,
    solver: S,
) -> Result<Posterior<ModalPredictor<S>>> {
    let p = predictor(data, solver)?;
    let scales = (NoiseScale::Sampled(0), NoiseScale::Sampled(1));
    let blocks = modal_blocks(data, &p, Weighting::PerEntry, N_MEAS, scales)?;
    let scales = [
        ("ln_sigma_eigenvalues".to_string(), LN_SIGMA_BOUNDS),
        ("ln_sigma_shapes".to_string(), LN_SIGMA_BOUNDS),
    ];
    Posterior::new(p, &smu_bounds(), &scales, blocks)
}
