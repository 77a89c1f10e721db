//! The finite-difference Jacobian of a residual function, for problems without an
//! analytic one. One step rule, that of scipy's `approx_derivative` with its default
//! relative step (so a scipy reference of the same problem differentiates alike):
//!
//! - step `h_j = rel * s_j * max(1, |x_j|)`, `s_j = +1` for `x_j >= 0` and `-1` otherwise,
//!   `rel = eps^(1/2) ~ 1.49e-8` for [`FdScheme::Forward`] and `eps^(1/3) ~ 6.06e-6` for
//!   [`FdScheme::Central`] (each balances truncation against rounding error: about
//!   `1e-8` and `1e-10` relative for smooth residuals of unit scale);
//! - every point evaluated lies inside the bounds. Forward: a step that would leave the
//!   box is flipped (`-h_j`); when neither direction fits, it goes to the farther bound.
//!   Central: where `x_j +- h_j` does not fit, the second-order one-sided difference
//!   `(-3 r(x) + 4 r(x + h) - r(x + 2h)) / 2h` towards the farther bound, `|h| <=` half
//!   the room there, unless a central difference with the smaller room fits a step at
//!   least as large;
//! - the divisor is the step as represented, `(x_j + h_j) - x_j`.
//!
//! Columns are computed one after another (the multistarts above run in parallel).

use super::Bounds;
use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// Finite-difference scheme of [`fd_jacobian`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FdScheme {
    /// `(r(x + h e_j) - r(x)) / h`: first order, `n + 1` residual evaluations.
    Forward,
    /// `(r(x + h e_j) - r(x - h e_j)) / 2h`: second order, `2 n` evaluations (one more
    /// when some variable is too close to a bound and takes the one-sided form).
    Central,
}

impl FdScheme {
    /// The relative step: `eps^(1/2)` forward, `eps^(1/3)` central.
    pub fn relative_step(self) -> f64 {
        match self {
            FdScheme::Forward => f64::EPSILON.sqrt(),
            FdScheme::Central => f64::EPSILON.cbrt(),
        }
    }
}

/// How one column is differenced (steps as added to `x_j`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stencil {
    /// `(r(x + h) - r(x)) / h`.
    OneSided(f64),
    /// `(r(x + h) - r(x - h)) / 2h`.
    Central(f64),
    /// `(-3 r(x) + 4 r(x + h) - r(x + 2h)) / 2h`.
    OneSidedSecondOrder(f64),
}

/// The stencil of one variable at `x` in `[lower, upper]` (module docs).
fn stencil(scheme: FdScheme, x: f64, lower: f64, upper: f64) -> Stencil {
    let sign = if x >= 0.0 { 1.0 } else { -1.0 };
    let h = scheme.relative_step() * sign * x.abs().max(1.0);
    let (below, above) = (x - lower, upper - x);
    match scheme {
        FdScheme::Forward => {
            let fits = |h: f64| x + h >= lower && x + h <= upper;
            if fits(h) {
                Stencil::OneSided(h)
            } else if h.abs() <= below.max(above) {
                Stencil::OneSided(-h)
            } else if above >= below {
                Stencil::OneSided(above)
            } else {
                Stencil::OneSided(-below)
            }
        }
        FdScheme::Central => {
            let h = h.abs();
            if below >= h && above >= h {
                return Stencil::Central(h);
            }
            let one_sided = if above >= below {
                h.min(0.5 * above)
            } else {
                -h.min(0.5 * below)
            };
            let room = below.min(above);
            if one_sided.abs() <= room {
                Stencil::Central(room)
            } else {
                Stencil::OneSidedSecondOrder(one_sided)
            }
        }
    }
}

/// Writes the finite-difference Jacobian `dr_i/dx_j` of `residuals` at `x` into `jac`
/// (`m x n`, `m = jac.nrows()`), evaluating only points inside `bounds` (module docs for
/// the step rule). `residuals(x, r)` writes the `m` residuals at `x` into `r`; its first
/// error is returned. Returns the number of residual evaluations.
///
/// # Errors
/// [`Error::Usage`] when `x`, `bounds` and `jac` disagree in size or `x` lies outside the
/// bounds; any error of `residuals`.
///
/// # Example
/// ```
/// use frfbayes::update::lsq::{fd_jacobian, Bounds, FdScheme};
/// use nalgebra::DMatrix;
///
/// // r(x) = (x0^2, x0 x1) at the upper bound of x0.
/// let bounds = Bounds::new(vec![0.0, 0.0], vec![2.0, 5.0])?;
/// let mut jac = DMatrix::zeros(2, 2);
/// let f = |x: &[f64], r: &mut [f64]| {
///     assert!(x[0] <= 2.0, "evaluated outside the box");
///     r[0] = x[0] * x[0];
///     r[1] = x[0] * x[1];
///     Ok(())
/// };
/// fd_jacobian(FdScheme::Central, &[2.0, 3.0], &bounds, f, &mut jac)?;
/// assert!((jac[(0, 0)] - 4.0).abs() < 1e-8 && (jac[(1, 1)] - 2.0).abs() < 1e-8);
/// # Ok::<(), frfbayes::Error>(())
/// ```
pub fn fd_jacobian<F>(
    scheme: FdScheme,
    x: &[f64],
    bounds: &Bounds,
    residuals: F,
    jac: &mut DMatrix<f64>,
) -> Result<usize>
where
    F: FnMut(&[f64], &mut [f64]) -> Result<()>,
{
    fd_jacobian_at(scheme, x, None, bounds, residuals, jac)
}

