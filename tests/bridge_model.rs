//! The 946-DOF steel pedestrian bridge of `../shared/data/real/bridge-fe` through the
//! `.mat` model manifest `experiments/models/bridge-fe.toml`: sizes, symmetry, M positive
//! definite, SMU's K0, and the lowest natural frequencies against an independent dense
//! solve (faer). Skips with a message when the shared data are absent.

use frfbayes::modal::Modes;
#[path = "oracle/condense.rs"]
mod condense_oracle;
use condense_oracle::condense;
use frfbayes::model::mat::MatData;
use frfbayes::model::{shared_root, ModelManifest, StructuralModel};
use nalgebra::DMatrix;
use std::path::{Path, PathBuf};

const GROUPS: [&str; 17] = [
    "K_Frame", "K_Truss", "K_Conc1", "K_Conc2", "K_Conc3", "K_Conc4", "K_Conc5", "K_Conc6",
    "K_Conc7", "K_Conc8", "K_Conc9", "K_Conc10", "K_Conc11", "K_y1", "K_z1", "K_y2", "K_z2",
];

fn bridge_mat() -> Option<PathBuf> {
    let p = shared_root().join("data/real/bridge-fe/SteelPedestrianBridgeExp.mat");
    if p.is_file() {
        Some(p)
    } else {
        println!(
            "skipped: {} not found (no ../shared beside the repository and no \
             FRFBAYES_SHARED_DIR)",
            p.display()
        );
        None
    }
}

fn load() -> StructuralModel {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/models/bridge-fe.toml");
    ModelManifest::load(&manifest).unwrap()
}

/// Eigenvalues of the pencil `(A, B)` (B positive definite) by faer: `L^-1 A L^-T` with
/// `B = L L^T`, then the self-adjoint eigenvalues, ascending.
fn faer_eigenvalues(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Vec<f64> {
    use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
    let n = a.nrows();
    let bf = faer::Mat::from_fn(n, n, |i, j| b[(i, j)]);
    let l = bf.llt(faer::Side::Lower).unwrap().L().to_owned();
    let mut x = faer::Mat::from_fn(n, n, |i, j| a[(i, j)]);
    solve_lower_triangular_in_place(l.as_ref(), x.as_mut(), faer::Par::Seq);
    let mut at = x.transpose().to_owned();
    solve_lower_triangular_in_place(l.as_ref(), at.as_mut(), faer::Par::Seq);
    let sym = faer::Mat::from_fn(n, n, |i, j| 0.5 * (at[(i, j)] + at[(j, i)]));
    let mut ev = sym.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    ev.sort_by(f64::total_cmp);
    ev
}

#[test]
fn bridge_loads_and_its_lowest_frequencies_match_a_dense_solve() {
    let Some(mat_path) = bridge_mat() else {
        return;
    };
    let model = load();
    assert_eq!(model.n_dof(), 946);
    assert_eq!(model.n_alpha(), 17);
    assert_eq!(model.n_beta(), 0);
    assert_eq!(model.measured_dofs().len(), 58);
    let names: Vec<&str> = model
        .alpha_parameters()
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(names[..3], ["Frame", "Truss", "Conc1"]);
    let (k, m) = (model.stiffness(&model.alpha_zero()), model.mass(&[]));
    let asym = |a: &DMatrix<f64>| (a - a.transpose()).amax() / a.amax();
    assert!(
        asym(&k) < 1e-12 && asym(&m) < 1e-12,
        "{} {}",
        asym(&k),
        asym(&m)
    );
    // M is diagonal (lumped) with 474 massless DOFs: positive definite on the other 472.
    let c = condense(&k, &m).unwrap();
    println!(
        "M: {} DOFs with mass, {} massless",
        c.kept.len(),
        c.massless.len()
    );
    assert_eq!(m.iter().filter(|x| **x != 0.0).count(), c.kept.len());
    assert!(
        c.m.clone().cholesky().is_some(),
        "M is not positive definite on its massed DOFs"
    );

    // SMU's K0 (LoadStructure.m) is the sum of the 17 groups; compare with `K_whole`.
    let mat = MatData::open(&mat_path).unwrap();
    let dense = |name: &str| {
        let a = mat.real(name).unwrap();
        DMatrix::from_column_slice(a.rows, a.cols, &a.data)
    };
    let sum = GROUPS
        .iter()
        .fold(DMatrix::zeros(946, 946), |s, g| s + dense(g));
    assert_eq!(
        (&k - &sum).amax(),
        0.0,
        "the manifest's K0 is not the sum of the groups"
    );
    let whole = dense("K_whole");
    let diff = &whole - &sum;
    println!(
        "K_whole - sum of the 17 groups: max |diff| {:.4e} ({:.3e} of max |K_whole|), {} of {} \
         entries differ",
        diff.amax(),
        diff.amax() / whole.amax(),
        diff.iter().filter(|d| **d != 0.0).count(),
        whole.iter().filter(|d| **d != 0.0).count()
    );
    // Equal up to the rounding of a different summation order.
    assert!(diff.amax() < 1e-12 * whole.amax());

    // The lowest natural frequencies: the condensed pencil's dense solve against faer's
    // eigenvalues of the full pencil through K^-1 M (mu = 1 / lambda; 0 for massless DOFs).
    let iota = nalgebra::DVector::from_element(c.kept.len(), 1.0);
    let modes = Modes::solve(&c.k, &c.m, &iota, Some(10)).unwrap();
    let mu = faer_eigenvalues(&m, &k);
    for (i, w) in modes.omega_rad_s.iter().enumerate() {
        let lambda = 1.0 / mu[mu.len() - 1 - i];
        let rel = (w * w - lambda).abs() / lambda;
        println!(
            "mode {}: {:.4} Hz, relative eigenvalue difference {rel:.2e}",
            i + 1,
            w / std::f64::consts::TAU
        );
        assert!(rel < 1e-9, "mode {}: {} vs {lambda}", i + 1, w * w);
    }
    let cw = condense(&whole, &m).unwrap();
    let whole_modes = Modes::solve(&cw.k, &cw.m, &iota, Some(5)).unwrap();
    let hz: Vec<String> = whole_modes
        .omega_rad_s
        .iter()
        .map(|w| format!("{:.4}", w / std::f64::consts::TAU))
        .collect();
    println!("with K_whole as K0 the lowest 5 are {} Hz", hz.join(", "));
    let exp = MatData::open(&mat_path.with_file_name("ExpModeInfo_FEM.mat")).unwrap();
    let lambda_exp = exp.vector("lambdaExp", Some(5)).unwrap();
    let hz: Vec<String> = lambda_exp
        .iter()
        .map(|l| format!("{:.4}", l.sqrt() / std::f64::consts::TAU))
        .collect();
    println!("measured: {} Hz", hz.join(", "));
}
