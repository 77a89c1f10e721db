//! Oracle tests of the forward model and its hypotheses on synthetic data layouts.

use super::data::{
    nominal_frequencies, ChannelData, DataOptions, DiagnosisData, SegmentData, SegmentSource,
};
use super::forward::{frame_system, solve_in_place, BaseParams, ExtendedModel};
use super::hypotheses::{all_hypotheses, hypothesis_by_name};
use super::hypothesis::Hypothesis;
use super::location::Location;
use super::posterior::ModelPosterior;
use crate::frf::{Excitation, FrfKind, FrfPair};
use crate::io::{Channel, NominalModel, Quantity};
use crate::signal::{windowed_modal_frf, InputKind};
use crate::simulate::{
    BaseFlexibility, DampingSpec, Dashpot, LinearSystem, LowPass, Oscillator, StructureSpec,
    SystemEffect,
};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

mod hypotheses;
mod likelihood;

const MASS: [f64; 4] = [5.1, 4.9, 4.95, 5.05];
const STIFF: [f64; 4] = [1090.0, 1258.0, 1378.0, 2666.0];
const XI: [f64; 4] = [0.017, 0.0115, 0.006, 0.004];

fn chan(name: &str, quantity: Quantity, floor: usize) -> Channel {
    Channel {
        name: name.into(),
        quantity,
        floor,
        unit: quantity.unit().into(),
    }
}

/// A segment with acc1..4 and disp1..4 at `freq_hz`, measured values all 1 (unused).
fn segment(name: &str, input: InputKind, tau: Option<f64>, freq_hz: &[f64]) -> SegmentData {
    let drift = vec![Some(1e-6), Some(2e-6), Some(0.5e-6), Some(3e-6)];
    segment_on(name, input, tau, freq_hz, &[1, 2, 3, 4], drift)
}

/// A segment with an accelerometer and a displacement sensor on each of `floors` at
/// `freq_hz` (channels `acc<f>`, `disp<f>`), measured values all 1 (unused), and the
/// stories' drift weights `drift`.
pub(super) fn segment_on(
    name: &str,
    input: InputKind,
    tau: Option<f64>,
    freq_hz: &[f64],
    floors: &[usize],
    drift: Vec<Option<f64>>,
) -> SegmentData {
    let input_channel = match &input {
        InputKind::Force { floor, channel } => chan(channel, Quantity::Force, *floor),
        InputKind::Ground { channel } => chan(channel, Quantity::GroundAcceleration, 0),
    };
    let mut channels = Vec::new();
    for (q, prefix, kind) in [
        (Quantity::Acceleration, "acc", FrfKind::Accelerance),
        (Quantity::Displacement, "disp", FrfKind::Receptance),
    ] {
        for &f in floors {
            let n = freq_hz.len();
            channels.push(ChannelData {
                channel: chan(&format!("{prefix}{f}"), q, f),
                kind,
                freq_index: (0..n).collect(),
                band: vec![None; n],
                h: vec![Complex64::new(1.0, 0.5); n],
                rel_err: vec![0.01; n],
                estimator_bias: Vec::new(),
            });
        }
    }
    SegmentData {
        name: name.into(),
        test: name.into(),
        impact: None,
        peak_force_n: None,
        input,
        input_channel,
        exp_window_tau_s: tau,
        freq_hz: freq_hz.to_vec(),
        bands: Vec::new(),
        channels,
        story_drift_lin_sq_m2: drift,
        input_gain: None,
        source: SegmentSource::default(),
    }
}

