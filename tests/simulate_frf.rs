//! Simulated responses against the analytic FRFs of the `frf` module.
//!
//! With a first-order hold the simulation is exact for the straight-line interpolation
//! of the pre-emphasised input samples (`frfbayes::simulate::pre_emphasised`), not for
//! the continuous input itself. For a sampled sinusoid `u_k = sin(omega t_k)` at step h
//! the pre-emphasised samples are `P(omega) u_k`, `P = 1 + sin^2(omega h / 2) / 3`, and
//! their interpolation has the spectrum of the samples times `P` and the triangle
//! kernel's `L(nu) = sinc^2(nu h / 2)` (unnormalised sinc of the half angle), so the
//! samples of the steady-state response are exactly `Im(G e^{j omega t_k})` with
//!
//! `G(omega) = D + P(omega) sum_m (H - D)(omega + m omega_s) L(omega + m omega_s)`,
//! `omega_s = 2 pi / h`,
//!
//! where `H(-nu) = conj(H(nu))` and `D` is the read-out's feedthrough (0 for receptance,
//! the mass line for accelerance), read from the raw samples. The m = 0 term is
//! `(H - D)(omega) (1 - (omega h)^4 / 90 + ...)`; the others are of order `(f h)^2 / m^2`
//! times `H - D` at high frequency. These tests compare with `G` to 1e-9 and report
//! `|G / H - 1|`, the hold's departure from the continuous FRF.

mod simulate_common;

use frfbayes::frf::{direct, modal_coefficient, modal_frf, Excitation, FrfKind, FrfPair};
use frfbayes::modal::Modes;
use frfbayes::simulate::{
    ChirpSpec, DampingSpec, Drive, Foh, ImpactSpec, LinearSystem, NoiseSpec, Response,
    SamplingSpec, SimModel, Simulator, StateSpace, StructureSpec, TestSpec,
};
use num_complex::Complex64;
use simulate_common::spectrum;
use std::f64::consts::PI;

const RATE_HZ: f64 = 5000.0;
/// Agreement with the aliased FOH response `G`: the simulation is exact to ~1e-12; the
/// transient left after 40 s at xi omega >= 0.9 /s is below e^-36 ~ 2e-16; truncating the
/// alias sum (see [`aliased`]) at |m| = 200 leaves terms of order (f h)^2 c / (m^3 omega_s)
/// < 1e-12 relative.
const STEADY_RTOL: f64 = 1e-9;
const ALIAS_TERMS: i64 = 200;

fn structure() -> StructureSpec {
    StructureSpec::ShearFrame {
        floor_mass_kg: vec![5.2, 4.9, 5.1],
        story_stiffness_n_per_m: vec![11_000.0, 13_000.0, 26_000.0],
    }
}

fn damping() -> DampingSpec {
    DampingSpec::Modal {
        xi: vec![0.05, 0.04, 0.03],
    }
}

/// `sum_m H(omega + m omega_s) L(omega + m omega_s)` for a frequency response `h(nu)`
/// valid at any real `nu` (negative too) with high-frequency limit `h_inf` (0 for
/// receptance, `(M^-1)_re` for accelerance). Since `sum_m L(omega + m omega_s) = 1`
/// (`sum_m 1/(x + m pi)^2 = 1/sin^2 x`), the limit is summed exactly and only
/// `h - h_inf`, whose terms fall like 1/m^3, is truncated.
fn aliased(
    h: &dyn Fn(f64) -> Complex64,
    h_inf: f64,
    omega: f64,
    step_s: f64,
    terms: i64,
) -> Complex64 {
    let ws = 2.0 * PI / step_s;
    let pre_emphasis = 1.0 + (0.5 * omega * step_s).sin().powi(2) / 3.0;
    pre_emphasis
        * (-terms..=terms)
            .map(|m| {
                let nu = omega + m as f64 * ws;
                let x = 0.5 * nu * step_s;
                let l = if x == 0.0 { 1.0 } else { (x.sin() / x).powi(2) };
                (h(nu) - h_inf) * l
            })
            .sum::<Complex64>()
        + h_inf
}

