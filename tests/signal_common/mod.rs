//! Shared helpers of the `signal_*` integration tests: exact simulation of modal systems
//! and the location of the shared four-story campaign.
#![allow(dead_code)]

use frfbayes::frf::{modal_coefficient, Excitation, FrfPair};
use frfbayes::io::{Channel, Quantity, Test, TestKind};
use frfbayes::modal::Modes;
use frfbayes::model::{Damping, StructuralModel};
use num_complex::Complex64;
use std::path::{Path, PathBuf};

/// The nominal four-story frame of the shared campaign, with Caughey damping ratios `xi`.
pub fn frame(xi: &[f64]) -> (Modes, Vec<f64>) {
    let model =
        StructuralModel::shear_frame(&[4.64; 4], &[1019.0, 1217.0, 1420.0, 2473.0]).unwrap();
    let k = model.stiffness(&model.alpha_zero());
    let m = model.mass(&model.beta_zero());
    let modes = Modes::solve(&k, &m, model.ground_influence(), None).unwrap();
    let mut c = vec![0.0; modes.n_modes()];
    Damping::Caughey { xi: xi.to_vec() }
        .modal_coefficients(&modes.omega_rad_s, &mut c)
        .unwrap();
    (modes, c)
}

/// A single-DOF "model" (unit mass): natural frequency `fn_hz`, damping ratio `xi`.
pub fn sdof(fn_hz: f64, xi: f64) -> (Modes, Vec<f64>) {
    let w = 2.0 * std::f64::consts::PI * fn_hz;
    let modes = Modes {
        omega_rad_s: vec![w],
        phi: nalgebra::DMatrix::from_element(1, 1, 1.0),
        participation: vec![1.0],
    };
    (modes, vec![2.0 * xi * w])
}

/// One mode's exact discretisation for an input that is linear between samples
/// (first-order hold): complex pole `p = -c/2 + j omega_d`, state `z' = p z + u`,
/// `z[n+1] = a z[n] + b0 u[n] + b1 u[n+1]`; `q = Im(z) / omega_d`, `q' = Im(p z) / omega_d`,
/// `q'' = u - c q' - omega^2 q`, all exact at the samples.
pub struct ModeDisc {
    pub p: Complex64,
    pub wd: f64,
    pub wn: f64,
    pub c: f64,
    pub a: Complex64,
    pub b0: Complex64,
    pub b1: Complex64,
}

impl ModeDisc {
    pub fn new(wn: f64, c: f64, dt: f64) -> Self {
        let sigma = 0.5 * c;
        let wd = (wn * wn - sigma * sigma).sqrt();
        let p = Complex64::new(-sigma, wd);
        let a = (p * dt).exp();
        let i0 = (a - 1.0) / p;
        let i1 = (a - 1.0 - p * dt) / (p * p);
        ModeDisc {
            p,
            wd,
            wn,
            c,
            a,
            b0: i0 - i1 / dt,
            b1: i1 / dt,
        }
    }

    /// Exact sampled (q, q'') for the sampled input `u` (piecewise linear).
    pub fn respond(&self, u: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut z = Complex64::new(0.0, 0.0);
        let mut q = Vec::with_capacity(u.len());
        let mut qdd = Vec::with_capacity(u.len());
        for n in 0..u.len() {
            if n > 0 {
                z = self.a * z + self.b0 * u[n - 1] + self.b1 * u[n];
            }
            let qn = z.im / self.wd;
            let qd = (self.p * z).im / self.wd;
            q.push(qn);
            qdd.push(u[n] - self.c * qd - self.wn * self.wn * qn);
        }
        (q, qdd)
    }

    /// Discrete transfer functions (u -> q, u -> q'') at `zeta` (any complex number).
    pub fn transfer(&self, zeta: Complex64) -> (Complex64, Complex64) {
        let zp = (self.b0 + self.b1 * zeta) / (zeta - self.a);
        let zc = (self.b0.conj() + self.b1.conj() * zeta) / (zeta - self.a.conj());
        let j2wd = Complex64::new(0.0, 2.0 * self.wd);
        let q = (zp - zc) / j2wd;
        let qd = (self.p * zp - self.p.conj() * zc) / j2wd;
        (q, 1.0 - self.c * qd - self.wn * self.wn * q)
    }
}

/// Exact sampled responses of every DOF (displacement relative to the ground,
/// acceleration relative to the ground) to input `u` at `excitation` (force at a DOF, or
/// ground acceleration).
pub fn simulate(
    modes: &Modes,
    c: &[f64],
    excitation: Excitation,
    u: &[f64],
    dt: f64,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n_dof = modes.phi.nrows();
    let mut disp = vec![vec![0.0; u.len()]; n_dof];
    let mut acc = vec![vec![0.0; u.len()]; n_dof];
    for (i, &ci) in c.iter().enumerate().take(modes.n_modes()) {
        let g = match excitation {
            Excitation::Dof(e) => modes.phi[(e, i)],
            Excitation::Ground => -modes.participation[i],
        };
        let ui: Vec<f64> = u.iter().map(|v| g * v).collect();
        let (q, qdd) = ModeDisc::new(modes.omega_rad_s[i], ci, dt).respond(&ui);
        for r in 0..n_dof {
            let ph = modes.phi[(r, i)];
            for n in 0..u.len() {
                disp[r][n] += ph * q[n];
                acc[r][n] += ph * qdd[n];
            }
        }
    }
    (disp, acc)
}

