//! Analytical frequency response functions.
//!
//! Conventions: `omega_rad_s` in rad/s; receptance in m/N (or m per m/s^2 of ground
//! acceleration), mobility `Y = j omega H` (Eq. 11), accelerance `A = -omega^2 H`
//! (Eq. 12). Ground-excitation FRFs are of the *relative* response (floor minus ground),
//! paper Eq. (14). Long vectors (Eqs. 18-19) are ordered block by block (one block per
//! test: one frequency grid), then pair by pair, then frequency by frequency.
//!
//! [`ModalFrf`] is the fast modal sum (Eqs. 7, 10, 15, 16) used in every inner loop;
//! [`direct`] is the direct inverse of Eq. (1), the oracle, and the forward model for
//! non-proportional viscous damping.

pub mod direct;

use crate::error::{Error, Result};
use crate::modal::Modes;
use num_complex::Complex64;

/// Which response quantity an FRF relates to the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrfKind {
    /// Displacement per input, `H` (Eq. 1).
    Receptance,
    /// Velocity per input, `Y = j omega H` (Eq. 11).
    Mobility,
    /// Acceleration per input, `A = -omega^2 H` (Eq. 12).
    Accelerance,
}

impl FrfKind {
    /// Power p of `(j omega)^p` that turns receptance into this kind.
    pub fn power(self) -> i32 {
        match self {
            FrfKind::Receptance => 0,
            FrfKind::Mobility => 1,
            FrfKind::Accelerance => 2,
        }
    }

    /// The complex factor `(j omega)^p`.
    #[inline]
    pub fn factor(self, omega_rad_s: f64) -> Complex64 {
        match self {
            FrfKind::Receptance => Complex64::new(1.0, 0.0),
            FrfKind::Mobility => Complex64::new(0.0, omega_rad_s),
            FrfKind::Accelerance => Complex64::new(-omega_rad_s * omega_rad_s, 0.0),
        }
    }
}

/// Where the input acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Excitation {
    /// A force at one DOF (0-based), Eqs. (7), (10).
    Dof(usize),
    /// Ground acceleration, Eqs. (15), (16); the response is relative to the ground.
    Ground,
}

/// One response / input pair of an FRF.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FrfPair {
    /// Response DOF (0-based).
    pub response: usize,
    pub excitation: Excitation,
    pub kind: FrfKind,
}

/// A frequency grid and the pairs evaluated on it (typically: one test).
#[derive(Debug, Clone, PartialEq)]
pub struct FrfBlock {
    pub omega_rad_s: Vec<f64>,
    pub pairs: Vec<FrfPair>,
}

/// Modal-sum coefficient of mode `i` for a pair: `phi_r,i phi_e,i` (Eqs. 7, 10) or
/// `-phi_r,i Gamma_i` (Eqs. 15, 16).
#[inline]
pub fn modal_coefficient(modes: &Modes, pair: &FrfPair, i: usize) -> f64 {
    match pair.excitation {
        Excitation::Dof(e) => modes.phi[(pair.response, i)] * modes.phi[(e, i)],
        Excitation::Ground => -modes.phi[(pair.response, i)] * modes.participation[i],
    }
}

/// One FRF value by modal superposition, for modal damping coefficients
/// `modal_c[i] = 2 xi_i omega_i` (see [`crate::model::Damping::modal_coefficients`]):
/// `H = sum_i coef_i / (omega_i^2 - omega^2 + j c_i omega)` times `(j omega)^p`.
pub fn modal_frf(modes: &Modes, modal_c: &[f64], pair: &FrfPair, omega_rad_s: f64) -> Complex64 {
    let mut h = Complex64::new(0.0, 0.0);
    for (i, (&wn, &c)) in modes.omega_rad_s.iter().zip(modal_c).enumerate() {
        let den = Complex64::new(wn * wn - omega_rad_s * omega_rad_s, c * omega_rad_s);
        h += modal_coefficient(modes, pair, i) / den;
    }
    h * pair.kind.factor(omega_rad_s)
}

/// Fast modal-sum evaluator for a fixed set of blocks (the long vectors of Eqs. 18-19).
/// Holds its scratch buffers, so evaluation does not allocate after the first call.
///
/// Layout for speed: the pole table `1 / (omega_i^2 - omega_k^2 + j c_i omega_k)` is
/// stored mode-major as separate real and imaginary arrays, and each pair's modal sum
/// accumulates over modes into per-frequency arrays, so the inner loops vectorise.
#[derive(Debug, Clone)]
pub struct ModalFrf {
    blocks: Vec<FrfBlock>,
    len: usize,
    pole_re: Vec<f64>,
    pole_im: Vec<f64>,
    acc_re: Vec<f64>,
    acc_im: Vec<f64>,
}