/// High-frequency limit of a modal FRF: 0 for receptance; for accelerance
/// `-nu^2 sum_i coef_i / (omega_i^2 - nu^2 + ...) -> sum_i coef_i` (the mass line).
fn limit(modes: &Modes, pair: &FrfPair) -> f64 {
    match pair.kind {
        FrfKind::Accelerance => (0..modes.n_modes())
            .map(|i| modal_coefficient(modes, pair, i))
            .sum::<f64>(),
        _ => 0.0,
    }
}

/// The system's modes and modal dashpot coefficients `2 xi_i omega_i`.
fn modes_and_dashpots(sys: &LinearSystem) -> (Modes, Vec<f64>) {
    let modes = sys.modes().unwrap();
    let c = modes
        .omega_rad_s
        .iter()
        .zip(sys.modal_damping_ratios().unwrap())
        .map(|(w, x)| 2.0 * x * w)
        .collect();
    (modes, c)
}

/// Least-squares fit of `y = Im(G e^{j omega t})` over samples `k0..` but the last (whose
/// step saw the raw, not the pre-emphasised, end sample); returns G.
fn fit_phasor(y: &[f64], omega: f64, k0: usize, rate_hz: f64) -> Complex64 {
    // y = Re(G) sin + Im(G) cos: normal equations in (s, c).
    let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (k, v) in y.iter().enumerate().take(y.len() - 1).skip(k0) {
        let t = k as f64 / rate_hz;
        let (s, c) = (omega * t).sin_cos();
        ss += s * s;
        sc += s * c;
        cc += c * c;
        ys += v * s;
        yc += v * c;
    }
    let det = ss * cc - sc * sc;
    Complex64::new((ys * cc - yc * sc) / det, (yc * ss - ys * sc) / det)
}

/// Steady-state response to `u = sin(omega t)`; returns the fitted phasor per response.
fn steady_state(
    sys: &LinearSystem,
    drive: Drive,
    responses: &[Response],
    f_hz: f64,
) -> Vec<Complex64> {
    steady_state_at(sys, drive, responses, f_hz, RATE_HZ)
}

/// [`steady_state`] sampled at `rate_hz`.
fn steady_state_at(
    sys: &LinearSystem,
    drive: Drive,
    responses: &[Response],
    f_hz: f64,
    rate_hz: f64,
) -> Vec<Complex64> {
    let ss = StateSpace::new(sys, &[drive]).unwrap();
    let out = ss.output_map(responses).unwrap();
    let foh = Foh::new(&ss, 1.0 / rate_hz).unwrap();
    let omega = 2.0 * PI * f_hz;
    let n = (45.0 * rate_hz) as usize;
    let u: Vec<f64> = (0..n).map(|k| (omega * k as f64 / rate_hz).sin()).collect();
    let y = foh.simulate(&out, &[u], None, &|_| {}).unwrap();
    y.iter()
        .map(|yr| fit_phasor(yr, omega, (40.0 * rate_hz) as usize, rate_hz))
        .collect()
}

fn assert_close(got: Complex64, expect: Complex64, continuous: Complex64, what: &str) {
    let err = (got - expect).norm() / expect.norm();
    let foh = (expect / continuous - 1.0).norm();
    println!("{what}: |sim/G - 1| = {err:.2e}, |G/H - 1| = {foh:.2e}");
    assert!(
        err <= STEADY_RTOL,
        "{what}: {got} vs {expect} (rel {err:e})"
    );
}

