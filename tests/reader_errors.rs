//! Campaign reader against the recording format: one committed tiny campaign per error
//! the spec lists (`tests/fixtures/campaigns/<case>/`, written by `generate.py` there),
//! a valid one, one with unknown keys, a writer round trip, and the real four-story data.

use frfbayes::io::{
    read_campaign, read_nominal, write_campaign, Campaign, Channel, NominalModel, Quantity, Test,
    TestKind,
};
use frfbayes::Error;
use std::path::{Path, PathBuf};

fn fixture(case: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/campaigns")
        .join(case)
}

fn read_err(case: &str) -> Error {
    match read_campaign(&fixture(case)) {
        Ok(_) => panic!("{case}: expected an error"),
        Err(e) => e,
    }
}

/// `case` fails with `Error::Invalid` on `<case>/<file>` and a message containing `needle`;
/// the displayed error names the file too.
fn assert_invalid(case: &str, file: &str, needle: &str) {
    let err = read_err(case);
    let shown = err.to_string();
    match &err {
        Error::Invalid { path, what } => {
            assert_eq!(path, &fixture(case).join(file), "{case}: {shown}");
            assert!(what.contains(needle), "{case}: `{needle}` not in: {shown}");
        }
        other => panic!("{case}: expected Error::Invalid, got {other:?}"),
    }
    assert!(shown.contains(file), "{case}: {shown}");
}

/// `case` fails with `Error::Cell` at `<case>/<file>:line:column`.
fn assert_cell(case: &str, file: &str, line: usize, column: usize, needle: &str) {
    let err = read_err(case);
    let shown = err.to_string();
    match &err {
        Error::Cell {
            path,
            line: l,
            column: c,
            what,
        } => {
            assert_eq!(path, &fixture(case).join(file), "{case}: {shown}");
            assert_eq!((*l, *c), (line, column), "{case}: {shown}");
            assert!(what.contains(needle), "{case}: `{needle}` not in: {shown}");
        }
        other => panic!("{case}: expected Error::Cell, got {other:?}"),
    }
    assert!(
        shown.contains(&format!("{file}:{line}:{column}:")),
        "{shown}"
    );
}

const HAMMER_TOML: &str = "tests/hammer-1/test.toml";
const HAMMER_CSV: &str = "tests/hammer-1/data.csv";

#[test]
fn valid_campaign_reads_with_channels_in_test_toml_order() {
    let c = read_campaign(&fixture("valid")).unwrap();
    assert_eq!(c.title, "tiny frame");
    assert_eq!(c.nominal.floor_mass_kg, [1.5, 2.0]);
    assert_eq!(c.nominal.story_stiffness_n_per_m, [100.0, 200.0]);
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    let names: Vec<&str> = c.tests.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["hammer-1", "shake"]);
    let hammer = &c.tests[0];
    assert_eq!(hammer.kind, TestKind::Hammer { excited_floor: 1 });
    assert_eq!(hammer.sample_rate_hz, 100.0);
    assert_eq!(hammer.n_samples(), 5);
    assert_eq!(
        hammer.channels[1],
        Channel {
            name: "acc1".into(),
            quantity: Quantity::Acceleration,
            floor: 1,
            unit: "m/s^2".into()
        }
    );
    // Cell (row i, data column j) holds 0.001 (i+1) (j+1); hammer columns follow test.toml.
    assert_eq!(hammer.data[3], [4e-3, 8e-3, 12e-3, 16e-3, 20e-3]);
    // The shake-table header is reversed: ground_acc is data column 3 in the file.
    let shake = &c.tests[1];
    assert_eq!(shake.kind, TestKind::ShakeTable);
    assert_eq!(shake.channels[0].name, "ground_acc");
    assert_eq!(shake.data[0], [3e-3, 6e-3, 9e-3, 12e-3, 15e-3]);
    assert_eq!(shake.data[2], [1e-3, 2e-3, 3e-3, 4e-3, 5e-3]);
    assert_eq!(read_nominal(&fixture("valid")).unwrap(), c.nominal);
}

