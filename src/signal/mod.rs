//! FRF estimation from recorded tests: windows, spectra, H1 / H2 / coherence, impact
//! blocks, full-record estimates of chirp tests, and half-power band selection (paper
//! section 3.1).
//!
//! Entry points: [`estimate_test`] and [`estimate_campaign`] give one [`TestFrf`] per test:
//! H1, H2 and coherence for every response channel on one frequency grid, the number of
//! averages, the exponential window's time constant (if any), and the selected frequency
//! points. [`TestFrf::frf_block`] and [`TestFrf::selected_magnitudes`] hand them to model
//! updating (Eqs. 17-19); [`TestFrf::selected_rel_std`] gives the Bendat & Piersol random
//! error of each magnitude.
//!
//! | test | input | responses | estimator |
//! |---|---|---|---|
//! | hammer | force (force window + exponential window) | absolute acceleration -> accelerance, displacement -> receptance | one block per impact, H1/H2 averaged over impacts ([`hammer`]) |
//! | shake table | ground acceleration | acceleration minus ground acceleration -> relative accelerance, relative displacement -> receptance (Eq. 14) | full-record H1 ([`sweep`]) |
//!
//! Coherence: ordinary block coherence is meaningless with 1-2 blocks, so by default it
//! comes from a local rational model of the FRF over neighbouring bins ([`noise`]).
//! Conventions of the transforms: [`spectra`].

pub mod bands;
mod estimate;
pub mod hammer;
pub mod noise;
pub mod spectra;
pub mod sweep;
pub mod windows;

pub use bands::{Band, BandOptions};
pub use estimate::{
    estimate_campaign, estimate_test, EstimateOptions, InputKind, ResponseFrf, TestFrf,
};
pub use hammer::HammerOptions;
pub use noise::{bendat_piersol_rel_std, CoherenceMethod};
pub use windows::{
    correct_exp_window_damping, exp_window_modal_parameters, unwindowed_pole, windowed_modal_frf,
    ExpWindow,
};
