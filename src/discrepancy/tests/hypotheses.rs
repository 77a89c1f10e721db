//! Each hypothesis against the simulator's system or its analytic factor, and what
//! every hypothesis must offer (locations, priors, the nominal model nested).

use super::*;

/// Prediction of `hypothesis` at `loc` with physical `effect` against the simulator's
/// system with `sim_effect` applied, solved independently at every `s`.
fn check_structural(name: &str, loc: Location, effect: &[f64], sim_effect: &dyn SystemEffect) {
    let data = synthetic();
    let h: Arc<dyn Hypothesis> = Arc::from(hypothesis_by_name(name).unwrap());
    let model = ExtendedModel::new(data.clone(), Some((h, loc))).unwrap();
    let pred = model.predict(&base(), effect).unwrap();
    let sys = simulator_system(&[sim_effect]);
    let err = max_rel_err(&model, &pred, |seg, ch, s| {
        oracle(&sys, seg, ch.channel.floor, power(ch.kind), s)
    });
    assert!(err < 1e-9, "{name}: {err:e}");
    // ... and it differs from the nominal model.
    let nominal = ExtendedModel::new(data, None)
        .unwrap()
        .predict(&base(), &[])
        .unwrap();
    let diff = pred
        .iter()
        .zip(&nominal)
        .map(|(a, b)| (a - b).norm() / b.norm())
        .fold(0.0, f64::max);
    assert!(diff > 1e-3, "{name} has no effect: {diff}");
}

#[test]
fn structural_hypotheses_match_the_simulators_systems() {
    // m_b 5 kg, k_b 8900 N/m, c_b 10 N s/m as (m_b, f_b, zeta_b).
    let f_b = (8900.0f64 / 5.0).sqrt() / (2.0 * std::f64::consts::PI);
    let zeta_b = 10.0 / (2.0 * (8900.0f64 * 5.0).sqrt());
    check_structural(
        "base_flexibility",
        Location::Whole,
        &[5.0, f_b, zeta_b],
        &BaseFlexibility {
            mass_kg: 5.0,
            stiffness_n_per_m: 8900.0,
            damping_n_s_per_m: 10.0,
        },
    );
    check_structural(
        "nonproportional_damping",
        Location::Story(3),
        &[4.0],
        &Dashpot::story(3, 4.0),
    );
    let (m, f, z) = (0.4, 3.5, 0.02);
    let k = m * (2.0 * std::f64::consts::PI * f).powi(2);
    check_structural(
        "secondary_oscillator",
        Location::Floor(2),
        &[m, f, z],
        &Oscillator {
            floor: 2,
            mass_kg: m,
            stiffness_n_per_m: k,
            damping_ratio: z,
        },
    );
}

#[test]
fn stiffness_nonlinearity_is_the_equivalent_linear_spring_per_segment() {
    let data = synthetic();
    let h: Arc<dyn Hypothesis> = Arc::from(hypothesis_by_name("stiffness_nonlinearity").unwrap());
    let story = 2;
    let k3 = 2.5e8;
    let model = ExtendedModel::new(data.clone(), Some((h, Location::Story(story)))).unwrap();
    let pred = model.predict(&base(), &[k3]).unwrap();
    // Oracle: the simulator's frame (damping from the linear frame's modes) with the
    // story spring raised by k3 times each segment's equivalent-linearisation weight.
    let err = max_rel_err(&model, &pred, |seg, ch, s| {
        let dk = k3 * seg.story_drift_lin_sq_m2[story - 1].unwrap();
        let mut sys = simulator_system(&[]);
        let kk = &mut sys.stiffness_n_per_m;
        kk[(story - 1, story - 1)] += dk;
        kk[(story - 2, story - 2)] += dk;
        kk[(story - 1, story - 2)] -= dk;
        kk[(story - 2, story - 1)] -= dk;
        oracle(&sys, seg, ch.channel.floor, power(ch.kind), s)
    });
    assert!(err < 1e-9, "{err:e}");
    // Segments differ: no shared factorisations.
    assert_eq!(model.n_factorisations(), 5 * 60);
}