/// [`fd_jacobian`] given `f0`, the residuals at `x` when the caller holds them (a
/// solver's current point): the one-sided stencils take them instead of evaluating
/// `x` again, which saves one of the forward scheme's `n + 1` evaluations. The result
/// is the same bits as [`fd_jacobian`]'s when `f0` is what `residuals(x)` gives.
///
/// # Errors
/// Those of [`fd_jacobian`], and [`Error::Usage`] when `f0` is not of length `m`.
pub fn fd_jacobian_at<F>(
    scheme: FdScheme,
    x: &[f64],
    f0: Option<&[f64]>,
    bounds: &Bounds,
    mut residuals: F,
    jac: &mut DMatrix<f64>,
) -> Result<usize>
where
    F: FnMut(&[f64], &mut [f64]) -> Result<()>,
{
    let (n, m) = (x.len(), jac.nrows());
    if f0.is_some_and(|f| f.len() != m) {
        return Err(Error::Usage(format!(
            "finite-difference Jacobian: {} residuals given at x for {m} rows",
            f0.map_or(0, <[f64]>::len)
        )));
    }
    if bounds.len() != n || jac.ncols() != n {
        return Err(Error::Usage(format!(
            "finite-difference Jacobian: {n} variables, {} bounds, {} Jacobian columns",
            bounds.len(),
            jac.ncols()
        )));
    }
    let (lower, upper) = (bounds.lower(), bounds.upper());
    if let Some(j) = (0..n).find(|&j| !(x[j] >= lower[j] && x[j] <= upper[j])) {
        return Err(Error::Usage(format!(
            "finite-difference Jacobian: variable {j} = {} is outside its bounds [{}, {}]",
            x[j], lower[j], upper[j]
        )));
    }
    let mut xs = x.to_vec();
    let (mut r1, mut r2) = (vec![0.0; m], vec![0.0; m]);
    let mut r0: Option<Vec<f64>> = f0.map(<[f64]>::to_vec);
    let mut n_evaluations = 0;
    for j in 0..n {
        let st = stencil(scheme, x[j], lower[j], upper[j]);
        let (h1, h2) = match st {
            Stencil::OneSided(h) => (h, 0.0),
            Stencil::Central(h) => (h, -h),
            Stencil::OneSidedSecondOrder(h) => (h, 2.0 * h),
        };
        xs[j] = x[j] + h1;
        let first = residuals(&xs, &mut r1);
        let second = first.and_then(|_| match st {
            Stencil::OneSided(_) => Ok(()),
            _ => {
                xs[j] = x[j] + h2;
                residuals(&xs, &mut r2)
            }
        });
        xs[j] = x[j];
        second?;
        n_evaluations += if matches!(st, Stencil::OneSided(_)) {
            1
        } else {
            2
        };
        if !matches!(st, Stencil::Central(_)) && r0.is_none() {
            let mut r = vec![0.0; m];
            residuals(x, &mut r)?;
            n_evaluations += 1;
            r0 = Some(r);
        }
        let mut col = jac.column_mut(j);
        match st {
            Stencil::OneSided(_) => {
                let (f0, dx) = (r0.as_deref().unwrap_or(&[]), (x[j] + h1) - x[j]);
                for (c, (a, b)) in col.iter_mut().zip(r1.iter().zip(f0)) {
                    *c = (a - b) / dx;
                }
            }
            Stencil::Central(_) => {
                let dx = (x[j] + h1) - (x[j] + h2);
                for (c, (a, b)) in col.iter_mut().zip(r1.iter().zip(&r2)) {
                    *c = (a - b) / dx;
                }
            }
            Stencil::OneSidedSecondOrder(_) => {
                let (f0, dx) = (r0.as_deref().unwrap_or(&[]), (x[j] + h2) - x[j]);
                for (c, ((a, b), f)) in col.iter_mut().zip(r1.iter().zip(&r2).zip(f0)) {
                    *c = (4.0 * a - b - 3.0 * f) / dx;
                }
            }
        }
    }
    Ok(n_evaluations)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth test function of three variables with its analytic Jacobian.
    fn r(x: &[f64], out: &mut [f64]) {
        out[0] = x[0].sin() * x[1];
        out[1] = (0.5 * x[0]).exp() + x[1].powi(3);
        out[2] = x[0] * x[1] * x[2];
        out[3] = x[2].ln();
    }

    fn analytic(x: &[f64]) -> DMatrix<f64> {
        let mut j = DMatrix::zeros(4, 3);
        j[(0, 0)] = x[0].cos() * x[1];
        j[(0, 1)] = x[0].sin();
        j[(1, 0)] = 0.5 * (0.5 * x[0]).exp();
        j[(1, 1)] = 3.0 * x[1] * x[1];
        j[(2, 0)] = x[1] * x[2];
        j[(2, 1)] = x[0] * x[2];
        j[(2, 2)] = x[0] * x[1];
        j[(3, 2)] = 1.0 / x[2];
        j
    }

    /// Differences at `x` in `bounds`, checking that every evaluation is inside the box;
    /// returns the largest error against the analytic Jacobian and the evaluation count.
    fn max_error(scheme: FdScheme, x: &[f64], bounds: &Bounds) -> (f64, usize) {
        let mut jac = DMatrix::from_element(4, 3, f64::NAN);
        let mut calls = 0;
        let f = |p: &[f64], out: &mut [f64]| {
            calls += 1;
            for (j, v) in p.iter().enumerate() {
                assert!(
                    *v >= bounds.lower()[j] && *v <= bounds.upper()[j],
                    "evaluated outside the box: {p:?}"
                );
            }
            r(p, out);
            Ok(())
        };
        let n_evaluations = fd_jacobian(scheme, x, bounds, f, &mut jac).unwrap();
        assert_eq!(n_evaluations, calls);
        ((jac - analytic(x)).amax(), n_evaluations)
    }

    // Error bounds from the step rule, for these residuals (values and derivatives of
    // order 1-30 at the points below): forward `h |r''| / 2 + 2 eps |r| / h` with
    // `h ~ 1.5e-8 max(1, |x|)`, below 1e-6; central `h^2 |r'''| / 6 + eps |r| / h` with
    // `h ~ 6e-6 max(1, |x|)`, below 1e-8 (one-sided second order: `h^2 |r'''| / 3 + 4 eps
    // |r| / h`, the same order).
    const FORWARD_TOL: f64 = 1e-6;
    const CENTRAL_TOL: f64 = 1e-8;

    #[test]
    fn interior_points_match_the_analytic_jacobian() {
        let bounds = Bounds::unbounded(3);
        for x in [[0.3, -1.2, 0.7], [-2.5, 0.4, 3.0], [0.0, 2.0, 1.0]] {
            let (e, n) = max_error(FdScheme::Forward, &x, &bounds);
            assert!(e < FORWARD_TOL, "forward at {x:?}: error {e:e}");
            assert_eq!(n, 4);
            let (e, n) = max_error(FdScheme::Central, &x, &bounds);
            assert!(e < CENTRAL_TOL, "central at {x:?}: error {e:e}");
            assert_eq!(n, 6);
        }
    }

    #[test]
    fn points_on_and_near_bounds_stay_inside_and_match() {
        let bounds = Bounds::new(vec![-1.0, -2.0, 0.5], vec![1.0, 2.0, 2.0]).unwrap();
        for x in [
            [1.0, -2.0, 2.0],       // on upper, lower, upper bounds
            [-1.0, 2.0, 0.5],       // on lower, upper, lower bounds
            [1.0 - 1e-6, 0.0, 1.9], // closer to the bound than a central step
        ] {
            let (e, _) = max_error(FdScheme::Forward, &x, &bounds);
            assert!(e < FORWARD_TOL, "forward at {x:?}: error {e:e}");
            let (e, n) = max_error(FdScheme::Central, &x, &bounds);
            assert!(e < CENTRAL_TOL, "central at {x:?}: error {e:e}");
            assert_eq!(n, 7, "one shared r(x) for the one-sided columns");
        }
    }

    #[test]
    fn a_box_narrower_than_the_step_shrinks_it() {
        // Width 1e-6 in x0 (less than a central step 6e-6), 1e-8 in x2 (less than a
        // forward step 1.5e-8), x2 on its upper bound: the stencils fit the box.
        let bounds = Bounds::new(vec![0.3, -5.0, 0.7], vec![0.3 + 1e-6, 5.0, 0.7 + 1e-8]).unwrap();
        let x = [0.3 + 4e-7, 1.0, 0.7 + 1e-8];
        let (e, _) = max_error(FdScheme::Central, &x, &bounds);
        assert!(e < 1e-6, "central in a narrow box: error {e:e}");
        let (e, _) = max_error(FdScheme::Forward, &x, &bounds);
        assert!(e < 1e-5, "forward in a narrow box: error {e:e}");
    }

    #[test]
    fn the_step_rule_is_scipys() {
        let st = |s, x| stencil(s, x, f64::NEG_INFINITY, f64::INFINITY);
        let eps = f64::EPSILON;
        assert_eq!(st(FdScheme::Forward, 0.0), Stencil::OneSided(eps.sqrt()));
        assert_eq!(
            st(FdScheme::Forward, -4.0),
            Stencil::OneSided(-4.0 * eps.sqrt())
        );
        assert_eq!(st(FdScheme::Central, -0.5), Stencil::Central(eps.cbrt()));
        assert_eq!(
            st(FdScheme::Central, 1e4),
            Stencil::Central(1e4 * eps.cbrt())
        );
        // Forward at the upper bound flips; central takes the second-order one-sided
        // form with half the room when the room is short.
        assert_eq!(
            stencil(FdScheme::Forward, 1.0, 0.0, 1.0),
            Stencil::OneSided(-eps.sqrt())
        );
        assert_eq!(
            stencil(FdScheme::Central, 1.0 - 1e-6, 0.0, 1.0),
            Stencil::OneSidedSecondOrder(-eps.cbrt())
        );
        let room = 2f64.powi(-20);
        assert_eq!(
            stencil(FdScheme::Central, 0.5, 0.5 - room, 0.5 + 2.0 * room),
            Stencil::Central(room)
        );
    }

    #[test]
    fn errors_name_the_problem() {
        let bounds = Bounds::new(vec![0.0], vec![1.0]).unwrap();
        let mut jac = DMatrix::zeros(1, 1);
        let ok = |_: &[f64], _: &mut [f64]| Ok(());
        let e = fd_jacobian(FdScheme::Forward, &[1.5], &bounds, ok, &mut jac).unwrap_err();
        assert!(e.to_string().contains("variable 0 = 1.5 is outside"), "{e}");
        let mut wide = DMatrix::zeros(1, 2);
        assert!(fd_jacobian(FdScheme::Central, &[0.5], &bounds, ok, &mut wide).is_err());
        let fail = |_: &[f64], _: &mut [f64]| Err(Error::Numerical("no modes".into()));
        let e = fd_jacobian(FdScheme::Central, &[0.5], &bounds, fail, &mut jac).unwrap_err();
        assert!(e.to_string().contains("no modes"), "{e}");
    }

    #[test]
    fn known_residuals_at_x_save_one_evaluation_and_change_no_bit() {
        let bounds = Bounds::new(vec![0.0, 0.0, 0.5], vec![2.0, 5.0, 3.0]).unwrap();
        for x in [[0.3, 1.2, 0.9], [2.0, 5.0, 3.0]] {
            // Opaque to the optimiser: `r(&x)` of a constant `x` may be folded at compile
            // time with a libm other than the one `fd_jacobian` calls at run time.
            let x = std::hint::black_box(x);
            let f = |p: &[f64], out: &mut [f64]| {
                r(p, out);
                Ok(())
            };
            let mut plain = DMatrix::zeros(4, 3);
            let n_plain = fd_jacobian(FdScheme::Forward, &x, &bounds, f, &mut plain).unwrap();
            let mut f0 = vec![0.0; 4];
            r(&x, &mut f0);
            let mut given = DMatrix::zeros(4, 3);
            let n_given =
                fd_jacobian_at(FdScheme::Forward, &x, Some(&f0), &bounds, f, &mut given).unwrap();
            assert_eq!(n_given, n_plain - 1);
            for (a, b) in plain.iter().zip(&given) {
                assert_eq!(a.to_bits(), b.to_bits(), "{x:?}: {plain} {given}");
            }
        }
        let mut jac = DMatrix::zeros(4, 3);
        let short = [0.0; 3];
        let f = |p: &[f64], out: &mut [f64]| {
            r(p, out);
            Ok(())
        };
        let err = fd_jacobian_at(
            FdScheme::Forward,
            &[1.0; 3],
            Some(&short),
            &bounds,
            f,
            &mut jac,
        );
        assert!(matches!(err, Err(Error::Usage(_))));
    }
}
