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
pub mod labels;

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
/// Layout for speed: [`Self::complex`] stores the pole table
/// `1 / (omega_i^2 - omega_k^2 + j c_i omega_k)` mode-major as separate real and imaginary
/// arrays, and each pair's modal sum accumulates over modes into per-frequency arrays, so
/// the inner loops vectorise; [`Self::magnitudes`] works chunk by chunk of frequencies.
#[derive(Debug, Clone)]
pub struct ModalFrf {
    blocks: Vec<FrfBlock>,
    len: usize,
    pole_re: Vec<f64>,
    pole_im: Vec<f64>,
    acc_re: Vec<f64>,
    acc_im: Vec<f64>,
    /// Scratch of [`Self::magnitudes`]: modal coefficients of one block's pairs.
    coef: Vec<f64>,
    /// Scratch of [`Self::magnitudes`]: one chunk's poles (3 lane arrays per mode).
    chunk: Vec<Lanes>,
    /// DOF count for which every pair has been checked (pairs never change).
    checked_n_dof: Option<usize>,
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
            coef: Vec::new(),
            chunk: Vec::new(),
            checked_n_dof: None,
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

    fn check(&mut self, modes: &Modes, modal_c: &[f64], out_len: usize) -> Result<()> {
        if out_len != self.len {
            return Err(Error::Usage(format!(
                "output has {out_len} entries, expected {}",
                self.len
            )));
        }
        let m = modes.n_modes();
        if modal_c.len() != m || modes.phi.ncols() != m || modes.participation.len() != m {
            return Err(Error::Usage(format!(
                "{} damping coefficients, {} mode shapes and {} participation factors for \
                 {m} modes",
                modal_c.len(),
                modes.phi.ncols(),
                modes.participation.len(),
            )));
        }
        let n = modes.phi.nrows();
        if self.checked_n_dof == Some(n) {
            return Ok(());
        }
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
        self.checked_n_dof = Some(n);
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
    /// The inner loop of every likelihood evaluation. Per block, chunk by chunk of
    /// [`LANES`] frequencies held in registers (no intermediate arrays): the chunk's poles
    /// `1 / (omega_i^2 - omega^2 + j c_i omega)` of every mode, then each pair's modal sum
    /// (modes in order) and magnitude. The poles' real reciprocals `1 / |den_i|^2` are
    /// found by batch inversion, one division per group of [`GROUP`] modes (a division
    /// costs as much as a dozen multiplications), which differs from [`Self::complex`]'s
    /// one division per pole by a few ulps. The results do not depend on the CPU: on
    /// x86-64 CPUs with AVX the same code runs with 4-wide vectors, and IEEE division and
    /// square root are exact and Rust never fuses multiply-adds, so the bits are the same
    /// (a test checks it).
    pub fn magnitudes(&mut self, modes: &Modes, modal_c: &[f64], out: &mut [f64]) -> Result<()> {
        self.check(modes, modal_c, out.len())?;
        let m = modes.n_modes();
        if m == 0 {
            out.fill(0.0);
            return Ok(());
        }
        let n = modes.phi.nrows();
        self.chunk.resize(3 * m, [0.0; LANES]);
        let mut offset = 0;
        for block in &self.blocks {
            let len = block.omega_rad_s.len() * block.pairs.len();
            // Modal coefficients of every pair, pair-major (Eqs. 7, 10, 15, 16).
            let phi = modes.phi.as_slice();
            self.coef.resize(block.pairs.len() * m, 0.0);
            for (pair, coef) in block.pairs.iter().zip(self.coef.chunks_exact_mut(m)) {
                let r = pair.response;
                for (i, c) in coef.iter_mut().enumerate() {
                    *c = match pair.excitation {
                        Excitation::Dof(e) => phi[i * n + r] * phi[i * n + e],
                        Excitation::Ground => -phi[i * n + r] * modes.participation[i],
                    };
                }
            }
            let args = BlockArgs {
                omega_rad_s: &block.omega_rad_s,
                pairs: &block.pairs,
                omega_n_rad_s: &modes.omega_rad_s,
                modal_c,
                coef: &self.coef,
                chunk: &mut self.chunk,
                out: &mut out[offset..offset + len],
            };
            offset += len;
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: the CPU supports AVX, checked just above.
                unsafe { block_magnitudes_avx(args) };
                continue;
            }
            block_magnitudes(args);
        }
        Ok(())
    }
}

