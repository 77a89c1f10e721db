//! The fast path of [`super::forward::ExtendedModel`] on larger models: the nominal
//! model's receptance as its modal sum, and a hypothesis' change of the system as a
//! low-rank update of it.
//!
//! # Formulation
//! The nominal model is classically damped (`C = (M Phi) diag(2 xi_i omega_i)
//! (M Phi)^T`, [`super::forward::frame_system`]), so with mass-normalised modes its
//! receptance at the Laplace variable `s` is the modal sum (paper Eq. 16)
//! `H0(s) = Phi diag(g_i) Phi^T`, `g_i = 1 / (s^2 + 2 xi_i omega_i s + omega_i^2)`.
//! A hypothesis changes the system on a few DOFs `S` and may add DOFs. With the added
//! DOFs padded by an identity (`Hp = diag(H0, I)`), the changed dynamic stiffness is
//! `Dp + P_S dD(s) P_S^T`, where `dD = dK + s dC + s^2 dM - I_added`, and by the
//! push-through form of the Woodbury identity
//! `x = Hp b - Hp P_S dD (I + P_S^T Hp P_S dD)^-1 P_S^T Hp b`.
//! Per `s` this costs `n (|F| + |S|) (|S| + rhs)` against the dense solve's `n^3 / 3`.

use crate::simulate::LinearSystem;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Models of fewer DOFs than this are solved densely (at 4 to 10 DOFs the LU is as cheap
/// as the modal sum, and their results stay bit for bit those of the dense solve).
pub const MODAL_MIN_DOF: usize = 16;

/// The nominal model's modes, mass-normalised, with their damping.
#[derive(Debug, Clone)]
pub struct ModalDamping {
    /// Mode shapes as columns, `Phi^T M Phi = I` (all modes).
    pub phi: DMatrix<f64>,
    /// `omega_i^2`, rad^2/s^2.
    pub omega_sq: Vec<f64>,
    /// `2 xi_i omega_i`, rad/s.
    pub two_xi_omega: Vec<f64>,
}

/// One system (the nominal's, changed by a hypothesis) as the nominal modal sum plus a
/// low-rank change (see the module docs).
#[derive(Debug, Clone)]
pub struct LowRankModal<'a> {
    modes: &'a ModalDamping,
    /// DOFs of the nominal model.
    n: usize,
    /// DOFs (of the changed system) where it differs from the padded nominal one.
    support: Vec<usize>,
    /// `dK`, `dC` and `dM` on the support (row-major `|S| x |S|`), the padding's
    /// identity taken off `dK` on added DOFs.
    dk: Vec<f64>,
    dc: Vec<f64>,
    dm: Vec<f64>,
}

/// The DOFs where `sys` differs from `nominal` padded with the identity (every added
/// DOF included); `None` when `sys` does not extend `nominal` DOF for DOF.
fn support(nominal: &LinearSystem, sys: &LinearSystem) -> Option<Vec<usize>> {
    let n = nominal.n_dof();
    let nv = sys.n_dof();
    if nv < n || sys.floor_dof != nominal.floor_dof || sys.base_dof != nominal.base_dof {
        return None;
    }
    let differs = |i: usize| {
        (0..nv).any(|j| {
            let inside = i < n && j < n;
            let pick = |a: &DMatrix<f64>, b: &DMatrix<f64>| match inside {
                true => a[(i, j)] != b[(i, j)],
                // A nominal row's coupling to an added DOF (the padding's is zero).
                false => a[(i, j)] != 0.0,
            };
            pick(&sys.stiffness_n_per_m, &nominal.stiffness_n_per_m)
                || pick(&sys.damping_n_s_per_m, &nominal.damping_n_s_per_m)
                || pick(&sys.mass_kg, &nominal.mass_kg)
        })
    };
    Some((0..nv).filter(|&i| i >= n || differs(i)).collect())
}

