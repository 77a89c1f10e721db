//! Synthetic four-story frame campaigns with known truth, shared by the recovery tests
//! and the timing run. Data come from the direct inverse of Eq. (1) / Eq. (14)
//! (`frf::direct`), independent of the modal sums the fit uses.
#![allow(dead_code)]

use frfbayes::frf::{direct, Excitation, FrfBlock, FrfKind, FrfPair};
use frfbayes::modal::Modes;
use frfbayes::model::{
    caughey_coefficients, caughey_damping_matrix, rayleigh_damping_matrix, StructuralModel,
};
use frfbayes::update::{DampingModel, Measurements, ObjectiveOptions, Problem, VariablesConfig};
use nalgebra::DMatrix;

/// The paper's nominal frame (Section 4.1, Table 1 initial values).
pub const MASS_KG: [f64; 4] = [4.64; 4];
pub const STIFFNESS_N_PER_M: [f64; 4] = [1019.0, 1217.0, 1420.0, 2473.0];
/// True multipliers: a few percent off nominal, inside the default bounds.
pub const ALPHA: [f64; 4] = [0.07, 0.04, -0.03, 0.08];
pub const BETA: [f64; 4] = [0.08, 0.07, 0.065, 0.09];
/// True Rayleigh coefficients (1/s, s) and Caughey ratios (Table 1-like).
pub const RAYLEIGH: [f64; 2] = [0.2, 2e-5];
pub const CAUGHEY: [f64; 4] = [0.016, 0.011, 0.005, 0.002];

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Test {
    /// Hammer at every floor, responses at every floor: 4 blocks x 4 pairs.
    Hammer,
    /// Shake table: one block of 4 ground pairs.
    Ground,
}

pub fn nominal() -> StructuralModel {
    StructuralModel::shear_frame(&MASS_KG, &STIFFNESS_N_PER_M).unwrap()
}

/// True theta in the layout of `frfbayes::update::Variables`.
pub fn truth(damping: DampingModel) -> Vec<f64> {
    let d: &[f64] = match damping {
        DampingModel::Rayleigh => &RAYLEIGH,
        DampingModel::Caughey => &CAUGHEY,
    };
    [&ALPHA[..], &BETA[..], d].concat()
}

/// True K, M, C.
fn true_matrices(damping: DampingModel) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let model = nominal();
    let (k, m) = (model.stiffness(&ALPHA), model.mass(&BETA));
    let c = match damping {
        DampingModel::Rayleigh => rayleigh_damping_matrix(&m, &k, RAYLEIGH[0], RAYLEIGH[1]),
        DampingModel::Caughey => {
            let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
            let a = caughey_coefficients(&modes.omega_rad_s, &CAUGHEY).unwrap();
            caughey_damping_matrix(&m, &k, &a).unwrap()
        }
    };
    (k, m, c)
}

/// `points_per_band` points evenly across each true half-power band
/// `omega_i (1 -+ xi_i)`, as an experimenter would pick them from the peaks.
pub fn half_power_grid(damping: DampingModel, points_per_band: usize) -> Vec<f64> {
    let model = nominal();
    let modes = Modes::solve(
        &model.stiffness(&ALPHA),
        &model.mass(&BETA),
        model.ground_influence(),
        None,
    )
    .unwrap();
    let xi: Vec<f64> = match damping {
        DampingModel::Rayleigh => modes
            .omega_rad_s
            .iter()
            .map(|w| (RAYLEIGH[0] + RAYLEIGH[1] * w * w) / (2.0 * w))
            .collect(),
        DampingModel::Caughey => CAUGHEY.to_vec(),
    };
    let mut grid = Vec::new();
    for (w, x) in modes.omega_rad_s.iter().zip(&xi) {
        for j in 0..points_per_band {
            let t = -1.0 + 2.0 * j as f64 / (points_per_band - 1) as f64;
            grid.push(w * (1.0 + x * t));
        }
    }
    grid
}

pub fn blocks(test: Test, kind: FrfKind, grid: &[f64]) -> Vec<FrfBlock> {
    match test {
        Test::Hammer => (0..4)
            .map(|e| FrfBlock {
                omega_rad_s: grid.to_vec(),
                pairs: (0..4)
                    .map(|r| FrfPair {
                        response: r,
                        excitation: Excitation::Dof(e),
                        kind,
                    })
                    .collect(),
            })
            .collect(),
        Test::Ground => vec![FrfBlock {
            omega_rad_s: grid.to_vec(),
            pairs: (0..4)
                .map(|r| FrfPair {
                    response: r,
                    excitation: Excitation::Ground,
                    kind,
                })
                .collect(),
        }],
    }
}

/// Noise-free true magnitudes by direct solves.
pub fn true_magnitudes(damping: DampingModel, blocks: &[FrfBlock]) -> Vec<f64> {
    let (k, m, c) = true_matrices(damping);
    let iota = nominal().ground_influence().clone();
    direct::block_frfs(&m, &k, &c, &iota, blocks)
        .unwrap()
        .iter()
        .map(|h| h.norm())
        .collect()
}

/// A problem on `magnitude` (and optional sigma) for one variant.
pub fn problem(
    damping: DampingModel,
    blocks: Vec<FrfBlock>,
    magnitude: Vec<f64>,
    sigma: Option<Vec<f64>>,
    config: &VariablesConfig,
    options: ObjectiveOptions,
) -> Problem {
    let data = Measurements {
        blocks,
        magnitude,
        sigma,
    };
    Problem::new(nominal(), data, damping, config, options).unwrap()
}

/// Config fixing the masses at their true multipliers (ground-only identifiability).
pub fn masses_fixed() -> VariablesConfig {
    let mut c = VariablesConfig::default();
    for (i, b) in BETA.iter().enumerate() {
        c.fixed.insert(format!("m{}", i + 1), *b);
    }
    c
}