/// Frequencies per chunk of the fused magnitude kernel.
const LANES: usize = 4;

/// Modes per batch inversion in the magnitude kernel.
const GROUP: usize = 4;

/// One value per frequency of a chunk.
type Lanes = [f64; LANES];

/// Inputs of [`block_magnitudes`] for one block.
struct BlockArgs<'a> {
    omega_rad_s: &'a [f64],
    pairs: &'a [FrfPair],
    omega_n_rad_s: &'a [f64],
    modal_c: &'a [f64],
    /// `coef[p * m + i]`: modal coefficient of mode `i` for pair `p`.
    coef: &'a [f64],
    /// Scratch, `3 m` lane arrays.
    chunk: &'a mut [Lanes],
    out: &'a mut [f64],
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn block_magnitudes_avx(args: BlockArgs<'_>) {
    block_magnitudes(args);
}

/// Most modes for which the magnitude kernel is compiled for the exact mode count (all
/// values in registers); more take a general path with the same arithmetic.
const MAX_FIXED_MODES: usize = 8;

/// The magnitudes `|sum_i coef_i / (omega_i^2 - omega^2 + j c_i omega)| omega^p` of every
/// pair of one block, chunk by chunk of frequencies (a last partial chunk repeats its
/// last frequency in the unused lanes).
#[inline(always)]
fn block_magnitudes(args: BlockArgs<'_>) {
    match args.omega_n_rad_s.len() {
        1 => block_magnitudes_fixed::<1>(args),
        2 => block_magnitudes_fixed::<2>(args),
        3 => block_magnitudes_fixed::<3>(args),
        4 => block_magnitudes_fixed::<4>(args),
        5 => block_magnitudes_fixed::<5>(args),
        6 => block_magnitudes_fixed::<6>(args),
        7 => block_magnitudes_fixed::<7>(args),
        8 => block_magnitudes_fixed::<8>(args),
        m => {
            debug_assert!(m > MAX_FIXED_MODES);
            block_magnitudes_any(args)
        }
    }
}

/// The frequencies of the chunk at `k0` and their squares; a partial chunk repeats its
/// last frequency.
#[inline(always)]
fn chunk_frequencies(omega: &[f64], k0: usize) -> (usize, Lanes, Lanes) {
    let n_valid = (omega.len() - k0).min(LANES);
    let w: Lanes = match omega[k0..].first_chunk::<LANES>() {
        Some(full) => *full,
        None => std::array::from_fn(|l| omega[k0 + l.min(n_valid - 1)]),
    };
    let w2: Lanes = std::array::from_fn(|l| w[l] * w[l]);
    (n_valid, w, w2)
}

/// `|re + j im| omega^p` of one chunk, into the valid part of `dst`.
#[inline(always)]
fn store_magnitudes(re: &Lanes, im: &Lanes, power: i32, w: &Lanes, w2: &Lanes, dst: &mut [f64]) {
    let scale = match power {
        0 => [1.0; LANES],
        1 => *w,
        _ => *w2,
    };
    let mag: Lanes = std::array::from_fn(|l| (re[l] * re[l] + im[l] * im[l]).sqrt() * scale[l]);
    match <&mut Lanes>::try_from(&mut *dst) {
        Ok(full) => *full = mag,
        Err(_) => dst.copy_from_slice(&mag[..dst.len()]),
    }
}

