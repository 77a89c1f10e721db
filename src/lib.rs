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

pub mod error;
pub mod frf;
pub mod modal;
pub mod model;

pub use error::{Error, Result};
