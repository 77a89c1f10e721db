//! The bounded least-squares solver on standard problems with known solutions, and the
//! determinism of multistart.

use frfbayes::update::lsq::{
    multistart, Active, Bounds, LeastSquaresProblem, MultistartOptions, Termination, Trf,
    TrfOptions, XScale,
};
use frfbayes::{Error, Result};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Accuracy required of converged solutions. With scipy's default tolerances (1e-8)
/// and quadratic convergence near a regular minimiser, the error is far below this.
const SOLUTION_TOL: f64 = 1e-7;

/// r(x) = (1 - x0, 10 (x1 - x0^2)).
struct Rosenbrock;

impl LeastSquaresProblem for Rosenbrock {
    type Workspace = ();
    fn n_params(&self) -> usize {
        2
    }
    fn n_residuals(&self) -> usize {
        2
    }
    fn workspace(&self) {}
    fn residuals(&self, x: &[f64], _: &mut (), r: &mut [f64]) -> Result<()> {
        r[0] = 1.0 - x[0];
        r[1] = 10.0 * (x[1] - x[0] * x[0]);
        Ok(())
    }
    fn jacobian(&self, x: &[f64], _: &mut (), j: &mut DMatrix<f64>) -> Result<()> {
        j[(0, 0)] = -1.0;
        j[(0, 1)] = 0.0;
        j[(1, 0)] = -20.0 * x[0];
        j[(1, 1)] = 10.0;
        Ok(())
    }
}

fn solve(bounds: &Bounds, x0: &[f64], opts: TrfOptions) -> frfbayes::update::lsq::Solution {
    Trf::new(opts)
        .minimize(&Rosenbrock, &mut (), x0, bounds)
        .unwrap()
}

#[test]
fn rosenbrock_unbounded_and_inactive_bounds() {
    for x_scale in [XScale::Unit, XScale::Jacobian] {
        let opts = TrfOptions {
            x_scale,
            ..Default::default()
        };
        for bounds in [
            Bounds::unbounded(2),
            Bounds::new(vec![-5.0, -5.0], vec![5.0, 5.0]).unwrap(),
        ] {
            let s = solve(&bounds, &[-1.2, 1.0], opts.clone());
            assert!(s.termination.converged(), "{s:?}");
            assert!((s.x[0] - 1.0).abs() < SOLUTION_TOL, "{s:?}");
            assert!((s.x[1] - 1.0).abs() < SOLUTION_TOL, "{s:?}");
            assert!(s.cost < 1e-20, "{s:?}");
            assert_eq!(s.active, vec![Active::Free; 2]);
        }
    }
}

#[test]
fn rosenbrock_with_active_bound() {
    // scipy's documented example: x1 >= 1.5 gives x = (1.22437075, 1.5). Oracle: on the
    // bound, x0 solves d/dx0 [(1 - x0)^2 + 100 (1.5 - x0^2)^2] = 0 (Newton, from 1.2).
    let mut x0 = 1.2_f64;
    for _ in 0..50 {
        let g = -2.0 * (1.0 - x0) - 400.0 * x0 * (1.5 - x0 * x0);
        let h = 2.0 - 400.0 * (1.5 - x0 * x0) + 800.0 * x0 * x0;
        x0 -= g / h;
    }
    assert!((x0 - 1.22437075).abs() < 1e-8);
    let bounds = Bounds::new(vec![f64::NEG_INFINITY, 1.5], vec![f64::INFINITY; 2]).unwrap();
    for x_scale in [XScale::Unit, XScale::Jacobian] {
        let s = solve(
            &bounds,
            &[2.0, 2.0],
            TrfOptions {
                x_scale,
                ..Default::default()
            },
        );
        assert!(s.termination.converged(), "{s:?}");
        assert!((s.x[0] - x0).abs() < SOLUTION_TOL, "{s:?} vs {x0}");
        assert!((s.x[1] - 1.5).abs() < SOLUTION_TOL, "{s:?}");
        assert_eq!(s.active, vec![Active::Free, Active::Lower]);
    }
}