/// [`block_magnitudes`] for exactly `M` modes.
#[inline(always)]
fn block_magnitudes_fixed<const M: usize>(args: BlockArgs<'_>) {
    let BlockArgs {
        omega_rad_s: omega,
        pairs,
        omega_n_rad_s,
        modal_c,
        coef,
        out,
        ..
    } = args;
    let nw = omega.len();
    let wn: [f64; M] = std::array::from_fn(|i| omega_n_rad_s[i]);
    let c: [f64; M] = std::array::from_fn(|i| modal_c[i]);
    let mut k0 = 0;
    while k0 < nw {
        let (n_valid, w, w2) = chunk_frequencies(omega, k0);
        let mut pole_re = [[0.0; LANES]; M];
        let mut pole_im = [[0.0; LANES]; M];
        let mut den_sq = [[0.0; LANES]; M];
        for i in 0..M {
            for l in 0..LANES {
                pole_re[i][l] = wn[i] * wn[i] - w2[l];
                pole_im[i][l] = c[i] * w[l];
                den_sq[i][l] = pole_re[i][l] * pole_re[i][l] + pole_im[i][l] * pole_im[i][l];
            }
        }
        reciprocals(&mut den_sq);
        for i in 0..M {
            for l in 0..LANES {
                pole_re[i][l] *= den_sq[i][l];
                pole_im[i][l] = -pole_im[i][l] * den_sq[i][l];
            }
        }
        for ((pair, coef), dst) in pairs
            .iter()
            .zip(coef.chunks_exact(M))
            .zip(out.chunks_exact_mut(nw))
        {
            let mut re = [0.0; LANES];
            let mut im = [0.0; LANES];
            for i in 0..M {
                for l in 0..LANES {
                    re[l] += coef[i] * pole_re[i][l];
                    im[l] += coef[i] * pole_im[i][l];
                }
            }
            let dst = &mut dst[k0..k0 + n_valid];
            store_magnitudes(&re, &im, pair.kind.power(), &w, &w2, dst);
        }
        k0 += n_valid;
    }
}

/// [`block_magnitudes`] for any number of modes (scratch in `args.chunk`).
#[inline(always)]
fn block_magnitudes_any(args: BlockArgs<'_>) {
    let BlockArgs {
        omega_rad_s: omega,
        pairs,
        omega_n_rad_s,
        modal_c,
        coef,
        chunk,
        out,
    } = args;
    let nw = omega.len();
    let m = omega_n_rad_s.len();
    let (pole_re, rest) = chunk.split_at_mut(m);
    let (pole_im, den_sq) = rest.split_at_mut(m);
    let mut k0 = 0;
    while k0 < nw {
        let (n_valid, w, w2) = chunk_frequencies(omega, k0);
        for i in 0..m {
            for l in 0..LANES {
                pole_re[i][l] = omega_n_rad_s[i] * omega_n_rad_s[i] - w2[l];
                pole_im[i][l] = modal_c[i] * w[l];
                den_sq[i][l] = pole_re[i][l] * pole_re[i][l] + pole_im[i][l] * pole_im[i][l];
            }
        }
        reciprocals(den_sq);
        for i in 0..m {
            for l in 0..LANES {
                pole_re[i][l] *= den_sq[i][l];
                pole_im[i][l] = -pole_im[i][l] * den_sq[i][l];
            }
        }
        for ((pair, coef), dst) in pairs
            .iter()
            .zip(coef.chunks_exact(m))
            .zip(out.chunks_exact_mut(nw))
        {
            let mut re = [0.0; LANES];
            let mut im = [0.0; LANES];
            for i in 0..m {
                for l in 0..LANES {
                    re[l] += coef[i] * pole_re[i][l];
                    im[l] += coef[i] * pole_im[i][l];
                }
            }
            let dst = &mut dst[k0..k0 + n_valid];
            store_magnitudes(&re, &im, pair.kind.power(), &w, &w2, dst);
        }
        k0 += n_valid;
    }
}

/// Replaces every entry by its reciprocal, in groups of [`GROUP`] by batch inversion:
/// with prefix products `p_j = d_0 ... d_j`, `1 / p_last` is the only division and
/// `1 / d_j = p_(j-1) / p_j`, unwound from the last. A group whose product is not a
/// normal number (an overflow, an underflow, a zero or a NaN) in some lane is divided
/// entry by entry instead.
#[inline(always)]
fn reciprocals(d: &mut [Lanes]) {
    for group in d.chunks_mut(GROUP) {
        let g = group.len();
        let mut prefix = [[0.0; LANES]; GROUP];
        prefix[0] = group[0];
        for i in 1..g {
            for l in 0..LANES {
                prefix[i][l] = prefix[i - 1][l] * group[i][l];
            }
        }
        let total = prefix[g - 1];
        if total.iter().fold(true, |ok, p| ok & p.is_normal()) {
            let mut inv: Lanes = std::array::from_fn(|l| 1.0 / total[l]);
            for i in (1..g).rev() {
                for l in 0..LANES {
                    let r = inv[l] * prefix[i - 1][l];
                    inv[l] *= group[i][l];
                    group[i][l] = r;
                }
            }
            group[0] = inv;
        } else {
            for x in group.iter_mut().flatten() {
                *x = 1.0 / *x;
            }
        }
    }
}

#[cfg(test)]
mod tests;
