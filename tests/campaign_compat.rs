//! Backward compatibility of the campaign reader: every shear-frame campaign of the
//! original recording format reads to the same in-memory campaign as before the format
//! was extended to general models (channels on DOFs, `docs/recording-format.md`).
//!
//! Each campaign is reduced to a 64-bit FNV-1a digest of everything the reader returns
//! (title, nominal model, tests, channels, every sample's bits, warnings; or the error
//! message of a campaign that must fail). The expected digests were recorded with the
//! reader of commit 53be414 (before the extension) and must never change: a changed
//! digest means a campaign of today reads differently. Error messages are digested too;
//! only the one for an unsupported `structure` was changed on purpose (it now lists
//! "general").

use frfbayes::io::{read_campaign, Campaign};
use std::path::{Path, PathBuf};

/// FNV-1a, 64 bits: a fixed, platform-independent digest.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
        // Field separator, so that ("ab", "c") and ("a", "bc") differ.
        self.0 ^= 0xff;
        self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
    }
    fn str(&mut self, s: &str) {
        self.bytes(s.as_bytes());
    }
    fn f64s(&mut self, v: &[f64]) {
        for x in v {
            self.bytes(&x.to_bits().to_le_bytes());
        }
    }
}

/// Digest of the fields a campaign had before the extension (a general model adds
/// `nominal.model`, which must be `None` for these campaigns).
fn digest(c: &Campaign) -> u64 {
    assert!(
        c.nominal.model.is_none(),
        "a shear-frame campaign has no model"
    );
    let mut h = Fnv::new();
    h.str(&c.title);
    h.str(&c.nominal.structure);
    h.f64s(&c.nominal.floor_mass_kg);
    h.f64s(&c.nominal.story_stiffness_n_per_m);
    for t in &c.tests {
        h.str(&t.name);
        h.str(&format!("{:?}", t.kind));
        h.f64s(&[t.sample_rate_hz]);
        for ch in &t.channels {
            h.str(&format!(
                "{}|{:?}|{}|{}",
                ch.name, ch.quantity, ch.floor, ch.unit
            ));
        }
        for d in &t.data {
            h.f64s(d);
        }
    }
    for w in &c.warnings {
        h.str(w);
    }
    h.0
}

/// Digest of reading `root`: the campaign, or the error message (with `root` removed, so
/// that the digest does not depend on where the repository is).
fn read_digest(root: &Path) -> u64 {
    match read_campaign(root) {
        Ok(c) => digest(&c),
        Err(e) => {
            let shown = e.to_string().replace(&root.display().to_string(), "<root>");
            let mut h = Fnv::new();
            h.str("error");
            h.str(&shown);
            h.0
        }
    }
}

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/campaigns")
}

/// Recorded with the reader before the extension (commit 53be414).
const FIXTURE_DIGESTS: &[(&str, u64)] = &[
    ("bad_sample_rate", 0xc5af6a827763f29e),
    ("bad_toml_syntax", 0xe2a88893ae319f45),
    ("channel_not_in_header", 0x72a7a7ce0a00a75b),
    ("comma_decimal_cell", 0x107068c8d68a6e6e),
    ("duplicate_channel", 0xaf507fbbac7db363),
    ("duplicate_header", 0x633f8f818bc2978a),
    ("empty_cell", 0x614373c2f74b2d06),
    ("excited_floor_ground", 0x16377035b61da4c1),
    ("excited_floor_out_of_range", 0xf715e201cc783243),
    ("floor_negative", 0x1b74466d99f240d1),
    ("floor_out_of_range", 0x5bb0897d3bd8d966),
    ("force_floor_mismatch", 0x9cc4ff3d56e60137),
    ("hammer_no_excited_floor", 0xe44f0028f2d826f3),
    ("hammer_no_force", 0xfc21ecfbd2f04c01),
    ("header_not_in_toml", 0x053b03f812d33fb4),
    ("header_time_not_first", 0xaf0bc172c16b3585),
    ("inf_value", 0x86787dce83bd5703),
    ("long_row", 0xa394bd7ec305ba30),
    ("mass_stiffness_length", 0x2b76f2815db80d19),
    ("missing_campaign_toml", 0x6f35c99fad7cfd13),
    ("missing_data_csv", 0x9cfd8b85a64740f9),
    ("missing_test_toml", 0x555c3620a6b98c45),
    ("missing_tests_folder", 0x845445a3efb7c33c),
    ("nan_value", 0x57e556ca6c2d13e2),
    ("negative_mass", 0x43fc72b6c6e0d5ca),
    ("no_nominal", 0xbcda791b2694e51a),
    ("no_samples", 0x97652d25249cc764),
    ("non_numeric_cell", 0x3a578b15ce4f7f04),
    ("shake_no_ground", 0xd12438a68048e63f),
    ("short_row", 0x02c3adcb024fac5a),
    ("time_jitter", 0x0393f4dc4b39ba76),
    ("time_not_uniform", 0x43674bc880cddbf9),
    ("time_not_zero", 0x0a851ad75dca51f2),
    ("unit_mismatch", 0x91a186ace0b132fe),
    ("unknown_keys", 0x01f3aa2362683ea7),
    ("unknown_kind", 0x6c91cf73dc24939e),
    ("unknown_quantity", 0x4d730d0398cc728a),
    // The one deliberate change: the error for an unknown structure now names both
    // "shear_frame" and "general" (it was 0x863f755f8df49dc9 before the extension).
    ("unsupported_structure", 0x94fad86c1956dfb3),
    ("valid", 0xe5b19c467c1e7278),
    ("zero_stiffness", 0xd88bd41175db9688),
];

