//! The paper's updating runs: for each table (hammer tests -> Table 1, shake-table test
//! -> Table 2) and each variant {Rayleigh, Caughey} x {receptance, accelerance}, build the
//! long vectors of measured magnitudes at the selected half-power-band points (Eqs.
//! 17-19, 23), update by bounded multistart least squares (Eqs. 22, 24), and report
//! physical values, FDAC per FRF, starts at the best minimum and variables on bounds.

use super::config::{ExperimentConfig, Weighting};
use crate::error::{Error, Result};
use crate::frf::labels::pair_label;
use crate::frf::{FrfBlock, FrfKind, FrfPair, ModalFrf};
use crate::modal::Modes;
use crate::model::{Damping, StructuralModel};
use crate::signal::TestFrf;
use crate::update::lsq::Active;
use crate::update::{
    fdac_per_pair, update, DampingModel, Measurements, MultistartOptions, ObjectiveOptions,
    Problem, UpdateResult, VariablesConfig,
};
use serde::Serialize;
use std::time::Instant;

/// Which test group a table is built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TableId {
    /// Table 1: the hammer tests (one excited floor each).
    Table1,
    /// Table 2: the shake-table test (ground excitation).
    Table2,
}

impl TableId {
    /// `table1` / `table2`.
    pub fn key(self) -> &'static str {
        match self {
            TableId::Table1 => "table1",
            TableId::Table2 => "table2",
        }
    }
    /// Whether a test estimate belongs to this table.
    pub fn includes(self, frf: &TestFrf) -> bool {
        matches!(
            (self, &frf.input),
            (TableId::Table1, crate::signal::InputKind::Force { .. })
                | (TableId::Table2, crate::signal::InputKind::Ground { .. })
        )
    }
}

/// One of the paper's eight updating variants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Variant {
    pub table: TableId,
    pub damping: DampingModel,
    pub kind: FrfKind,
}

impl Variant {
    /// The table column this variant fills (`rayleigh_receptance`, ...).
    pub fn column(&self) -> String {
        let d = match self.damping {
            DampingModel::Rayleigh => "rayleigh",
            DampingModel::Caughey => "caughey",
        };
        let k = match self.kind {
            FrfKind::Receptance => "receptance",
            FrfKind::Mobility => "mobility",
            FrfKind::Accelerance => "accelerance",
        };
        format!("{d}_{k}")
    }

    /// The eight variants in the paper's order (Table 1 then Table 2).
    pub fn all() -> Vec<Variant> {
        let mut v = Vec::new();
        for table in [TableId::Table1, TableId::Table2] {
            for damping in [DampingModel::Rayleigh, DampingModel::Caughey] {
                for kind in [FrfKind::Receptance, FrfKind::Accelerance] {
                    v.push(Variant {
                        table,
                        damping,
                        kind,
                    });
                }
            }
        }
        v
    }
}

/// The measured long vector of one variant: every test of the table, the responses of
/// `kind`, at each test's selected points; with Bendat & Piersol sigmas when weighted.
pub fn measurements(
    frfs: &[&TestFrf],
    kind: FrfKind,
    weighting: Weighting,
) -> Result<Measurements> {
    let mut blocks = Vec::new();
    let mut magnitude = Vec::new();
    let mut sigma = Vec::new();
    for frf in frfs {
        let full = frf.frf_block()?;
        let mags = frf.selected_magnitudes();
        let rel = frf.selected_rel_std();
        let nw = full.omega_rad_s.len();
        let mut pairs = Vec::new();
        for (j, p) in full.pairs.iter().enumerate() {
            if p.kind != kind {
                continue;
            }
            pairs.push(*p);
            magnitude.extend_from_slice(&mags[j * nw..(j + 1) * nw]);
            sigma.extend(
                mags[j * nw..(j + 1) * nw]
                    .iter()
                    .zip(&rel[j * nw..(j + 1) * nw])
                    .map(|(m, r)| m * r),
            );
        }
        if !pairs.is_empty() && nw > 0 {
            blocks.push(FrfBlock {
                omega_rad_s: full.omega_rad_s.clone(),
                pairs,
            });
        }
    }
    if blocks.is_empty() {
        return Err(Error::Usage(format!(
            "no {kind:?} FRFs with selected points in these tests"
        )));
    }
    let sigma = match weighting {
        Weighting::None => None,
        Weighting::Coherence => Some(sigma),
    };
    Ok(Measurements {
        blocks,
        magnitude,
        sigma,
    })
}

