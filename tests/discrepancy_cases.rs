//! The missing-physics benchmark cases (`experiments/models/discrepancy/`): every case
//! agrees with its entry in `cases.toml` (verdict, location, noise, seed), keeps the
//! four-story layout, and has an effect of the size the benchmark asks for. The design
//! figures of the README are printed with `--nocapture`.
//!
//! Generating every campaign (slow, ignored by default):
//!
//! ```text
//! cargo test --release --test discrepancy_cases -- --ignored --nocapture
//! ```
//!
//! writes them under `$FRFBAYES_CASES_OUT` (default: `discrepancy-cases` in the system
//! temporary folder) with `frfbayes simulate`, and prints the time taken.

use frfbayes::io::bundled::bundled_four_story;
use frfbayes::io::{read_campaign, Channel, Quantity, TestKind};
use frfbayes::simulate::{
    EffectSpec, NoiseSpec, SensorEffect, SimModel, Simulator, StructureSpec, TestSpec,
};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

const HYPOTHESES: [&str; 6] = [
    "base_flexibility",
    "nonproportional_damping",
    "secondary_oscillator",
    "stiffness_nonlinearity",
    "sensor_timing",
    "sensor_dynamics",
];

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Index {
    hypotheses: Vec<String>,
    case: Vec<Case>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Case {
    id: String,
    model: String,
    verdict: String,
    location: Location,
    size: String,
    noise_scale: f64,
    seed: u64,
    /// The true effect parameters (scoring only; absent for `none`).
    #[serde(default)]
    truth: std::collections::BTreeMap<String, f64>,
}

#[derive(Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct Location {
    story: Option<usize>,
    floor: Option<usize>,
    channels: Option<Vec<String>>,
    quantity: Option<Quantity>,
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models")
}

fn index() -> Index {
    let text = std::fs::read_to_string(root().join("discrepancy/cases.toml")).unwrap();
    toml::from_str(&text).unwrap()
}

fn load(case: &Case) -> SimModel {
    SimModel::from_path(&root().join("discrepancy").join(&case.model)).unwrap()
}

/// The recorded four-story campaign (bundled in the repository): its tests, sorted by
/// name, as (name, kind, channels).
fn recorded_layout() -> Vec<(String, TestKind, Vec<Channel>)> {
    let real = read_campaign(&bundled_four_story().unwrap()).unwrap();
    real.tests
        .into_iter()
        .map(|t| (t.name, t.kind, t.channels))
        .collect()
}

