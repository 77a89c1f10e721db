use super::decode::{MI_INT32, MI_INT8, MI_MATRIX, MI_UINT32};
use super::*;
use std::io::Write;

#[test]
fn reads_a_double_matrix_column_major() {
    let bytes = write_test_mat(&[("a", 6, 2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])]);
    let m = MatData::from_bytes(Path::new("t.mat"), &bytes).unwrap();
    let a = m.real("a").unwrap();
    assert_eq!((a.rows, a.cols), (2, 3));
    assert_eq!(a.get(1, 2), 6.0);
    assert_eq!(a.column(1), &[3.0, 4.0]);
    let err = m.vector("a", None).unwrap_err().to_string();
    assert!(err.contains("`a` is 2 x 3"), "{err}");
    let err = m.real("b").unwrap_err().to_string();
    assert!(
        err.contains("t.mat")
            && err.contains("no numeric variable `b`")
            && err.contains("`b` (numeric variables: a)"),
        "{err}"
    );
}

#[test]
fn every_integer_class_decodes() {
    let signed = [-3.0, 0.0, 7.0, 100.0];
    let unsigned = [3.0, 0.0, 7.0, 200.0];
    let mut vars: Vec<(String, u32, Vec<f64>)> = Vec::new();
    for class in 7..=15u32 {
        let v = if class == 7 || class % 2 == 0 {
            signed
        } else {
            unsigned
        };
        vars.push((format!("v{class}"), class, v.to_vec()));
    }
    let spec: Vec<(&str, u32, usize, usize, &[f64])> = vars
        .iter()
        .map(|(n, c, v)| (n.as_str(), *c, 2, 2, v.as_slice()))
        .collect();
    let m = MatData::from_bytes(Path::new("ints.mat"), &write_test_mat(&spec)).unwrap();
    for (name, class, v) in &vars {
        assert_eq!(&m.real(name).unwrap().data, v, "class {class}");
    }
    let classes: Vec<&str> = m.variables().iter().map(|v| v.class).collect();
    assert_eq!(
        classes,
        ["single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"]
    );
}

/// An `miMATRIX` element of a sparse real `rows x cols` matrix given column by column.
fn sparse_element(
    name: &str,
    rows: usize,
    cols: usize,
    entries: &[(usize, usize, f64)],
) -> Vec<u8> {
    let mut b = Vec::new();
    let mut sub = |ty: u32, data: Vec<u8>| {
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&(data.len() as u32).to_le_bytes());
        b.extend_from_slice(&data);
        while !b.len().is_multiple_of(8) {
            b.push(0);
        }
    };
    let le = |v: &[i32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    sub(MI_UINT32, le(&[5, entries.len() as i32]));
    sub(MI_INT32, le(&[rows as i32, cols as i32]));
    sub(MI_INT8, name.as_bytes().to_vec());
    let ir: Vec<i32> = entries.iter().map(|e| e.0 as i32).collect();
    let jc: Vec<i32> = (0..=cols)
        .map(|c| entries.iter().filter(|e| e.1 < c).count() as i32)
        .collect();
    sub(MI_INT32, le(&ir));
    sub(MI_INT32, le(&jc));
    sub(9, entries.iter().flat_map(|e| e.2.to_le_bytes()).collect());
    let mut out = MI_MATRIX.to_le_bytes().to_vec();
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(&b);
    out
}