/// The outcome of one variant.
#[derive(Debug)]
pub struct VariantRun {
    pub variant: Variant,
    pub problem: Problem,
    pub result: UpdateResult,
    /// FRF labels (`H4,1`) in long-vector order, with FDAC of the initial and updated
    /// model over the selected points.
    pub fdac: Vec<(String, f64, f64)>,
    /// Physical values by name as fitted to the (windowed) estimates.
    pub fitted: Vec<(String, f64)>,
    /// Physical values with the exponential window's damping removed (the table values).
    pub corrected: Vec<(String, f64)>,
    /// Exponential-window time constant of the data, s.
    pub window_tau_s: Option<f64>,
    /// Natural frequencies of the updated model, Hz.
    pub freq_hz: Vec<f64>,
    /// Modal damping ratios the updated damping implies, window contribution removed
    /// (Rayleigh: `(a0 / omega_i + a1 omega_i) / 2`, Eq. 7; Caughey: `xi_i`).
    pub damping_ratios: Vec<f64>,
    pub n_points: usize,
    pub wall_s: f64,
}

impl VariantRun {
    /// Variables on a bound at the best fit, as `name (lower|upper)`.
    pub fn on_bounds(&self) -> Vec<String> {
        self.result
            .on_bounds()
            .into_iter()
            .map(|(n, a)| {
                format!(
                    "{n} ({})",
                    if a == Active::Lower { "lower" } else { "upper" }
                )
            })
            .collect()
    }
}

/// Magnitudes of one FRF pair of the model at `theta` over `omega_rad_s` (for figures).
pub fn model_curve(
    problem: &Problem,
    theta: &[f64],
    pair: FrfPair,
    omega_rad_s: &[f64],
) -> Result<Vec<f64>> {
    let vars = problem.variables();
    let model = problem.model();
    let (alpha, beta, damping) = vars.split(theta);
    let modes = Modes::solve(
        &model.stiffness(alpha),
        &model.mass(beta),
        model.ground_influence(),
        Some(problem.n_modes()),
    )?;
    let mut c = vec![0.0; modes.n_modes()];
    damping.modal_coefficients(&modes.omega_rad_s, &mut c)?;
    let mut eval = ModalFrf::new(vec![FrfBlock {
        omega_rad_s: omega_rad_s.to_vec(),
        pairs: vec![pair],
    }]);
    let mut out = vec![0.0; eval.len()];
    eval.magnitudes(&modes, &c, &mut out)?;
    Ok(out)
}

/// Removes the exponential window's added damping (`1/tau` on every decay rate) from
/// fitted damping: Rayleigh `a0 - 2/tau`; Caughey `xi_i - 1/(tau omega_i)` with
/// `omega_i` of the updated model. Leaves everything else unchanged.
fn correct_window(
    model: &StructuralModel,
    problem: &Problem,
    theta: &[f64],
    names: &[String],
    physical: &[f64],
    tau_s: Option<f64>,
) -> Result<Vec<(String, f64)>> {
    let mut out: Vec<(String, f64)> = names
        .iter()
        .cloned()
        .zip(physical.iter().copied())
        .collect();
    let Some(tau) = tau_s else { return Ok(out) };
    let eps = 1.0 / tau;
    let (alpha, beta, damping) = problem.variables().split(theta);
    match damping {
        Damping::Rayleigh { .. } => {
            if let Some(a0) = out.iter_mut().find(|(n, _)| n == "a0") {
                a0.1 -= 2.0 * eps;
            }
        }
        Damping::Caughey { .. } => {
            let modes = Modes::solve(
                &model.stiffness(alpha),
                &model.mass(beta),
                model.ground_influence(),
                Some(problem.n_modes()),
            )?;
            for (i, w) in modes.omega_rad_s.iter().enumerate() {
                let name = format!("xi{}", i + 1);
                if let Some(x) = out.iter_mut().find(|(n, _)| *n == name) {
                    x.1 -= eps / w;
                }
            }
        }
    }
    Ok(out)
}