#[test]
fn steady_state_force_response_matches_modal_frf() {
    let sys = LinearSystem::from_spec(&structure(), &damping()).unwrap();
    let (modes, c) = modes_and_dashpots(&sys);
    let e = 1;
    let responses: Vec<Response> = (0..3)
        .flat_map(|dof| {
            [
                Response::Displacement { dof },
                Response::Acceleration { dof },
            ]
        })
        .collect();
    let mut freqs = modes.freq_hz();
    freqs.extend([1.3, 7.7, 21.0]);
    for f in freqs {
        let got = steady_state(&sys, Drive::Force { dof: e }, &responses, f);
        for r in 0..3 {
            for (j, kind) in [FrfKind::Receptance, FrfKind::Accelerance]
                .into_iter()
                .enumerate()
            {
                let pair = FrfPair {
                    response: r,
                    excitation: Excitation::Dof(e),
                    kind,
                };
                let h = |nu: f64| modal_frf(&modes, &c, &pair, nu);
                let omega = 2.0 * PI * f;
                let expect = aliased(&h, limit(&modes, &pair), omega, 1.0 / RATE_HZ, ALIAS_TERMS);
                assert_close(
                    got[2 * r + j],
                    expect,
                    h(omega),
                    &format!("{f:.3} Hz {r}<-{e} {kind:?}"),
                );
            }
        }
    }
}

#[test]
fn steady_state_ground_response_matches_modal_frf() {
    // Relative displacement against Eq. (15); absolute acceleration = relative
    // accelerance + 1 (the ground's own acceleration, sampled exactly).
    let sys = LinearSystem::from_spec(&structure(), &damping()).unwrap();
    let (modes, c) = modes_and_dashpots(&sys);
    let responses: Vec<Response> = (0..3)
        .flat_map(|dof| {
            [
                Response::Displacement { dof },
                Response::Acceleration { dof },
            ]
        })
        .collect();
    for f in [modes.freq_hz()[0], 5.5, modes.freq_hz()[2], 30.0] {
        let got = steady_state(&sys, Drive::Ground, &responses, f);
        let omega = 2.0 * PI * f;
        for r in 0..3 {
            let pair = |kind| FrfPair {
                response: r,
                excitation: Excitation::Ground,
                kind,
            };
            let h = |nu: f64| modal_frf(&modes, &c, &pair(FrfKind::Receptance), nu);
            let expect = aliased(&h, 0.0, omega, 1.0 / RATE_HZ, 3);
            assert_close(
                got[2 * r],
                expect,
                h(omega),
                &format!("{f:.3} Hz disp{r}/a_g"),
            );
            let a = |nu: f64| modal_frf(&modes, &c, &pair(FrfKind::Accelerance), nu);
            let expect = aliased(
                &a,
                limit(&modes, &pair(FrfKind::Accelerance)),
                omega,
                1.0 / RATE_HZ,
                ALIAS_TERMS,
            ) + 1.0;
            assert_close(
                got[2 * r + 1],
                expect,
                a(omega) + 1.0,
                &format!("{f:.3} Hz acc{r}/a_g"),
            );
        }
    }
}

#[test]
fn steady_state_with_non_proportional_damping_matches_direct_solve() {
    // A dashpot of 40 N s/m between floors 1 and 3 makes C non-proportional; the oracle is
    // the direct inverse of Eq. (1) (and Eq. 14 for the ground).
    let mut sys = LinearSystem::from_spec(&structure(), &damping()).unwrap();
    let cd = 40.0;
    for (i, j, s) in [(0, 0, 1.0), (2, 2, 1.0), (0, 2, -1.0), (2, 0, -1.0)] {
        sys.damping_n_s_per_m[(i, j)] += s * cd;
    }
    let (m, k, c) = (&sys.mass_kg, &sys.stiffness_n_per_m, &sys.damping_n_s_per_m);
    let iota = &sys.ground_influence;
    let responses: Vec<Response> = (0..3).map(|dof| Response::Displacement { dof }).collect();
    for f in [2.5, 6.0, 11.0] {
        let omega = 2.0 * PI * f;
        let force = steady_state(&sys, Drive::Force { dof: 2 }, &responses, f);
        let ground = steady_state(&sys, Drive::Ground, &responses, f);
        for r in 0..3 {
            let h = |nu: f64| -> Complex64 {
                let x = direct::receptance_matrix(m, k, c, nu.abs()).unwrap()[(r, 2)];
                if nu < 0.0 {
                    x.conj()
                } else {
                    x
                }
            };
            assert_close(
                force[r],
                aliased(&h, 0.0, omega, 1.0 / RATE_HZ, 3),
                h(omega),
                &format!("{f} Hz {r}<-2 non-prop"),
            );
            let g = |nu: f64| -> Complex64 {
                let x = direct::ground_receptance(m, k, c, iota, nu.abs()).unwrap()[r];
                if nu < 0.0 {
                    x.conj()
                } else {
                    x
                }
            };
            assert_close(
                ground[r],
                aliased(&g, 0.0, omega, 1.0 / RATE_HZ, 3),
                g(omega),
                &format!("{f} Hz {r}/a_g non-prop"),
            );
        }
    }
}