impl<'a> LowRankModal<'a> {
    /// `sys` as `nominal` (whose modes are `modes`) plus a change on at most `max_rank`
    /// DOFs; `None` when the change is larger or `sys` does not extend `nominal`.
    pub fn new(
        nominal: &LinearSystem,
        modes: &'a ModalDamping,
        sys: &LinearSystem,
        max_rank: usize,
    ) -> Option<Self> {
        let support = support(nominal, sys)?;
        if support.len() > max_rank {
            return None;
        }
        let n = nominal.n_dof();
        let r = support.len();
        let mut dk = vec![0.0; r * r];
        let mut dc = vec![0.0; r * r];
        let mut dm = vec![0.0; r * r];
        for (a, &i) in support.iter().enumerate() {
            for (b, &j) in support.iter().enumerate() {
                let nominal_of = |m: &DMatrix<f64>| match i < n && j < n {
                    true => m[(i, j)],
                    false => 0.0,
                };
                let pad = if i == j && i >= n { 1.0 } else { 0.0 };
                dk[a * r + b] =
                    sys.stiffness_n_per_m[(i, j)] - nominal_of(&nominal.stiffness_n_per_m) - pad;
                dc[a * r + b] =
                    sys.damping_n_s_per_m[(i, j)] - nominal_of(&nominal.damping_n_s_per_m);
                dm[a * r + b] = sys.mass_kg[(i, j)] - nominal_of(&nominal.mass_kg);
            }
        }
        Some(LowRankModal {
            modes,
            n,
            support,
            dk,
            dc,
            dm,
        })
    }

    /// The modal coordinates `Phi^T b` of a right-hand side `b` of the changed system
    /// (its nominal DOFs).
    pub fn project(&self, b: &[f64]) -> Vec<f64> {
        let phi = &self.modes.phi;
        (0..phi.ncols())
            .map(|i| (0..self.n).map(|d| phi[(d, i)] * b[d]).sum())
            .collect()
    }

    /// The padded nominal receptance `Hp(s)[i, j]` from the modal factors `g`.
    fn h_pad(&self, g: &[Complex64], i: usize, j: usize) -> Complex64 {
        match (i < self.n, j < self.n) {
            (true, true) => {
                let phi = &self.modes.phi;
                g.iter()
                    .enumerate()
                    .map(|(m, gm)| gm * (phi[(i, m)] * phi[(j, m)]))
                    .sum()
            }
            _ if i == j => Complex64::new(1.0, 0.0),
            _ => Complex64::new(0.0, 0.0),
        }
    }

    /// `Hp(s) b` at DOF `d`, from `b`'s modal coordinates `q` (and `b` itself on added DOFs).
    fn h_pad_b(&self, g: &[Complex64], q: &[f64], b: &[f64], d: usize) -> Complex64 {
        match d < self.n {
            true => {
                let phi = &self.modes.phi;
                g.iter()
                    .zip(q)
                    .enumerate()
                    .map(|(m, (gm, qm))| gm * (phi[(d, m)] * qm))
                    .sum()
            }
            false => Complex64::new(b[d], 0.0),
        }
    }