#[test]
fn termination_on_budget_and_bad_start() {
    let s = solve(
        &Bounds::unbounded(2),
        &[-1.2, 1.0],
        TrfOptions {
            max_evaluations: Some(3),
            ..Default::default()
        },
    );
    assert_eq!(s.termination, Termination::MaxEvaluations);
    assert!(s.n_evaluations <= 3);
    let bounds = Bounds::new(vec![0.0, 0.0], vec![1.0, 1.0]).unwrap();
    let e = Trf::default()
        .minimize(&Rosenbrock, &mut (), &[2.0, 0.5], &bounds)
        .unwrap_err();
    assert!(e.to_string().contains("outside"), "{e}");
    assert!(Bounds::new(vec![1.0], vec![1.0]).is_err());
}

/// r(x) = A x - b.
struct Linear {
    a: DMatrix<f64>,
    b: DVector<f64>,
}

impl LeastSquaresProblem for Linear {
    type Workspace = ();
    fn n_params(&self) -> usize {
        self.a.ncols()
    }
    fn n_residuals(&self) -> usize {
        self.a.nrows()
    }
    fn workspace(&self) {}
    fn residuals(&self, x: &[f64], _: &mut (), r: &mut [f64]) -> Result<()> {
        let v = &self.a * DVector::from_column_slice(x) - &self.b;
        r.copy_from_slice(v.as_slice());
        Ok(())
    }
    fn jacobian(&self, _: &[f64], _: &mut (), j: &mut DMatrix<f64>) -> Result<()> {
        j.copy_from(&self.a);
        Ok(())
    }
}

/// Bounded linear least squares by enumeration of all 3^n active sets: for each,
/// fix the active variables on their bounds, solve the free ones by unconstrained least
/// squares, keep the feasible candidate of least cost. The problem is strictly convex
/// (A has full column rank), so that candidate is the unique minimiser.
fn bvls_by_enumeration(a: &DMatrix<f64>, b: &DVector<f64>, l: &[f64], u: &[f64]) -> Vec<f64> {
    let n = a.ncols();
    let mut best = (f64::INFINITY, vec![]);
    for code in 0..3usize.pow(n as u32) {
        let mut state = vec![0; n];
        let mut c = code;
        for s in state.iter_mut() {
            *s = c % 3;
            c /= 3;
        }
        let mut x = vec![0.0; n];
        let free: Vec<usize> = (0..n).filter(|&i| state[i] == 0).collect();
        for i in 0..n {
            x[i] = match state[i] {
                1 => l[i],
                2 => u[i],
                _ => 0.0,
            };
        }
        let rhs = b - a * DVector::from_column_slice(&x);
        if !free.is_empty() {
            let af = DMatrix::from_fn(a.nrows(), free.len(), |r, c| a[(r, free[c])]);
            let sol = (af.transpose() * &af)
                .cholesky()
                .unwrap()
                .solve(&(af.transpose() * &rhs));
            for (k, &i) in free.iter().enumerate() {
                x[i] = sol[k];
            }
        }
        if (0..n).all(|i| x[i] >= l[i] - 1e-14 && x[i] <= u[i] + 1e-14) {
            let cost = (a * DVector::from_column_slice(&x) - b).norm_squared();
            if cost < best.0 {
                best = (cost, x);
            }
        }
    }
    best.1
}

#[test]
fn bounded_linear_least_squares_matches_enumeration() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for trial in 0..5 {
        let (m, n) = (20, 5);
        let a = DMatrix::from_fn(m, n, |_, _| rng.random_range(-1.0..1.0));
        let b = DVector::from_fn(m, |_, _| rng.random_range(-3.0..3.0));
        let l: Vec<f64> = (0..n).map(|_| rng.random_range(-0.5..0.0)).collect();
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..0.5)).collect();
        let oracle = bvls_by_enumeration(&a, &b, &l, &u);
        let problem = Linear { a, b };
        let bounds = Bounds::new(l.clone(), u.clone()).unwrap();
        let s = Trf::default()
            .minimize(&problem, &mut (), &vec![0.0; n], &bounds)
            .unwrap();
        assert!(s.termination.converged(), "trial {trial}: {s:?}");
        for i in 0..n {
            assert!(
                (s.x[i] - oracle[i]).abs() < SOLUTION_TOL,
                "trial {trial}: x = {:?}, oracle {oracle:?}",
                s.x
            );
        }
        // At least one bound is active in these draws, so the test exercises them.
        assert!(s.active.iter().any(|a| *a != Active::Free), "trial {trial}");
    }
}

