//! QR of the Jacobian, the solver's hot spot (`2 m n^2` flops per iteration for `m`
//! residuals and `n` variables; everything after it works on `n x n` data).
//!
//! Tall matrices are reduced block by block (TSQR, Demmel et al. 2012): the running
//! `n x n` factor `R` is stacked on the next block of rows and reduced by Householder
//! reflections that exploit the zeros below the diagonal of `R`. Each block is sized
//! to stay in the L1 cache, so every reflection reads its columns from L1 instead of
//! streaming the whole Jacobian once per column. The flop count is that of a plain
//! Householder QR.
//!
//! On x86-64 CPUs with AVX2 the same code is compiled a second time with 256-bit
//! vectors and chosen at run time; it performs the same operations in the same order
//! (Rust never contracts `a * b + c` into an FMA), so both paths give bit-identical
//! results.

use nalgebra::DMatrix;

/// Doubles per block of the tall QR (`rows x n`): 32 KiB, within a typical L1 data cache.
const BLOCK_DOUBLES: usize = 4096;

/// QR of `a` (m x n) applied to `f` (length m): writes the `n x n` upper-triangular
/// factor `R` (rows beyond `m` zero) into `r` and the first `n` entries of `Q^T f`
/// (zero beyond `m`) into `qtf`, so that `||a x + f||^2 = ||R x + qtf||^2 + const`
/// for every `x`. `a` and `f` are used as scratch.
pub(crate) fn householder_qr(
    a: &mut DMatrix<f64>,
    f: &mut [f64],
    r: &mut DMatrix<f64>,
    qtf: &mut [f64],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        unsafe { householder_qr_avx2(a, f, r, qtf) };
        return;
    }
    householder_qr_body::<Portable>(a, f, r, qtf);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn householder_qr_avx2(
    a: &mut DMatrix<f64>,
    f: &mut [f64],
    r: &mut DMatrix<f64>,
    qtf: &mut [f64],
) {
    householder_qr_body::<Avx2>(a, f, r, qtf);
}

/// The dot product a QR variant uses.
trait Kernel {
    fn dot(a: &[f64], b: &[f64]) -> f64;
}

/// Plain Rust, vectorised by the compiler.
struct Portable;

impl Kernel for Portable {
    #[inline(always)]
    fn dot(a: &[f64], b: &[f64]) -> f64 {
        dot(a, b)
    }
}

/// AVX2 intrinsics; only instantiated inside `householder_qr_avx2`, which runs only
/// after the CPU was found to support AVX2.
#[cfg(target_arch = "x86_64")]
struct Avx2;

#[cfg(target_arch = "x86_64")]
impl Kernel for Avx2 {
    #[inline(always)]
    fn dot(a: &[f64], b: &[f64]) -> f64 {
        // SAFETY: see the type's docs.
        unsafe { dot_avx2(a, b) }
    }
}

#[inline(always)]
fn householder_qr_body<K: Kernel>(
    a: &mut DMatrix<f64>,
    f: &mut [f64],
    r: &mut DMatrix<f64>,
    qtf: &mut [f64],
) {
    let (m, n) = a.shape();
    let block = (BLOCK_DOUBLES / n.max(1)).max(32);
    if m <= block {
        householder_in_place::<K>(a, f, r, qtf);
    } else {
        householder_blocked::<K>(a, f, block, r, qtf);
    }
}

/// `col -= s v`.
#[inline(always)]
fn axpy(col: &mut [f64], s: f64, v: &[f64]) {
    for (q, p) in col.iter_mut().zip(v) {
        *q -= s * p;
    }
}

/// Plain Householder QR of the whole matrix, in place.
#[inline(always)]
fn householder_in_place<K: Kernel>(
    a: &mut DMatrix<f64>,
    f: &mut [f64],
    r: &mut DMatrix<f64>,
    qtf: &mut [f64],
) {
    let (m, n) = a.shape();
    let steps = m.min(n);
    for j in 0..steps {
        let x = &a.as_slice()[j * m + j..(j + 1) * m];
        let norm = K::dot(x, x).sqrt();
        if norm == 0.0 {
            continue;
        }
        // v = x + sign(x0) ||x|| e1, stored in place; H = I - 2 v v^T / (v^T v), and
        // v^T v = 2 ||x|| (||x|| + |x0|).
        let x0 = a[(j, j)];
        let alpha = if x0 >= 0.0 { -norm } else { norm };
        a[(j, j)] = x0 - alpha;
        let tau = 1.0 / (norm * (norm + x0.abs()));
        let (head, tail) = a.as_mut_slice().split_at_mut((j + 1) * m);
        let v = &head[j * m + j..j * m + m];
        for c in 0..n - j - 1 {
            let col = &mut tail[c * m + j..c * m + m];
            let s = tau * K::dot(v, col);
            axpy(col, s, v);
        }
        let fj = &mut f[j..m];
        let s = tau * K::dot(v, fj);
        axpy(fj, s, v);
        a[(j, j)] = alpha;
    }
    r.fill(0.0);
    for c in 0..n {
        for row in 0..steps.min(c + 1) {
            r[(row, c)] = a[(row, c)];
        }
    }
    for (i, q) in qtf.iter_mut().enumerate() {
        *q = if i < m { f[i] } else { 0.0 };
    }
}

