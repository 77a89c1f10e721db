//! Effects through the whole simulator: physics effects (a dashpot, an attached
//! oscillator) must give campaign FRFs equal to the direct solve of the changed system;
//! sensor effects (time offset, low-pass) must change exactly the channels they name, by
//! exactly their own transfer function.

mod simulate_common;

use frfbayes::io::{Campaign, Quantity, TestKind};
use frfbayes::simulate::{
    BaseFlexibility, DampingSpec, Dashpot, EffectSpec, ImpactSpec, LowPass, NoiseSpec, Oscillator,
    SamplingSpec, SensorEffect, SimModel, Simulator, StructureSpec, TestSpec, TimeOffset,
};
use nalgebra::DMatrix;
use num_complex::Complex64;
use simulate_common::{decimation_tolerance, foh_frf, spectrum, stop_band_peak, INTERNAL_RATE_HZ};
use std::f64::consts::PI;
use std::path::Path;

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

fn run(m: SimModel) -> (Simulator, Campaign) {
    let sim = Simulator::new(m).unwrap();
    let c = sim.run(1, &|_| {}).unwrap();
    (sim, c)
}

#[test]
fn dashpot_and_oscillator_change_the_frfs_as_the_direct_solve_says() {
    let mut m = model();
    m.effects = vec![
        EffectSpec::Dashpot(Dashpot::between([1, 3], 40.0)),
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
        let g_stop = stop_band_peak(|w| foh_frf(mm, kk, cc, r, e, accel, w));
        for bin in (20..n / 2).step_by(7) {
            let f = bin as f64 * 500.0 / n as f64;
            if f > 60.0 {
                break;
            }
            let est = y[bin] / u[bin];
            let expect = foh_frf(mm, kk, cc, r, e, accel, 2.0 * PI * f);
            let tol = decimation_tolerance(g_stop, expect, u_max, u[bin].norm());
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
        quantity: None,
        tests: None,
        natural_frequency_hz: 80.0,
        damping_ratio: 0.6,
    };
    m.sensor_effects = vec![
        SensorEffect::TimeOffset(TimeOffset {
            channels: vec!["acc3".into(), "disp3".into()],
            quantity: None,
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
    // Y_fx / Y = the FOH-sampled low-pass of the pre-emphasised samples (see its unit
    // test). Both effects commute with
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
                lp.sampled_response(f, INTERNAL_RATE_HZ, 20)
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

[[effect]]
kind = "dashpot"
story = 3
coefficient_n_s_per_m = 2.0

[[effect]]
kind = "base_flexibility"
mass_kg = 5.0
stiffness_n_per_m = 40000.0
damping_n_s_per_m = 10.0

[[effect]]
kind = "stiffness_nonlinearity"
story = 1
k3_n_per_m3 = 1e7

[[sensor_effect]]
kind = "low_pass"
quantity = "acceleration"
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
    assert_eq!(m.effects.len(), 5);
    assert_eq!(m.sensor_effects.len(), 2);
    assert!(m.sensor_effects[0].applies_to("hammer-floor2", "acc3", Quantity::Acceleration));
    assert!(!m.sensor_effects[0].applies_to("hammer-floor2", "disp3", Quantity::Displacement));
    assert!(m.sensor_effects[1].applies_to("shake-table-chirp", "disp3", Quantity::Displacement));
    assert!(!m.sensor_effects[1].applies_to("hammer-floor1", "disp3", Quantity::Displacement));
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
        (
            "story = 3\ncoefficient",
            "story = 3\nfloors = [2, 3]\ncoefficient",
            "exactly one of `story` or `floors`",
        ),
        ("story = 1\nk3", "story = 5\nk3", "story must be in 1..=4"),
        ("k3_n_per_m3 = 1e7", "k3_n_per_m3 = nan", "k3_n_per_m3 must be finite"),
        (
            "mass_kg = 5.0",
            "mass_kg = 0.0",
            "base_flexibility mass_kg and stiffness_n_per_m must be positive",
        ),
        (
            "kind = \"stiffness_nonlinearity\"\nstory = 1\nk3_n_per_m3 = 1e7",
            "kind = \"base_flexibility\"\nmass_kg = 1.0\nstiffness_n_per_m = 1.0\ndamping_n_s_per_m = 0.0",
            "given twice",
        ),
        (
            "quantity = \"acceleration\"",
            "quantity = \"acceleration\"\nchannels = [\"acc1\"]",
            "not both",
        ),
        ("quantity = \"acceleration\"", "quantity = \"velocity\"", "unknown variant"),
        (
            "quantity = \"acceleration\"",
            "quantity = \"ground_acceleration\"\ntests = [\"hammer-floor1\"]",
            "none of its tests records",
        ),
    ] {
        let text = format!("{base}{effects}").replacen(from, to, 1);
        let e = SimModel::from_toml(&text, path).unwrap_err().to_string();
        assert!(
            e.starts_with("fx.toml") && e.contains(needle),
            "expected {needle:?} in: {e}"
        );
    }
    // The effects reach the simulated system: an oscillator DOF, then the base DOF, and
    // a cubic spring across story 1 from the base to floor 1.
    let sim = Simulator::new(m).unwrap();
    assert_eq!(sim.system().n_dof(), 6);
    assert_eq!(sim.system().floor_dof, vec![0, 1, 2, 3]);
    assert_eq!(sim.system().base_dof, Some(5));
    let spring = sim.cubic_springs()[0];
    assert_eq!((spring.upper_dof, spring.lower_dof), (0, Some(5)));
    assert_eq!(spring.k3_n_per_m3, 1e7);
    // Both dashpots: 5 N s/m floor 1 to the base (moved there by the base), 2 N s/m
    // across story 3; the oscillator is on floor 4 (DOF 4).
    let c = &sim.system().damping_n_s_per_m;
    let plain = {
        let mut m = SimModel::from_toml(&base, path).unwrap();
        m.effects = vec![
            EffectSpec::Oscillator(Oscillator {
                floor: 4,
                mass_kg: 0.3,
                stiffness_n_per_m: 120.0,
                damping_ratio: 0.02,
            }),
            EffectSpec::BaseFlexibility(BaseFlexibility {
                mass_kg: 5.0,
                stiffness_n_per_m: 40000.0,
                damping_n_s_per_m: 10.0,
            }),
        ];
        Simulator::new(m)
            .unwrap()
            .system()
            .damping_n_s_per_m
            .clone()
    };
    let d = c - plain;
    let mut expect = DMatrix::<f64>::zeros(6, 6);
    for (i, j, v) in [(0, 0, 5.0), (5, 5, 5.0), (0, 5, -5.0), (5, 0, -5.0)] {
        expect[(i, j)] += v;
    }
    for (i, j, v) in [(1, 1, 2.0), (2, 2, 2.0), (1, 2, -2.0), (2, 1, -2.0)] {
        expect[(i, j)] += v;
    }
    assert!((d - expect).amax() < 1e-12);
}