/// Rosenbrock whose residuals fail (as an inadmissible model would) for x0 > 1.5.
struct Failing;

impl LeastSquaresProblem for Failing {
    type Workspace = ();
    fn n_params(&self) -> usize {
        2
    }
    fn n_residuals(&self) -> usize {
        2
    }
    fn workspace(&self) {}
    fn residuals(&self, x: &[f64], ws: &mut (), r: &mut [f64]) -> Result<()> {
        if x[0] > 1.5 {
            return Err(Error::Model("outside the admissible region".into()));
        }
        Rosenbrock.residuals(x, ws, r)
    }
    fn jacobian(&self, x: &[f64], ws: &mut (), j: &mut DMatrix<f64>) -> Result<()> {
        Rosenbrock.jacobian(x, ws, j)
    }
}

#[test]
fn failed_evaluations_shrink_the_step() {
    let s = Trf::default()
        .minimize(&Failing, &mut (), &[-1.2, 1.0], &Bounds::unbounded(2))
        .unwrap();
    assert!((s.x[0] - 1.0).abs() < SOLUTION_TOL && (s.x[1] - 1.0).abs() < SOLUTION_TOL);
}

/// A tilted double well: r = (x0^2 - 1, 0.3 (x0 - 1), x1 - 0.3). The global minimum
/// is x = (1, 0.3) with zero cost; a local minimum near x0 = -1 has cost ~0.18.
struct DoubleWell;

impl LeastSquaresProblem for DoubleWell {
    type Workspace = ();
    fn n_params(&self) -> usize {
        2
    }
    fn n_residuals(&self) -> usize {
        3
    }
    fn workspace(&self) {}
    fn residuals(&self, x: &[f64], _: &mut (), r: &mut [f64]) -> Result<()> {
        r[0] = x[0] * x[0] - 1.0;
        r[1] = 0.3 * (x[0] - 1.0);
        r[2] = x[1] - 0.3;
        Ok(())
    }
    fn jacobian(&self, x: &[f64], _: &mut (), j: &mut DMatrix<f64>) -> Result<()> {
        j.fill(0.0);
        j[(0, 0)] = 2.0 * x[0];
        j[(1, 0)] = 0.3;
        j[(2, 1)] = 1.0;
        Ok(())
    }
}

#[test]
fn multistart_is_deterministic_across_thread_counts() {
    let bounds = Bounds::new(vec![-4.0, -1.0], vec![4.0, 1.0]).unwrap();
    let opts = MultistartOptions {
        n_starts: 24,
        seed: 3,
        ..Default::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| multistart(&DoubleWell, &bounds, Some(&[-3.0, 0.0]), &opts).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.starts.len(), 24);
    assert_eq!(one.starts[0].start, vec![-3.0, 0.0]);
    for (a, b) in one.starts.iter().zip(&two.starts) {
        assert_eq!(a.start, b.start);
        assert_eq!(a.solution.as_ref().unwrap(), b.solution.as_ref().unwrap());
    }
    // Starts left of the barrier end in the local minimum, so fewer than all starts
    // reach the global one.
    assert!(
        (one.best.x[0] - 1.0).abs() < SOLUTION_TOL && (one.best.x[1] - 0.3).abs() < SOLUTION_TOL
    );
    assert!(
        one.n_at_best >= 1 && one.n_at_best < 24,
        "{}",
        one.n_at_best
    );
    let counted = one
        .starts
        .iter()
        .filter(|s| s.solution.as_ref().unwrap().cost < 1e-12)
        .count();
    assert_eq!(counted, one.n_at_best);
    // A different seed gives a different design.
    let other = multistart(
        &DoubleWell,
        &bounds,
        None,
        &MultistartOptions { seed: 4, ..opts },
    )
    .unwrap();
    assert_ne!(other.starts[1].start, one.starts[1].start);
}