/// At a light driving point the accelerance is mostly its feedthrough `1 / m`, which
/// the read-out takes from the raw samples; the hold's error falls on the small rest.
/// With a 0.05 kg top floor on a 15 kg frame, `D` is 120-450 times `|H|` at 2-12 Hz: a
/// plain straight-line hold errs there by `(D / |H|) (omega h)^2 / 12`, the
/// pre-emphasised one by `(D / |H|) (omega h)^4 / 90` plus what the images near the
/// sample rate leak through the hold (`|H - D|` there times `(f h)^2`, times `D / |H|`).
/// At 2400 Hz, the bridge campaigns' internal rate, both are far below the plain hold's
/// error; at 400 Hz the light mass' own mode (115 Hz) leaks 2e-3 (measured), a reason
/// the simulator steps at an oversampled internal rate.
#[test]
fn light_driving_point_accelerance_is_the_continuous_frf() {
    let sys = LinearSystem::from_spec(
        &StructureSpec::ShearFrame {
            floor_mass_kg: vec![5.2, 9.9, 0.05],
            story_stiffness_n_per_m: vec![11_000.0, 13_000.0, 26_000.0],
        },
        &damping(),
    )
    .unwrap();
    let (modes, c) = modes_and_dashpots(&sys);
    let pair = FrfPair {
        response: 2,
        excitation: Excitation::Dof(2),
        kind: FrfKind::Accelerance,
    };
    let d = limit(&modes, &pair);
    let rate_hz = 2400.0;
    let step_s = 1.0 / rate_hz;
    let responses = [Response::Acceleration { dof: 2 }];
    for f in [2.0, 5.0, 12.0] {
        let omega = 2.0 * PI * f;
        let h = |nu: f64| modal_frf(&modes, &c, &pair, nu);
        let got = steady_state_at(&sys, Drive::Force { dof: 2 }, &responses, f, rate_hz)[0];
        let expect = aliased(&h, d, omega, step_s, ALIAS_TERMS);
        let plain = (expect - d) / (1.0 + (0.5 * omega * step_s).sin().powi(2) / 3.0) + d;
        let continuous = h(omega);
        let sim_err = (got - expect).norm() / expect.norm();
        let (pre, lin) = (
            (expect / continuous - 1.0).norm(),
            (plain / continuous - 1.0).norm(),
        );
        println!(
            "{f} Hz: D/|H| = {:.0}, |sim/G - 1| = {sim_err:.1e}, pre-emphasised {pre:.1e}, plain {lin:.1e}",
            d / continuous.norm()
        );
        assert!(
            d > 50.0 * continuous.norm(),
            "not a light driving point at {f} Hz"
        );
        assert!(sim_err < 1e-9, "{f} Hz: simulation {got} against {expect}");
        assert!(
            pre < lin / 20.0,
            "{f} Hz: {pre:e} against the plain hold's {lin:e}"
        );
    }
}

