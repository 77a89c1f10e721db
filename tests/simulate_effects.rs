//! Effects through the whole simulator: physics effects (a dashpot, an attached
//! oscillator) must give campaign FRFs equal to the direct solve of the changed system;
//! sensor effects (time offset, low-pass) must change exactly the channels they name, by
//! exactly their own transfer function.

use frfbayes::frf::direct;
use frfbayes::io::{Campaign, Quantity, TestKind};
use frfbayes::simulate::{
    DampingSpec, Dashpot, EffectSpec, ImpactSpec, LowPass, NoiseSpec, Oscillator, SamplingSpec,
    SensorEffect, SimModel, Simulator, StructureSpec, TestSpec, TimeOffset,
};
use nalgebra::DMatrix;
use num_complex::Complex64;
use realfft::RealFftPlanner;
use std::f64::consts::PI;
use std::path::Path;

const INTERNAL_RATE_HZ: f64 = 5000.0;

fn model() -> SimModel {
    SimModel {
        title: "effects".into(),
        seed: Some(1),
        structure: StructureSpec::ShearFrame {
            floor_mass_kg: vec![5.2, 4.9, 5.1],
            story_stiffness_n_per_m: vec![11_000.0, 13_000.0, 26_000.0],
        },
        damping: DampingSpec::Modal {
            xi: vec![0.05, 0.04, 0.03],
        },
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
        tests: vec![TestSpec::Hammer {
            name: "hammer".into(),
            excited_floor: 2,
            duration_s: 40.0,
            pulse_duration_s: 0.003,
            impacts: vec![ImpactSpec {
                time_s: 1.0,
                peak_force_n: 50.0,
            }],
        }],
    }
}

fn spectrum(x: &[f64]) -> Vec<Complex64> {
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(x.len());
    let mut input = x.to_vec();
    let mut out = fft.make_output_vec();
    fft.process(&mut input, &mut out).unwrap();
    out
}

fn run(m: SimModel) -> (Simulator, Campaign) {
    let sim = Simulator::new(m).unwrap();
    let c = sim.run(1, &|_| {}).unwrap();
    (sim, c)
}

/// FOH-sampled FRF `sum_m X(nu_m) sinc^2(nu_m h / 2)` with `X` the direct receptance
/// (times `-nu^2` for accelerance, whose mass-line limit `(M^-1)_re` is summed exactly as
/// in `simulate_frf.rs`).
fn foh_frf(
    m: &DMatrix<f64>,
    k: &DMatrix<f64>,
    c: &DMatrix<f64>,
    r: usize,
    e: usize,
    accel: bool,
    omega: f64,
) -> Complex64 {
    let h = 1.0 / INTERNAL_RATE_HZ;
    let ws = 2.0 * PI / h;
    let limit = if accel {
        m.clone().try_inverse().unwrap()[(r, e)]
    } else {
        0.0
    };
    let terms = if accel { 100 } else { 2 };
    (-terms..=terms)
        .map(|j| {
            let nu = omega + j as f64 * ws;
            let x = direct::receptance_matrix(m, k, c, nu.abs()).unwrap()[(r, e)];
            let x = if nu < 0.0 { x.conj() } else { x };
            let x = if accel { -nu * nu * x } else { x };
            let a = 0.5 * nu * h;
            let l = if a == 0.0 { 1.0 } else { (a.sin() / a).powi(2) };
            (x - limit) * l
        })
        .sum::<Complex64>()
        + limit
}