#[test]
fn sensor_hypotheses_are_their_analytic_factors() {
    let data = synthetic();
    let nominal = ExtendedModel::new(data.clone(), None).unwrap();
    let p0 = nominal.predict(&base(), &[]).unwrap();
    let lp = LowPass {
        channels: vec![],
        quantity: Some(Quantity::Acceleration),
        tests: None,
        natural_frequency_hz: 40.0,
        damping_ratio: 0.6,
    };
    let cases: Vec<(&str, Location, Vec<f64>)> = vec![
        (
            "sensor_timing",
            Location::Channels(vec!["force".into()]),
            vec![0.01],
        ),
        (
            "sensor_timing",
            Location::Quantity(Quantity::Displacement),
            vec![0.02],
        ),
        (
            "sensor_timing",
            Location::Channels(vec!["acc2".into(), "acc4".into()]),
            vec![-0.006],
        ),
        (
            "sensor_dynamics",
            Location::Quantity(Quantity::Acceleration),
            vec![40.0, 0.6],
        ),
        (
            "sensor_dynamics",
            Location::Channels(vec!["ground_acc".into()]),
            vec![30.0, 0.7],
        ),
    ];
    for (name, loc, effect) in cases {
        let h: Arc<dyn Hypothesis> = Arc::from(hypothesis_by_name(name).unwrap());
        let model = ExtendedModel::new(data.clone(), Some((h, loc.clone()))).unwrap();
        let pred = model.predict(&base(), &effect).unwrap();
        let factor = |c: &Channel, s: Complex64| -> Complex64 {
            if !loc.covers_channel(&c.name, c.quantity) {
                return Complex64::new(1.0, 0.0);
            }
            if name == "sensor_timing" {
                // y(t - T): Laplace factor e^{-sT}.
                (-s * effect[0]).exp()
            } else {
                let w = 2.0 * std::f64::consts::PI * effect[0];
                w * w / (s * s + 2.0 * effect[1] * w * s + w * w)
            }
        };
        let mut worst: f64 = 0.0;
        for (seg, ranges) in data.segments.iter().zip(model.layout()) {
            let s_all = seg.laplace();
            for (ch, r) in seg.channels.iter().zip(ranges) {
                for ((p, q), &k) in pred[r.clone()]
                    .iter()
                    .zip(&p0[r.clone()])
                    .zip(&ch.freq_index)
                {
                    let s = s_all[k];
                    let expect = q * factor(&ch.channel, s) / factor(&seg.input_channel, s);
                    worst = worst.max((p - expect).norm() / expect.norm());
                }
            }
        }
        assert!(worst < 1e-12, "{name} at {loc}: {worst:e}");
    }
    // The low-pass formula is the simulator's (unwindowed).
    for f in [0.5, 5.0, 40.0, 100.0] {
        let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
        let ours = crate::discrepancy::hypotheses::low_pass(40.0, 0.6, s);
        assert!((ours - lp.response(f)).norm() < 1e-14);
    }
}

#[test]
fn every_hypothesis_has_locations_priors_and_nests_the_nominal_model() {
    let data = synthetic();
    let n_channels = data.channels().len();
    assert_eq!(n_channels, 10); // force, ground_acc, acc1..4, disp1..4
    let expect_locations = [1, 4, 4, 4, 2 + n_channels, 2 + n_channels];
    for (h, n_loc) in all_hypotheses().into_iter().zip(expect_locations) {
        let locs = h.locations(&data);
        assert_eq!(locs.len(), n_loc, "{}", h.name());
        let h: Arc<dyn Hypothesis> = Arc::from(h);
        for loc in locs {
            let params = h.parameters(&data, &loc).unwrap();
            assert!(!params.is_empty());
            for p in &params {
                assert!(p.lower < p.upper, "{} {}", h.name(), p.name);
                // Physical <-> coordinate round trip.
                let z = 0.3 * p.lower + 0.7 * p.upper;
                assert!((p.coordinate_of(p.physical(z)) - z).abs() < 1e-12);
            }
            let post = ModelPosterior::new(data.clone(), Some((h.clone(), loc.clone()))).unwrap();
            assert_eq!(post.dim(), 13 + params.len());
            // The end of the box nearest to no effect is close to the nominal model.
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut z = post.sample_prior(&mut rng).unwrap();
            assert!(post.ln_prior(&z).is_finite());
            for (i, p) in params.iter().enumerate() {
                let j = 13 + i;
                z[j] = match p.no_effect {
                    Some(v)
                        if v == 0.0
                            && matches!(
                                p.coordinate,
                                crate::discrepancy::hypothesis::Coordinate::Linear { .. }
                            ) =>
                    {
                        0.0
                    }
                    Some(0.0) => p.lower,
                    Some(_) => p.upper,
                    None if p.name.ends_with("damping_ratio")
                        || p.name == "oscillator_frequency" =>
                    {
                        p.upper
                    }
                    None => z[j],
                };
            }
            let b = post.base_params(&z);
            let near = post
                .model()
                .predict(&b, &post.effect_physical(&z).unwrap())
                .unwrap();
            let nom = ExtendedModel::new(data.clone(), None)
                .unwrap()
                .predict(&b, &[])
                .unwrap();
            // Largest change relative to each channel's largest magnitude.
            let model = post.model();
            let rel = model
                .layout()
                .iter()
                .flatten()
                .map(|r| {
                    let scale = nom[r.clone()].iter().map(|c| c.norm()).fold(0.0, f64::max);
                    near[r.clone()]
                        .iter()
                        .zip(&nom[r.clone()])
                        .map(|(a, c)| (a - c).norm() / scale)
                        .fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            assert!(rel < 0.1, "{} at {loc}: {rel}", h.name());
        }
        assert!(h.parameters(&data, &Location::Floor(99)).is_err());
    }
}
