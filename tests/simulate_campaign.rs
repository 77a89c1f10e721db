//! Whole campaigns: reproducibility from the seed, noise statistics, the layout of the
//! written campaign, the shipped model files, and the command line.

use frfbayes::io::{Campaign, Quantity, TestKind};
use frfbayes::simulate::{
    resolve_seed, ChirpSpec, DampingSpec, ImpactSpec, NoiseSpec, SamplingSpec, SimModel, Simulator,
    StructureSpec, TestSpec,
};
use std::path::{Path, PathBuf};
use std::process::Command;

fn small_model(noise: NoiseSpec) -> SimModel {
    SimModel {
        title: "small".into(),
        seed: Some(3),
        structure: StructureSpec::ShearFrame {
            floor_mass_kg: vec![5.0, 5.0],
            story_stiffness_n_per_m: vec![1500.0, 2500.0],
        },
        damping: DampingSpec::Rayleigh {
            a0_per_s: 0.2,
            a1_s: 1e-4,
        },
        nominal: None,
        sampling: SamplingSpec {
            output_rate_hz: 500.0,
            oversampling: 10,
            passband_fraction: 0.8,
            stopband_attenuation_db: 100.0,
        },
        noise,
        effects: vec![],
        sensor_effects: vec![],
        tests: vec![
            TestSpec::ShakeTable {
                name: "b-shake".into(),
                chirp: ChirpSpec {
                    f0_hz: 0.0,
                    f1_hz: 10.0,
                    start_s: 0.0,
                    sweep_duration_s: 10.0,
                    taper_s: 1.0,
                    amplitude_m_per_s2: 0.08,
                },
                ring_down_s: 5.0,
            },
            TestSpec::Hammer {
                name: "a-hammer".into(),
                excited_floor: 2,
                duration_s: 12.0,
                pulse_duration_s: 0.003,
                impacts: vec![
                    ImpactSpec {
                        time_s: 1.0,
                        peak_force_n: 50.0,
                    },
                    ImpactSpec {
                        time_s: 7.0,
                        peak_force_n: 40.0,
                    },
                ],
            },
        ],
    }
}

fn noise() -> NoiseSpec {
    NoiseSpec {
        force_n: 0.02,
        ground_acceleration_m_per_s2: 0.002,
        acceleration_m_per_s2: 0.005,
        displacement_m: 2e-6,
        ar1_coefficient: 0.0,
    }
}

fn run(model: SimModel, seed: u64) -> Campaign {
    Simulator::new(model).unwrap().run(seed, &|_| {}).unwrap()
}

fn assert_same(a: &Campaign, b: &Campaign) {
    assert_eq!(a.tests.len(), b.tests.len());
    for (x, y) in a.tests.iter().zip(&b.tests) {
        assert_eq!(x.name, y.name);
        assert_eq!(x.channels, y.channels);
        // Bit-identical samples.
        for (p, q) in x.data.iter().zip(&y.data) {
            assert!(p.iter().zip(q).all(|(u, v)| u.to_bits() == v.to_bits()));
        }
    }
}

#[test]
fn campaign_layout_follows_the_recording_format() {
    let c = run(small_model(noise()), 1);
    assert_eq!(c.title, "small");
    assert_eq!(c.nominal.floor_mass_kg, vec![5.0, 5.0]);
    let names: Vec<&str> = c.tests.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["a-hammer", "b-shake"], "tests sorted by name");
    let hammer = &c.tests[0];
    assert_eq!(hammer.kind, TestKind::Hammer { excited_floor: 2 });
    assert_eq!(hammer.n_samples(), 6000);
    assert_eq!(hammer.sample_rate_hz, 500.0);
    let chans: Vec<(&str, Quantity, usize, &str)> = hammer
        .channels
        .iter()
        .map(|c| (c.name.as_str(), c.quantity, c.floor, c.unit.as_str()))
        .collect();
    assert_eq!(
        chans,
        [
            ("force", Quantity::Force, 2, "N"),
            ("acc1", Quantity::Acceleration, 1, "m/s^2"),
            ("acc2", Quantity::Acceleration, 2, "m/s^2"),
            ("disp1", Quantity::Displacement, 1, "m"),
            ("disp2", Quantity::Displacement, 2, "m"),
        ]
    );
    let shake = &c.tests[1];
    assert_eq!(shake.kind, TestKind::ShakeTable);
    assert_eq!(shake.n_samples(), 7500);
    assert_eq!(shake.channels[0].name, "ground_acc");
    assert_eq!(shake.channels[0].quantity, Quantity::GroundAcceleration);
    assert_eq!(shake.channels[0].floor, 0);
    assert!(c.tests.iter().all(
        |t| t.data.len() == t.channels.len() && t.data.iter().all(|d| d.len() == t.n_samples())
    ));
}