impl ModalFrf {
    /// An evaluator for `blocks`. Pairs must refer to DOFs of the model that will be
    /// evaluated (checked at evaluation).
    pub fn new(blocks: Vec<FrfBlock>) -> Self {
        let len = blocks
            .iter()
            .map(|b| b.omega_rad_s.len() * b.pairs.len())
            .sum();
        ModalFrf {
            blocks,
            len,
            pole_re: Vec::new(),
            pole_im: Vec::new(),
            acc_re: Vec::new(),
            acc_im: Vec::new(),
        }
    }

    /// The blocks this evaluator was built for.
    pub fn blocks(&self) -> &[FrfBlock] {
        &self.blocks
    }

    /// Length of the long vector.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when there is nothing to evaluate.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn check(&self, modes: &Modes, modal_c: &[f64], out_len: usize) -> Result<()> {
        if out_len != self.len {
            return Err(Error::Usage(format!(
                "output has {out_len} entries, expected {}",
                self.len
            )));
        }
        if modal_c.len() != modes.n_modes() {
            return Err(Error::Usage(format!(
                "{} damping coefficients for {} modes",
                modal_c.len(),
                modes.n_modes()
            )));
        }
        let n = modes.phi.nrows();
        for b in &self.blocks {
            for p in &b.pairs {
                let e_ok = match p.excitation {
                    Excitation::Dof(e) => e < n,
                    Excitation::Ground => true,
                };
                if p.response >= n || !e_ok {
                    return Err(Error::Usage(format!(
                        "FRF pair {p:?} outside a {n}-DOF model"
                    )));
                }
            }
        }
        Ok(())
    }

    /// Visits every pair of every block with its receptance-type modal sum (before the
    /// `(j omega)^p` factor) in `acc_re`/`acc_im`, calling `emit(offset, pair, omega, re, im)`.
    #[inline]
    fn for_each(
        &mut self,
        modes: &Modes,
        modal_c: &[f64],
        mut emit: impl FnMut(usize, &FrfPair, &[f64], &[f64], &[f64]),
    ) {
        let m = modes.n_modes();
        let mut offset = 0;
        for block in &self.blocks {
            let omega = &block.omega_rad_s;
            let nw = omega.len();
            self.pole_re.resize(m * nw, 0.0);
            self.pole_im.resize(m * nw, 0.0);
            self.acc_re.resize(nw, 0.0);
            self.acc_im.resize(nw, 0.0);
            for (i, (&wn, &c)) in modes.omega_rad_s.iter().zip(modal_c).enumerate() {
                let pre = &mut self.pole_re[i * nw..(i + 1) * nw];
                let pim = &mut self.pole_im[i * nw..(i + 1) * nw];
                for ((pr, pi), &w) in pre.iter_mut().zip(pim.iter_mut()).zip(omega) {
                    let re = wn * wn - w * w;
                    let im = c * w;
                    let inv = 1.0 / (re * re + im * im);
                    *pr = re * inv;
                    *pi = -im * inv;
                }
            }
            for pair in &block.pairs {
                self.acc_re.fill(0.0);
                self.acc_im.fill(0.0);
                for i in 0..m {
                    let c = modal_coefficient(modes, pair, i);
                    let pre = &self.pole_re[i * nw..(i + 1) * nw];
                    let pim = &self.pole_im[i * nw..(i + 1) * nw];
                    for (a, p) in self.acc_re.iter_mut().zip(pre) {
                        *a += c * p;
                    }
                    for (a, p) in self.acc_im.iter_mut().zip(pim) {
                        *a += c * p;
                    }
                }
                emit(offset, pair, omega, &self.acc_re, &self.acc_im);
                offset += nw;
            }
        }
    }

    /// Complex FRFs into `out` (length [`Self::len`]).
    pub fn complex(&mut self, modes: &Modes, modal_c: &[f64], out: &mut [Complex64]) -> Result<()> {
        self.check(modes, modal_c, out.len())?;
        self.for_each(modes, modal_c, |offset, pair, omega, re, im| {
            let dst = &mut out[offset..offset + omega.len()];
            for (((o, &w), &r), &i) in dst.iter_mut().zip(omega).zip(re).zip(im) {
                *o = Complex64::new(r, i) * pair.kind.factor(w);
            }
        });
        Ok(())
    }

    /// FRF magnitudes (Eq. 17) into `out` (length [`Self::len`]).
    ///
    /// The inner loop of every likelihood evaluation: per block, the pole table once,
    /// then each pair's modal sum and magnitude in one pass over the frequencies, in
    /// chunks of [`LANES`] frequencies held in registers (no intermediate arrays). The
    /// arithmetic (order of the sums included) is that of [`Self::complex`] before the
    /// kind factor, so the results do not depend on the CPU; on x86-64 CPUs with AVX
    /// the same code runs with 4-wide vectors (IEEE division and square root are exact,
    /// and Rust never fuses multiply-adds, so the bits are the same).
    pub fn magnitudes(&mut self, modes: &Modes, modal_c: &[f64], out: &mut [f64]) -> Result<()> {
        self.check(modes, modal_c, out.len())?;
        let m = modes.n_modes();
        let mut offset = 0;
        for block in &self.blocks {
            let nw = block.omega_rad_s.len();
            let len = nw * block.pairs.len();
            self.pole_re.resize(m * nw, 0.0);
            self.pole_im.resize(m * nw, 0.0);
            // Modal coefficients of every pair, pair-major (`acc_re` is free scratch here).
            self.acc_re.clear();
            for pair in &block.pairs {
                self.acc_re
                    .extend((0..m).map(|i| modal_coefficient(modes, pair, i)));
            }
            let args = BlockArgs {
                omega_rad_s: &block.omega_rad_s,
                pairs: &block.pairs,
                omega_n_rad_s: &modes.omega_rad_s,
                modal_c,
                coef: &self.acc_re,
                pole_re: &mut self.pole_re,
                pole_im: &mut self.pole_im,
                out: &mut out[offset..offset + len],
            };
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: the CPU supports AVX, checked just above.
                unsafe { block_magnitudes_avx(args) };
                offset += len;
                continue;
            }
            block_magnitudes(args);
            offset += len;
        }
        Ok(())
    }
}

