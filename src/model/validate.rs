//! Checks of user-supplied matrices and vectors, with errors that name the matrix (its
//! file or variable), the entry at fault and what is expected.

use super::sparse::Triplets;
use super::SYMMETRY_RTOL;
use crate::error::{Error, Result};

/// Checks that `t` is square (`n x n` when `n` is given), finite and symmetric to
/// [`SYMMETRY_RTOL`] of its largest entry. `label` names it in errors; an asymmetric
/// matrix is reported with its worst entry pair.
pub fn check_matrix(label: &str, t: &Triplets, n: Option<usize>) -> Result<()> {
    if t.rows != t.cols {
        return Err(Error::Model(format!(
            "{label} is {} x {}; expected a square matrix",
            t.rows, t.cols
        )));
    }
    if let Some(n) = n.filter(|&n| n != t.rows) {
        return Err(Error::Model(format!(
            "{label} is {} x {}; expected {n} x {n} like the other matrices",
            t.rows, t.cols
        )));
    }
    if let Some(&(i, j, v)) = t.entries.iter().find(|e| !e.2.is_finite()) {
        return Err(Error::Model(format!(
            "{label} has a non-finite entry ({}, {}) = {v}",
            i + 1,
            j + 1
        )));
    }
    let summed = summed_entries(t);
    let scale = summed.iter().fold(0.0_f64, |a, e| a.max(e.2.abs()));
    let mirror = |i: usize, j: usize| {
        summed
            .binary_search_by(|e| (e.0, e.1).cmp(&(i, j)))
            .map_or(0.0, |k| summed[k].2)
    };
    let worst = summed
        .iter()
        .map(|&(i, j, v)| (i, j, v, mirror(j, i)))
        .max_by(|a, b| (a.2 - a.3).abs().total_cmp(&(b.2 - b.3).abs()));
    if let Some((i, j, v, w)) = worst {
        let d = (v - w).abs();
        if d > SYMMETRY_RTOL * scale {
            return Err(Error::Model(format!(
                "{label} is not symmetric: worst pair ({}, {}) = {v:e} but ({}, {}) = {w:e}, \
                 a difference of {:.2e} of its largest entry (tolerance {SYMMETRY_RTOL:e})",
                i + 1,
                j + 1,
                j + 1,
                i + 1,
                d / scale
            )));
        }
    }
    Ok(())
}

/// The entries of `t` sorted by (row, column) with repeated positions added up.
fn summed_entries(t: &Triplets) -> Vec<(usize, usize, f64)> {
    let mut e = t.entries.clone();
    e.sort_by_key(|&(i, j, _)| (i, j));
    let mut out: Vec<(usize, usize, f64)> = Vec::with_capacity(e.len());
    for (i, j, v) in e {
        match out.last_mut() {
            Some(last) if (last.0, last.1) == (i, j) => last.2 += v,
            _ => out.push((i, j, v)),
        }
    }
    out
}

/// Checks that a vector has `n` finite entries.
pub fn check_vector(label: &str, v: &[f64], n: usize) -> Result<()> {
    if v.len() != n {
        return Err(Error::Model(format!(
            "{label} has {} entries; expected one per DOF ({n})",
            v.len()
        )));
    }
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(Error::Model(format!(
            "{label}: entry {} is {}",
            k + 1,
            v[k]
        )));
    }
    Ok(())
}

/// 1-based DOF numbers (as MATLAB and Matrix Market count) to 0-based indices, each
/// checked to be a whole number in `1..=n`.
pub fn dof_list(label: &str, v: &[f64], n: usize) -> Result<Vec<usize>> {
    v.iter()
        .enumerate()
        .map(|(k, &d)| {
            if d.fract() == 0.0 && d >= 1.0 && d <= n as f64 {
                Ok(d as usize - 1)
            } else {
                Err(Error::Model(format!(
                    "{label}: entry {} is DOF {d}, outside 1..={n} (DOF numbers are 1-based \
                     whole numbers)",
                    k + 1
                )))
            }
        })
        .collect()
}