#[test]
fn dashpot_and_oscillator_change_the_frfs_as_the_direct_solve_says() {
    let mut m = model();
    m.effects = vec![
        EffectSpec::Dashpot(Dashpot {
            floors: [1, 3],
            coefficient_n_s_per_m: 40.0,
        }),
        EffectSpec::Oscillator(Oscillator {
            floor: 3,
            mass_kg: 0.5,
            stiffness_n_per_m: 0.5 * (2.0 * PI * 6.0_f64).powi(2),
            damping_ratio: 0.03,
        }),
    ];
    let (sim, c) = run(m);
    let sys = sim.system();
    assert_eq!(sys.n_dof(), 4);
    let (mm, kk, cc) = (&sys.mass_kg, &sys.stiffness_n_per_m, &sys.damping_n_s_per_m);
    let test = &c.tests[0];
    let TestKind::Hammer { excited_floor } = test.kind else {
        panic!("hammer expected")
    };
    let e = sys.dof_of_floor(excited_floor).unwrap();
    let n = test.n_samples();
    let u = spectrum(&test.data[0]);
    let u_max = u.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let mut worst: f64 = 0.0;
    for (ch, data) in test.channels.iter().zip(&test.data).skip(1) {
        let accel = ch.quantity == Quantity::Acceleration;
        let r = sys.dof_of_floor(ch.floor).unwrap();
        let y = spectrum(data);
        let g_stop = (0..40)
            .map(|i| {
                foh_frf(
                    mm,
                    kk,
                    cc,
                    r,
                    e,
                    accel,
                    2.0 * PI * (250.0 + 56.25 * i as f64),
                )
                .norm()
            })
            .fold(0.0, f64::max);
        for bin in (20..n / 2).step_by(7) {
            let f = bin as f64 * 500.0 / n as f64;
            if f > 60.0 {
                break;
            }
            let est = y[bin] / u[bin];
            let expect = foh_frf(mm, kk, cc, r, e, accel, 2.0 * PI * f);
            // Decimation-aliasing bound as in simulate_frf.rs (100 dB: delta = 1e-5).
            let tol = 9.0 * 1.5e-5 * (g_stop + expect.norm()) * u_max / u[bin].norm()
                + 1e-9 * expect.norm();
            let err = (est - expect).norm();
            worst = worst.max(err / expect.norm());
            assert!(err <= tol, "{} at {f} Hz: {est} vs {expect}", ch.name);
        }
    }
    println!("dashpot + oscillator: worst relative FRF error {worst:.2e}");
}

/// Channels by name.
fn channel<'a>(c: &'a Campaign, name: &str) -> &'a [f64] {
    let t = &c.tests[0];
    let i = t.channels.iter().position(|ch| ch.name == name).unwrap();
    &t.data[i]
}

#[test]
fn sensor_effects_change_only_their_channels_by_their_transfer_function() {
    let (_, plain) = run(model());
    let mut m = model();
    let offset_s = 0.00437;
    let lp = LowPass {
        channels: vec!["acc1".into()],
        tests: None,
        natural_frequency_hz: 80.0,
        damping_ratio: 0.6,
    };
    m.sensor_effects = vec![
        SensorEffect::TimeOffset(TimeOffset {
            channels: vec!["acc3".into(), "disp3".into()],
            tests: Some(vec!["hammer".into()]),
            offset_s,
        }),
        SensorEffect::LowPass(lp.clone()),
    ];
    let (_, fx) = run(m);
    for name in ["force", "acc2", "disp1", "disp2"] {
        let (a, b) = (channel(&plain, name), channel(&fx, name));
        assert!(
            a.iter().zip(b).all(|(p, q)| p.to_bits() == q.to_bits()),
            "{name} changed"
        );
    }
    // Offset channels: Y_fx / Y = e^{-j w offset} in the pass band; low-passed channel:
    // Y_fx / Y = the FOH-sampled low-pass (see its unit test). Both effects commute with
    // the anti-aliasing filter, so the ratio is exact but for decimation images, at most
    // 9 x 1.5e-5 of the content above 250 Hz relative to the bin: for bins above 1e-3 of
    // the peak that is below 1e-4 (measured: < 1e-7). A one-sample (0.2 ms) timing error
    // would give 2 pi f h > 1e-2 at 10 Hz.
    let n = plain.tests[0].n_samples();
    for (name, kind) in [("acc3", 0), ("disp3", 0), ("acc1", 1)] {
        let (a, b) = (
            spectrum(channel(&plain, name)),
            spectrum(channel(&fx, name)),
        );
        let a_max = a.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for bin in 1..n / 2 {
            let f = bin as f64 * 500.0 / n as f64;
            if f > 150.0 || a[bin].norm() < 1e-3 * a_max {
                continue;
            }
            let expect = if kind == 0 {
                Complex64::from_polar(1.0, -2.0 * PI * f * offset_s)
            } else {
                (-20..=20)
                    .map(|j| {
                        let nu = f + j as f64 * INTERNAL_RATE_HZ;
                        let x = PI * nu / INTERNAL_RATE_HZ;
                        let l = if nu == 0.0 {
                            1.0
                        } else {
                            (x.sin() / x).powi(2)
                        };
                        lp.response(nu) * l
                    })
                    .sum()
            };
            let err = (b[bin] / a[bin] - expect).norm();
            worst = worst.max(err);
            assert!(
                err < 1e-4,
                "{name} at {f} Hz: ratio {} vs {expect}",
                b[bin] / a[bin]
            );
        }
        println!("{name}: worst transfer error {worst:.2e}");
    }
}

