use super::*;
use crate::error::Error;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

fn frf(n: usize, precision: Precision, even: bool, complex: bool) -> Function58 {
    let x: Vec<f64> = (0..n)
        .map(|k| 0.5 + 0.25 * k as f64 + 1e-3 * (k * k) as f64)
        .collect();
    let ordinate = if complex {
        Ordinate::Complex(
            (0..n)
                .map(|k| Complex64::new(1.0 / (k as f64 + 0.3), -2.5e-7 * k as f64 - 1e-9))
                .collect(),
        )
    } else {
        Ordinate::Real((0..n).map(|k| (k as f64 * 0.7).sin() * 1e3).collect())
    };
    Function58 {
        id_lines: [
            "H1 acc2 / force".into(),
            "hammer-1".into(),
            "NONE".into(),
            "frfbayes".into(),
            "NONE".into(),
        ],
        function_type: FunctionType::Frf,
        function_id: 3,
        version: 0,
        load_case: 0,
        response: NodeDof {
            entity: "acc2".into(),
            node: 2,
            direction: -1,
        },
        reference: NodeDof {
            entity: "force".into(),
            node: 1,
            direction: 1,
        },
        abscissa: if even {
            Abscissa::Even {
                min: 0.0,
                step: 0.0625,
            }
        } else {
            Abscissa::Uneven(x)
        },
        z_axis_value: 0.0,
        axes: [
            Axis {
                data_type: 18,
                label: "Frequency".into(),
                units: "Hz".into(),
                ..Default::default()
            },
            Axis {
                data_type: 12,
                length_exp: 1,
                label: "Acceleration".into(),
                units: "m/s^2".into(),
                ..Default::default()
            },
            Axis {
                data_type: 13,
                force_exp: 1,
                label: "Force".into(),
                units: "N".into(),
                ..Default::default()
            },
            Axis {
                label: "NONE".into(),
                units: "NONE".into(),
                ..Default::default()
            },
        ],
        ordinate,
        precision,
    }
}

fn rel_close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1e-300)
}

fn assert_same(a: &Function58, b: &Function58, tol: f64) {
    assert_eq!(a.id_lines, b.id_lines);
    assert_eq!(
        (a.function_type, a.function_id, a.version, a.load_case),
        (b.function_type, b.function_id, b.version, b.load_case)
    );
    assert_eq!((&a.response, &a.reference), (&b.response, &b.reference));
    assert_eq!(a.axes, b.axes);
    assert_eq!(a.precision, b.precision);
    let (xa, xb) = (a.abscissa_values(), b.abscissa_values());
    assert_eq!(xa.len(), xb.len());
    for (p, q) in xa.iter().zip(&xb) {
        assert!(rel_close(*p, *q, 5e-6), "abscissa {p} vs {q}");
    }
    let (ya, yb) = (a.ordinate.to_complex(), b.ordinate.to_complex());
    for (p, q) in ya.iter().zip(&yb) {
        assert!(
            rel_close(p.re, q.re, tol) && rel_close(p.im, q.im, tol),
            "{p} vs {q}"
        );
    }
}