#[test]
fn same_seed_same_campaign_whatever_the_thread_count() {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let a = one.install(|| run(small_model(noise()), 11));
    let b = two.install(|| run(small_model(noise()), 11));
    assert_same(&a, &b);
    // Reordering the tests in the model changes nothing either (streams hash names).
    let mut m = small_model(noise());
    m.tests.reverse();
    assert_same(&a, &run(m, 11));
}

#[test]
fn different_seeds_differ_by_noise_of_the_stated_level() {
    let a = run(small_model(noise()), 1);
    let b = run(small_model(noise()), 2);
    let clean = run(small_model(NoiseSpec::default()), 1);
    let z = noise();
    for ((ta, tb), tc) in a.tests.iter().zip(&b.tests).zip(&clean.tests) {
        for (i, ch) in ta.channels.iter().enumerate() {
            let std = match ch.quantity {
                Quantity::Force => z.force_n,
                Quantity::GroundAcceleration => z.ground_acceleration_m_per_s2,
                Quantity::Acceleration => z.acceleration_m_per_s2,
                Quantity::Displacement => z.displacement_m,
            };
            let n = ta.n_samples() as f64;
            // a - clean is exactly the noise: n iid N(0, std^2) draws. The sample std has
            // relative standard error 1/sqrt(2n) (< 0.01 here); allow 5 of them. The
            // difference of two seeds has std sqrt(2) std, same relative error.
            let sd = |x: &[f64], y: &[f64]| {
                (x.iter().zip(y).map(|(p, q)| (p - q).powi(2)).sum::<f64>() / n).sqrt()
            };
            let tol = 5.0 / (2.0 * n).sqrt();
            let s1 = sd(&ta.data[i], &tc.data[i]) / std;
            let s2 = sd(&ta.data[i], &tb.data[i]) / (std * 2f64.sqrt());
            assert!((s1 - 1.0).abs() < tol, "{} {}: {s1}", ta.name, ch.name);
            assert!((s2 - 1.0).abs() < tol, "{} {}: {s2}", ta.name, ch.name);
            // Across channels the noise is independent: correlation within 5/sqrt(n).
            if i > 0 {
                let prev: Vec<f64> = ta.data[i - 1]
                    .iter()
                    .zip(&tc.data[i - 1])
                    .map(|(p, q)| p - q)
                    .collect();
                let cur: Vec<f64> = ta.data[i]
                    .iter()
                    .zip(&tc.data[i])
                    .map(|(p, q)| p - q)
                    .collect();
                let dot: f64 = prev.iter().zip(&cur).map(|(p, q)| p * q).sum();
                let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
                let corr = dot / (norm(&prev) * norm(&cur));
                assert!(
                    corr.abs() < 5.0 / n.sqrt(),
                    "{} {}: corr {corr}",
                    ta.name,
                    ch.name
                );
            }
        }
    }
}

