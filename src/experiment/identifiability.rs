//! Why damping is poorly identified, from the updating problems themselves:
//!
//! - **Fisher information** at the optimum in log-parameter coordinates (relative
//!   changes), `F = J_log^T J_log / s^2` with `s^2 = ||r||^2 / (N - p)` (Gauss-Newton;
//!   the paper's plain residuals are homoscedastic by assumption). Its inverse gives the
//!   asymptotic coefficient of variation of every parameter, its eigenvalues how many
//!   combinations the data pin down, and eigenvectors with (numerically) zero eigenvalue
//!   the unidentified directions (the mass-stiffness scale under ground excitation).
//! - **Where the damping information comes from**: the share of `F_{xi_i xi_i}` that
//!   comes from points inside the half-power band of mode i.
//! - **Au's uncertainty law**: for modal identification the coefficients of variation
//!   scale as `delta_f^2 ~ xi / (2 pi N_c B_f)` and `delta_xi^2 ~ 1 / (2 pi xi N_c B_xi)`
//!   (Au 2014), so `delta_xi / delta_f ~ (1/xi) sqrt(B_f / B_xi)`: damping is worse by a
//!   factor of order 1/xi. We report `xi_i delta_xi,i / delta_f,i`, which the law says is
//!   of order one and roughly the same for every mode.
//! - **Frequency resolution and windowing**: the bias of half-power damping estimates
//!   read off an exponentially windowed FRF sampled at the block's bin spacing, against
//!   the model's own damping (analytic FRF, no noise), for several windows and block
//!   lengths. A model fitted at the same bins has no resolution bias, and the window's
//!   pole shift is removed exactly.

use super::pipeline::VariantRun;
use crate::error::Result;
use crate::frf::{Excitation, FrfKind, FrfPair};
use crate::modal::Modes;
use crate::signal::bands::{half_power_band, HALF_POWER_DB};
use crate::signal::{windowed_modal_frf, TestFrf};
use crate::update::lsq::{fd_jacobian, Bounds, FdScheme};
use crate::update::VariableKind;
use nalgebra::DMatrix;

/// Eigenvalues below this fraction of the largest count as unidentified directions.
pub const NULL_RTOL: f64 = 1e-10;

/// Fisher-information analysis of one variant at its optimum.
#[derive(Debug, Clone)]
pub struct FisherAnalysis {
    pub variant: String,
    pub names: Vec<String>,
    /// Asymptotic coefficient of variation of each (physical) parameter, %; `None` when
    /// the parameter has a component along an unidentified direction.
    pub cv_percent: Vec<Option<f64>>,
    /// Eigenvalues of the Fisher information in log coordinates, descending.
    pub eigenvalues: Vec<f64>,
    /// Matching unit eigenvectors (columns), entries in `names` order.
    pub eigenvectors: DMatrix<f64>,
    /// Correlation matrix of the asymptotic covariance (identifiable subspace).
    pub correlation: DMatrix<f64>,
    /// Natural frequencies of the model at the optimum, Hz, and their CV, %.
    pub freq_hz: Vec<f64>,
    pub freq_cv_percent: Vec<Option<f64>>,
    /// For Caughey variants: share of the information on `xi_i` from mode i's band.
    pub band_share: Vec<Option<f64>>,
    /// Residual variance `s^2` (of the normalised residuals).
    pub residual_variance: f64,
}

/// `d theta / d ln(physical)` of a variable: multipliers act on `k0 (1 + alpha)`.
fn log_scale(kind: VariableKind, theta: f64) -> f64 {
    match kind {
        VariableKind::Alpha(_) | VariableKind::Beta(_) => 1.0 + theta,
        _ => theta,
    }
}

/// Natural frequencies (rad/s) of the variant's model at `theta`.
fn omegas(run: &VariantRun, theta: &[f64]) -> Result<Vec<f64>> {
    let p = &run.problem;
    let (alpha, beta, _) = p.variables().split(theta);
    let m = p.model();
    Ok(Modes::solve(
        &m.stiffness(alpha),
        &m.mass(beta),
        m.ground_influence(),
        Some(p.n_modes()),
    )?
    .omega_rad_s)
}