pub(super) fn synthetic() -> Arc<DiagnosisData> {
    let nominal = NominalModel::shear_frame(vec![4.64; 4], vec![1019.0, 1217.0, 1420.0, 2473.0]);
    let freq: Vec<f64> = (1..=60).map(|i| 0.3 * i as f64).collect();
    let force = |f: usize| InputKind::Force {
        floor: f,
        channel: "force".into(),
    };
    let mut segments = vec![
        segment("h1", force(1), Some(19.4), &freq),
        segment("h3", force(3), Some(19.4), &freq),
        segment("h2-raw", force(2), None, &freq),
        segment(
            "shake",
            InputKind::Ground {
                channel: "ground_acc".into(),
            },
            None,
            &freq,
        ),
    ];
    // A second impact of test h3, with a larger drift: shares h3's grid.
    let mut strong = segment("h3b", force(3), Some(19.4), &freq);
    strong.story_drift_lin_sq_m2 = vec![Some(4e-6), Some(8e-6), Some(2e-6), Some(9e-6)];
    segments.push(strong);
    Arc::new(DiagnosisData {
        title: "synthetic".into(),
        nominal_freq_hz: nominal_frequencies(&nominal).unwrap(),
        model: Arc::new(nominal.structural_model().unwrap()),
        nominal,
        segments,
        options: DataOptions::default(),
        reduction: None,
    })
}

pub(super) fn base() -> BaseParams {
    BaseParams::from_physical(&synthetic().model, &STIFF, &MASS, XI.to_vec()).unwrap()
}

/// The simulator's system for the same frame, with `effects` applied.
fn simulator_system(effects: &[&dyn SystemEffect]) -> LinearSystem {
    let mut s = LinearSystem::from_spec(
        &StructureSpec::ShearFrame {
            floor_mass_kg: MASS.to_vec(),
            story_stiffness_n_per_m: STIFF.to_vec(),
        },
        &DampingSpec::Modal { xi: XI.to_vec() },
    )
    .unwrap();
    for e in effects {
        e.apply(&mut s).unwrap();
    }
    s
}

/// Independent oracle: `D(s)^-1` by nalgebra's general inverse; the ratio a channel of
/// `seg` measures (floor `floor`, `power` of s) at Laplace variable `s`.
fn oracle(
    sys: &LinearSystem,
    seg: &SegmentData,
    floor: usize,
    power: i32,
    s: Complex64,
) -> Complex64 {
    let n = sys.n_dof();
    let d = DMatrix::from_fn(n, n, |i, j| {
        sys.stiffness_n_per_m[(i, j)]
            + s * sys.damping_n_s_per_m[(i, j)]
            + s * s * sys.mass_kg[(i, j)]
    });
    let inv = d.try_inverse().unwrap();
    let r = sys.floor_dof[floor - 1];
    match &seg.input {
        InputKind::Force { floor: e, .. } => inv[(r, sys.floor_dof[e - 1])] * s.powi(power),
        InputKind::Ground { .. } => {
            let rhs: DVector<Complex64> =
                (&sys.mass_kg * &sys.ground_influence).map(|v| Complex64::new(-v, 0.0));
            let x = (&inv * rhs)[r];
            let h = x * s.powi(power);
            if power == 2 {
                h + 1.0
            } else {
                h
            }
        }
    }
}

/// Largest error of `pred` against `f(segment, channel, point)`, relative to each
/// channel's largest magnitude.
fn max_rel_err(
    model: &ExtendedModel,
    pred: &[Complex64],
    f: impl Fn(&SegmentData, &ChannelData, Complex64) -> Complex64,
) -> f64 {
    let data = model.data();
    let mut worst: f64 = 0.0;
    for (seg, ranges) in data.segments.iter().zip(model.layout()) {
        let s_all = seg.laplace();
        for (ch, r) in seg.channels.iter().zip(ranges) {
            let expect: Vec<Complex64> = ch
                .freq_index
                .iter()
                .map(|&k| f(seg, ch, s_all[k]))
                .collect();
            let scale = expect.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for (p, e) in pred[r.clone()].iter().zip(&expect) {
                worst = worst.max((p - e).norm() / scale);
            }
        }
    }
    worst
}

fn power(kind: FrfKind) -> i32 {
    kind.power()
}