#[test]
fn effects_parse_from_the_model_file_and_are_checked() {
    let base = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/four-story-truth.toml"),
    )
    .unwrap();
    let effects = r#"
[[effect]]
kind = "dashpot"
floors = [0, 1]
coefficient_n_s_per_m = 5.0

[[effect]]
kind = "oscillator"
floor = 4
mass_kg = 0.3
stiffness_n_per_m = 120.0
damping_ratio = 0.02

[[sensor_effect]]
kind = "low_pass"
channels = ["acc1", "acc2", "acc3", "acc4"]
natural_frequency_hz = 60.0
damping_ratio = 0.6

[[sensor_effect]]
kind = "time_offset"
channels = ["disp3"]
tests = ["shake-table-chirp"]
offset_s = -0.004
"#;
    let path = Path::new("fx.toml");
    let m = SimModel::from_toml(&format!("{base}{effects}"), path).unwrap();
    assert_eq!(m.effects.len(), 2);
    assert_eq!(m.sensor_effects.len(), 2);
    assert!(m.sensor_effects[1].applies_to("shake-table-chirp", "disp3"));
    assert!(!m.sensor_effects[1].applies_to("hammer-floor1", "disp3"));
    for (from, to, needle) in [
        (
            "floor = 4\nmass_kg",
            "floor = 5\nmass_kg",
            "oscillator floor",
        ),
        ("floors = [0, 1]", "floors = [1, 1]", "two different floors"),
        (
            "channels = [\"disp3\"]",
            "channels = [\"disp9\"]",
            "no channel \"disp9\"",
        ),
        (
            "tests = [\"shake-table-chirp\"]",
            "tests = [\"nope\"]",
            "no test named",
        ),
        (
            "kind = \"low_pass\"",
            "kind = \"low_pass\"\ngain = 2.0",
            "unknown field `gain`",
        ),
        (
            "natural_frequency_hz = 60.0",
            "natural_frequency_hz = -1.0",
            "natural_frequency_hz",
        ),
        ("oversampling = 10", "oversampling = 2", "oversampling >= 4"),
    ] {
        let text = format!("{base}{effects}").replacen(from, to, 1);
        let e = SimModel::from_toml(&text, path).unwrap_err().to_string();
        assert!(
            e.starts_with("fx.toml") && e.contains(needle),
            "expected {needle:?} in: {e}"
        );
    }
    // The effects reach the simulated system: a fifth DOF, non-proportional damping.
    let sim = Simulator::new(m).unwrap();
    assert_eq!(sim.system().n_dof(), 5);
    assert_eq!(sim.system().floor_dof, vec![0, 1, 2, 3]);
}