#[test]
fn unknown_keys_and_stray_files_are_warnings() {
    let c = read_campaign(&fixture("unknown_keys")).unwrap();
    assert_eq!(
        c.warnings,
        [
            "campaign.toml: unknown key `operator` ignored",
            "campaign.toml [nominal]: unknown key `damping_ratio` ignored",
            "tests/notes.txt: not a test folder; ignored",
            "tests/hammer-1/test.toml: unknown key `temperature_c` ignored",
            "tests/hammer-1/test.toml channel `force`: unknown key `serial` ignored",
        ]
    );
    assert_eq!(c.tests.len(), 2);
}

#[test]
fn read_nominal_needs_only_campaign_toml() {
    let n = read_nominal(&fixture("missing_tests_folder")).unwrap();
    assert_eq!(n.n_floors(), 2);
    assert!(read_nominal(&fixture("missing_campaign_toml")).is_err());
    assert!(read_nominal(&fixture("negative_mass")).is_err());
}

#[test]
fn missing_files() {
    assert_invalid("missing_campaign_toml", "campaign.toml", "not found");
    assert_invalid("missing_tests_folder", "tests", "not found");
    assert_invalid("missing_test_toml", "tests/shake/test.toml", "not found");
    assert_invalid("missing_data_csv", "tests/shake/data.csv", "not found");
}

#[test]
fn campaign_toml_errors() {
    assert_invalid(
        "negative_mass",
        "campaign.toml",
        "floor_mass_kg[1] (floor 2) is -2",
    );
    assert_invalid(
        "zero_stiffness",
        "campaign.toml",
        "story_stiffness_n_per_m[0] (story 1) is 0",
    );
    assert_invalid("mass_stiffness_length", "campaign.toml", "has 2 values but");
    assert_invalid(
        "unsupported_structure",
        "campaign.toml",
        "\"truss\" is not supported",
    );
    assert_invalid("no_nominal", "campaign.toml", "no [nominal] section");
}

#[test]
fn test_toml_errors() {
    assert_invalid("bad_toml_syntax", HAMMER_TOML, "line 1");
    assert_invalid("hammer_no_force", HAMMER_TOML, "quantity = \"force\"");
    assert_invalid(
        "hammer_no_excited_floor",
        HAMMER_TOML,
        "needs `excited_floor`",
    );
    assert_invalid(
        "excited_floor_out_of_range",
        HAMMER_TOML,
        "excited_floor = 3 is outside 0..=2",
    );
    assert_invalid(
        "excited_floor_ground",
        HAMMER_TOML,
        "excited_floor = 0 is the ground",
    );
    assert_invalid(
        "force_floor_mismatch",
        HAMMER_TOML,
        "at floor 2 but excited_floor = 1",
    );
    assert_invalid(
        "shake_no_ground",
        "tests/shake/test.toml",
        "quantity = \"ground_acceleration\"",
    );
    assert_invalid(
        "floor_out_of_range",
        HAMMER_TOML,
        "floor = 3 is outside 0..=2",
    );
    assert_invalid("floor_negative", HAMMER_TOML, "floor = -1 is outside 0..=2");
    assert_invalid(
        "unknown_kind",
        HAMMER_TOML,
        "kind = \"impact\" is not known",
    );
    assert_invalid(
        "unknown_quantity",
        HAMMER_TOML,
        "quantity = \"velocity\" is not known",
    );
    assert_invalid("unit_mismatch", HAMMER_TOML, "unit = \"g\" does not match");
    assert_invalid("duplicate_channel", HAMMER_TOML, "`acc1` is used twice");
    assert_invalid("bad_sample_rate", HAMMER_TOML, "sample_rate_hz = 0");
}

#[test]
fn header_errors() {
    assert_invalid("channel_not_in_header", HAMMER_CSV, "no column `disp1`");
    assert_cell(
        "header_not_in_toml",
        HAMMER_CSV,
        1,
        6,
        "`acc9` is not a channel",
    );
    assert_cell(
        "header_time_not_first",
        HAMMER_CSV,
        1,
        1,
        "must be `time_s`",
    );
    assert_cell("duplicate_header", HAMMER_CSV, 1, 4, "`acc1` appears twice");
}

