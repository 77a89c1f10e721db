//! # frfbayes
//!
//! FRF-based finite-element model updating (Wang et al., "Experimental model updating
//! using frequency response functions"; the paper's equation numbers are cited
//! throughout), extended with Bayesian uncertainty and a search for missing physics.
//!
//! ## Conventions
//! - SI units throughout; names carry units (`freq_hz`, `omega_rad_s`, `mass_kg`).
//! - Floors are numbered 1..n from the ground up in files and reports; DOF indices in
//!   code are 0-based (floor f is DOF f-1).
//! - FRF arrays are ordered (response, excitation, frequency); long vectors (Eqs. 18-19)
//!   concatenate blocks, then pairs, then frequencies.
//! - Ground-excitation FRFs relate the response *relative* to the ground to the ground
//!   acceleration (Eq. 14).
//! - Randomness comes only from `rand_chacha::ChaCha8Rng` seeded by the caller.
//!
//! ## Modules
//! - [`model`]: K(alpha), M(beta) (Eqs. 20-21), damping models (Eqs. 2, 8-9).
//! - [`modal`]: generalised eigenproblem, mass-normalised modes, MAC.
//! - [`frf`]: modal-sum FRFs (Eqs. 7, 10-12, 15-17) and the direct-solve oracle (Eq. 1).
//! - [`io`]: campaign reader/writer, atomic outputs.
//! - [`signal`]: FRF estimation from recordings (H1, H2, coherence, bands).
//! - [`simulate`]: synthetic campaigns with known truth.
//! - [`update`]: bounded multistart least squares (Eqs. 22-24), FDAC, RSD.
//! - [`mcmc`]: affine-invariant ensemble sampler and diagnostics.
//! - [`bayes`]: posterior of the model given FRF magnitudes, sampling runs, SBC.
//! - [`predict`]: what a model predicts at the observed channels (one trait, fast paths
//!   behind it).
//! - [`infer`]: one posterior (prior, likelihood blocks) for fits, sampling, evidence and
//!   Laplace.
//! - [`plot`]: figures (PNG and SVG) from results.
//! - [`report`]: one self-contained `report.html` per study, from its Markdown and figures.
//! - [`discrepancy`]: locating and explaining missing physics.
//! - [`dist`]: runs spread over MPI ranks (task farm, collective gathers); one rank
//!   in the `frfbayes` binary (the MPI world: `frfbayes-mpi`, package `mpi/`).
//! - [`uff`]: Universal File Format dataset 58 / 58b (measured FRFs in and out).

pub mod bayes;
pub mod discrepancy;
pub mod dist;
pub mod error;
pub mod experiment;
pub mod frf;
pub mod infer;
pub mod io;
pub mod mcmc;
pub mod modal;
pub mod model;
pub mod plot;
pub mod predict;
pub mod real;
pub mod report;
pub mod signal;
pub mod simulate;
pub mod uff;
pub mod update;

pub use error::{Error, Result};