#[test]
fn small_solver_matches_the_general_inverse() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for n in [1usize, 3, 6] {
        let a: Vec<Complex64> = (0..n * n)
            .map(|_| Complex64::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5))
            .collect();
        let b: Vec<Complex64> = (0..2 * n)
            .map(|_| Complex64::new(rng.random::<f64>(), rng.random::<f64>()))
            .collect();
        let am = DMatrix::from_row_slice(n, n, &a);
        let bm = DMatrix::from_row_slice(n, 2, &b);
        let x = am.try_inverse().unwrap() * bm;
        let (mut a2, mut b2) = (a.clone(), b.clone());
        solve_in_place(n, &mut a2, &mut b2, 2).unwrap();
        for i in 0..n {
            for j in 0..2 {
                assert!(
                    (b2[i * 2 + j] - x[(i, j)]).norm()
                        < 1e-12 * x.iter().map(|v| v.norm()).fold(1.0, f64::max)
                );
            }
        }
    }
    let mut zero = vec![Complex64::new(0.0, 0.0); 4];
    let mut b = vec![Complex64::new(1.0, 0.0); 2];
    assert!(solve_in_place(2, &mut zero, &mut b, 1).is_err());
}

#[test]
fn nominal_model_matches_the_windowed_modal_sum_and_the_direct_solve() {
    let data = synthetic();
    let model = ExtendedModel::new(data.clone(), None).unwrap();
    // Hammer segments share factorisations: 3 distinct grids (tau = 19.4 s, hammer
    // without window and shake table share s = j omega) -> 2 x 60 slots.
    assert_eq!(model.n_factorisations(), 120);
    let b = base();
    let pred = model.predict(&b, &[]).unwrap();
    let sys = frame_system(&data.model, &b).unwrap();
    let modes = sys.modes().unwrap();
    let modal_c: Vec<f64> = XI
        .iter()
        .zip(&modes.omega_rad_s)
        .map(|(x, w)| 2.0 * x * w)
        .collect();
    // Modal sum at omega - j/tau (signal::windows); absolute accelerance = relative + 1.
    let err = max_rel_err(&model, &pred, |seg, ch, s| {
        let excitation = match seg.input {
            InputKind::Force { floor, .. } => Excitation::Dof(floor - 1),
            InputKind::Ground { .. } => Excitation::Ground,
        };
        let pair = FrfPair {
            response: ch.channel.floor - 1,
            excitation,
            kind: ch.kind,
        };
        let tau = seg.exp_window_tau_s.unwrap_or(f64::INFINITY);
        let h = windowed_modal_frf(&modes, &modal_c, &pair, s.im, tau);
        if excitation == Excitation::Ground && ch.kind == FrfKind::Accelerance {
            h + 1.0
        } else {
            h
        }
    });
    assert!(err < 1e-9, "modal sum: {err:e}");
    // Unwindowed segments against frf::direct (Eqs. 1 and 14).
    let err = max_rel_err(&model, &pred, |seg, ch, s| {
        if seg.exp_window_tau_s.is_some() {
            return oracle(&sys, seg, ch.channel.floor, power(ch.kind), s);
        }
        let w = s.im;
        let f = ch.channel.floor - 1;
        let x = match seg.input {
            InputKind::Force { floor, .. } => crate::frf::direct::receptance_matrix(
                &sys.mass_kg,
                &sys.stiffness_n_per_m,
                &sys.damping_n_s_per_m,
                w,
            )
            .unwrap()[(f, floor - 1)],
            InputKind::Ground { .. } => crate::frf::direct::ground_receptance(
                &sys.mass_kg,
                &sys.stiffness_n_per_m,
                &sys.damping_n_s_per_m,
                &sys.ground_influence,
                w,
            )
            .unwrap()[f],
        };
        let h = x * ch.kind.factor(w);
        if seg.is_ground() && ch.kind == FrfKind::Accelerance {
            h + 1.0
        } else {
            h
        }
    });
    assert!(err < 1e-9, "direct: {err:e}");
    // The frame is the simulator's modal-damped frame.
    let sim = simulator_system(&[]);
    assert!((&sim.damping_n_s_per_m - &sys.damping_n_s_per_m).amax() < 1e-9);
    assert!((&sim.stiffness_n_per_m - &sys.stiffness_n_per_m).amax() < 1e-9);
}