/// Frequencies per chunk of the fused magnitude kernel.
const LANES: usize = 4;

/// Inputs of [`block_magnitudes`] for one block.
struct BlockArgs<'a> {
    omega_rad_s: &'a [f64],
    pairs: &'a [FrfPair],
    omega_n_rad_s: &'a [f64],
    modal_c: &'a [f64],
    /// `coef[p * m + i]`: modal coefficient of mode `i` for pair `p`.
    coef: &'a [f64],
    pole_re: &'a mut [f64],
    pole_im: &'a mut [f64],
    out: &'a mut [f64],
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn block_magnitudes_avx(args: BlockArgs<'_>) {
    block_magnitudes(args);
}

/// Pole table `1 / (omega_i^2 - omega^2 + j c_i omega)` (mode-major) and the magnitudes
/// `|sum_i coef_i pole_i| omega^p` of every pair of one block.
#[inline(always)]
fn block_magnitudes(args: BlockArgs<'_>) {
    let BlockArgs {
        omega_rad_s: omega,
        pairs,
        omega_n_rad_s,
        modal_c,
        coef,
        pole_re,
        pole_im,
        out,
    } = args;
    let nw = omega.len();
    let m = omega_n_rad_s.len();
    for (i, (&wn, &c)) in omega_n_rad_s.iter().zip(modal_c).enumerate() {
        let pre = &mut pole_re[i * nw..(i + 1) * nw];
        let pim = &mut pole_im[i * nw..(i + 1) * nw];
        for ((pr, pi), &w) in pre.iter_mut().zip(pim.iter_mut()).zip(omega) {
            let re = wn * wn - w * w;
            let im = c * w;
            let inv = 1.0 / (re * re + im * im);
            *pr = re * inv;
            *pi = -im * inv;
        }
    }
    let (pole_re, pole_im) = (&*pole_re, &*pole_im);
    let n_chunks = nw / LANES;
    for ((pair, coef), dst) in pairs
        .iter()
        .zip(coef.chunks_exact(m))
        .zip(out.chunks_exact_mut(nw))
    {
        let power = pair.kind.power();
        let scale = |w: f64| match power {
            0 => 1.0,
            1 => w,
            _ => w * w,
        };
        for chunk in 0..n_chunks {
            let k0 = chunk * LANES;
            let mut re = [0.0; LANES];
            let mut im = [0.0; LANES];
            for (i, &c) in coef.iter().enumerate() {
                let pr = &pole_re[i * nw + k0..i * nw + k0 + LANES];
                let pi = &pole_im[i * nw + k0..i * nw + k0 + LANES];
                for l in 0..LANES {
                    re[l] += c * pr[l];
                    im[l] += c * pi[l];
                }
            }
            let w = &omega[k0..k0 + LANES];
            let o = &mut dst[k0..k0 + LANES];
            for l in 0..LANES {
                o[l] = (re[l] * re[l] + im[l] * im[l]).sqrt() * scale(w[l]);
            }
        }
        for k in n_chunks * LANES..nw {
            let (mut re, mut im) = (0.0, 0.0);
            for (i, &c) in coef.iter().enumerate() {
                re += c * pole_re[i * nw + k];
                im += c * pole_im[i * nw + k];
            }
            dst[k] = (re * re + im * im).sqrt() * scale(omega[k]);
        }
    }
}

#[cfg(test)]
mod tests;