fn pipeline_model() -> SimModel {
    SimModel {
        title: "frf check".into(),
        seed: Some(1),
        structure: structure(),
        damping: damping(),
        nominal: None,
        sampling: SamplingSpec {
            output_rate_hz: 500.0,
            oversampling: 10,
            passband_fraction: 0.8,
            stopband_attenuation_db: 100.0,
        },
        noise: NoiseSpec::default(),
        effects: vec![],
        sensor_effects: vec![],
        tests: vec![
            TestSpec::Hammer {
                name: "hammer".into(),
                excited_floor: 2,
                duration_s: 40.0,
                pulse_duration_s: 0.003,
                impacts: vec![ImpactSpec {
                    time_s: 1.0,
                    peak_force_n: 50.0,
                }],
            },
            TestSpec::ShakeTable {
                name: "shake".into(),
                chirp: ChirpSpec {
                    f0_hz: 0.5,
                    f1_hz: 40.0,
                    start_s: 0.5,
                    sweep_duration_s: 20.0,
                    taper_s: 1.0,
                    amplitude_m_per_s2: 0.1,
                },
                ring_down_s: 20.0,
            },
        ],
    }
}

/// The FRF between the anti-aliased, decimated input and output channels of a noise-free
/// campaign is the analytic FRF (in its exact FOH form `G`). The filter cancels in the
/// ratio; what remains is decimation aliasing of both channels: with images `k` at
/// 250 Hz and above attenuated by at most 1.5 delta (delta = 1e-5 for 100 dB, see the
/// `antialias` tests), `Y/U = (G U + sum_k F_k G_k U_k) / (U + sum_k F_k U_k)`
/// `~ G + sum_k F_k (G_k - G) U_k / U`, bounded per bin by
/// `9 images x 1.5 delta x (max_{f >= 250 Hz} |G| + |G(f)|) x max|U| / |U(f)|`.
#[test]
fn anti_aliased_campaign_frfs_equal_analytic_frfs() {
    let model = pipeline_model();
    let sim = Simulator::new(model).unwrap();
    let campaign = sim.run(1, &|_| {}).unwrap();
    let sys = sim.system();
    let (modes, c) = modes_and_dashpots(sys);
    let delta = 1e-5;
    let step_s = 1.0 / RATE_HZ;
    for test in &campaign.tests {
        let n = test.n_samples();
        let u = spectrum(&test.data[0]);
        let u_max = u.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let (excitation, f_lo, f_hi) = match test.kind {
            frfbayes::io::TestKind::Hammer { excited_floor } => {
                (Excitation::Dof(excited_floor - 1), 0.5, 60.0)
            }
            frfbayes::io::TestKind::ShakeTable => (Excitation::Ground, 2.0, 38.0),
        };
        let mut worst: f64 = 0.0;
        for (ch, data) in test.channels.iter().zip(&test.data).skip(1) {
            let kind = match ch.quantity {
                frfbayes::io::Quantity::Acceleration => FrfKind::Accelerance,
                _ => FrfKind::Receptance,
            };
            let pair = FrfPair {
                response: ch.floor - 1,
                excitation,
                kind,
            };
            // Absolute acceleration for the ground test: relative accelerance + 1.
            let shift = if kind == FrfKind::Accelerance && excitation == Excitation::Ground {
                1.0
            } else {
                0.0
            };
            let h_inf = limit(&modes, &pair);
            let g = |omega: f64| {
                aliased(
                    &|nu| modal_frf(&modes, &c, &pair, nu),
                    h_inf,
                    omega,
                    step_s,
                    ALIAS_TERMS,
                ) + shift
            };
            let g_stop = (0..200)
                .map(|i| g(2.0 * PI * (250.0 + 11.25 * i as f64)).norm())
                .fold(0.0, f64::max);
            let y = spectrum(data);
            for bin in 1..n / 2 {
                let f = bin as f64 * 500.0 / n as f64;
                if f < f_lo || f > f_hi {
                    continue;
                }
                let est = y[bin] / u[bin];
                let expect = g(2.0 * PI * f);
                let tol = 9.0 * 1.5 * delta * (g_stop + expect.norm()) * u_max / u[bin].norm()
                    + 1e-9 * expect.norm();
                let err = (est - expect).norm();
                worst = worst.max(err / expect.norm());
                assert!(
                    err <= tol,
                    "{} {} at {f} Hz: {est} vs {expect} (err {err:e}, tol {tol:e})",
                    test.name,
                    ch.name
                );
            }
        }
        println!("{}: worst relative FRF error {worst:.2e}", test.name);
    }
}