#[test]
fn written_campaign_holds_the_simulated_samples() {
    let model = small_model(noise());
    let sim = Simulator::new(model).unwrap();
    let c = sim.run(5, &|_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let root = frfbayes::io::write_campaign(&c, &dir.path().join("camp")).unwrap();
    sim.write_truth(&root, 5).unwrap();
    let toml_of = |p: PathBuf| -> toml::Table {
        toml::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let campaign = toml_of(root.join("campaign.toml"));
    assert_eq!(campaign["title"].as_str(), Some("small"));
    assert_eq!(
        campaign["nominal"]["structure"].as_str(),
        Some("shear_frame")
    );
    for t in &c.tests {
        let dir = root.join("tests").join(&t.name);
        let meta = toml_of(dir.join("test.toml"));
        assert_eq!(meta["sample_rate_hz"].as_float(), Some(500.0));
        let kind = meta["kind"].as_str().unwrap();
        match t.kind {
            TestKind::Hammer { excited_floor } => {
                assert_eq!(kind, "hammer");
                assert_eq!(
                    meta["excited_floor"].as_integer(),
                    Some(excited_floor as i64)
                );
            }
            TestKind::ShakeTable => assert_eq!(kind, "shake_table"),
        }
        let chans = meta["channel"].as_array().unwrap();
        assert_eq!(chans.len(), t.channels.len());
        // The CSV: header, then exactly the in-memory samples (shortest round-trip text).
        let mut r = csv::Reader::from_path(dir.join("data.csv")).unwrap();
        let header: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
        let mut expect = vec!["time_s".to_string()];
        expect.extend(t.channels.iter().map(|c| c.name.clone()));
        assert_eq!(header, expect);
        let mut rows = 0;
        for (i, rec) in r.records().enumerate() {
            let rec = rec.unwrap();
            let time: f64 = rec[0].parse().unwrap();
            assert!((time - i as f64 / 500.0).abs() < 1e-12);
            for (j, d) in t.data.iter().enumerate() {
                let v: f64 = rec[j + 1].parse().unwrap();
                assert_eq!(v.to_bits(), d[i].to_bits());
            }
            rows += 1;
        }
        assert_eq!(rows, t.n_samples());
    }
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["seed"], 5);
    let f = truth["natural_frequencies_hz"].as_array().unwrap();
    let modes = sim.system().modes().unwrap().freq_hz();
    assert_eq!(f.len(), 2);
    assert!((f[0].as_f64().unwrap() - modes[0]).abs() < 1e-12);
    // The model round-trips through truth.json.
    let model: SimModel = serde_json::from_value(truth["model"].clone()).unwrap();
    assert_eq!(&model, sim.model());
}

#[test]
fn written_campaign_reads_back_identically() {
    let model = small_model(noise());
    let sim = Simulator::new(model).unwrap();
    let c = sim.run(8, &|_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let root = frfbayes::io::write_campaign(&c, &dir.path().join("camp")).unwrap();
    sim.write_truth(&root, 8).unwrap();
    let r = frfbayes::io::read_campaign(&root).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.title, c.title);
    assert_eq!(r.nominal, c.nominal);
    assert_eq!(r.tests.len(), c.tests.len());
    for (a, b) in r.tests.iter().zip(&c.tests) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.kind, b.kind);
        assert_eq!(a.sample_rate_hz, b.sample_rate_hz);
        assert_eq!(a.channels, b.channels);
    }
    assert_same(&r, &c);
}

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models")
}

#[test]
fn shipped_models_parse_and_the_noise_free_variant_differs_only_in_noise() {
    let truth = SimModel::from_path(&models_dir().join("four-story-truth.toml")).unwrap();
    let clean =
        SimModel::from_path(&models_dir().join("four-story-truth-noise-free.toml")).unwrap();
    assert_eq!(clean.noise, NoiseSpec::default());
    assert!(truth.noise.acceleration_m_per_s2 > 0.0);
    let mut t = truth.clone();
    t.noise = NoiseSpec::default();
    t.title = clean.title.clone();
    assert_eq!(t, clean);
    // The template campaign's layout: 4 hammer tests of 120 s and a 130 s chirp.
    let sim = Simulator::new(truth).unwrap();
    let n: Vec<usize> = sim
        .model()
        .tests
        .iter()
        .map(|t| sim.n_output_samples(t))
        .collect();
    assert_eq!(n, [60000, 60000, 60000, 60000, 65000]);
}

#[test]
fn truth_model_reproduces_the_layout_of_the_recorded_campaign() {
    // The recorded campaign, bundled in the repository (identical to ../shared's copy).
    let real =
        frfbayes::io::read_campaign(&frfbayes::io::bundled::bundled_four_story().unwrap()).unwrap();
    let model = SimModel::from_path(&models_dir().join("four-story-truth.toml")).unwrap();
    let sim = Simulator::new(model).unwrap();
    assert_eq!(
        real.nominal,
        sim.model().nominal_model(sim.system().n_dof()).unwrap()
    );
    let mut specs: Vec<&TestSpec> = sim.model().tests.iter().collect();
    specs.sort_by_key(|t| t.name().to_string());
    assert_eq!(specs.len(), real.tests.len());
    for (spec, test) in specs.into_iter().zip(&real.tests) {
        assert_eq!(spec.name(), test.name);
        assert_eq!(
            sim.n_output_samples(spec),
            test.n_samples(),
            "{}",
            test.name
        );
        assert_eq!(sim.model().sampling.output_rate_hz, test.sample_rate_hz);
        let channels: Vec<_> = sim
            .channels(spec, 0)
            .unwrap()
            .into_iter()
            .map(|c| c.channel)
            .collect();
        assert_eq!(channels, test.channels, "{}", test.name);
        let kind = match spec {
            TestSpec::Hammer { excited_floor, .. } => TestKind::Hammer {
                excited_floor: *excited_floor,
            },
            TestSpec::ShakeTable { .. } => TestKind::ShakeTable,
        };
        assert_eq!(kind, test.kind);
    }
}

