use super::*;
use crate::frf::direct::receptance_matrix;
use crate::uff::{
    write_uff, Abscissa, Axis, Encoding, Function58, FunctionType, NodeDof, Ordinate, Precision,
};
use nalgebra::DMatrix;

const G: f64 = crate::uff::units::STANDARD_GRAVITY_M_S2;

/// Accelerance `A_rj` of the fixture frame (1.5, 2 kg; 100, 200 N/m; C = 0.002 K + 0.01 M).
fn accelerance(r: usize, j: usize, freq_hz: &[f64]) -> Vec<Complex64> {
    let m = DMatrix::from_row_slice(2, 2, &[1.5, 0.0, 0.0, 2.0]);
    let k = DMatrix::from_row_slice(2, 2, &[300.0, -200.0, -200.0, 200.0]);
    let c = &k * 0.002 + &m * 0.01;
    freq_hz
        .iter()
        .map(|f| {
            let w = 2.0 * std::f64::consts::PI * f;
            receptance_matrix(&m, &k, &c, w).unwrap()[(r, j)] * (-w * w)
        })
        .collect()
}

fn function(
    resp: (i64, i32),
    refr: (i64, i32),
    ty: FunctionType,
    y: Vec<Complex64>,
    units: &str,
) -> Function58 {
    let axis = |data_type, units: &str| Axis {
        data_type,
        units: units.into(),
        label: "NONE".into(),
        ..Default::default()
    };
    Function58 {
        id_lines: [
            "t".into(),
            "NONE".into(),
            "NONE".into(),
            "NONE".into(),
            "NONE".into(),
        ],
        function_type: ty,
        function_id: 0,
        version: 0,
        load_case: 0,
        response: NodeDof {
            entity: "NONE".into(),
            node: resp.0,
            direction: resp.1,
        },
        reference: NodeDof {
            entity: "NONE".into(),
            node: refr.0,
            direction: refr.1,
        },
        abscissa: Abscissa::Even {
            min: 0.0,
            step: 0.002,
        },
        z_axis_value: 0.0,
        axes: [
            axis(18, "Hz"),
            axis(12, units),
            axis(13, if ty == FunctionType::Frf { "N" } else { "NONE" }),
            axis(0, "NONE"),
        ],
        ordinate: Ordinate::Complex(y),
        precision: Precision::Double,
    }
}

fn setup(manifest: &str, funcs: &[Function58]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("model")).unwrap();
    std::fs::write(
        dir.path().join("model/campaign.toml"),
        "title = \"t\"\n[nominal]\nstructure = \"shear_frame\"\nfloor_mass_kg = [1.5, 2.0]\nstory_stiffness_n_per_m = [100.0, 200.0]\n",
    )
    .unwrap();
    write_uff(
        &dir.path().join("h.uff"),
        funcs,
        Encoding::Binary {
            little_endian: true,
        },
    )
    .unwrap();
    let m = dir.path().join("frfs.toml");
    std::fs::write(&m, manifest).unwrap();
    (dir, m)
}

const MANIFEST: &str = r#"
model = "model"
n_averages = 8
[[test]]
name = "hammer-1"
file = "h.uff"
excitation = "force"
excited_dof = 1
exp_window_tau_s = 10.0
[[test.channel]]
dof = 1
node = "1+X"
[[test.channel]]
dof = 2
node = "2+X"
"#;

/// FRFs in g/N, one response and the reference recorded in -X: the TestFrf holds the
/// model's accelerance in SI, the coherence of the file, bands at both modes.
#[test]
fn uff_frfs_map_to_model_dofs_with_units_and_signs() {
    let f: Vec<f64> = (0..2500).map(|k| 0.002 * k as f64).collect();
    let a11: Vec<Complex64> = accelerance(0, 0, &f);
    let a21: Vec<Complex64> = accelerance(1, 0, &f);
    let in_g = |v: &[Complex64], s: f64| v.iter().map(|h| h * s / G).collect::<Vec<_>>();
    let coh: Vec<Complex64> = (0..2500)
        .map(|k| Complex64::new(0.9 + (1e-4 * k as f64) % 0.09, 0.0))
        .collect();
    let funcs = [
        // reference recorded at 1-X: both FRFs flip sign; response 2 at 2-X flips back
        function((1, 1), (1, -1), FunctionType::Frf, in_g(&a11, -1.0), "g"),
        function((2, -1), (1, -1), FunctionType::Frf, in_g(&a21, 1.0), "g"),
        function(
            (2, -1),
            (1, -1),
            FunctionType::Coherence,
            coh.clone(),
            "NONE",
        ),
        function((3, 2), (1, -1), FunctionType::Frf, in_g(&a21, 1.0), "g"),
    ];
    let (_dir, path) = setup(MANIFEST, &funcs);
    let opts = EstimateOptions {
        freq_max_hz: Some(4.0),
        ..Default::default()
    };
    let m = read_measured(&path, &opts).unwrap();
    assert_eq!(m.nominal.n_floors(), 2);
    assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
    assert!(m.warnings[0].contains("3+Y"), "{:?}", m.warnings);
    let t = &m.tests[0];
    let nk = t.freq_hz.len();
    assert!(nk > 1900 && nk < 2500 && t.freq_hz[nk - 1] <= 4.0, "{nk}");
    assert_eq!(
        t.input,
        InputKind::Force {
            floor: 1,
            channel: "force".into()
        }
    );
    assert_eq!((t.n_averages, t.exp_window_tau_s), (8, Some(10.0)));
    for (r, truth) in t.responses.iter().zip([&a11, &a21]) {
        assert_eq!(r.kind, FrfKind::Accelerance);
        for (k, (h, t)) in r.h1.iter().zip(truth.iter()).enumerate().skip(1) {
            assert!((h - t).norm() <= 1e-12 * t.norm(), "{k}");
        }
    }
    assert_eq!(t.responses[1].coherence[7], coh[7].re);
    assert_eq!(t.responses[0].coherence[7], 1.0 / (1.0 + 2.0 * 8.0 * 1e-4));
    assert_eq!(t.bands.len(), 2);
    assert!(!t.selected.is_empty());
}