#[test]
fn every_form_round_trips() {
    let encodings = [
        Encoding::Ascii,
        Encoding::Binary {
            little_endian: true,
        },
        Encoding::Binary {
            little_endian: false,
        },
    ];
    for precision in [Precision::Single, Precision::Double] {
        for even in [true, false] {
            for complex in [true, false] {
                // 13 points: every ASCII layout ends with a partly filled line
                let f = frf(13, precision, even, complex);
                for enc in encodings {
                    let bytes = write_uff_bytes(std::slice::from_ref(&f), enc).unwrap();
                    let back = read_uff_bytes(Path::new("t.uff"), &bytes).unwrap();
                    assert_eq!(back.functions.len(), 1);
                    let (g, loc, e) = &back.functions[0];
                    assert_eq!((*e, loc.line, loc.byte), (enc, 1, 0));
                    // binary double is exact, single rounds to f32, ASCII double keeps 12 digits
                    let tol = match (enc, precision) {
                        (_, Precision::Single) => 1e-5,
                        (Encoding::Ascii, Precision::Double) => 1e-11,
                        (Encoding::Binary { .. }, Precision::Double) => 0.0,
                    };
                    assert_same(&f, g, tol);
                    if matches!(enc, Encoding::Binary { .. }) && precision == Precision::Double {
                        assert_eq!(f.ordinate, g.ordinate, "binary double must be exact");
                        if !even {
                            assert_eq!(f.abscissa, g.abscissa);
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn several_datasets_and_other_datasets_skipped() {
    let a = frf(5, Precision::Double, true, true);
    let mut b = frf(7, Precision::Single, false, false);
    b.function_type = FunctionType::Coherence;
    let prefix = b"    -1\n   164\n         1SI - mks (Newton)  2\n    -1\n";
    let mut bytes = prefix.to_vec();
    bytes.extend(
        write_uff_bytes(
            std::slice::from_ref(&a),
            Encoding::Binary {
                little_endian: true,
            },
        )
        .unwrap(),
    );
    bytes.extend(write_uff_bytes(std::slice::from_ref(&b), Encoding::Ascii).unwrap());
    bytes.extend(b"\n");
    let file = read_uff_bytes(Path::new("t.uff"), &bytes).unwrap();
    assert_eq!(file.skipped.len(), 1);
    assert_eq!(file.skipped[0].0, "164");
    assert_eq!(file.functions.len(), 2);
    assert_eq!(file.functions[0].0.ordinate, a.ordinate);
    assert_eq!(file.functions[1].0.function_type, FunctionType::Coherence);
    assert_eq!(
        file.functions[1].1.byte,
        prefix.len()
            + write_uff_bytes(
                &[a],
                Encoding::Binary {
                    little_endian: true
                }
            )
            .unwrap()
            .len()
    );
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/uff")
        .join(name)
}

/// An analyser's FRF export (pyuff's `non_ascii_header.uff`): complex single precision,
/// even, units `(1/N)*(m/s²)` in record 9 alone, lines padded and not.
#[test]
fn analyser_frf_with_non_ascii_units() {
    let file = read_uff(&fixture("non_ascii_header.uff")).unwrap();
    assert_eq!(file.functions.len(), 1);
    let f = &file.functions[0].0;
    assert_eq!(f.function_type, FunctionType::Frf);
    assert_eq!(f.precision, Precision::Single);
    assert_eq!(f.id_lines[4], "H1 : #  2 / #  1");
    assert_eq!(
        f.abscissa,
        Abscissa::Even {
            min: 0.0,
            step: 1.95313e-1
        }
    );
    let y = f.ordinate.to_complex();
    assert_eq!(y.len(), 6);
    assert_eq!(y[0], Complex64::new(4.07994e-1, 0.0));
    assert_eq!(y[5], Complex64::new(3.75037, 2.93363));
    assert_eq!(f.ordinate_axis().units, "(1/N)*(m/s²)");
    let (num, den) =
        units::frf_units(&f.ordinate_axis().units, &f.denominator_axis().units).unwrap();
    assert_eq!(
        (num.dimension, den.dimension),
        (units::Dimension::Acceleration, units::Dimension::Force)
    );
}

/// HBM catman's time history: the last data line holds one value, every line padded.
#[test]
fn catman_time_history_last_line_partly_filled() {
    let file = read_uff(&fixture("time-history-not-all-columns-filled.uff")).unwrap();
    let f = &file.functions[0].0;
    assert_eq!(f.function_type, FunctionType::TimeResponse);
    assert_eq!(f.len(), 13);
    assert_eq!(
        f.ordinate,
        Ordinate::Real(vec![
            -3.81956, -3.56616, -2.98987, -2.62207, -3.22879, -3.63712, -3.90210, -3.69214,
            -3.42426, -3.48508, -4.03966, -3.46046, -5.84096,
        ])
    );
    assert_eq!(
        f.abscissa,
        Abscissa::Even {
            min: 0.0,
            step: 5e-5
        }
    );
    assert_eq!(f.id_lines[1], "UFF58 file created by HBM catman");
}

/// A file whose header announces 2,508,876 points but holds 42 values: a clear error,
/// no attempt to allocate for the announced size.
#[test]
fn announced_points_beyond_the_file_is_an_error() {
    let err = read_uff(&fixture("dataset_milestone_in_header.uff")).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, Error::Cell { line: 9, .. }), "{msg}");
    assert!(
        msg.contains("dataset_milestone_in_header.uff") && msg.contains("2508876"),
        "{msg}"
    );
}

#[test]
fn errors_name_the_line_or_byte() {
    let f = frf(4, Precision::Double, true, true);
    let good =
        String::from_utf8(write_uff_bytes(std::slice::from_ref(&f), Encoding::Ascii).unwrap())
            .unwrap();
    let case = |text: String| read_uff_bytes(Path::new("bad.uff"), text.as_bytes()).unwrap_err();
    // a bad number in record 12 (line 14, third field)
    let lines: Vec<&str> = good.lines().collect();
    let mut bad = lines.clone();
    let row = bad[13].replacen("E", "X", 3);
    bad[13] = &row;
    let err = case(bad.join("\n"));
    assert!(matches!(err, Error::Cell { line: 14, .. }), "{err}");
    assert!(err.to_string().starts_with("bad.uff:14:"), "{err}");
    // a bad direction in record 6
    let mut bad = lines.clone();
    let row = format!("{}  9{}", &lines[7][..51], &lines[7][54..]);
    bad[7] = &row;
    let err = case(bad.join("\n")).to_string();
    assert!(
        err.contains("bad.uff:8:") && err.contains("response direction 9"),
        "{err}"
    );
    // an unknown data type in record 7
    let mut bad = lines.clone();
    let row = format!("         3{}", &lines[8][10..]);
    bad[8] = &row;
    let err = case(bad.join("\n")).to_string();
    assert!(
        err.contains("bad.uff:9:") && err.contains("ordinate data type 3"),
        "{err}"
    );
    // one value too few
    let mut bad = lines.clone();
    let row = lines[14][..60].to_string();
    bad[14] = &row;
    let err = case(bad.join("\n")).to_string();
    assert!(
        err.contains("record 12 holds 7 values, record 7 announces 8"),
        "{err}"
    );
    // binary: DEC floats, and a header byte count that matches nothing
    let bin = write_uff_bytes(
        std::slice::from_ref(&f),
        Encoding::Binary {
            little_endian: true,
        },
    )
    .unwrap();
    let text = String::from_utf8_lossy(&bin).into_owned();
    let dec = text.replacen("     1     2          11", "     1     1          11", 1);
    let err = read_uff_bytes(Path::new("b.uff"), dec.as_bytes())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("b.uff:2:") && err.contains("floating-point format 1"),
        "{err}"
    );
    let mut cut = bin.clone();
    cut.truncate(bin.len() - 12);
    let err = read_uff_bytes(Path::new("b.uff"), &cut)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("b.uff: byte offset") && err.contains("only"),
        "{err}"
    );
}

/// pyuff writes `num_pts x 8` as the byte count of complex data (half the true size);
/// the reader takes the size from record 7 and checks it against the end marker.
#[test]
fn binary_byte_count_of_pyuff_is_tolerated() {
    let f = frf(6, Precision::Double, true, true);
    let bin = write_uff_bytes(
        std::slice::from_ref(&f),
        Encoding::Binary {
            little_endian: true,
        },
    )
    .unwrap();
    let text = String::from_utf8_lossy(&bin[..120]).into_owned();
    assert!(text.contains("          96"), "{text}");
    let mut wrong = bin.clone();
    let at = text.find("          96").unwrap();
    wrong[at..at + 12].copy_from_slice(b"          48");
    let back = read_uff_bytes(Path::new("p.uff"), &wrong).unwrap();
    assert_eq!(back.functions[0].0.ordinate, f.ordinate);
}

/// No truncation or corruption of valid files panics, and every truncation that cuts
/// into a dataset is an error.
#[test]
fn truncations_and_corruptions_never_panic() {
    let funcs = [
        frf(9, Precision::Double, true, true),
        frf(5, Precision::Single, false, false),
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for enc in [
        Encoding::Ascii,
        Encoding::Binary {
            little_endian: true,
        },
        Encoding::Binary {
            little_endian: false,
        },
    ] {
        let bytes = write_uff_bytes(&funcs, enc).unwrap();
        let first_end = write_uff_bytes(&funcs[..1], enc).unwrap().len();
        for n in 0..bytes.len() {
            let r = read_uff_bytes(Path::new("t.uff"), &bytes[..n]);
            // complete: nothing but blanks after the end of a dataset
            let kept = bytes[..n].trim_ascii_end().len();
            let complete = kept == 0 || kept == first_end - 1 || kept == bytes.len() - 1;
            assert_eq!(r.is_ok(), complete, "{enc:?} cut at {n}: {r:?}");
        }
        for _ in 0..3000 {
            let mut b = bytes.clone();
            for _ in 0..rng.random_range(1..4) {
                let k = rng.random_range(0..b.len());
                b[k] = rng.random();
            }
            let _ = read_uff_bytes(Path::new("t.uff"), &b);
        }
    }
}

#[test]
fn fortran_numbers() {
    assert_eq!(write::fortran_e(-123.456, 13, 5), " -1.23456E+02");
    assert_eq!(write::fortran_e(0.0, 20, 11), "   0.00000000000E+00");
    assert_eq!(write::fortran_e(1e-120, 13, 5), " 1.00000E-120");
    let mut out = Vec::new();
    let text = b" 1.0D+00-2.5E-03  3.0E+00 1.47553E-102";
    read_numbers(text, &mut out).unwrap();
    assert_eq!(out, vec![1.0, -2.5e-3, 3.0, 1.47553e-102]);
    assert!(read_numbers(b" 1.47553-102", &mut out).is_err());
    assert!(read_numbers(b" NaN", &mut out).is_err());
}

fn read_numbers(text: &[u8], out: &mut Vec<f64>) -> crate::Result<()> {
    read::parse_numbers(text, |c, t| Error::Usage(format!("column {c}: {t}")), out)
}
