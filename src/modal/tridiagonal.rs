//! Eigenpairs of a small symmetric tridiagonal matrix by the implicit QL method with
//! Wilkinson shifts (`tql2` of EISPACK: Bowdler, Martin, Reinsch and Wilkinson, Numer.
//! Math. 11, 293-306, 1968; the variant of Press et al., Numerical Recipes, `tqli`).
//!
//! A shear frame's mass matrix is diagonal and its stiffness matrix tridiagonal, so
//! `M^-1/2 K M^-1/2` is tridiagonal and this replaces the general symmetric eigen-solve
//! (Householder reduction, then the same kind of QR sweeps) in the likelihood's inner
//! loop. Sizes are compile-time constants: everything stays on the stack.

/// Most QL sweeps per eigenvalue before giving up (EISPACK uses 30).
const MAX_SWEEPS: usize = 30;

/// Largest magnitude of an entry accepted: rotations form `f^2 + g^2` without scaling,
/// so entries stay far from the square root of the largest `f64`.
pub(super) const MAX_ENTRY: f64 = 1e100;

/// Eigenvalues (unordered) and orthonormal eigenvectors (`vectors[i]` belongs to
/// `values[i]`) of the symmetric tridiagonal matrix with diagonal `diag` and
/// off-diagonal `off` (`off[i]` joins rows `i` and `i + 1`; `off[N - 1]` is ignored).
/// `None` when an eigenvalue does not converge in [`MAX_SWEEPS`] sweeps (non-finite
/// input) or when an entry exceeds [`MAX_ENTRY`].
#[allow(clippy::needless_range_loop)] // index loops mirror the published algorithm
pub(super) fn symmetric_tridiagonal_eigen<const N: usize>(
    diag: [f64; N],
    off: [f64; N],
) -> Option<([f64; N], [[f64; N]; N])> {
    let (mut d, mut e) = (diag, off);
    if N == 0 {
        return Some((d, [[0.0; N]; N]));
    }
    e[N - 1] = 0.0;
    if d.iter()
        .chain(&e)
        .any(|x| x.is_nan() || x.abs() > MAX_ENTRY)
    {
        return None;
    }
    let mut z = [[0.0; N]; N];
    for (i, v) in z.iter_mut().enumerate() {
        v[i] = 1.0;
    }
    for l in 0..N {
        let mut sweeps = 0;
        loop {
            // The first negligible off-diagonal at or after `l` splits the matrix.
            let mut m = l;
            while m + 1 < N {
                let dd = d[m].abs() + d[m + 1].abs();
                if e[m].abs() <= f64::EPSILON * dd {
                    break;
                }
                m += 1;
            }
            if m == l {
                break;
            }
            sweeps += 1;
            if sweeps > MAX_SWEEPS {
                return None;
            }
            // Wilkinson shift from the leading 2 x 2 block, then the implicit QL sweep of
            // plane rotations from row m - 1 up to row l.
            let mut g = (d[l + 1] - d[l]) / (2.0 * e[l]);
            let mut r = (g * g + 1.0).sqrt();
            g = d[m] - d[l] + e[l] / (g + r.copysign(g));
            let (mut s, mut c, mut p) = (1.0, 1.0, 0.0);
            let mut underflow = false;
            for i in (l..m).rev() {
                let f = s * e[i];
                let b = c * e[i];
                r = (f * f + g * g).sqrt();
                e[i + 1] = r;
                if r == 0.0 {
                    // Recover from underflow: the sweep ends here.
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    underflow = true;
                    break;
                }
                s = f / r;
                c = g / r;
                g = d[i + 1] - p;
                r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
                let (lo, hi) = z.split_at_mut(i + 1);
                let (zi, zi1) = (&mut lo[i], &mut hi[0]);
                for k in 0..N {
                    let f = zi1[k];
                    zi1[k] = s * zi[k] + c * f;
                    zi[k] = c * zi[k] - s * f;
                }
            }
            if underflow {
                continue;
            }
            d[l] -= p;
            e[l] = g;
            e[m] = 0.0;
        }
    }
    Some((d, z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Against nalgebra's `SymmetricEigen` on random symmetric tridiagonal matrices of 1 to
    /// 6 rows (entries spanning several orders of magnitude, some off-diagonals zero, some
    /// exactly repeated diagonals): the same eigenvalues to rounding (backward stability:
    /// errors of a few eps times the norm), orthonormal vectors, small residuals, and the
    /// same vectors up to sign where eigenvalues are well separated.
    fn check<const N: usize>(rng: &mut ChaCha8Rng) {
        for case in 0..200 {
            let scale = 10f64.powf(rng.random_range(-3.0..6.0));
            let mut diag = [0.0; N];
            let mut off = [0.0; N];
            for i in 0..N {
                diag[i] = scale * rng.random_range(-1.0..1.0);
                off[i] = scale * rng.random_range(-1.0..1.0);
                if case % 7 == 0 && i % 2 == 1 {
                    off[i] = 0.0;
                }
                if case % 11 == 0 {
                    diag[i] = scale;
                }
            }
            let a = DMatrix::from_fn(N, N, |i, j| {
                if i == j {
                    diag[i]
                } else if i + 1 == j {
                    off[i]
                } else if j + 1 == i {
                    off[j]
                } else {
                    0.0
                }
            });
            let norm = a.norm();
            let (values, vectors) = symmetric_tridiagonal_eigen(diag, off).unwrap();
            let reference = a.clone().symmetric_eigen();
            let mut mine: Vec<f64> = values.to_vec();
            let mut theirs: Vec<f64> = reference.eigenvalues.iter().copied().collect();
            mine.sort_by(f64::total_cmp);
            theirs.sort_by(f64::total_cmp);
            for (x, y) in mine.iter().zip(&theirs) {
                assert!(
                    (x - y).abs() <= 1e-13 * norm,
                    "N {N} case {case}: {x} vs {y}"
                );
            }
            for i in 0..N {
                let v = DVector::from_column_slice(&vectors[i]);
                assert!(
                    (&a * &v - &v * values[i]).norm() <= 1e-13 * norm,
                    "N {N} case {case}"
                );
                for (j, wj) in vectors.iter().enumerate() {
                    let w = DVector::from_column_slice(wj);
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((v.dot(&w) - want).abs() <= 1e-13, "N {N} case {case}");
                }
                // Well separated: the eigenvector is determined up to sign.
                let gap = values
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, x)| (x - values[i]).abs())
                    .fold(f64::INFINITY, f64::min);
                if gap > 1e-3 * norm {
                    let k = (0..N)
                        .min_by(|&p, &q| {
                            let dp = (reference.eigenvalues[p] - values[i]).abs();
                            dp.total_cmp(&(reference.eigenvalues[q] - values[i]).abs())
                        })
                        .unwrap();
                    let dot = reference.eigenvectors.column(k).dot(&v).abs();
                    assert!((dot - 1.0).abs() <= 1e-9, "N {N} case {case}: {dot}");
                }
            }
        }
    }

    #[test]
    fn agrees_with_nalgebra_symmetric_eigen() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        check::<1>(&mut rng);
        check::<2>(&mut rng);
        check::<3>(&mut rng);
        check::<4>(&mut rng);
        check::<5>(&mut rng);
        check::<6>(&mut rng);
    }

    #[test]
    fn refuses_non_finite_and_huge_entries() {
        assert!(symmetric_tridiagonal_eigen([1.0, f64::NAN], [0.5, 0.0]).is_none());
        assert!(symmetric_tridiagonal_eigen([1.0, 2.0], [f64::INFINITY, 0.0]).is_none());
        assert!(symmetric_tridiagonal_eigen([1e200, 2.0], [1.0, 0.0]).is_none());
        // The ignored last off-diagonal may hold anything.
        assert!(symmetric_tridiagonal_eigen([1.0, 2.0], [1.0, f64::NAN]).is_some());
    }
}