#[test]
fn model_errors_name_the_file_and_the_problem() {
    let path = Path::new("m.toml");
    let base = std::fs::read_to_string(models_dir().join("four-story-truth.toml")).unwrap();
    for (from, to, needle) in [
        (
            "oversampling = 10",
            "oversampling = 10\noversampling_x = 2",
            "oversampling_x",
        ),
        (
            "excited_floor = 4",
            "excited_floor = 5",
            "excited_floor must be in 1..=4",
        ),
        (
            "time_s = 62.0003, peak_force_n = 45.0",
            "time_s = 119.999, peak_force_n = 45.0",
            "does not fit",
        ),
        ("f1_hz = 10.0", "f1_hz = 300.0", "output Nyquist"),
        ("model = \"modal\"", "model = \"viscous\"", "viscous"),
        (
            "xi = [0.017, 0.0115, 0.006, 0.004]",
            "xi = [0.017, 0.0115]",
            "one ratio per mode",
        ),
        (
            "pulse_duration_s = 0.003",
            "pulse_duration_s = 0.0003",
            "shorter than two internal samples",
        ),
        (
            "name = \"hammer-floor2\"",
            "name = \"hammer-floor1\"",
            "used twice",
        ),
        (
            "name = \"hammer-floor2\"",
            "name = \"../x\"",
            "plain folder name",
        ),
        (
            "floor_mass_kg = [5.155",
            "floor_mass_kg = [-5.155",
            "floor 1 mass must be positive",
        ),
    ] {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let e = SimModel::from_toml(&text, path).unwrap_err().to_string();
        assert!(e.starts_with("m.toml"), "{e}");
        assert!(e.contains(needle), "expected {needle:?} in: {e}");
    }
    let mut m = SimModel::from_toml(&base, path).unwrap();
    m.seed = None;
    assert!(resolve_seed(&m, None, path)
        .unwrap_err()
        .to_string()
        .contains("--seed"));
    assert_eq!(resolve_seed(&m, Some(4), path).unwrap(), 4);
}

#[test]
fn command_line_writes_a_campaign_and_reports_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.toml");
    let mut text = std::fs::read_to_string(models_dir().join("four-story-truth.toml")).unwrap();
    // Shorter records keep the test fast.
    text = text.replace("duration_s = 120.0", "duration_s = 4.0");
    text = text.replace("time_s = 62.0003", "time_s = 3.0");
    text = text.replace("ring_down_s = 70.0", "ring_down_s = 1.0");
    text = text.replace("sweep_duration_s = 60.0", "sweep_duration_s = 3.0");
    std::fs::write(&model, &text).unwrap();
    let out = dir.path().join("camp");
    let bin = env!("CARGO_BIN_EXE_frfbayes");
    let status = Command::new(bin)
        .args(["simulate", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&out)
        .args(["--seed", "9"])
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    for t in ["hammer-floor1", "hammer-floor4", "shake-table-chirp"] {
        assert!(out.join("tests").join(t).join("data.csv").is_file());
    }
    assert!(out.join("truth.json").is_file());
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("run.json")).unwrap()).unwrap();
    assert_eq!(run["seed"], 9);
    // A bad model: error names the file, nothing is written.
    std::fs::write(
        &model,
        text.replace("excited_floor = 3", "excited_floor = 0"),
    )
    .unwrap();
    let out2 = dir.path().join("camp2");
    let r = Command::new(bin)
        .args(["simulate", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&out2)
        .output()
        .unwrap();
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("model.toml") && err.contains("excited_floor"),
        "{err}"
    );
    assert!(!out2.exists());
}