/// Exact discrete-time FRF of the simulated system for a pair at `zeta`.
pub fn discrete_frf(
    modes: &Modes,
    c: &[f64],
    pair: &FrfPair,
    zeta: Complex64,
    dt: f64,
) -> Complex64 {
    let mut h = Complex64::new(0.0, 0.0);
    for (i, &ci) in c.iter().enumerate().take(modes.n_modes()) {
        let (q, qdd) = ModeDisc::new(modes.omega_rad_s[i], ci, dt).transfer(zeta);
        let coef = modal_coefficient(modes, pair, i);
        h += coef
            * match pair.kind {
                frfbayes::frf::FrfKind::Receptance => q,
                frfbayes::frf::FrfKind::Accelerance => qdd,
                frfbayes::frf::FrfKind::Mobility => unimplemented!("not simulated"),
            };
    }
    h
}

/// Half-sine pulse of `width` samples and peak `amp`, starting at sample `start`, added to `u`.
pub fn add_pulse(u: &mut [f64], start: usize, width: usize, amp: f64) {
    for i in 0..=width {
        u[start + i] += amp * (std::f64::consts::PI * i as f64 / width as f64).sin();
    }
}

/// The shake-table drive of the shared campaign: linear chirp 0 -> `f1_hz` over `sweep_s`
/// with 1 s cosine tapers, zero afterwards, `total_s` long.
pub fn chirp(fs: f64, sweep_s: f64, f1_hz: f64, total_s: f64, amp: f64) -> Vec<f64> {
    let n = (total_s * fs).round() as usize;
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            if t > sweep_s {
                return 0.0;
            }
            let taper = if t < 1.0 {
                0.5 * (1.0 - (std::f64::consts::PI * t).cos())
            } else if t > sweep_s - 1.0 {
                0.5 * (1.0 - (std::f64::consts::PI * (sweep_s - t)).cos())
            } else {
                1.0
            };
            let phase = std::f64::consts::PI * f1_hz / sweep_s * t * t;
            amp * taper * phase.sin()
        })
        .collect()
}

fn channel(name: &str, quantity: Quantity, floor: usize) -> Channel {
    Channel {
        name: name.into(),
        quantity,
        floor,
        unit: quantity.unit().into(),
    }
}

/// A hammer test laid out like the shared campaign: force, acc1.., disp1...
pub fn hammer_test(
    name: &str,
    floor: usize,
    fs: f64,
    force: Vec<f64>,
    disp: Vec<Vec<f64>>,
    acc: Vec<Vec<f64>>,
) -> Test {
    let n = disp.len();
    let mut channels = vec![channel("force", Quantity::Force, floor)];
    let mut data = vec![force];
    for (r, a) in acc.into_iter().enumerate() {
        channels.push(channel(
            &format!("acc{}", r + 1),
            Quantity::Acceleration,
            r + 1,
        ));
        data.push(a);
    }
    for (r, d) in disp.into_iter().enumerate() {
        channels.push(channel(
            &format!("disp{}", r + 1),
            Quantity::Displacement,
            r + 1,
        ));
        data.push(d);
    }
    assert_eq!(channels.len(), 1 + 2 * n);
    Test {
        name: name.into(),
        kind: TestKind::Hammer {
            excited_floor: floor,
        },
        sample_rate_hz: fs,
        channels,
        data,
    }
}

/// A shake-table test laid out like the shared campaign; `acc_rel` is made absolute here.
pub fn shake_test(
    name: &str,
    fs: f64,
    ground: Vec<f64>,
    disp: Vec<Vec<f64>>,
    acc_rel: Vec<Vec<f64>>,
) -> Test {
    let mut channels = vec![channel("ground_acc", Quantity::GroundAcceleration, 0)];
    let mut data = vec![ground.clone()];
    for (r, a) in acc_rel.into_iter().enumerate() {
        channels.push(channel(
            &format!("acc{}", r + 1),
            Quantity::Acceleration,
            r + 1,
        ));
        data.push(a.iter().zip(&ground).map(|(x, g)| x + g).collect());
    }
    for (r, d) in disp.into_iter().enumerate() {
        channels.push(channel(
            &format!("disp{}", r + 1),
            Quantity::Displacement,
            r + 1,
        ));
        data.push(d);
    }
    Test {
        name: name.into(),
        kind: TestKind::ShakeTable,
        sample_rate_hz: fs,
        channels,
        data,
    }
}

/// `../shared/data/four-story` when present (or under `$FRFBAYES_SHARED_DIR`, for
/// checkouts that are not next to `shared`, e.g. git worktrees).
pub fn shared_campaign_dir() -> Option<PathBuf> {
    let mut roots = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")];
    if let Some(d) = std::env::var_os("FRFBAYES_SHARED_DIR") {
        roots.push(PathBuf::from(d));
    }
    roots
        .into_iter()
        .map(|r| r.join("data/four-story"))
        .find(|p| p.join("campaign.toml").exists())
}

/// Bound on a free decay of mode `j` started by a unit impulse, seen in a windowed block:
/// its two pole terms `R / (s - p)`, `conj(R) / (s - conj(p))` (`R = coef / (2 j omega_d)`,
/// `s = j omega + 1/tau`) enter with unrelated phases, so their magnitudes add; times
/// `|s|^p` for the FRF kind.
pub fn pole_terms(modes: &Modes, c: &[f64], pair: &FrfPair, j: usize, omega: f64, tau: f64) -> f64 {
    let sigma = 0.5 * c[j];
    let wd = (modes.omega_rad_s[j].powi(2) - sigma * sigma).sqrt();
    let s = Complex64::new(1.0 / tau, omega);
    let p = Complex64::new(-sigma, wd);
    let r = modal_coefficient(modes, pair, j).abs() / (2.0 * wd);
    r * (1.0 / (s - p).norm() + 1.0 / (s - p.conj()).norm()) * s.norm().powi(pair.kind.power())
}
