//! Acceptance of FRF estimation (issue 2) on campaigns from the simulator.

use frfbayes::frf::{modal_frf, FrfPair};
use frfbayes::io::Campaign;
use frfbayes::modal::Modes;
use frfbayes::model::StructuralModel;
use frfbayes::signal::EstimateSection;
use frfbayes::signal::{
    estimate_campaign, windowed_modal_frf, EstimateOptions, HammerEstimator, InputKind, TestFrf,
};
use frfbayes::simulate::{DampingSpec, SimModel, Simulator, StructureSpec};
use num_complex::Complex64;
use std::f64::consts::PI;
use std::path::Path;
use std::time::Instant;

fn sim_model(file: &str) -> SimModel {
    SimModel::from_path(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("experiments/models")
            .join(file),
    )
    .unwrap()
}

/// The true modes and modal damping coefficients `2 xi_i omega_i` of a simulation model.
fn truth(model: &SimModel) -> (Modes, Vec<f64>) {
    let StructureSpec::ShearFrame {
        floor_mass_kg,
        story_stiffness_n_per_m,
    } = &model.structure
    else {
        panic!("shear frame expected");
    };
    let s = StructuralModel::shear_frame(floor_mass_kg, story_stiffness_n_per_m).unwrap();
    let k = s.stiffness(&s.alpha_zero());
    let m = s.mass(&s.beta_zero());
    let modes = Modes::solve(&k, &m, s.ground_influence(), None).unwrap();
    let DampingSpec::Modal { xi } = &model.damping else {
        panic!("modal damping expected");
    };
    let c = modes
        .omega_rad_s
        .iter()
        .zip(xi)
        .map(|(w, x)| 2.0 * x * w)
        .collect();
    (modes, c)
}

fn campaign(file: &str) -> (Campaign, Modes, Vec<f64>) {
    let model = sim_model(file);
    let (modes, c) = truth(&model);
    let seed = model.seed.unwrap_or(1);
    let t0 = Instant::now();
    let campaign = Simulator::new(model).unwrap().run(seed, &|_| {}).unwrap();
    println!("simulated in {:.2} s", t0.elapsed().as_secs_f64());
    (campaign, modes, c)
}

/// The analytic FRF an estimate stands for.
fn analytic(est: &TestFrf, modes: &Modes, c: &[f64], pair: &FrfPair, f_hz: f64) -> Complex64 {
    let w = 2.0 * PI * f_hz;
    match (est.input.clone(), est.exp_window_tau_s) {
        (InputKind::Force { .. }, Some(tau)) => windowed_modal_frf(modes, c, pair, w, tau),
        _ => modal_frf(modes, c, pair, w),
    }
}

/// Worst relative error `|H1 - H| / |H|` over 0.3-10 Hz at the bins with coherence > 0.99,
/// per response: (channel, worst, at Hz, bins compared).
fn worst_errors(e: &TestFrf, modes: &Modes, c: &[f64]) -> Vec<(String, f64, f64, usize)> {
    e.responses
        .iter()
        .map(|r| {
            let pair = r.pair(&e.input).unwrap();
            let (mut worst, mut at, mut n) = (0.0f64, 0.0, 0);
            for (k, &f) in e.freq_hz.iter().enumerate() {
                if !(0.3..=10.0).contains(&f) || r.coherence[k] <= 0.99 {
                    continue;
                }
                let h = analytic(e, modes, c, &pair, f);
                let err = (r.h1[k] - h).norm() / h.norm();
                n += 1;
                if err > worst {
                    worst = err;
                    at = f;
                }
            }
            (r.channel.name.clone(), worst, at, n)
        })
        .collect()
}

/// Estimates every test and returns the worst error of each test and channel kind
/// (acceleration, displacement), printing them; `require_bins`: at least 500 bins with
/// coherence > 0.99 in every channel.
fn report(
    label: &str,
    campaign: &Campaign,
    opts: &EstimateOptions,
    modes: &Modes,
    c: &[f64],
    require_bins: bool,
) -> f64 {
    let t0 = Instant::now();
    let est = estimate_campaign(campaign, opts).unwrap();
    println!("{label}: estimated in {:.2} s", t0.elapsed().as_secs_f64());
    let mut worst_all = 0.0f64;
    for e in &est {
        let rows = worst_errors(e, modes, c);
        for kind in ["acc", "disp"] {
            let (name, w, at, _) =
                rows.iter()
                    .filter(|r| r.0.starts_with(kind))
                    .fold(("", 0.0, 0.0, 0), |a, r| {
                        if r.1 >= a.1 {
                            (&r.0, r.1, r.2, r.3)
                        } else {
                            a
                        }
                    });
            let min_bins = rows.iter().map(|r| r.3).min().unwrap_or(0);
            println!(
                "  {:<18} {kind:<4}: worst {:.3} % ({name} at {at:.3} Hz; >= {min_bins} bins per channel)",
                e.test,
                100.0 * w
            );
            assert!(
                !require_bins || min_bins > 500,
                "{} {name}: only {min_bins} bins with coherence > 0.99",
                e.test
            );
        }
        worst_all = rows.iter().map(|r| r.1).fold(worst_all, f64::max);
    }
    worst_all
}