#[test]
fn cell_errors_give_line_and_column() {
    assert_cell(
        "non_numeric_cell",
        HAMMER_CSV,
        4,
        3,
        "`abc` is not a number",
    );
    assert_cell(
        "comma_decimal_cell",
        HAMMER_CSV,
        3,
        2,
        "`1,5` is not a number",
    );
    assert_cell("empty_cell", HAMMER_CSV, 3, 2, "empty cell");
    assert_cell("nan_value", HAMMER_CSV, 5, 4, "NaN or infinite");
    assert_cell("inf_value", HAMMER_CSV, 3, 5, "NaN or infinite");
    assert_cell(
        "short_row",
        HAMMER_CSV,
        4,
        5,
        "4 cells but the header has 5",
    );
    assert_cell("long_row", HAMMER_CSV, 5, 6, "6 cells but the header has 5");
    assert_invalid("no_samples", HAMMER_CSV, "no samples");
}

#[test]
fn time_column_must_be_uniform_from_zero() {
    assert_cell("time_not_zero", HAMMER_CSV, 2, 1, "must start at 0");
    // Line 4 (sample 2) is missing: the next row is a whole period late.
    assert_cell(
        "time_not_uniform",
        HAMMER_CSV,
        4,
        1,
        "sample 2 should be at 0.02 s",
    );
    // 0.032 instead of 0.030: a fifth of a period, beyond the 4-decimal rounding.
    assert_cell(
        "time_jitter",
        HAMMER_CSV,
        5,
        1,
        "sample 3 should be at 0.03 s",
    );
}

fn in_memory_campaign(sample_rate_hz: f64, n_samples: usize) -> Campaign {
    let channels = vec![
        Channel {
            name: "f".into(),
            quantity: Quantity::Force,
            floor: 2,
            unit: "N".into(),
        },
        Channel {
            name: "a1".into(),
            quantity: Quantity::Acceleration,
            floor: 1,
            unit: "m/s^2".into(),
        },
    ];
    // Values with long decimal expansions and a wide range of magnitudes.
    let data = (0..2)
        .map(|j| {
            (0..n_samples)
                .map(|i| ((i * 7 + j * 3) as f64).sin() * 10f64.powi((i % 9) as i32 - 6) / 3.0)
                .collect()
        })
        .collect();
    Campaign {
        root: PathBuf::new(),
        title: "round trip \"quoted\"".into(),
        nominal: NominalModel::shear_frame(vec![4.64, 4.64 / 3.0], vec![1019.0, 1217.5]),
        tests: vec![Test {
            name: "hammer".into(),
            kind: TestKind::Hammer { excited_floor: 2 },
            sample_rate_hz,
            channels,
            data,
        }],
        warnings: Vec::new(),
    }
}

#[test]
fn writer_output_reads_back_bit_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    // 333.3 Hz: time_s is printed with many decimals and not exactly on the grid.
    for (k, rate_hz) in [500.0, 333.3, 1024.0].into_iter().enumerate() {
        let original = in_memory_campaign(rate_hz, 2000);
        let root = tmp.path().join(format!("c{k}"));
        write_campaign(&original, &root).unwrap();
        let back = read_campaign(&root).unwrap();
        assert_eq!(back.title, original.title);
        assert_eq!(back.nominal, original.nominal);
        assert!(back.warnings.is_empty());
        let (a, b) = (&original.tests[0], &back.tests[0]);
        assert_eq!((b.kind, b.sample_rate_hz), (a.kind, a.sample_rate_hz));
        assert_eq!(b.channels, a.channels);
        assert_eq!(b.data, a.data, "{rate_hz} Hz");
    }
}