#[test]
fn compressed_and_sparse_variables_decode() {
    let mut bytes = write_test_mat(&[("d", 6, 1, 2, &[1.5, -2.0])]);
    let element = sparse_element("S", 3, 2, &[(0, 0, 4.0), (2, 0, -1.0), (1, 1, 2.5)]);
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(&element).unwrap();
    let z = z.finish().unwrap();
    bytes.extend_from_slice(&15u32.to_le_bytes());
    bytes.extend_from_slice(&(z.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&z);
    let m = MatData::from_bytes(Path::new("s.mat"), &bytes).unwrap();
    assert_eq!(m.names(), ["d", "S"]);
    let s = m.real("S").unwrap();
    assert_eq!(s.data, [4.0, 0.0, -1.0, 0.0, 2.5, 0.0]);
    let t = m.real_triplets("S").unwrap();
    assert_eq!(t.entries, [(0, 0, 4.0), (2, 0, -1.0), (1, 1, 2.5)]);
    let t = m.real_triplets("d").unwrap();
    assert_eq!(t.entries, [(0, 0, 1.5), (0, 1, -2.0)]);
}

#[test]
fn malformed_files_give_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let good = write_test_mat(&[("v", 6, 3, 1, &[1.0, 2.0, 3.0])]);
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("short.mat", b"MATLAB 5.0".to_vec()),
        ("truncated.mat", good[..good.len() - 12].to_vec()),
        ("badendian.mat", {
            let mut b = good.clone();
            b[126] = b'X';
            b
        }),
    ];
    for (name, bytes) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, &bytes).unwrap();
        let err = MatData::open(&p).unwrap_err().to_string();
        assert!(err.contains(name), "{name}: {err}");
    }
    // A NaN in the data is reported with its position.
    let nan = write_test_mat(&[("v", 6, 3, 1, &[1.0, f64::NAN, 3.0])]);
    let m = MatData::from_bytes(Path::new("n.mat"), &nan).unwrap();
    let err = m.vector("v", Some(3)).unwrap_err().to_string();
    assert!(err.contains("`v`: element 2"), "{err}");
    let err = MatData::open(&dir.path().join("missing.mat"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.mat"), "{err}");
}

/// Oracle: on every `.mat` file of `../shared/data/real` that the `matfile` crate can
/// parse, this decoder gives the same variables and the same values.
#[test]
fn agrees_with_the_matfile_crate_on_the_shared_files() {
    let Some(real) = crate::model::shared_dir("data/real") else {
        return;
    };
    let mut compared = 0;
    for dataset in std::fs::read_dir(&real).unwrap() {
        let dataset = dataset.unwrap().path();
        if !dataset.is_dir() {
            continue;
        }
        for file in std::fs::read_dir(dataset).unwrap() {
            let path = file.unwrap().path();
            if path.extension().is_none_or(|e| e != "mat") {
                continue;
            }
            let bytes = std::fs::read(&path).unwrap();
            let Ok(reference) = matfile::MatFile::parse(&bytes[..]) else {
                continue;
            };
            let ours = MatData::from_bytes(&path, &bytes).unwrap();
            for a in reference.arrays() {
                let (re, im) = reference_values(a.data());
                let got = ours.dense(a.name()).unwrap();
                assert_eq!(&[got.0, got.1], a.size().as_slice(), "{}", a.name());
                assert_eq!(got.2, re, "{} in {}", a.name(), path.display());
                assert_eq!(got.3, im, "{} in {}", a.name(), path.display());
                compared += 1;
            }
        }
    }
    println!("{compared} variables agree with matfile");
    assert!(compared > 0);
}

fn reference_values(d: &matfile::NumericData) -> (Vec<f64>, Option<Vec<f64>>) {
    use matfile::NumericData as N;
    fn c<T: Copy + Into<f64>>(re: &[T], im: &Option<Vec<T>>) -> (Vec<f64>, Option<Vec<f64>>) {
        let f = |v: &[T]| v.iter().map(|&x| x.into()).collect();
        (f(re), im.as_deref().map(f))
    }
    match d {
        N::Int8 { real, imag } => c(real, imag),
        N::UInt8 { real, imag } => c(real, imag),
        N::Int16 { real, imag } => c(real, imag),
        N::UInt16 { real, imag } => c(real, imag),
        N::Int32 { real, imag } => c(real, imag),
        N::UInt32 { real, imag } => c(real, imag),
        N::Single { real, imag } => c(real, imag),
        N::Double { real, imag } => c(real, imag),
        N::Int64 { .. } | N::UInt64 { .. } => panic!("no 64-bit integers in the shared files"),
    }
}