    /// Responses at DOFs `rows` to the right-hand sides `rhs` (each `(b, Phi^T b)`,
    /// [`Self::project`]) at `s`, into `out` (rhs-major, rows within). Errors when the
    /// changed dynamic stiffness is singular at `s`.
    pub fn solve(
        &self,
        s: Complex64,
        rhs: &[(&[f64], &[f64])],
        rows: &[usize],
        out: &mut [Complex64],
    ) -> std::result::Result<(), ()> {
        let s2 = s * s;
        let g: Vec<Complex64> = self
            .modes
            .omega_sq
            .iter()
            .zip(&self.modes.two_xi_omega)
            .map(|(w2, c)| (s2 + s * c + w2).inv())
            .collect();
        let nr = rhs.len();
        let nf = rows.len();
        for (r, (b, q)) in rhs.iter().enumerate() {
            for (f, &d) in rows.iter().enumerate() {
                out[r * nf + f] = self.h_pad_b(&g, q, b, d);
            }
        }
        let k = self.support.len();
        if k == 0 {
            return Ok(());
        }
        let sup = &self.support;
        // dD(s) on the support.
        let dd: Vec<Complex64> = (0..k * k)
            .map(|e| self.dk[e] + s * self.dc[e] + s2 * self.dm[e])
            .collect();
        let hss: Vec<Complex64> = (0..k * k)
            .map(|e| self.h_pad(&g, sup[e / k], sup[e % k]))
            .collect();
        // A = I + Hss dD; y = A^-1 (Hp b)_S; w = dD y.
        let mut a = vec![Complex64::new(0.0, 0.0); k * k];
        for i in 0..k {
            for j in 0..k {
                let v: Complex64 = (0..k).map(|l| hss[i * k + l] * dd[l * k + j]).sum();
                a[i * k + j] = v + if i == j { 1.0 } else { 0.0 };
            }
        }
        let mut y = vec![Complex64::new(0.0, 0.0); k * nr];
        for (r, (b, q)) in rhs.iter().enumerate() {
            for (i, &d) in sup.iter().enumerate() {
                y[i * nr + r] = self.h_pad_b(&g, q, b, d);
            }
        }
        solve_in_place(k, &mut a, &mut y, nr)?;
        for (f, &d) in rows.iter().enumerate() {
            let hfs: Vec<Complex64> = sup.iter().map(|&j| self.h_pad(&g, d, j)).collect();
            for r in 0..nr {
                let mut corr = Complex64::new(0.0, 0.0);
                for l in 0..k {
                    let w: Complex64 = (0..k).map(|m| dd[l * k + m] * y[m * nr + r]).sum();
                    corr += hfs[l] * w;
                }
                out[r * nf + f] -= corr;
            }
        }
        Ok(())
    }
}

/// Solves `A X = B` in place by Gaussian elimination with partial pivoting: `a` is
/// `n x n` row-major (destroyed), `b` is `n x nr` row-major and receives `X`.
///
/// The shear frames' systems (1 to 8 DOFs, one or two right-hand sides) take copies of
/// [`eliminate`] with `n` (and `nr`) constant, which the compiler unrolls and checks once:
/// the same operations in the same order, so the same bits.
pub(crate) fn solve_in_place(
    n: usize,
    a: &mut [Complex64],
    b: &mut [Complex64],
    nr: usize,
) -> std::result::Result<(), ()> {
    macro_rules! fixed {
        ($($n:literal),*) => {
            match (n, nr) {
                $(($n, 1) => eliminate($n, a, b, 1),
                  ($n, 2) => eliminate($n, a, b, 2),
                  ($n, _) => eliminate($n, a, b, nr),)*
                _ => eliminate(n, a, b, nr),
            }
        };
    }
    fixed!(1, 2, 3, 4, 5, 6, 7, 8)
}

/// [`solve_in_place`]'s elimination, inlined into each of its fixed-size copies.
#[inline(always)]
fn eliminate(
    n: usize,
    a: &mut [Complex64],
    b: &mut [Complex64],
    nr: usize,
) -> std::result::Result<(), ()> {
    let a = &mut a[..n * n];
    let b = &mut b[..n * nr];
    for c in 0..n {
        let mut p = c;
        let mut best = a[c * n + c].norm_sqr();
        for r in c + 1..n {
            let v = a[r * n + c].norm_sqr();
            if v > best {
                best = v;
                p = r;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return Err(());
        }
        if p != c {
            for j in 0..n {
                a.swap(c * n + j, p * n + j);
            }
            for j in 0..nr {
                b.swap(c * nr + j, p * nr + j);
            }
        }
        let inv = a[c * n + c].inv();
        for r in c + 1..n {
            let f = a[r * n + c] * inv;
            if f == Complex64::new(0.0, 0.0) {
                continue;
            }
            for j in c + 1..n {
                let v = a[c * n + j];
                a[r * n + j] -= f * v;
            }
            for j in 0..nr {
                let v = b[c * nr + j];
                b[r * nr + j] -= f * v;
            }
        }
    }
    for c in (0..n).rev() {
        let inv = a[c * n + c].inv();
        for j in 0..nr {
            let mut v = b[c * nr + j];
            for k in c + 1..n {
                v -= a[c * n + k] * b[k * nr + j];
            }
            b[c * nr + j] = v * inv;
        }
    }
    Ok(())
}