/// Two structural effects (an oscillator on floor 2, then a flexible base) predict what
/// the simulator's system with both applied predicts; a sensor effect on top multiplies
/// by its analytic factor; and a composite with nothing accepted is its hypothesis.
#[test]
fn several_effects_are_the_simulators_system_with_all_of_them() {
    use super::extension::{Effect, WithEffects};
    let data = synthetic();
    let by = |n: &str| -> Arc<dyn Hypothesis> { Arc::from(hypothesis_by_name(n).unwrap()) };
    let (m, f, z) = (0.4, 3.5, 0.02);
    let osc = Oscillator {
        floor: 2,
        mass_kg: m,
        stiffness_n_per_m: m * (2.0 * std::f64::consts::PI * f).powi(2),
        damping_ratio: z,
    };
    let f_b = (8900.0f64 / 5.0).sqrt() / (2.0 * std::f64::consts::PI);
    let zeta_b = 10.0 / (2.0 * (8900.0f64 * 5.0).sqrt());
    let flex = BaseFlexibility {
        mass_kg: 5.0,
        stiffness_n_per_m: 8900.0,
        damping_n_s_per_m: 10.0,
    };
    let accepted = vec![Effect {
        hypothesis: by("secondary_oscillator"),
        location: Location::Floor(2),
    }];
    let both = WithEffects::new(&data, accepted.clone(), by("base_flexibility")).unwrap();
    let both: Arc<dyn Hypothesis> = Arc::new(both);
    let params = both.parameters(&data, &Location::Whole).unwrap();
    assert_eq!(params.len(), 6);
    assert_eq!(both.name(), "base_flexibility");
    let effect = [m, f, z, 5.0, f_b, zeta_b];
    let model = ExtendedModel::new(data.clone(), Some((both.clone(), Location::Whole))).unwrap();
    let pred = model.predict(&base(), &effect).unwrap();
    let sys = simulator_system(&[&osc, &flex]);
    let err = max_rel_err(&model, &pred, |seg, ch, s| {
        oracle(&sys, seg, ch.channel.floor, power(ch.kind), s)
    });
    assert!(err < 1e-9, "oscillator + base: {err:e}");

    // A sensor delay on every displacement channel on top of both.
    let accepted2 = vec![
        accepted[0].clone(),
        Effect {
            hypothesis: by("base_flexibility"),
            location: Location::Whole,
        },
    ];
    let three: Arc<dyn Hypothesis> =
        Arc::new(WithEffects::new(&data, accepted2, by("sensor_timing")).unwrap());
    let loc = Location::Quantity(Quantity::Displacement);
    let model3 = ExtendedModel::new(data.clone(), Some((three, loc.clone()))).unwrap();
    let delay = 0.004;
    let pred3 = model3
        .predict(&base(), &[m, f, z, 5.0, f_b, zeta_b, delay])
        .unwrap();
    let err3 = max_rel_err(&model3, &pred3, |seg, ch, s| {
        let h = oracle(&sys, seg, ch.channel.floor, power(ch.kind), s);
        let covered = |c: &Channel| loc.covers_channel(&c.name, c.quantity);
        let fac = |c: &Channel| {
            if covered(c) {
                (-s * delay).exp()
            } else {
                1.0.into()
            }
        };
        h * fac(&ch.channel) / fac(&seg.input_channel)
    });
    assert!(err3 < 1e-9, "oscillator + base + delay: {err3:e}");

    // Nothing accepted: the hypothesis itself, bit for bit.
    let alone = WithEffects::new(&data, vec![], by("secondary_oscillator")).unwrap();
    let alone = ExtendedModel::new(data.clone(), Some((Arc::new(alone), Location::Floor(2))));
    let direct = ExtendedModel::new(data, Some((by("secondary_oscillator"), Location::Floor(2))));
    assert_eq!(
        alone.unwrap().predict(&base(), &[m, f, z]).unwrap(),
        direct.unwrap().predict(&base(), &[m, f, z]).unwrap()
    );
}