#[test]
fn every_fixture_campaign_reads_as_before() {
    let mut cases: Vec<String> = std::fs::read_dir(fixtures())
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    cases.sort();
    let got: Vec<(String, u64)> = cases
        .iter()
        .map(|c| (c.clone(), read_digest(&fixtures().join(c))))
        .collect();
    let table: String = got
        .iter()
        .map(|(c, d)| format!("    (\"{c}\", 0x{d:016x}),\n"))
        .collect();
    let expected: Vec<(String, u64)> = FIXTURE_DIGESTS
        .iter()
        .map(|(c, d)| (c.to_string(), *d))
        .collect();
    assert_eq!(got, expected, "digests now:\n{table}");
}

/// The bundled four-story campaign (`paper_repro/data`).
const BUNDLED_DIGEST: u64 = 0x1f29_7360_574c_7e8b;

#[test]
fn bundled_four_story_reads_as_before() {
    let root = frfbayes::io::bundled::bundled_four_story().unwrap();
    let d = read_digest(&root);
    assert_eq!(d, BUNDLED_DIGEST, "digest now: 0x{d:016x}");
}

/// `../shared/data/four-story` (the same files as the bundle).
#[test]
fn shared_four_story_reads_as_before() {
    let shared = std::env::var_os("FRFBAYES_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared"));
    let root = shared.join("data/four-story");
    if !root.is_dir() {
        println!(
            "skipped: {} not found (no ../shared next to this clone)",
            root.display()
        );
        return;
    }
    let d = read_digest(&root);
    assert_eq!(d, BUNDLED_DIGEST, "digest now: 0x{d:016x}");
}

/// A short shear-frame simulation (hammer and shake table, with noise): the simulator's
/// output for shear frames is unchanged by the extension to general models.
#[test]
fn shear_frame_simulation_is_as_before() {
    let text = r#"
title = "compat"
seed = 5
[structure]
kind = "shear_frame"
floor_mass_kg = [5.0, 4.0, 4.5]
story_stiffness_n_per_m = [1200.0, 1300.0, 2500.0]
[damping]
model = "caughey"
xi = [0.02, 0.01]
[nominal]
floor_mass_kg = [4.6, 4.6, 4.6]
story_stiffness_n_per_m = [1000.0, 1200.0, 2400.0]
[sampling]
output_rate_hz = 200.0
oversampling = 4
[noise]
force_n = 0.02
ground_acceleration_m_per_s2 = 0.002
acceleration_m_per_s2 = 0.005
displacement_m = 2e-6
[[test]]
name = "hammer-2"
kind = "hammer"
excited_floor = 2
duration_s = 4.0
pulse_duration_s = 0.005
impacts = [{ time_s = 0.5, peak_force_n = 40.0 }]
[[test]]
name = "shake"
kind = "shake_table"
ring_down_s = 1.0
[test.chirp]
f0_hz = 0.5
f1_hz = 20.0
sweep_duration_s = 3.0
taper_s = 0.5
amplitude_m_per_s2 = 0.1
"#;
    let model = frfbayes::simulate::SimModel::from_toml(text, Path::new("compat.toml")).unwrap();
    let sim = frfbayes::simulate::Simulator::new(model).unwrap();
    let campaign = sim.run(5, &|_| {}).unwrap();
    let d = digest(&campaign);
    assert_eq!(d, SIMULATION_DIGEST, "digest now: 0x{d:016x}");
}

/// Recorded with the simulator of 2026-11-28, whose state is driven by pre-emphasised
/// input samples (`frfbayes::simulate::pre_emphasised`); the simulator before the
/// extension (commit 53be414) and up to then gave 0x5066_2154_e072_6a26. A simulation
/// is not a reading: this digest changes when the simulator's physics does, on purpose.
const SIMULATION_DIGEST: u64 = 0xb023_b384_0c2d_0bcf;