/// Block-by-block QR of a tall `a` (m > block), in place: the running `R` (in `r`) is
/// stacked on the next `block` rows of `a`; the reflection of column `j` has `v` zero
/// in rows `j+1..n` of `R` (below its diagonal), so it touches `R`'s row `j` and the
/// block only, and the block's rows of all columns stay in the L1 cache meanwhile.
#[inline(always)]
fn householder_blocked<K: Kernel>(
    a: &mut DMatrix<f64>,
    f: &mut [f64],
    block: usize,
    r: &mut DMatrix<f64>,
    qtf: &mut [f64],
) {
    let (m, n) = a.shape();
    r.fill(0.0);
    qtf.fill(0.0);
    let rs = r.as_mut_slice();
    let aa = a.as_mut_slice();
    let mut start = 0;
    while start < m {
        let rows = start..start + block.min(m - start);
        for j in 0..n {
            let d = rs[j * n + j];
            let (head, tail) = aa.split_at_mut((j + 1) * m);
            let v = &head[j * m..(j + 1) * m][rows.clone()];
            let norm = (d * d + K::dot(v, v)).sqrt();
            if norm == 0.0 {
                continue;
            }
            let alpha = if d >= 0.0 { -norm } else { norm };
            let v0 = d - alpha;
            let tau = 1.0 / (norm * (norm + d.abs()));
            for c in 0..n - j - 1 {
                let col = &mut tail[c * m..(c + 1) * m][rows.clone()];
                // R[j, j + 1 + c]
                let rc = &mut rs[(j + 1 + c) * n + j];
                let s = tau * (v0 * *rc + K::dot(v, col));
                *rc -= s * v0;
                axpy(col, s, v);
            }
            let fb = &mut f[rows.clone()];
            let s = tau * (v0 * qtf[j] + K::dot(v, fb));
            qtf[j] -= s * v0;
            axpy(fb, s, v);
            rs[j * n + j] = alpha;
        }
        start = rows.end;
    }
}

/// `sum_k a_k b_k` with 16 interleaved partial sums, so the loop vectorises into
/// independent chains (a sequential sum cannot be reordered by the compiler, and one
/// chain is bound by the latency of addition).
#[inline(always)]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    const LANES: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; LANES];
    let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for t in 0..LANES {
            acc[t] += x[t] * y[t];
        }
    }
    let mut tail = 0.0;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    // Pairwise reduction of the lanes.
    let mut width = LANES / 2;
    while width > 0 {
        for t in 0..width {
            acc[t] += acc[t + width];
        }
        width /= 2;
    }
    acc[0] + tail
}