/// The same hypothesis accepted twice gets distinct parameter names, and the added
/// hypothesis is not offered where it is already accepted.
#[test]
fn a_second_oscillator_has_its_own_names_and_locations() {
    use super::extension::{Effect, WithEffects};
    let data = synthetic();
    let osc: Arc<dyn Hypothesis> = Arc::from(hypothesis_by_name("secondary_oscillator").unwrap());
    let accepted = vec![Effect {
        hypothesis: osc.clone(),
        location: Location::Floor(3),
    }];
    let two = WithEffects::new(&data, accepted, osc).unwrap();
    let locs = two.locations(&data);
    assert!(!locs.contains(&Location::Floor(3)), "{locs:?}");
    assert_eq!(locs.len(), 3);
    let names: Vec<String> = two
        .parameters(&data, &Location::Floor(1))
        .unwrap()
        .into_iter()
        .map(|p| p.name)
        .collect();
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), names.len(), "{names:?}");
    assert!(names[3].ends_with("_2"), "{names:?}");
}

#[test]
fn a_story_without_drift_sensors_is_a_location_that_says_why_it_is_not_tested() {
    use super::hypotheses::StiffnessNonlinearityHypothesis;
    let mut data = (*synthetic()).clone();
    for seg in &mut data.segments {
        seg.story_drift_lin_sq_m2[2] = None;
    }
    let h = StiffnessNonlinearityHypothesis;
    assert_eq!(h.locations(&data).len(), 4);
    assert!(h.parameters(&data, &Location::Story(2)).is_ok());
    let e = h
        .parameters(&data, &Location::Story(3))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not testable") && e.contains("floors 2 and 3"),
        "{e}"
    );
}

#[test]
fn the_location_search_is_the_same_on_one_thread_and_on_two() {
    // Locations and the channel growth's candidates are fitted side by side: the search
    // of a channel hypothesis (every single channel and quantity, then growth) must
    // give the same fits, bit for bit, whatever the thread count.
    use super::search::{search, SearchOptions};
    let (_, data) = noisy_synthetic(0.01, 7);
    let data = Arc::new(data);
    let nominal = ModelPosterior::new(data.clone(), None).unwrap();
    let z0 = nominal.z_of(&base(), 0.01, &[]);
    let h: Arc<dyn Hypothesis> = Arc::from(hypothesis_by_name("sensor_timing").unwrap());
    let opts = SearchOptions {
        n_effect_starts: 2,
        ..SearchOptions::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| search(&data, &h, &z0, &opts, &mut |_, _| {}).unwrap())
    };
    let (one, two) = (run(1), run(2));
    assert!(
        one.tried.len() > data.channels().len(),
        "{}",
        one.tried.len()
    );
    assert_eq!(one.tried.len(), two.tried.len());
    for (a, b) in one.tried.iter().zip(&two.tried) {
        assert_eq!(a.location, b.location);
        assert_eq!(a.map.z, b.map.z);
        assert_eq!(a.map.ln_likelihood.to_bits(), b.map.ln_likelihood.to_bits());
    }
}

/// The synthetic data at `base()` times `1 + eps n`, `n` complex standard normal (each
/// component `N(0, 1)`: the likelihood's convention for `rel_err = eps`), with every
/// point's `rel_err` set to `eps`; and the truth.
fn noisy_synthetic(eps: f64, seed: u64) -> (Vec<Complex64>, DiagnosisData) {
    use rand_distr::StandardNormal;
    let clean = synthetic();
    let truth = ExtendedModel::new(clean.clone(), None)
        .unwrap()
        .predict(&base(), &[])
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut data = (*clean).clone();
    let mut it = truth.iter();
    for seg in &mut data.segments {
        for ch in &mut seg.channels {
            ch.rel_err = vec![eps; ch.len()];
            for h in &mut ch.h {
                let n = Complex64::new(rng.sample(StandardNormal), rng.sample(StandardNormal));
                *h = it.next().unwrap() * (1.0 + eps * n);
            }
        }
    }
    (truth, data)
}