/// Fisher analysis of one variant.
pub fn fisher_analysis(run: &VariantRun, frfs: &[TestFrf]) -> Result<FisherAnalysis> {
    let problem = &run.problem;
    let theta = &run.result.best.theta;
    let vars = problem.variables().variables();
    let free: Vec<usize> = (0..vars.len())
        .filter(|&i| vars[i].fixed.is_none())
        .collect();
    let jac = problem.jacobian_at(theta)?;
    let r = problem.residuals_at(theta)?;
    let (n, p) = (r.len(), free.len());
    let s2 = r.iter().map(|v| v * v).sum::<f64>() / (n.saturating_sub(p).max(1)) as f64;
    let scales: Vec<f64> = free
        .iter()
        .map(|&i| log_scale(vars[i].kind, theta[i]))
        .collect();
    let jl = DMatrix::from_fn(n, p, |k, j| jac[(k, free[j])] * scales[j]);
    let fisher = (jl.transpose() * &jl) / s2;
    let spec = FisherSpectrum::new(&fisher);
    let cov = spec.pseudo_inverse();
    let cv_percent: Vec<Option<f64>> = (0..p)
        .map(|a| {
            if spec.touches_null(a) {
                None
            } else {
                Some(100.0 * cov[(a, a)].max(0.0).sqrt())
            }
        })
        .collect();
    let correlation = DMatrix::from_fn(p, p, |a, b| {
        cov[(a, b)] / (cov[(a, a)] * cov[(b, b)]).sqrt().max(f64::MIN_POSITIVE)
    });
    let w0 = omegas(run, theta)?;
    let freq_cv_percent = frequency_cv_percent(run, &free, &scales, &spec, &cov, w0.len())?;
    let band_share = xi_band_share(run, frfs, &free, &jl);
    Ok(FisherAnalysis {
        variant: format!("{} {}", run.variant.table.key(), run.variant.column()),
        names: free.iter().map(|&i| vars[i].name.clone()).collect(),
        cv_percent,
        eigenvalues: spec.eigenvalues,
        eigenvectors: spec.eigenvectors,
        correlation,
        freq_hz: w0
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect(),
        freq_cv_percent,
        band_share,
        residual_variance: s2,
    })
}

/// Eigen-decomposition of a Fisher information, eigenvalues descending, with its
/// unidentified directions.
struct FisherSpectrum {
    eigenvalues: Vec<f64>,
    /// Matching unit eigenvectors (columns).
    eigenvectors: DMatrix<f64>,
    /// Columns whose eigenvalue is at most [`NULL_RTOL`] times the largest.
    null: Vec<usize>,
}

impl FisherSpectrum {
    fn new(fisher: &DMatrix<f64>) -> Self {
        let p = fisher.nrows();
        let eig = fisher.clone().symmetric_eigen();
        let mut order: Vec<usize> = (0..p).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let eigenvalues: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
        let eigenvectors = DMatrix::from_fn(p, p, |row, col| eig.eigenvectors[(row, order[col])]);
        let lmax = eigenvalues
            .first()
            .copied()
            .unwrap_or(0.0)
            .max(f64::MIN_POSITIVE);
        let null: Vec<usize> = (0..p)
            .filter(|&c| eigenvalues[c] <= NULL_RTOL * lmax)
            .collect();
        FisherSpectrum {
            eigenvalues,
            eigenvectors,
            null,
        }
    }

    /// Pseudo-inverse on the identifiable subspace: the asymptotic covariance.
    fn pseudo_inverse(&self) -> DMatrix<f64> {
        let p = self.eigenvalues.len();
        DMatrix::from_fn(p, p, |a, b| {
            (0..p)
                .filter(|c| !self.null.contains(c))
                .map(|c| {
                    self.eigenvectors[(a, c)] * self.eigenvectors[(b, c)] / self.eigenvalues[c]
                })
                .sum::<f64>()
        })
    }

    /// Whether parameter `a` has a component along an unidentified direction.
    fn touches_null(&self, a: usize) -> bool {
        self.null
            .iter()
            .any(|&c| self.eigenvectors[(a, c)].abs() > 1e-3)
    }
}

/// CV (%) of each of the `n_modes` natural frequencies by the delta method (central
/// differences in log parameters): `None` when a frequency depends on an unidentified
/// direction.
fn frequency_cv_percent(
    run: &VariantRun,
    free: &[usize],
    scales: &[f64],
    spec: &FisherSpectrum,
    cov: &DMatrix<f64>,
    n_modes: usize,
) -> Result<Vec<Option<f64>>> {
    let theta = &run.result.best.theta;
    let p = free.len();
    // `ln omega_m` against `u_j`, `theta_i = theta_i,0 + u_j scale_j`, at `u = 0`.
    let ln_omegas = |u: &[f64], out: &mut [f64]| {
        let mut t = theta.clone();
        for ((&i, s), du) in free.iter().zip(scales).zip(u) {
            t[i] += du * s;
        }
        for (o, w) in out.iter_mut().zip(omegas(run, &t)?) {
            *o = w.ln();
        }
        Ok(())
    };
    let mut dlnw = DMatrix::zeros(n_modes, p);
    fd_jacobian(
        FdScheme::Central,
        &vec![0.0; p],
        &Bounds::unbounded(p),
        ln_omegas,
        &mut dlnw,
    )?;
    let grads: Vec<Vec<f64>> = (0..n_modes)
        .map(|m| dlnw.row(m).iter().copied().collect())
        .collect();
    Ok(grads
        .iter()
        .map(|g| {
            let along_null = spec
                .null
                .iter()
                .map(|&c| {
                    (0..p)
                        .map(|a| g[a] * spec.eigenvectors[(a, c)])
                        .sum::<f64>()
                        .abs()
                })
                .fold(0.0, f64::max);
            if along_null > 1e-6 {
                return None;
            }
            let v: f64 = (0..p)
                .flat_map(|a| (0..p).map(move |b| (a, b)))
                .map(|(a, b)| g[a] * cov[(a, b)] * g[b])
                .sum();
            Some(100.0 * v.max(0.0).sqrt())
        })
        .collect())
}

