use super::*;
use crate::io::NominalModel;

fn channel(name: &str, quantity: Quantity, floor: usize) -> Channel {
    Channel {
        name: name.into(),
        quantity,
        floor,
        unit: quantity.unit().into(),
    }
}

/// A damped oscillation "response" to a pulse: enough for the error paths.
fn record(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut f = vec![0.0; n];
    f[100] = 10.0;
    f[101] = 5.0;
    let y = (0..n)
        .map(|i| {
            let t = i.saturating_sub(100) as f64 * 0.01;
            if i < 100 {
                0.0
            } else {
                (-0.5 * t).exp() * (6.0 * t).sin()
            }
        })
        .collect();
    (f, y)
}

fn hammer(channels: Vec<Channel>, data: Vec<Vec<f64>>) -> Test {
    Test {
        name: "h".into(),
        kind: TestKind::Hammer { excited_floor: 1 },
        sample_rate_hz: 100.0,
        channels,
        data,
    }
}

#[test]
fn estimate_test_errors_name_the_file_and_the_problem() {
    let (f, y) = record(4000);
    let no_force = hammer(
        vec![channel("acc1", Quantity::Acceleration, 1)],
        vec![y.clone()],
    );
    let e = estimate_test(&no_force, &EstimateOptions::default()).unwrap_err();
    assert!(e.to_string().contains("tests/h/data.csv") && e.to_string().contains("force"));
    let no_resp = hammer(vec![channel("force", Quantity::Force, 1)], vec![f.clone()]);
    assert!(estimate_test(&no_resp, &EstimateOptions::default()).is_err());
    let mut shake = hammer(
        vec![channel("acc1", Quantity::Acceleration, 1)],
        vec![y.clone()],
    );
    shake.kind = TestKind::ShakeTable;
    let e = estimate_test(&shake, &EstimateOptions::default()).unwrap_err();
    assert!(e.to_string().contains("ground_acceleration"));
    let quiet = hammer(
        vec![
            channel("force", Quantity::Force, 1),
            channel("acc1", Quantity::Acceleration, 1),
        ],
        vec![vec![0.0; 4000], y.clone()],
    );
    let e = estimate_test(&quiet, &EstimateOptions::default()).unwrap_err();
    assert!(e.to_string().contains("no impact"));
    let mut bad_rate = quiet.clone();
    bad_rate.sample_rate_hz = 0.0;
    assert!(estimate_test(&bad_rate, &EstimateOptions::default()).is_err());
}

#[test]
fn campaign_defaults_peaks_to_floors_and_prefixes_root() {
    let (f, y) = record(4000);
    let test = hammer(
        vec![
            channel("force", Quantity::Force, 1),
            channel("acc1", Quantity::Acceleration, 1),
            channel("disp1", Quantity::Displacement, 1),
        ],
        vec![f, y.clone(), y],
    );
    let campaign = Campaign {
        root: PathBuf::from("/data/c"),
        title: "t".into(),
        nominal: NominalModel::shear_frame(vec![1.0], vec![1.0]),
        tests: vec![test.clone()],
        warnings: Vec::new(),
    };
    let est = estimate_campaign(&campaign, &EstimateOptions::default()).unwrap();
    assert_eq!(est.len(), 1);
    let e = &est[0];
    assert_eq!(e.bands.len(), 1);
    assert!((e.bands[0].peak_hz - 6.0 / (2.0 * std::f64::consts::PI)).abs() < 0.02);
    assert_eq!(
        e.input,
        InputKind::Force {
            floor: 1,
            channel: "force".into()
        }
    );
    let pairs = e.pairs().unwrap();
    assert_eq!(pairs[0].kind, FrfKind::Accelerance);
    assert_eq!(pairs[1].kind, FrfKind::Receptance);
    assert_eq!(pairs[0].excitation, Excitation::Dof(0));
    let block = e.frf_block().unwrap();
    assert_eq!(block.omega_rad_s.len(), e.selected.len());
    let mags = e.selected_magnitudes();
    assert_eq!(mags.len(), 2 * e.selected.len());
    assert_eq!(mags[0], e.responses[0].h1[e.selected[0]].norm());
    assert_eq!(e.selected_rel_std().len(), mags.len());
    let mut broken = campaign;
    broken.tests[0].data[0] = vec![0.0; 4000];
    let err = estimate_campaign(&broken, &EstimateOptions::default()).unwrap_err();
    assert!(
        err.to_string().starts_with("/data/c/tests/h/data.csv"),
        "{err}"
    );
}
