//! Campaigns on general models (`docs/recording-format.md`): a nominal model named by a
//! Matrix Market manifest, channels and impacts on DOFs (1-based) with a sign. One tiny
//! campaign per error, each differing from a valid one in a single place, written into a
//! temporary folder; the error must name the file, the key and what to write instead.

use frfbayes::io::{read_campaign, write_campaign, Quantity, TestKind};
use frfbayes::Error;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A 3-DOF model that is not a shear frame: springs ground-1, 1-2, 2-3 and 1-3.
const K0: &str = "%%MatrixMarket matrix coordinate real symmetric\n3 3 5\n\
                  1 1 3000\n2 1 -1000\n3 1 -500\n2 2 2000\n3 3 1500\n";
const K1: &str = "%%MatrixMarket matrix coordinate real symmetric\n3 3 1\n1 1 1500\n";
const M0: &str = "%%MatrixMarket matrix coordinate real symmetric\n3 3 3\n1 1 2\n2 2 1.5\n3 3 1\n";
const MANIFEST: &str =
    "k0 = \"K0.mtx\"\nm0 = \"M0.mtx\"\n[[alpha]]\nname = \"k_base\"\nmatrix = \"K1.mtx\"\n";

const CAMPAIGN: &str = "title = \"tiny general\"\n\n[nominal]\nstructure = \"general\"\n\
                        manifest = \"../model/model.toml\"\n";

const HAMMER: &str = "kind = \"hammer\"\nsample_rate_hz = 100.0\nexcited_dof = 2\n\n\
    [[channel]]\nname = \"force\"\nquantity = \"force\"\ndof = 2\nunit = \"N\"\n\n\
    [[channel]]\nname = \"acc1\"\nquantity = \"acceleration\"\ndof = 1\nunit = \"m/s^2\"\n\n\
    [[channel]]\nname = \"acc3\"\nquantity = \"acceleration\"\ndof = 3\nsign = -1\nunit = \"m/s^2\"\n";

const SHAKE: &str = "kind = \"shake_table\"\nsample_rate_hz = 100.0\n\n\
    [[channel]]\nname = \"ground_acc\"\nquantity = \"ground_acceleration\"\nunit = \"m/s^2\"\n\n\
    [[channel]]\nname = \"disp3\"\nquantity = \"displacement\"\ndof = 3\nunit = \"m\"\n";

const HAMMER_TOML: &str = "campaign/tests/hammer-2/test.toml";
const CAMPAIGN_TOML: &str = "campaign/campaign.toml";

/// `time_s` and one column per name; cell (row i, column j) = 0.001 (i+1) (j+1).
fn csv(names: &[&str]) -> String {
    let mut s = format!("time_s,{}\n", names.join(","));
    for i in 0..5 {
        s += &format!("{:.2}", i as f64 / 100.0);
        for j in 0..names.len() {
            s += &format!(",{:e}", 0.001 * (i + 1) as f64 * (j + 1) as f64);
        }
        s += "\n";
    }
    s
}

/// The valid case: files by path relative to the case folder.
fn base() -> BTreeMap<&'static str, String> {
    BTreeMap::from([
        ("model/K0.mtx", K0.to_string()),
        ("model/K1.mtx", K1.to_string()),
        ("model/M0.mtx", M0.to_string()),
        ("model/model.toml", MANIFEST.to_string()),
        (CAMPAIGN_TOML, CAMPAIGN.to_string()),
        (HAMMER_TOML, HAMMER.to_string()),
        (
            "campaign/tests/hammer-2/data.csv",
            csv(&["force", "acc1", "acc3"]),
        ),
        ("campaign/tests/shake/test.toml", SHAKE.to_string()),
        (
            "campaign/tests/shake/data.csv",
            csv(&["ground_acc", "disp3"]),
        ),
    ])
}

/// Writes `files` into a new temporary folder; returns it (kept alive) and the campaign.
fn write(files: &BTreeMap<&str, String>) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for (rel, text) in files {
        let p = dir.path().join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    let root = dir.path().join("campaign");
    (dir, root)
}