#[test]
fn four_story_campaign_reads_cleanly() {
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
    let start = std::time::Instant::now();
    let c = read_campaign(&root).unwrap();
    println!(
        "read_campaign(four-story): {:.3} s",
        start.elapsed().as_secs_f64()
    );
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    assert_eq!(c.nominal.floor_mass_kg, [4.64; 4]);
    assert_eq!(
        c.nominal.story_stiffness_n_per_m,
        [1019.0, 1217.0, 1420.0, 2473.0]
    );
    assert_eq!(c.tests.len(), 5);
    for (i, t) in c.tests.iter().enumerate() {
        assert_eq!(t.channels.len(), 9, "{}", t.name);
        assert_eq!(t.sample_rate_hz, 500.0);
        assert!(t.data.iter().all(|d| d.len() == t.n_samples()));
        if i < 4 {
            assert_eq!(t.name, format!("hammer-floor{}", i + 1));
            assert_eq!(
                t.kind,
                TestKind::Hammer {
                    excited_floor: i + 1
                }
            );
            assert_eq!(t.n_samples(), 60_000);
        } else {
            assert_eq!(t.name, "shake-table-chirp");
            assert_eq!(t.kind, TestKind::ShakeTable);
            assert_eq!(t.n_samples(), 65_000);
        }
    }
    // First and last rows of hammer-floor1/data.csv, read by hand.
    let t = &c.tests[0];
    assert_eq!(t.data[0][0], -1.093788e-02);
    assert_eq!(t.data[8][59_999], 3.198554e-06);
}

/// Copies the `valid` fixture into a temporary folder.
fn copy_valid(tmp: &Path) -> PathBuf {
    fn copy_dir(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let p = e.unwrap().path();
            let dest = to.join(p.file_name().unwrap());
            if p.is_dir() {
                copy_dir(&p, &dest);
            } else {
                std::fs::copy(&p, &dest).unwrap();
            }
        }
    }
    let root = tmp.join("campaign");
    copy_dir(&fixture("valid"), &root);
    root
}

#[test]
fn crlf_bom_spaces_and_blank_lines_are_tolerated() {
    let tmp = tempfile::tempdir().unwrap();
    let root = copy_valid(tmp.path());
    let csv = root.join(HAMMER_CSV);
    let text = std::fs::read_to_string(&csv).unwrap();
    let spaced: Vec<String> = text
        .lines()
        .map(|l| l.split(',').collect::<Vec<_>>().join(" , "))
        .collect();
    std::fs::write(&csv, format!("\u{feff}{}\r\n\r\n", spaced.join("\r\n"))).unwrap();
    let expected = read_campaign(&fixture("valid")).unwrap();
    let got = read_campaign(&root).unwrap();
    assert_eq!(got.tests[0].data, expected.tests[0].data);
    // Line numbers stay right with CRLF endings: the bad cell is line 3, column 2.
    let broken =
        std::fs::read_to_string(&csv)
            .unwrap()
            .replacen("0.0100 , 2.000000e-03", "0.0100 , x", 1);
    std::fs::write(&csv, broken).unwrap();
    match read_campaign(&root) {
        Err(Error::Cell { line, column, .. }) => assert_eq!((line, column), (3, 2)),
        other => panic!("expected a cell error, got {other:?}"),
    }
}

#[test]
fn empty_tests_folder_and_integer_rate() {
    let tmp = tempfile::tempdir().unwrap();
    let root = copy_valid(tmp.path());
    // An integer sample rate is a rate too.
    let toml = root.join(HAMMER_TOML);
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(
        &toml,
        text.replace("sample_rate_hz = 100.0", "sample_rate_hz = 100"),
    )
    .unwrap();
    assert_eq!(read_campaign(&root).unwrap().tests[0].sample_rate_hz, 100.0);
    // Hidden folders are not tests; with none left, the error names tests/.
    for t in ["hammer-1", "shake"] {
        let from = root.join("tests").join(t);
        std::fs::rename(&from, root.join("tests").join(format!(".{t}"))).unwrap();
    }
    match read_campaign(&root) {
        Err(Error::Invalid { path, what }) => {
            assert_eq!(path, root.join("tests"));
            assert!(what.contains("no test folders"), "{what}");
        }
        other => panic!("expected Error::Invalid, got {other:?}"),
    }
}
