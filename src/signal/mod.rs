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
//! | hammer | force (force window + exponential window) | absolute acceleration -> accelerance, displacement -> receptance | one exponentially windowed transform from the first impact to the end of the record, tail cut by the record end estimated and put back ([`hammer`], [`tail`]); or one block per impact |
//! | shake table | ground acceleration | acceleration minus ground acceleration -> relative accelerance, relative displacement -> receptance (Eq. 14) | full-record H1 ([`sweep`]) |
//!
//! Coherence: ordinary block coherence is meaningless with 1-2 blocks (1 by construction
//! for the single whole-record transform), so by default it comes from local polynomial /
//! rational models of the FRF over neighbouring bins ([`noise`]): their residual is the
//! noise power per bin (bins spaced and normalised for the exponential window's
//! correlation, [`correlation`]), plus the force noise inside the force windows, which is
//! smooth in frequency and so invisible to a local model but known from the force
//! channel's quiet samples. With `n_averages` (1 for a whole record) it gives the Bendat &
//! Piersol error of `|H1|`.
//! Conventions of the transforms: [`spectra`].
//!
//! Measured FRFs (an analyser's UFF 58/58b, `.mat` or CSV export) become the same
//! [`TestFrf`]s through [`measured`], without estimation; [`measured::export`] writes
//! ours as UFF 58.
//!
//! ## Handing over to model updating
//! - `TestFrf::frf_block()` / `selected_magnitudes()` / `selected_rel_std()`: one
//!   [`crate::frf::FrfBlock`] per test (selected frequencies, one pair per response), the
//!   experimental `|H1|` in the same long-vector order, and its relative random error.
//! - Hammer estimates carry an exponential window (`exp_window_tau_s`): they estimate
//!   `H(omega - j/tau)`, every pole's decay rate raised by `1/tau`. Either evaluate the model
//!   the same way ([`windowed_modal_frf`], or [`exp_window_modal_parameters`] for the fast
//!   receptance sum) or correct identified damping ([`correct_exp_window_damping`]).
//!
//! ## Defaults (`EstimateOptions::default()`)
//! Impact threshold 10 x MAD noise, impacts >= 1 s apart and >= 10 % of the largest, 0.1 s
//! pre-trigger, force window pulse +- 30 ms flat + 20 ms taper, whole-record hammer
//! transform with tail correction, exponential window to 5 % at the record end; local models over 9 bins; no zero padding (bins stay independent for the
//! coherence); bands: as many peaks as the model has modes, half-power band x 1, searched
//! where the input is within 40 dB of its maximum and the mean coherence is at least 0.5,
//! peaks at least 3 dB prominent with coherence at least 0.9. On the shared campaign this
//! finds 0.861, 2.685, 4.268, 5.731 Hz in every hammer test and 0.862, 2.692, 4.262,
//! 5.723 Hz in the shake-table test.

pub mod bands;
mod common_input;
pub mod correlation;
mod estimate;
pub mod frf_csv;
pub mod hammer;
pub mod input_noise;
mod local_coherence;
pub mod measured;
pub mod noise;
mod settings;
pub mod spectra;
pub mod sweep;
pub mod tail;
pub mod windows;

pub use bands::{Band, BandOptions};
pub use estimate::{
    common_input_rel_var, estimate_campaign, estimate_h1, estimate_test, EstimateOptions,
    InputKind, ResponseFrf, TestFrf,
};
pub use hammer::{
    windowed_force, HammerEstimator, HammerOptions, MIN_FORCE_WINDOW_SAMPLES,
    MIN_PRETRIGGER_SAMPLES,
};
pub use input_noise::{InputNoise, LowRank};
pub use noise::{bendat_piersol_rel_std, pooled_rel_std, CoherenceMethod};
pub use settings::{EstimateSection, SensorLowPass};
pub use windows::{
    correct_exp_window_damping, exp_window_modal_parameters, unwindowed_pole, windowed_modal_frf,
    ExpWindow,
};