/// The base case with `from` replaced by `to` in `file` (which must contain it).
fn edited(file: &'static str, from: &str, to: &str) -> BTreeMap<&'static str, String> {
    let mut f = base();
    let text = f.get_mut(file).unwrap();
    assert!(text.contains(from), "{file} has no `{from}`");
    *text = text.replacen(from, to, 1);
    f
}

/// Reading `files` fails with `Error::Invalid` on `file` and a message containing every
/// needle; the displayed error names the file.
fn assert_invalid(files: &BTreeMap<&str, String>, file: &str, needles: &[&str]) {
    let (dir, root) = write(files);
    let err = match read_campaign(&root) {
        Ok(_) => panic!("expected an error for {file} containing {needles:?}"),
        Err(e) => e,
    };
    let shown = err.to_string();
    match &err {
        Error::Invalid { path, what } => {
            assert_eq!(path, &dir.path().join(file), "{shown}");
            for n in needles {
                assert!(what.contains(n), "`{n}` not in: {shown}");
            }
        }
        other => panic!("expected Error::Invalid, got {other:?}"),
    }
    assert!(shown.contains(file), "{shown}");
}

#[test]
fn general_campaign_reads_dofs_and_applies_signs() {
    let (dir, root) = write(&base());
    let c = read_campaign(&root).unwrap();
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    assert_eq!(c.nominal.structure, "general");
    let g = c.nominal.model.as_ref().unwrap();
    assert_eq!(g.n_dof, 3);
    assert_eq!(
        g.manifest,
        dir.path().join("model/model.toml").canonicalize().unwrap()
    );
    assert_eq!(c.nominal.n_floors(), 3);
    let model = c.nominal.structural_model().unwrap();
    assert_eq!((model.n_dof(), model.n_alpha()), (3, 1));
    let hammer = &c.tests[0];
    assert_eq!(hammer.kind, TestKind::Hammer { excited_floor: 2 });
    let dofs: Vec<Option<usize>> = hammer.channels.iter().map(|ch| ch.dof()).collect();
    assert_eq!(dofs, [Some(1), Some(0), Some(2)]);
    // acc3 has sign = -1: its samples are the column times -1.
    let column = |j: usize| -> Vec<f64> { (1..=5).map(|i| 0.001 * i as f64 * j as f64).collect() };
    assert_eq!(hammer.data[1], column(2));
    let negated: Vec<f64> = column(3).iter().map(|v| -v).collect();
    assert_eq!(hammer.data[2], negated);
    let shake = &c.tests[1];
    assert_eq!(shake.kind, TestKind::ShakeTable);
    assert_eq!(shake.channels[0].quantity, Quantity::GroundAcceleration);
    assert_eq!(shake.channels[0].floor, 0);
    assert_eq!(shake.channels[1].dof(), Some(2));
}

#[test]
fn a_negated_column_with_sign_minus_one_reads_as_the_column() {
    let mut f = edited(HAMMER_TOML, "dof = 3\nsign = -1\n", "dof = 3\nsign = 1.0\n");
    let (_d1, plus) = write(&f);
    let csv_path = "campaign/tests/hammer-2/data.csv";
    let plus = read_campaign(&plus).unwrap();
    // Negate the acc3 column (the last) and say so with sign = -1.
    let negated: Vec<String> = f[csv_path]
        .lines()
        .enumerate()
        .map(|(i, l)| match (i, l.rsplit_once(',')) {
            (0, _) | (_, None) => l.to_string(),
            (_, Some((head, last))) => format!("{head},{:e}", -last.parse::<f64>().unwrap()),
        })
        .collect();
    f.insert(csv_path, negated.join("\n") + "\n");
    *f.get_mut(HAMMER_TOML).unwrap() = HAMMER.to_string();
    let (_d2, minus) = write(&f);
    let minus = read_campaign(&minus).unwrap();
    assert_eq!(plus.tests[0].data, minus.tests[0].data);
    assert_eq!(plus.tests[0].channels, minus.tests[0].channels);
}

#[test]
fn nominal_model_errors() {
    assert_invalid(
        &edited(
            CAMPAIGN_TOML,
            "../model/model.toml",
            "../model/missing.toml",
        ),
        CAMPAIGN_TOML,
        &[
            "manifest = \"../model/missing.toml\"",
            "not found",
            "relative to the campaign folder",
        ],
    );
    assert_invalid(
        &edited(CAMPAIGN_TOML, "manifest = \"../model/model.toml\"\n", ""),
        CAMPAIGN_TOML,
        &["needs the model", "add manifest = "],
    );
    assert_invalid(
        &edited(
            CAMPAIGN_TOML,
            "\"general\"\n",
            "\"general\"\nfloor_mass_kg = [1.0]\n",
        ),
        CAMPAIGN_TOML,
        &[
            "floor_mass_kg belongs to a shear frame",
            "remove floor_mass_kg",
        ],
    );
    assert_invalid(
        &edited(CAMPAIGN_TOML, "\"general\"", "\"truss\""),
        CAMPAIGN_TOML,
        &["\"truss\" is not supported", "\"general\" with manifest"],
    );
    // A broken matrix: the error names campaign.toml's key and the matrix file and line.
    let mut f = base();
    f.insert("model/K1.mtx", K1.replace("1500", "abc"));
    assert_invalid(
        &f,
        CAMPAIGN_TOML,
        &[
            "manifest = \"../model/model.toml\"",
            "K1.mtx:3:",
            "not a number",
        ],
    );
}

#[test]
fn channel_location_errors() {
    let hammer = |from: &str, to: &str| edited(HAMMER_TOML, from, to);
    assert_invalid(
        &hammer("dof = 1\n", "dof = \"tip\"\n"),
        HAMMER_TOML,
        &[
            "#2 (`acc1`)",
            "dof = \"tip\" is not a known DOF",
            "integer 1..=3",
        ],
    );
    assert_invalid(
        &hammer("dof = 1\n", "dof = 4\n"),
        HAMMER_TOML,
        &[
            "#2 (`acc1`)",
            "dof = 4 is outside 1..=3",
            "model.toml has 3 DOFs",
            "dof = <1..=3>",
        ],
    );
    assert_invalid(
        &hammer("dof = 1\n", "dof = 0\n"),
        HAMMER_TOML,
        &["dof = 0 is not a DOF", "1-based"],
    );
    assert_invalid(
        &hammer("dof = 1\n", "dof = 1.5\n"),
        HAMMER_TOML,
        &["dof = 1.5 is not a DOF number", "integer 1..=3"],
    );
    assert_invalid(
        &hammer("sign = -1\n", "sign = 2\n"),
        HAMMER_TOML,
        &["#3 (`acc3`)", "sign = 2 must be +1 or -1", "sign = -1"],
    );
    assert_invalid(
        &hammer("sign = -1\n", "sign = -0.5\n"),
        HAMMER_TOML,
        &["sign = -0.5 must be +1 or -1"],
    );
    assert_invalid(
        &hammer("dof = 1\n", "dof = 1\nfloor = 1\n"),
        HAMMER_TOML,
        &[
            "#2 (`acc1`)",
            "both `floor` and `dof`",
            "keep dof = <1..=3>",
        ],
    );
    assert_invalid(
        &hammer("dof = 1\n", "floor = 1\n"),
        HAMMER_TOML,
        &[
            "floor = 1: floors belong to shear frames",
            "write dof = <1..=3> instead",
        ],
    );
    assert_invalid(
        &hammer("dof = 1\n", ""),
        HAMMER_TOML,
        &["#2 (`acc1`)", "no `dof`; add dof = <1..=3>"],
    );
    let shake = "campaign/tests/shake/test.toml";
    assert_invalid(
        &edited(
            shake,
            "\"ground_acceleration\"\n",
            "\"ground_acceleration\"\ndof = 1\n",
        ),
        shake,
        &[
            "ground_acceleration channel measures the ground",
            "remove `dof`",
        ],
    );
}

#[test]
fn hammer_location_errors() {
    let hammer = |from: &str, to: &str| edited(HAMMER_TOML, from, to);
    assert_invalid(
        &hammer("excited_dof = 2\n", "excited_dof = 7\n"),
        HAMMER_TOML,
        &["excited_dof = 7 is outside 1..=3"],
    );
    assert_invalid(
        &hammer("excited_dof = 2\n", "excited_floor = 2\n"),
        HAMMER_TOML,
        &[
            "excited_floor belongs to shear frames",
            "write excited_dof = <1..=3> instead",
        ],
    );
    assert_invalid(
        &hammer("excited_dof = 2\n", "excited_dof = 2\nexcited_floor = 2\n"),
        HAMMER_TOML,
        &["both `excited_floor` and `excited_dof`"],
    );
    assert_invalid(
        &hammer("excited_dof = 2\n", ""),
        HAMMER_TOML,
        &["a hammer test needs `excited_dof` (the impacted DOF, 1..=3)"],
    );
    assert_invalid(
        &hammer("excited_dof = 2\n", "excited_dof = 1\n"),
        HAMMER_TOML,
        &["force channel `force` is at DOF 2 but excited_dof = 1"],
    );
}

/// On a shear frame, `dof = k` is floor `k` and `excited_dof = k` is `excited_floor = k`.
#[test]
fn shear_frame_channels_may_name_dofs() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/campaigns/valid");
    let expected = read_campaign(&fixture).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("c");
    write_campaign(&expected, &root).unwrap();
    for test in ["hammer-1", "shake"] {
        let p = root.join("tests").join(test).join("test.toml");
        let text = std::fs::read_to_string(&p).unwrap();
        let text = text
            .replace("excited_floor = ", "excited_dof = ")
            .replace("floor = 1\n", "dof = 1\n")
            .replace("floor = 2\n", "dof = 2\n");
        std::fs::write(&p, text).unwrap();
    }
    let got = read_campaign(&root).unwrap();
    assert!(got.warnings.is_empty(), "{:?}", got.warnings);
    assert_eq!(got.nominal, expected.nominal);
    for (a, b) in got.tests.iter().zip(&expected.tests) {
        assert_eq!(
            (&a.kind, &a.channels, &a.data),
            (&b.kind, &b.channels, &b.data)
        );
    }
}

#[test]
fn general_campaign_writes_and_reads_back() {
    let (dir, root) = write(&base());
    let original = read_campaign(&root).unwrap();
    // Written elsewhere: the manifest is named relative to the new folder.
    let out = dir.path().join("elsewhere/deeper/copy");
    write_campaign(&original, &out).unwrap();
    let text = std::fs::read_to_string(out.join("campaign.toml")).unwrap();
    assert!(
        text.contains("manifest = \"../../../model/model.toml\""),
        "{text}"
    );
    let back = read_campaign(&out).unwrap();
    assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    assert_eq!(back.nominal, original.nominal);
    for (a, b) in back.tests.iter().zip(&original.tests) {
        assert_eq!(
            (&a.kind, &a.channels, &a.data),
            (&b.kind, &b.channels, &b.data)
        );
    }
}