/// [`dot`] with AVX2 intrinsics: lanes `4q..4q+4` of the 16 partial sums live in
/// register `q`, and the reduction and the tail are [`dot`]'s, so the result is
/// bit-identical.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn dot_avx2(a: &[f64], b: &[f64]) -> f64 {
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_setzero_pd, _mm256_storeu_pd,
    };
    const LANES: usize = 16;
    let n = a.len().min(b.len());
    let chunks = n / LANES;
    let (pa, pb) = (a.as_ptr(), b.as_ptr());
    let mut acc = [_mm256_setzero_pd(); 4];
    for c in 0..chunks {
        for (q, acc) in acc.iter_mut().enumerate() {
            let off = c * LANES + 4 * q;
            // In bounds: off + 4 <= chunks * LANES <= n.
            let x = _mm256_loadu_pd(pa.add(off));
            let y = _mm256_loadu_pd(pb.add(off));
            *acc = _mm256_add_pd(*acc, _mm256_mul_pd(x, y));
        }
    }
    let mut lanes = [0.0; LANES];
    for (q, acc) in acc.iter().enumerate() {
        _mm256_storeu_pd(lanes.as_mut_ptr().add(4 * q), *acc);
    }
    let mut tail = 0.0;
    for k in chunks * LANES..n {
        tail += a[k] * b[k];
    }
    let mut width = LANES / 2;
    while width > 0 {
        for t in 0..width {
            lanes[t] += lanes[t + width];
        }
        width /= 2;
    }
    lanes[0] + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;

    /// A tall test matrix with a spread of column scales.
    fn tall(m: usize, n: usize) -> (DMatrix<f64>, Vec<f64>) {
        let a = DMatrix::from_fn(m, n, |i, j| {
            ((i * 7 + j * 13) as f64).sin() / (1.0 + j as f64) + if i == j { 2.0 } else { 0.0 }
        });
        let f = (0..m).map(|i| (i as f64 * 0.37).cos()).collect();
        (a, f)
    }

    fn qr(a0: &DMatrix<f64>, f0: &[f64], dispatched: bool) -> (DMatrix<f64>, Vec<f64>) {
        let n = a0.ncols();
        let (mut a, mut f) = (a0.clone(), f0.to_vec());
        let (mut r, mut qtf) = (DMatrix::zeros(n, n), vec![0.0; n]);
        if dispatched {
            householder_qr(&mut a, &mut f, &mut r, &mut qtf);
        } else {
            householder_qr_body::<Portable>(&mut a, &mut f, &mut r, &mut qtf);
        }
        (r, qtf)
    }

    #[test]
    fn vector_paths_agree_bit_for_bit() {
        // Plain (m = 103 fits one block) and blocked (m = 1500, remainder blocks).
        for (m, n) in [(103, 7), (1500, 7)] {
            let (a0, f0) = tall(m, n);
            let ((r1, q1), (r2, q2)) = (qr(&a0, &f0, true), qr(&a0, &f0, false));
            assert!(r1
                .iter()
                .zip(r2.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(q1.iter().zip(&q2).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
        let (_, f0) = tall(1001, 1);
        let naive: f64 = f0.iter().map(|v| v * v).sum();
        assert!((dot(&f0, &f0) - naive).abs() <= 1e-13 * naive);
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            for len in [0, 5, 16, 37, 998] {
                let (x, y) = (&f0[..len], &f0[3..3 + len]);
                // SAFETY: AVX2 is supported (checked above).
                let fast = unsafe { dot_avx2(x, y) };
                assert_eq!(fast.to_bits(), dot(x, y).to_bits(), "length {len}");
            }
        }
    }

    #[test]
    fn blocked_qr_solves_least_squares() {
        // m = 2000 rows and n = 9: blocks of 455 rows, the last one partial.
        let (a0, f0) = tall(2000, 9);
        let (r, qtf) = qr(&a0, &f0, true);
        let ata = a0.transpose() * &a0;
        assert!((r.transpose() * &r - &ata).amax() < 1e-12 * ata.amax());
        for i in 0..9 {
            for j in 0..i {
                assert_eq!(r[(i, j)], 0.0);
            }
        }
        // Least-squares solution from R x = -qtf against the normal equations (well
        // conditioned here, so both are accurate to ~1e-13).
        let x_qr = r
            .lu()
            .solve(&DVector::from_iterator(9, qtf.iter().map(|v| -v)))
            .unwrap();
        let atf = a0.transpose() * DVector::from_vec(f0.clone());
        let x_ne = ata.lu().solve(&(-atf)).unwrap();
        assert!(
            (&x_qr - &x_ne).amax() < 1e-11 * x_ne.amax(),
            "{}",
            (x_qr - x_ne).amax()
        );
        // ||f||^2 = ||qtf||^2 + ||residual||^2 at the minimiser.
        let res = &a0 * &x_qr + DVector::from_vec(f0.clone());
        let lhs: f64 = f0.iter().map(|v| v * v).sum();
        let rhs = qtf.iter().map(|v| v * v).sum::<f64>() + res.norm_squared();
        assert!((lhs - rhs).abs() < 1e-11 * lhs);
    }

    #[test]
    fn qr_preserves_norms_and_solves_least_squares() {
        let a0 = DMatrix::from_row_slice(
            5,
            3,
            &[
                1.0, 2.0, 0.5, -1.0, 0.3, 4.0, 2.0, 2.0, 1.0, 0.0, -3.0, 2.0, 1.5, 1.0, -1.0,
            ],
        );
        let f0 = vec![1.0, -2.0, 0.5, 3.0, 0.25];
        let (mut a, mut f) = (a0.clone(), f0.clone());
        let mut r = DMatrix::zeros(3, 3);
        let mut qtf = vec![0.0; 3];
        householder_qr(&mut a, &mut f, &mut r, &mut qtf);
        // R^T R = A^T A.
        let ata = a0.transpose() * &a0;
        assert!((r.transpose() * &r - &ata).amax() < 1e-12 * ata.amax());
        // Least-squares solution from R x = -qtf equals the normal-equation solution.
        let x_qr = r
            .clone()
            .lu()
            .solve(&DVector::from_iterator(3, qtf.iter().map(|v| -v)))
            .unwrap();
        let atf = a0.transpose() * DVector::from_vec(f0.clone());
        let x_ne = ata.lu().solve(&(-atf)).unwrap();
        assert!((x_qr - x_ne).amax() < 1e-12);
        for i in 0..3 {
            for j in 0..i {
                assert_eq!(r[(i, j)], 0.0);
            }
        }
    }

    #[test]
    fn qr_of_wide_matrix_pads_with_zero_rows() {
        let a0 = DMatrix::from_row_slice(2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let (mut a, mut f) = (a0.clone(), vec![1.0, 1.0]);
        let mut r = DMatrix::zeros(3, 3);
        let mut qtf = vec![0.0; 3];
        householder_qr(&mut a, &mut f, &mut r, &mut qtf);
        assert!((r.transpose() * &r - a0.transpose() * &a0).amax() < 1e-12);
        assert_eq!(qtf[2], 0.0);
        assert!((qtf[0].powi(2) + qtf[1].powi(2) - 2.0).abs() < 1e-12);
    }
}