#[test]
fn manifest_errors_say_what_to_write() {
    let f: Vec<f64> = (0..1501).map(|k| 0.002 * k as f64).collect();
    let coh = vec![Complex64::new(0.95, 0.0); 1501];
    let funcs = [
        function(
            (1, 1),
            (1, 1),
            FunctionType::Frf,
            accelerance(0, 0, &f),
            "m/s^2",
        ),
        function((1, 1), (1, 1), FunctionType::Coherence, coh, "NONE"),
        function(
            (2, 1),
            (1, 1),
            FunctionType::Frf,
            accelerance(1, 0, &f),
            "furlong",
        ),
    ];
    let err = |m: &str| {
        let (_d, p) = setup(m, &funcs);
        read_measured(&p, &EstimateOptions::default())
            .unwrap_err()
            .to_string()
    };
    let e = err(&MANIFEST
        .replace("n_averages = 8\n", "")
        .replace("node = \"2+X\"", "node = \"2+X\"\nunit = \"m/s^2/N\""));
    assert!(
        e.contains("frfs.toml") && e.contains("hammer-1") && e.contains("add n_averages"),
        "{e}"
    );
    let e = err(MANIFEST);
    assert!(e.contains("\"furlong\"") && e.contains("give unit"), "{e}");
    let e = err(&MANIFEST.replace("node = \"2+X\"", "node = \"2+Y\""));
    assert!(e.contains("0 FRFs for response 2+Y"), "{e}");
    let e = err(&MANIFEST.replace("dof = 2\n", "dof = 3\n"));
    assert!(e.contains("dof = 3") && e.contains("1..=2"), "{e}");
    let e = err(&MANIFEST.replace("excited_dof = 1\n", ""));
    assert!(e.contains("needs excited_dof"), "{e}");
    let e = err(&MANIFEST.replace(
        "node = \"2+X\"",
        "node = \"2+X\"\nunit = \"m/s^2/N\"\nsurprise = 1",
    ));
    assert!(e.contains("surprise"), "{e}");
    let e = err(&MANIFEST.replace("model = \"model\"", "model = \"nowhere\""));
    assert!(e.contains("model = \"nowhere\""), "{e}");
}

/// The CSV table of `frfbayes frf` read back as measured FRFs.
#[test]
fn csv_table_in() {
    let f: Vec<f64> = (0..1501).map(|k| 0.002 * k as f64).collect();
    let a = accelerance(1, 1, &f);
    let mut text = String::from("freq_hz,acc2_re,acc2_im,acc2_coherence\n");
    for (k, h) in a.iter().enumerate() {
        text.push_str(&format!("{:e},{:e},{:e},0.99\n", f[k], h.re, h.im));
    }
    let manifest = "model = \"model\"\nn_averages = 4\n[[test]]\nname = \"h2\"\nfile = \"f.csv\"\nexcitation = \"force\"\nexcited_dof = 2\n[[test.channel]]\ndof = 2\nname = \"acc2\"\nquantity = \"acceleration\"\n";
    let (dir, p) = setup(manifest, &[]);
    std::fs::write(dir.path().join("f.csv"), text).unwrap();
    let m = read_measured(&p, &EstimateOptions::default()).unwrap();
    let r = &m.tests[0].responses[0];
    assert_eq!(
        (r.channel.floor, r.kind, r.h1[50]),
        (2, FrfKind::Accelerance, a[50])
    );
    assert_eq!(r.coherence[3], 0.99);
}