/// Band share of the information on each free `xi` (in order): the part of its column
/// of the log-scaled Jacobian `jl` squared that falls in its mode's half-power band of
/// the variant's tests (`None` for a zero column).
fn xi_band_share(
    run: &VariantRun,
    frfs: &[TestFrf],
    free: &[usize],
    jl: &DMatrix<f64>,
) -> Vec<Option<f64>> {
    let problem = &run.problem;
    let vars = problem.variables().variables();
    let n = jl.nrows();
    let mut band_share = Vec::new();
    let point_freq_hz: Vec<(usize, f64)> = {
        // (block index, frequency) of every long-vector point.
        let mut v = Vec::new();
        for (b, block) in problem.blocks().iter().enumerate() {
            for _ in &block.pairs {
                v.extend(
                    block
                        .omega_rad_s
                        .iter()
                        .map(|w| (b, w / (2.0 * std::f64::consts::PI))),
                );
            }
        }
        v
    };
    let group: Vec<&TestFrf> = frfs
        .iter()
        .filter(|f| run.variant.table.includes(f))
        .collect();
    for (j, &i) in free.iter().enumerate() {
        if let VariableKind::Xi(mode) = vars[i].kind {
            let total: f64 = (0..n).map(|k| jl[(k, j)].powi(2)).sum();
            let inside: f64 = (0..n)
                .filter(|&k| {
                    let (b, f) = point_freq_hz[k];
                    group
                        .get(b)
                        .and_then(|t| t.bands.get(mode))
                        .is_some_and(|band| f >= band.lo_hz && f <= band.hi_hz)
                })
                .map(|k| jl[(k, j)].powi(2))
                .sum();
            band_share.push(if total > 0.0 {
                Some(inside / total)
            } else {
                None
            });
        }
    }
    band_share
}

/// Half-power damping read off an analytic, exponentially windowed FRF sampled every
/// `1 / block_s` Hz, window-corrected, relative to the model's damping.
#[derive(Debug, Clone)]
pub struct HalfPowerBias {
    pub block_s: f64,
    /// `None`: no exponential window.
    pub tau_s: Option<f64>,
    /// Per mode: half-power estimate after window correction divided by the true ratio,
    /// minus one (relative bias); `None` when the band could not be resolved.
    pub rel_bias: Vec<Option<f64>>,
}

/// Half-power bias of a Caughey model (modes and ratios), each mode read off the
/// driving-point receptance at the DOF where its shape is largest, for each (block
/// length, window) combination.
pub fn half_power_bias(
    modes: &Modes,
    xi: &[f64],
    blocks_s: &[f64],
    taus_s: &[Option<f64>],
) -> Vec<HalfPowerBias> {
    let c: Vec<f64> = modes
        .omega_rad_s
        .iter()
        .zip(xi)
        .map(|(w, x)| 2.0 * x * w)
        .collect();
    let fmax = modes.freq_hz().last().copied().unwrap_or(1.0) * 1.3;
    let mut out = Vec::new();
    for &t in blocks_s {
        for &tau in taus_s {
            let df = 1.0 / t;
            let freq: Vec<f64> = (1..)
                .map(|k| k as f64 * df)
                .take_while(|f| *f <= fmax)
                .collect();
            let tau_eff = tau.unwrap_or(f64::INFINITY);
            let valid = vec![true; freq.len()];
            let rel_bias = modes
                .freq_hz()
                .iter()
                .zip(xi)
                .zip(&modes.omega_rad_s)
                .enumerate()
                .map(|(mode, ((fn_hz, x), w))| {
                    let dof = modes.phi.column(mode).iamax();
                    let pair = FrfPair {
                        response: dof,
                        excitation: Excitation::Dof(dof),
                        kind: FrfKind::Receptance,
                    };
                    let db: Vec<f64> = freq
                        .iter()
                        .map(|f| {
                            20.0 * windowed_modal_frf(
                                modes,
                                &c,
                                &pair,
                                2.0 * std::f64::consts::PI * f,
                                tau_eff,
                            )
                            .norm()
                            .log10()
                        })
                        .collect();
                    // The bin nearest to the mode, then climb to the local maximum.
                    let mut k = ((fn_hz / df).round() as usize)
                        .saturating_sub(1)
                        .min(freq.len().saturating_sub(1));
                    while k + 1 < db.len() && db[k + 1] > db[k] {
                        k += 1;
                    }
                    while k > 0 && db[k - 1] > db[k] {
                        k -= 1;
                    }
                    let band = half_power_band(&db, &freq, &valid, k);
                    let resolved =
                        band.hi_hz > band.lo_hz && db[k].is_finite() && HALF_POWER_DB > 0.0;
                    if !resolved {
                        return None;
                    }
                    let mut est = band.damping_ratio();
                    if let Some(tau) = tau {
                        est -= 1.0 / (tau * w);
                    }
                    Some(est / x - 1.0)
                })
                .collect();
            out.push(HalfPowerBias {
                block_s: t,
                tau_s: tau,
                rel_bias,
            });
        }
    }
    out
}
