//! Synthetic campaigns with known truth: `frfbayes simulate --model <toml> --out <dir>`.
//!
//! The simulator writes a campaign in the shared recording format
//! (`../shared/spec/recording-format.md`) from a *simulation model*: the true structure
//! and damping, the tests to run, and the instruments. It is the project's source of test
//! data whose answer is known.
//!
//! # How a test is simulated
//!
//! 1. **System** ([`system`]): general `M`, `K`, `C` matrices with a map from floors to
//!    DOFs and the ground influence vector `iota`; the shear frame and its damping are
//!    built from the model, then any [`SystemEffect`]s transform it (extra DOFs allowed).
//! 2. **Input** ([`excitation`]): hammer impacts are half-sine force pulses on the excited
//!    floor's DOF (base fixed); the shake table drives a linear chirp of ground
//!    acceleration `a_g` with raised-cosine tapers, then zero (the ring-down). Both are
//!    defined in continuous time and sampled at the internal rate
//!    `oversampling * output_rate_hz`.
//! 3. **Dynamics** ([`discrete`]): relative coordinates,
//!    `M x'' + C x' + K x = f - M iota a_g`, discretised *exactly* for an input that is
//!    linear between the internal samples (first-order hold, one matrix exponential of an
//!    augmented matrix): no integrator error. Displacements are `x` (relative to the
//!    ground / table), accelerations are absolute, `x'' + a_g`, with `x''` from the state
//!    equation. Cubic story springs ([`nonlinear`]) are extra inputs with a cubic Hermite
//!    hold, solved implicitly per step (fourth order; exact when `k3 = 0`).
//! 4. **Sensors** ([`sensor`]): each channel's internal-rate signal goes through its chain
//!    of [`SensorStage`]s: the anti-aliasing FIR low-pass and decimation ([`antialias`];
//!    the same zero-phase filter on every channel, input included, so FRFs are
//!    unaffected), then Gaussian white noise of the quantity's standard deviation, drawn
//!    from `ChaCha8Rng` seeded by the seed on a stream of its own per channel (a hash of
//!    `test/channel`), so the result does not depend on the order or thread count.
//!
//! The internal simulation runs half the filter length past the end of each record so
//! that the filtered record is exact to its last sample; before `t = 0` the system is at
//! rest with zero input.
//!
//! # Simulation model file
//!
//! ```toml
//! title = "four-story frame (simulated)"   # written to campaign.toml
//! seed = 1                                 # noise seed (optional; --seed overrides)
//!
//! [structure]                              # the true structure
//! kind = "shear_frame"                     # floors 1..n from the ground up
//! floor_mass_kg = [5.155, 4.953, 4.949, 5.143]
//! story_stiffness_n_per_m = [1090.0, 1258.0, 1378.0, 2666.0]
//!
//! [damping]                                # the true damping, one of:
//! model = "modal"                          #   C = M Phi diag(2 xi_i omega_i) Phi^T M
//! xi = [0.015, 0.010, 0.006, 0.004]        #   one ratio per mode
//! # model = "rayleigh"                     #   C = a0 M + a1 K (paper Eq. 2)
//! # a0_per_s = 0.2
//! # a1_s = 1e-5
//! # model = "caughey"                      #   Caughey series (Eq. 8) with xi.len() terms
//! # xi = [0.015, 0.010]                    #   fitted to the first modes (Eq. 9)
//!
//! [nominal]                                # optional: the belief written to
//! floor_mass_kg = [4.64, 4.64, 4.64, 4.64] # campaign.toml (default: the true structure)
//! story_stiffness_n_per_m = [1019.0, 1217.0, 1420.0, 2473.0]
//!
//! [sampling]
//! output_rate_hz = 500.0
//! oversampling = 10                        # internal rate 5000 Hz; 1 = no anti-aliasing
//! passband_fraction = 0.8                  # optional: pass band to 0.8 * 250 Hz
//! stopband_attenuation_db = 100.0          # optional: from 250 Hz up
//!
//! [noise]                                  # optional: std of white noise per quantity
//! force_n = 0.02
//! ground_acceleration_m_per_s2 = 0.002
//! acceleration_m_per_s2 = 0.005
//! displacement_m = 2e-6
//!
//! [[test]]
//! name = "hammer-floor1"                   # folder name under tests/
//! kind = "hammer"
//! excited_floor = 1
//! duration_s = 120.0                       # record length
//! pulse_duration_s = 0.003                 # half-sine length (>= 2 internal samples)
//! impacts = [{ time_s = 2.0, peak_force_n = 55.0 }, { time_s = 62.0, peak_force_n = 52.0 }]
//!
//! [[test]]
//! name = "shake-table-chirp"
//! kind = "shake_table"
//! ring_down_s = 70.0                       # zero input after the sweep
//! [test.chirp]                             # a_g, linear in frequency
//! f0_hz = 0.0
//! f1_hz = 10.0
//! start_s = 0.0                            # optional; zero input before
//! sweep_duration_s = 60.0
//! taper_s = 1.0                            # raised-cosine taper at each end
//! amplitude_m_per_s2 = 0.08
//! ```
//!
//! Optional effects, applied in the order given:
//!
//! ```toml
//! [[effect]]                               # physics (see the effects module)
//! kind = "dashpot"                         # viscous damper, non-proportional C
//! floors = [1, 3]                          # between floors 1 and 3 (0 = the base);
//! coefficient_n_s_per_m = 20.0             # or `story = s` (floors s-1 and s)
//!
//! [[effect]]
//! kind = "oscillator"                      # secondary mass on a spring: one extra DOF
//! floor = 4
//! mass_kg = 0.3
//! stiffness_n_per_m = 120.0
//! damping_ratio = 0.02                     # c = 2 zeta sqrt(k m)
//!
//! [[effect]]
//! kind = "base_flexibility"                # base mass under story 1: one extra DOF
//! mass_kg = 5.0
//! stiffness_n_per_m = 9000.0               # base to ground / table
//! damping_n_s_per_m = 10.0
//!
//! [[effect]]
//! kind = "stiffness_nonlinearity"          # cubic spring k3 d^3 across story 2
//! story = 2                                # (d: the story drift; k3 < 0 softens)
//! k3_n_per_m3 = 2.5e8
//!
//! [[sensor_effect]]                        # instruments, before anti-aliasing
//! kind = "low_pass"                        # H = w^2 / (s^2 + 2 zeta w s + w^2)
//! channels = ["acc1", "acc2"]              # or quantity = "acceleration" (all acc)
//! natural_frequency_hz = 60.0
//! damping_ratio = 0.6
//!
//! [[sensor_effect]]
//! kind = "time_offset"                     # the channel records y(t - offset_s)
//! channels = ["disp3"]
//! tests = ["shake-table-chirp"]            # optional; all tests when absent
//! offset_s = 0.004                         # needs oversampling >= 4
//! ```
//!
//! Unknown keys are errors (a misspelt key would otherwise silently fall back to a
//! default). Every test records the input (`force` at the excited floor or
//! `ground_acc`), `acc1..n` and `disp1..n`. Besides the campaign, `truth.json` in its
//! folder records the model, the seed and the true modes.
//!
//! # Adding an effect
//!
//! A change of physics is one more [`SystemEffect`] in its own file under [`effects`]
//! and a variant of [`EffectSpec`], applied to the [`LinearSystem`] after the structure
//! is built (extra DOFs allowed). A change of instrument is one more [`SensorStage`] in
//! its own file under [`sensor_effects`] and a variant of [`SensorEffect`]; it runs at
//! the internal rate before [`Decimate`]. A nonlinear element needs an input in
//! [`nonlinear`] (as the cubic spring is): the FOH step is exact only for linear systems.
//!
//! The missing-physics benchmark cases built from these effects are in
//! `experiments/models/discrepancy/` (README there).

pub mod antialias;
mod campaign;
pub mod config;
pub mod discrete;
pub mod effects;
pub mod excitation;
pub mod general;
pub mod modal_basis;
pub mod nonlinear;
pub mod sensor;
pub mod sensor_effects;
pub mod system;
mod validate;

pub use campaign::{resolve_seed, ChannelPlan, Simulator};
pub use config::{
    ChirpSpec, DampingSpec, ImpactSpec, NoiseSpec, NominalSpec, SamplingSpec, SimModel,
    StructureSpec, TestSpec,
};
pub use discrete::{
    hold_gain, polynomial_hold, pre_emphasised, Drive, Foh, OutputMap, Response, StateSpace,
};
pub use effects::{BaseFlexibility, Dashpot, EffectSpec, Oscillator, StiffnessNonlinearity};
pub use modal_basis::ModalBasis;
pub use nonlinear::{CubicSpring, NonlinearFoh};
pub use sensor::{Decimate, GaussianNoise, SensorStage, Signal};
pub use sensor_effects::{LowPass, SensorEffect, TimeOffset};
pub use system::{LinearSystem, SystemEffect};
