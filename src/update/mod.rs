//! FRF-based model updating, paper Sections 3.1-3.2 (Eqs. 17-24): bounded multistart
//! least squares on FRF magnitudes with analytical Jacobians, and the FDAC and RSD
//! metrics of Section 4.
//!
//! - [`Variables`] / [`VariablesConfig`]: the layout of `theta` = (alpha, beta, a0, a1)
//!   or (alpha, beta, xi_1..xi_m) and its box (Eqs. 22e-f, 24e-f); damping is optimised
//!   on a log scale.
//! - [`Problem`]: residuals `|H^A(theta)| - |H^E|` over the long vector (Eqs. 18-19,
//!   23), optionally weighted by per-point sigmas or on a log scale, and their
//!   analytical Jacobian (eigenvalue and Fox-Kapoor eigenvector derivatives, chained
//!   through participation, damping and magnitude; see `sensitivity.rs`).
//! - [`lsq`]: the generic solver: trust-region reflective bounded least squares (a
//!   port of scipy's `least_squares(method="trf")`) and Latin hypercube multistart.
//! - [`update`]: multistart updating of a [`Problem`], reported in physical units.
//! - [`fdac`], [`rsd_percent`], [`gauss_newton_covariance`]: metrics.
//! - [`ProblemSpec`]: a problem as JSON ([`Problem::spec`], [`Problem::from_spec`]),
//!   and [`start_points`]: the starts [`update`] uses, for comparisons with other
//!   solvers on identical data and starts.
//!
//! # Identifiability under ground excitation
//! Scaling `M` and `K` together by `s` leaves `lambda_i` unchanged, scales `phi_i` by
//! `s^(-1/2)` and `Gamma_i = phi_i^T M iota` by `s^(1/2)`, so `phi_ri Gamma_i` in
//! Eqs. (15)-(16) and Rayleigh's `c_i = a0 + a1 lambda_i` are unchanged: ground-excitation
//! FRFs are exactly invariant along `(1 + alpha, 1 + beta) -> s (1 + alpha, 1 + beta)`.
//! Shake-table data alone therefore cannot fix the overall mass (and stiffness) scale;
//! the fit slides along this ridge until a bound stops it (as the masses of the paper's
//! Table 2 do). Fix at least one mass ([`VariablesConfig::fixed`]) or add force-excited
//! (hammer) data, whose FRFs scale as `1/s`.
//!
//! # Example
//! ```
//! use frfbayes::frf::{Excitation, FrfBlock, FrfKind, FrfPair, ModalFrf};
//! use frfbayes::modal::Modes;
//! use frfbayes::model::{Damping, StructuralModel};
//! use frfbayes::update::{
//!     update, DampingModel, Measurements, MultistartOptions, ObjectiveOptions, Problem,
//!     VariablesConfig,
//! };
//! let nominal = StructuralModel::shear_frame(&[1.0, 1.0], &[100.0, 100.0])?;
//! let pairs = (0..2)
//!     .map(|r| FrfPair { response: r, excitation: Excitation::Dof(0), kind: FrfKind::Receptance })
//!     .collect();
//! let blocks = vec![FrfBlock { omega_rad_s: (1..60).map(|i| 0.3 * i as f64).collect(), pairs }];
//!
//! // Synthetic measurements at known values: theta = (alpha1, alpha2, beta1, beta2, a0, a1).
//! let truth = [0.05, 0.10, -0.02, 0.03, 0.05, 1e-4];
//! let (k, m) = (nominal.stiffness(&truth[..2]), nominal.mass(&truth[2..4]));
//! let modes = Modes::solve(&k, &m, nominal.ground_influence(), None)?;
//! let mut modal_c = vec![0.0; 2];
//! Damping::Rayleigh { a0_per_s: truth[4], a1_s: truth[5] }
//!     .modal_coefficients(&modes.omega_rad_s, &mut modal_c)?;
//! let mut frf = ModalFrf::new(blocks.clone());
//! let mut magnitude = vec![0.0; frf.len()];
//! frf.magnitudes(&modes, &modal_c, &mut magnitude)?;
//!
//! let data = Measurements { blocks, magnitude, sigma: None };
//! let problem = Problem::new(nominal, data, DampingModel::Rayleigh,
//!     &VariablesConfig::default(), ObjectiveOptions::default())?;
//! let result = update(&problem, &MultistartOptions { n_starts: 8, ..Default::default() })?;
//! for (x, t) in result.best.theta.iter().zip(&truth) {
//!     assert!((x - t).abs() < 1e-6 * t.abs().max(1e-3));
//! }
//! println!("{} of 8 starts reached the best fit", result.n_at_best);
//! # Ok::<(), frfbayes::Error>(())
//! ```

mod fit;
pub mod lsq;
mod metrics;
mod problem;
mod sensitivity;
mod spec;
mod variables;

pub use fit::{
    internal_start_points, start_points, update, Fit, StartFit, UpdateRecord, UpdateResult,
};
pub use lsq::{Active, MultistartOptions, Termination, TrfOptions, XScale};
pub use metrics::{
    fdac, fdac_complex, fdac_per_pair, gain_relative_error, gauss_newton_covariance, pair_ranges,
    rsd_percent,
};
pub use problem::{Measurements, ObjectiveOptions, Problem, ProblemWorkspace, ResidualForm};
pub use sensitivity::REPEATED_EIGENVALUE_RTOL;
pub use spec::{BlockSpec, ModelSpec, PairSpec, ParameterSpec, ProblemSpec, PROBLEM_SPEC_FORMAT};
pub use variables::{DampingModel, Scale, Variable, VariableKind, Variables, VariablesConfig};