/// Runs one variant.
pub fn run_variant(
    model: &StructuralModel,
    frfs: &[TestFrf],
    variant: Variant,
    cfg: &ExperimentConfig,
    seed: u64,
) -> Result<VariantRun> {
    run_variant_with(model, frfs, variant, cfg, seed, &|p, ms| update(p, ms))
}

/// [`run_variant`] with the multistart update made by `solve` (e.g. one computed on
/// another rank of an MPI run).
pub fn run_variant_with(
    model: &StructuralModel,
    frfs: &[TestFrf],
    variant: Variant,
    cfg: &ExperimentConfig,
    seed: u64,
    solve: &dyn Fn(&Problem, &MultistartOptions) -> Result<UpdateResult>,
) -> Result<VariantRun> {
    let t0 = Instant::now();
    let group: Vec<&TestFrf> = frfs.iter().filter(|f| variant.table.includes(f)).collect();
    if group.is_empty() {
        return Err(Error::Usage(format!(
            "no tests for {} in the campaign",
            variant.table.key()
        )));
    }
    let taus: Vec<Option<f64>> = group.iter().map(|f| f.exp_window_tau_s).collect();
    let window_tau_s = taus[0];
    if taus.iter().any(|t| t != &window_tau_s) {
        return Err(Error::Usage(format!(
            "tests of {} were windowed differently ({taus:?}); use one common exponential window",
            variant.table.key()
        )));
    }
    let data = measurements(&group, variant.kind, cfg.update.weighting)?;
    let n_points = data.magnitude.len();
    let vars_cfg: &VariablesConfig = match (variant.table, &cfg.update.variables_shake_table) {
        (TableId::Table2, Some(v)) => v,
        _ => &cfg.update.variables,
    };
    let options = ObjectiveOptions {
        residual: cfg.update.residual,
        n_modes: None,
    };
    let problem = Problem::new(
        model.clone(),
        data.clone(),
        variant.damping,
        vars_cfg,
        options,
    )?;
    let ms = MultistartOptions {
        n_starts: cfg.update.starts,
        seed,
        ..Default::default()
    };
    let result = solve(&problem, &ms)?;
    let initial = problem.variables().initial();
    let labels: Vec<String> = data
        .blocks
        .iter()
        .flat_map(|b| b.pairs.iter().map(pair_label))
        .collect();
    let f_init = fdac_per_pair(
        &data.blocks,
        &problem.magnitudes(&initial)?,
        &data.magnitude,
    )?;
    let f_best = fdac_per_pair(
        &data.blocks,
        &problem.magnitudes(&result.best.theta)?,
        &data.magnitude,
    )?;
    let fdac = labels
        .into_iter()
        .zip(f_init)
        .zip(f_best)
        .map(|((l, a), b)| (l, a, b))
        .collect();
    let fitted: Vec<(String, f64)> = result
        .names
        .iter()
        .cloned()
        .zip(result.best.physical.iter().copied())
        .collect();
    let corrected = correct_window(
        model,
        &problem,
        &result.best.theta,
        &result.names,
        &result.best.physical,
        window_tau_s,
    )?;
    let (alpha, beta, _) = problem.variables().split(&result.best.theta);
    let modes = Modes::solve(
        &model.stiffness(alpha),
        &model.mass(beta),
        model.ground_influence(),
        Some(problem.n_modes()),
    )?;
    let value = |name: &str| corrected.iter().find(|(n, _)| n == name).map(|x| x.1);
    let damping_ratios = modes
        .omega_rad_s
        .iter()
        .enumerate()
        .map(|(i, w)| match variant.damping {
            DampingModel::Rayleigh => {
                (value("a0").unwrap_or(0.0) / w + value("a1").unwrap_or(0.0) * w) / 2.0
            }
            DampingModel::Caughey => value(&format!("xi{}", i + 1)).unwrap_or(f64::NAN),
        })
        .collect();
    Ok(VariantRun {
        variant,
        problem,
        result,
        fdac,
        fitted,
        corrected,
        window_tau_s,
        freq_hz: modes.freq_hz(),
        damping_ratios,
        n_points,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}