#[test]
fn every_case_matches_its_index_entry_and_the_benchmark_ranges() {
    let index = index();
    assert_eq!(index.hypotheses, HYPOTHESES);
    for h in HYPOTHESES.iter().chain(&["none"]) {
        let n = index.case.iter().filter(|c| c.verdict == *h).count();
        assert!(n >= 3, "{h}: {n} cases");
    }
    let reference = SimModel::from_path(&root().join("four-story-truth.toml")).unwrap();
    let layout = recorded_layout();
    assert_eq!(layout.len(), 5);
    let plain = Simulator::new(SimModel {
        effects: vec![],
        sensor_effects: vec![],
        ..reference.clone()
    })
    .unwrap();
    let modes = plain.system().modes().unwrap();
    let f_hz = modes.freq_hz();
    let xi0 = plain.system().modal_damping_ratios().unwrap();
    let StructureSpec::ShearFrame { floor_mass_kg, .. } = &reference.structure else {
        panic!("shear frame expected");
    };
    println!("plain frame: f {f_hz:.4?} Hz, xi {xi0:.4?}");
    for (i, case) in index.case.iter().enumerate() {
        let id = &case.id;
        assert!(index.case[..i]
            .iter()
            .all(|c| c.id != *id && c.seed != case.seed));
        assert!(
            HYPOTHESES.contains(&case.verdict.as_str()) || case.verdict == "none",
            "{id}: verdict {}",
            case.verdict
        );
        assert_eq!(case.model, format!("{id}.toml"));
        let m = load(case);
        // The same frame, beliefs, instruments and layout as the recorded campaign.
        assert_eq!(m.seed, Some(case.seed), "{id}");
        assert_eq!(case.truth.is_empty(), case.verdict == "none", "{id}: truth");
        assert_eq!(m.structure, reference.structure, "{id}");
        assert_eq!(m.damping, reference.damping, "{id}");
        assert_eq!(m.nominal, reference.nominal, "{id}");
        assert_eq!(m.sampling, reference.sampling, "{id}");
        let s = case.noise_scale;
        let r = &reference.noise;
        let expect = NoiseSpec {
            force_n: s * r.force_n,
            ground_acceleration_m_per_s2: s * r.ground_acceleration_m_per_s2,
            acceleration_m_per_s2: s * r.acceleration_m_per_s2,
            displacement_m: s * r.displacement_m,
            ar1_coefficient: 0.0,
        };
        for (a, b) in [
            (m.noise.force_n, expect.force_n),
            (
                m.noise.ground_acceleration_m_per_s2,
                expect.ground_acceleration_m_per_s2,
            ),
            (m.noise.acceleration_m_per_s2, expect.acceleration_m_per_s2),
            (m.noise.displacement_m, expect.displacement_m),
        ] {
            assert!((a - b).abs() <= 1e-12 * b, "{id}: noise {a} vs {b}");
        }
        assert_eq!(m.tests.len(), layout.len(), "{id}");
        for t in &m.tests {
            if let TestSpec::Hammer { impacts, .. } = t {
                // A weak then a strong impact, for level-against-level checks.
                assert!(
                    impacts.len() == 2 && impacts[1].peak_force_n >= 4.0 * impacts[0].peak_force_n,
                    "{id}"
                );
            }
        }
        // Same tests (the campaign sorts them by name) and channels as recorded.
        let sim = Simulator::new(m.clone()).unwrap();
        for (t, (name, kind, channels)) in m.tests.iter().zip(&layout) {
            assert_eq!(t.name(), name, "{id}");
            let ours_kind = match t {
                TestSpec::Hammer { excited_floor, .. } => TestKind::Hammer {
                    excited_floor: *excited_floor,
                },
                TestSpec::ShakeTable { .. } => TestKind::ShakeTable,
            };
            assert_eq!(ours_kind, *kind, "{id} {name}");
            let ours: Vec<Channel> = sim
                .channels(t, 1)
                .unwrap()
                .into_iter()
                .map(|p| p.channel)
                .collect();
            assert_eq!(&ours, channels, "{id} {name}");
        }
        // The effect, where it is, and its size.
        let fx = &m.effects;
        let sx = &m.sensor_effects;
        let loc = &case.location;
        let n_effects = fx.len() + sx.len();
        let design = match case.verdict.as_str() {
            "none" => {
                assert_eq!(n_effects, 0, "{id}");
                assert_eq!(*loc, Location::default());
                "-".to_string()
            }
            "base_flexibility" => {
                assert!(n_effects == 1 && matches!(fx[0], EffectSpec::BaseFlexibility(_)));
                assert_eq!(*loc, Location::default());
                let f = sim.system().modes().unwrap().freq_hz();
                let drop = f[0] / f_hz[0] - 1.0;
                assert!((-0.08..=-0.02).contains(&drop), "{id}: f1 {drop}");
                format!("f1 {:+.1}%, f {:.2?} Hz (5 modes)", 100.0 * drop, f)
            }
            "nonproportional_damping" => {
                let EffectSpec::Dashpot(d) = &fx[0] else {
                    panic!("{id}: dashpot expected")
                };
                assert!(n_effects == 1 && d.story.is_some() && d.story == loc.story);
                assert!(loc.floor.is_none() && loc.channels.is_none() && loc.quantity.is_none());
                // Added modal damping, (Phi^T C Phi)_ii / 2 w_i less the proportional part.
                let xi = sim.system().modal_damping_ratios().unwrap();
                let added: Vec<f64> = xi.iter().zip(&xi0).map(|(a, b)| a - b).collect();
                let most = added.iter().fold(0.0_f64, |m, v| m.max(*v));
                assert!((0.005..=0.03).contains(&most), "{id}: {added:?}");
                format!(
                    "added xi {:.2?}%",
                    added.iter().map(|v| 100.0 * v).collect::<Vec<_>>()
                )
            }
            "secondary_oscillator" => {
                let EffectSpec::Oscillator(o) = &fx[0] else {
                    panic!("{id}: oscillator expected")
                };
                assert!(n_effects == 1 && Some(o.floor) == loc.floor);
                assert!(loc.story.is_none() && loc.channels.is_none() && loc.quantity.is_none());
                let ratio = o.mass_kg / floor_mass_kg[o.floor - 1];
                assert!((0.02..=0.10).contains(&ratio), "{id}: mass ratio {ratio}");
                let f = o.freq_hz();
                assert!(f >= 0.9 * f_hz[0] && f <= 1.1 * f_hz[3], "{id}: {f} Hz");
                format!(
                    "mass {:.1}% of floor {}, tuned {:.2} Hz, f {:.3?} Hz",
                    100.0 * ratio,
                    o.floor,
                    f,
                    sim.system().modes().unwrap().freq_hz()
                )
            }
            "stiffness_nonlinearity" => {
                let EffectSpec::StiffnessNonlinearity(c) = &fx[0] else {
                    panic!("{id}: stiffness_nonlinearity expected")
                };
                assert!(n_effects == 1 && Some(c.story) == loc.story && c.k3_n_per_m3 != 0.0);
                assert!(loc.floor.is_none() && loc.channels.is_none() && loc.quantity.is_none());
                "see cubic_cases_move_mode_1_between_impact_levels".to_string()
            }
            "sensor_timing" => {
                let SensorEffect::TimeOffset(t) = &sx[0] else {
                    panic!("{id}: time_offset expected")
                };
                assert!(n_effects == 1 && t.tests.is_none());
                assert_eq!(
                    loc.channels.as_deref(),
                    (!t.channels.is_empty()).then_some(&t.channels[..])
                );
                assert_eq!(loc.quantity, t.quantity);
                assert!((0.005..=0.030).contains(&t.offset_s.abs()), "{id}");
                format!("phase {:.1} deg at f4", 360.0 * f_hz[3] * t.offset_s)
            }
            "sensor_dynamics" => {
                let SensorEffect::LowPass(l) = &sx[0] else {
                    panic!("{id}: low_pass expected")
                };
                assert!(n_effects == 1 && l.tests.is_none());
                assert_eq!(
                    loc.channels.as_deref(),
                    (!l.channels.is_empty()).then_some(&l.channels[..])
                );
                assert_eq!(loc.quantity, l.quantity);
                assert!((15.0..=60.0).contains(&l.natural_frequency_hz), "{id}");
                assert!((0.3..=0.7).contains(&l.damping_ratio), "{id}");
                let h = l.response(f_hz[3]);
                format!(
                    "at f4: gain {:+.2}%, phase {:.1} deg",
                    100.0 * (h.norm() - 1.0),
                    h.arg().to_degrees()
                )
            }
            v => panic!("{id}: unknown verdict {v}"),
        };
        println!("{id:28} {:32} {design}", case.size);
    }
}