/// Issue 2 acceptance: the noise-free simulated campaign (four hammer tests with two
/// impacts 60 s apart, one chirp shake-table test) estimated with the default options
/// matches the analytic FRF of the true system (hammer: at `s = j omega + 1/tau`, the
/// exponential window's exact effect; shake table: relative ground FRF) within 0.5 %
/// wherever the coherence exceeds 0.99 over 0.3-10 Hz. `freq_max_hz = 12` only drops bins
/// above 12 Hz from the local noise models (each uses 9 neighbouring bins) and the output:
/// the estimate below 10 Hz is the same, at a tenth of the cost. Also checked: the
/// experiment pipeline's fixed `tau = 20 s`. Measured worst errors: see the printout
/// (whole record, default: 0.11 % in hammer receptances at 3.6-10 Hz; impact blocks: 13 %).
#[test]
fn noise_free_campaign_matches_the_analytic_frfs() {
    let (campaign, modes, c) = campaign("four-story-truth-noise-free.toml");
    let default = EstimateOptions {
        freq_max_hz: Some(12.0),
        ..EstimateOptions::default()
    };
    let mut pipeline = EstimateSection::default().options();
    pipeline.freq_max_hz = Some(12.0);
    for (label, opts) in [
        ("default options", default),
        ("pipeline (tau 20 s)", pipeline),
    ] {
        let worst = report(label, &campaign, &opts, &modes, &c, true);
        assert!(worst < 5e-3, "{label}: worst error {:.3} %", 100.0 * worst);
    }
    // for the record: the block-per-impact estimator fails (ring-down of impact 1 in block 2)
    let mut blocks = default;
    blocks.hammer.estimator = HammerEstimator::ImpactBlocks;
    let worst = report("impact blocks", &campaign, &blocks, &modes, &c, false);
    assert!(worst > 5e-3, "{worst}");
}

/// Estimator comparison on noisy campaigns (printed): total error at the selected points
/// against the analytic FRF (rms of `|H1 - H| / |H|`), and the mean `z^2`.
#[test]
#[ignore = "measurement, ~1 min"]
fn compare_hammer_estimators() {
    let mut model = sim_model("four-story-truth.toml");
    let (modes, c) = truth(&model);
    match std::env::var("NOISE").as_deref() {
        Ok("force") => {
            model.noise.acceleration_m_per_s2 = 0.0;
            model.noise.displacement_m = 0.0;
        }
        Ok("response") => {
            model.noise.force_n = 0.0;
        }
        _ => {}
    }
    let sim = Simulator::new(model).unwrap();
    let configs: Vec<(&str, EstimateOptions)> = {
        let mut v = Vec::new();
        for (name, base) in [
            ("pipeline", EstimateSection::default().options()),
            ("default", EstimateOptions::default()),
        ] {
            for (e, tc) in [
                (HammerEstimator::WholeRecord, true),
                (HammerEstimator::ImpactBlocks, false),
            ] {
                let mut o = base;
                o.hammer.estimator = e;
                o.hammer.tail_correction = tc;
                v.push((
                    if name == "pipeline" {
                        if e == HammerEstimator::WholeRecord {
                            "pipeline whole"
                        } else {
                            "pipeline blocks"
                        }
                    } else if e == HammerEstimator::WholeRecord {
                        "default whole"
                    } else {
                        "default blocks"
                    },
                    o,
                ));
            }
        }
        v
    };
    let mut acc = vec![(0.0, 0.0, 0usize, vec![(0.0, 0usize); 4]); configs.len()];
    let mut zs: Vec<Vec<f64>> = vec![Vec::new(); configs.len()];
    let mut ss: Vec<Vec<f64>> = vec![Vec::new(); configs.len()];
    for seed in 1..=2u64 {
        let campaign = sim.run(seed, &|_| {}).unwrap();
        for (ci, (_, o)) in configs.iter().enumerate() {
            let est = estimate_campaign(&campaign, o).unwrap();
            for e in est
                .iter()
                .filter(|e| matches!(e.input, InputKind::Force { .. }))
            {
                let sd = e.selected_rel_std();
                let mags = e.selected_magnitudes();
                let mut idx = 0;
                for r in &e.responses {
                    let pair = r.pair(&e.input).unwrap();
                    for &k in &e.selected {
                        let h = analytic(e, &modes, &c, &pair, e.freq_hz[k]);
                        let rel = (r.h1[k] - h).norm() / h.norm();
                        let z = (mags[idx] - h.norm()) / (mags[idx] * sd[idx]);
                        let mode = e
                            .bands
                            .iter()
                            .position(|b| {
                                e.freq_hz[k] >= b.lo_hz - 1e-9 && e.freq_hz[k] <= b.hi_hz + 1e-9
                            })
                            .unwrap_or(0);
                        zs[ci].push(z * z);
                        ss[ci].push(sd[idx]);
                        acc[ci].0 += rel * rel;
                        acc[ci].1 += z * z;
                        acc[ci].2 += 1;
                        acc[ci].3[mode].0 += rel * rel;
                        acc[ci].3[mode].1 += 1;
                        idx += 1;
                    }
                }
            }
        }
    }
    for (ci, (name, _)) in configs.iter().enumerate() {
        let mut z = zs[ci].clone();
        z.sort_by(f64::total_cmp);
        let mut s = ss[ci].clone();
        s.sort_by(f64::total_cmp);
        println!(
            "{name}: z^2 median {:.2} p90 {:.2} max {:.1}; predicted rel std median {:.3} %",
            z[z.len() / 2],
            z[z.len() * 9 / 10],
            z[z.len() - 1],
            100.0 * s[s.len() / 2]
        );
    }
    for ((name, _), (e2, z2, n, modes)) in configs.iter().zip(&acc) {
        let per_mode: Vec<String> = modes
            .iter()
            .map(|(s, n)| format!("{:.3} %", 100.0 * (s / *n as f64).sqrt()))
            .collect();
        println!(
            "{name}: rms |H1 - H| / |H| at the selected points {:.3} % (per mode {per_mode:?}), mean z^2 {:.2}, {n} points",
            100.0 * (e2 / *n as f64).sqrt(),
            z2 / *n as f64
        );
    }
}