/// Mean frequency of mode 1 over `count` cycles from sample `from` (zero crossings of
/// the modal coordinate).
fn mode1_freq_hz(eta: &[f64], rate_hz: f64, from: usize, count: usize) -> f64 {
    let crossings: Vec<f64> = (from..eta.len() - 1)
        .filter(|&k| eta[k] < 0.0 && eta[k + 1] >= 0.0)
        .map(|k| k as f64 + eta[k] / (eta[k] - eta[k + 1]))
        .take(count + 1)
        .collect();
    count as f64 * rate_hz / (crossings[count] - crossings[0])
}

#[test]
fn cubic_cases_move_mode_1_between_impact_levels() {
    // The benchmark asks for a mode-1 frequency 1-5% apart between the weak and strong
    // impacts. Measured on hammer-floor4 without noise: the modal coordinate
    // eta_1 = phi_1^T M x from the displacements, its mean frequency over the 5 cycles
    // from 0.5 s after each impact (the amplitude then is ~90% of the impact's, so the
    // shift is that of the early FRF-dominating part of the decay).
    let index = index();
    for case in index
        .case
        .iter()
        .filter(|c| c.verdict == "stiffness_nonlinearity")
    {
        let mut m = load(case);
        m.noise = NoiseSpec::default();
        m.tests.retain(|t| t.name() == "hammer-floor4");
        let sim = Simulator::new(m.clone()).unwrap();
        let modes = sim.system().modes().unwrap();
        let t = sim.simulate_test(&m.tests[0], 1, &|_| {}).unwrap();
        let StructureSpec::ShearFrame { floor_mass_kg, .. } = &m.structure else {
            panic!("shear frame expected");
        };
        let eta: Vec<f64> = (0..t.n_samples())
            .map(|k| {
                t.channels
                    .iter()
                    .zip(&t.data)
                    .filter(|(c, _)| c.quantity == Quantity::Displacement)
                    .map(|(c, x)| modes.phi[(c.floor - 1, 0)] * floor_mass_kg[c.floor - 1] * x[k])
                    .sum()
            })
            .collect();
        let TestSpec::Hammer { impacts, .. } = &m.tests[0] else {
            unreachable!()
        };
        let f0 = modes.freq_hz()[0];
        let rate = t.sample_rate_hz;
        let at = |t0: f64| mode1_freq_hz(&eta, rate, ((t0 + 0.5) * rate) as usize, 5) / f0 - 1.0;
        let (weak, strong) = (at(impacts[0].time_s), at(impacts[1].time_s));
        println!(
            "{:28} mode 1: weak {:+.2}%, strong {:+.2}%, between {:+.2}%",
            case.id,
            100.0 * weak,
            100.0 * strong,
            100.0 * (strong - weak)
        );
        assert!(weak.abs() < 0.003, "{}: {weak}", case.id);
        assert!(
            (0.01..=0.05).contains(&(strong - weak).abs()),
            "{}",
            case.id
        );
    }
}

#[test]
#[ignore = "simulates all 21 benchmark campaigns (~45 s on 2 cores, 1.3 GB)"]
fn generate_all_cases() {
    let out = std::env::var_os("FRFBAYES_CASES_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("discrepancy-cases"));
    std::fs::create_dir_all(&out).unwrap();
    let index = index();
    let start = Instant::now();
    for case in &index.case {
        let t0 = Instant::now();
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_frfbayes"))
            .arg("simulate")
            .arg("--model")
            .arg(root().join("discrepancy").join(&case.model))
            .arg("--out")
            .arg(out.join(&case.id))
            .stdout(std::process::Stdio::null())
            .status()
            .unwrap();
        assert!(status.success(), "{}", case.id);
        let campaign = frfbayes::io::read_campaign(&out.join(&case.id)).unwrap();
        assert_eq!(campaign.tests.len(), 5);
        println!("{:28} {:5.1} s", case.id, t0.elapsed().as_secs_f64());
    }
    println!(
        "{} cases into {} in {:.1} s",
        index.case.len(),
        out.display(),
        start.elapsed().as_secs_f64()
    );
}
