//! Evidence near the decision threshold (issue 14, item 3): stepping-stone and
//! warp-III bridge sampling (`frfbayes::infer::nested`) against the exact Bayes factors
//! of the nested linear-Gaussian problems of `frfbayes::infer::validation`.
//!
//! Default tests: the generalised stepping-stone and the bridge on every problem, one
//! seed each, within a tolerance from their own standard errors; the screen that
//! `diagnose` uses (`frfbayes::infer::screened`: gain bound, Laplace in logit
//! coordinates, generalised stepping-stone) on every problem and on a clear null.
//! Ignored: the measurement over seeds (bias and sd of `ln Z` and `Delta ln Z` of the
//! estimators, time and likelihood evaluations), and the export of the problems for
//! `experiments/evidence/tmcmc_pymc.py`.

use std::time::Instant;

use frfbayes::discrepancy::model_evidence::LAPLACE_ALLOWANCE_NATS;
use frfbayes::discrepancy::verdict::decisive_ln_bayes_factor;
use frfbayes::infer::importance_evidence;
use frfbayes::infer::validation::{NestedModel, NestedProblem, ProblemSpec};
use frfbayes::infer::TemperedTarget;
use frfbayes::infer::{
    bridge_evidence, choose_estimator, gain_bound, laplace_of, referenced_evidence,
    screened_evidence, stepping_stone, BaseEvidence, BridgeOptions, Estimator, EvidenceOptions,
    Extension, ScreenOptions, GSS_REPLICATES, IMPORTANCE_DRAWS,
};

/// Seed of the problem data (the same problems for every estimator and tool).
const PROBLEM_SEED: u64 = 1;

/// One estimate of a model's `ln Z`.
struct Estimate {
    ln_z: f64,
    se: f64,
    seconds: f64,
    evaluations: u64,
}

fn bridge(t: &NestedModel<'_>, seed: u64) -> Estimate {
    let t0 = Instant::now();
    let start = t.best_fit().unwrap();
    let o = BridgeOptions::new(t.dim(), seed);
    let b = bridge_evidence(t, t.bounds(), &start, &o).unwrap();
    Estimate {
        ln_z: b.ln_z,
        se: b.ln_z_se,
        seconds: t0.elapsed().as_secs_f64(),
        evaluations: b.n_likelihood_evaluations,
    }
}

// Replicates of the generalised stepping-stone: `GSS_REPLICATES` (4: three degrees of
// freedom for its standard error, at a fraction of the prior-referenced run's cost).

fn referenced(t: &NestedModel<'_>, seed: u64) -> Estimate {
    let t0 = Instant::now();
    let start = t.best_fit().unwrap();
    let mut o = EvidenceOptions::new(t.dim(), seed);
    o.final_steps = 0;
    o.n_replicates = GSS_REPLICATES;
    let effect: Vec<usize> = (t.n_base()..t.dim()).collect();
    let r = referenced_evidence(t, t.bounds(), &start, &effect, &o).unwrap();
    Estimate {
        ln_z: r.evidence.ln_z,
        se: r.evidence.ln_z_se,
        seconds: t0.elapsed().as_secs_f64(),
        evaluations: r.n_likelihood_evaluations,
    }
}

fn stepping<T: TemperedTarget>(t: &T, seed: u64) -> Estimate {
    let t0 = Instant::now();
    let mut o = EvidenceOptions::new(t.dim(), seed);
    o.final_steps = 0;
    let e = stepping_stone(t, &o, None).unwrap();
    Estimate {
        ln_z: e.ln_z,
        se: e.ln_z_se,
        seconds: t0.elapsed().as_secs_f64(),
        evaluations: e.n_likelihood_evaluations,
    }
}

fn problems() -> Vec<NestedProblem> {
    ProblemSpec::all()
        .iter()
        .map(|s| s.build(PROBLEM_SEED).unwrap())
        .collect()
}

/// Two-sided 0.1 % Student t quantile with `GSS_REPLICATES - 1 = 3` degrees of freedom.
const T3_9995: f64 = 12.924;

/// The generalised stepping-stone on every problem and both models, one seed: within
/// `t_3(0.9995) se + 0.1` nats of the exact `ln Z` (`se` from 4 replicates; 0.1: the
/// downward bias of `ln` of an unbiased `Z` estimate plus the finite ensemble's; measured
/// up to 0.33 on one model, inside `t se` with the replicates' se of 0.03-0.17). The bound `Delta ln Z <= gain`
/// holds for the estimates within their errors.
#[test]
fn referenced_stepping_stone_matches_exact_evidence() {
    for p in problems() {
        let (base, ext) = (p.base(), p.extension());
        let eb = referenced(&base, 11);
        let ee = referenced(&ext, 12);
        for (e, exact, which) in [(&eb, p.ln_z_base, "base"), (&ee, p.ln_z_extension, "ext")] {
            let err = e.ln_z - exact;
            assert!(
                err.abs() < T3_9995 * e.se + 0.1,
                "{} {which}: ln Z {:.4} +- {:.4}, exact {exact:.4}",
                p.name,
                e.ln_z,
                e.se
            );
        }
        let se = eb.se.hypot(ee.se);
        assert!(ee.ln_z - eb.ln_z <= gain_bound(p.gain, 0.0) + T3_9995 * se + 0.2);
    }
}

/// The bridge where the posterior in logit coordinates is one peak (the corner and
/// interior problems): within `4 se + 0.15` (4 se: two-sided 1e-4; 0.15 its measured
/// bias, up to 0.13 on the decisive extension). On the log-uniform plateau it is biased low by ~0.25 nats
/// (walkers cross slowly between the peak and the plateau): a known limit, measured, not
/// tested.
#[test]
fn bridge_matches_exact_evidence_on_single_peaks() {
    for p in problems()
        .iter()
        .filter(|p| !p.name.starts_with("null_log"))
    {
        let (base, ext) = (p.base(), p.extension());
        for (e, exact, which) in [
            (bridge(&base, 21), p.ln_z_base, "base"),
            (bridge(&ext, 22), p.ln_z_extension, "ext"),
        ] {
            assert!(
                (e.ln_z - exact).abs() < 4.0 * e.se + 0.15,
                "{} {which}: ln Z {:.4} +- {:.4}, exact {exact:.4}",
                p.name,
                e.ln_z,
                e.se
            );
        }
    }
}

/// Importance sampling from the generalised stepping-stone's reference (the screen's
/// step 3) on every problem, both models, 20 seeds. Where its Pareto diagnostic and
/// standard error let the screen keep it, its `ln Z` is within `4 se + 0.05` nats of
/// the exact value (4 se: a 6e-5 two-sided normal tail per estimate, 200 estimates;
/// 0.05: the downward bias of `ln` of an unbiased mean, about `se^2 / 2`, and the
/// delta method's own error), and it is kept on the decisive problem (every seed),
/// where its use is meant to save the tempered run.
#[test]
fn importance_sampling_is_right_where_it_is_kept() {
    let mut kept_decisive = 0;
    for p in problems() {
        for extended in [false, true] {
            let t = if extended { p.extension() } else { p.base() };
            let start = t.best_fit().unwrap();
            let lap = laplace_of(&t, t.bounds(), &start).unwrap();
            let effect: Vec<usize> = if extended {
                (t.n_base()..t.dim()).collect()
            } else {
                Vec::new()
            };
            let exact = t.reference_ln_z();
            let (mut kept, mut worst) = (0, 0.0f64);
            for seed in 0..20u64 {
                let is = importance_evidence(
                    &t,
                    t.bounds(),
                    &lap.u_mode,
                    &lap.laplace,
                    &effect,
                    IMPORTANCE_DRAWS,
                    100,
                    1000 + seed,
                )
                .unwrap();
                if !is.reliable() {
                    continue;
                }
                kept += 1;
                let err = is.ln_z - exact;
                worst = worst.max(err.abs() / is.ln_z_se);
                assert!(
                    err.abs() < 4.0 * is.ln_z_se + 0.05,
                    "{} ({}): ln Z {:.4} +- {:.4} (k {:.2}, ESS {:.0}), exact {exact:.4}",
                    p.name,
                    if extended { "extension" } else { "base" },
                    is.ln_z,
                    is.ln_z_se,
                    is.pareto_k,
                    is.ess
                );
            }
            eprintln!(
                "{} ({}): kept {kept}/20, largest |error| / se {worst:.2}",
                p.name,
                if extended { "extension" } else { "base" }
            );
            if extended && p.name.starts_with("decisive") {
                kept_decisive = kept;
            }
        }
    }
    assert_eq!(
        kept_decisive, 20,
        "importance sampling not kept on the decisive problem"
    );
}

/// The validation problems and a clear null: 4 effects inside their box whose best fit
/// gains 8 nats, above `ln 150`, so that the bound does not rule it out, while the
/// effects' Occam factor (about 5 nats each) puts `Delta ln Z` near -12.
fn screen_problems() -> Vec<NestedProblem> {
    let mut specs = ProblemSpec::all();
    let interior = specs
        .iter()
        .find(|s| s.name == "decisive_interior")
        .cloned()
        .unwrap();
    specs.push(ProblemSpec {
        name: "clear_interior_null",
        gain: 8.0,
        ..interior
    });
    specs
        .iter()
        .map(|s| s.build(PROBLEM_SEED).unwrap())
        .collect()
}

fn screen_options(seed: u64, dim: usize) -> ScreenOptions {
    let mut evidence = EvidenceOptions::new(dim, seed);
    evidence.final_steps = 0;
    ScreenOptions {
        threshold_nats: decisive_ln_bayes_factor(),
        laplace_allowance_nats: LAPLACE_ALLOWANCE_NATS,
        evidence,
        gss_replicates: GSS_REPLICATES,
        importance_draws: IMPORTANCE_DRAWS,
    }
}

/// The screen of `diagnose` on problems with exact Bayes factors:
/// - the estimator is the one its rule names from the exact gain: the bound where the
///   gain is below `ln 150` (the two nulls), otherwise Laplace or the generalised
///   stepping-stone;
/// - a bound holds: the exact `Delta ln Z` is at most the bound, and so is the reported
///   value;
/// - Laplace's `Delta` (in logit coordinates) is within the stated allowance of the
///   exact one on every problem (the allowance's claim), and where Laplace decides (far
///   below the threshold, or far above it with no rival), the decision is the exact
///   one's;
/// - the generalised stepping-stone is within `t_3(0.9995) sd + 0.2` of the exact value
///   (0.2: the bias of `ln` of an unbiased estimate plus the finite ensemble's, measured
///   up to 0.29 per model on the corner problems; see the README).
#[test]
fn the_screen_chooses_its_estimator_by_rule_and_is_right() {
    let thr = decisive_ln_bayes_factor();
    for (k, p) in screen_problems().iter().enumerate() {
        let (base, ext) = (p.base(), p.extension());
        let seed = 31 + 10 * k as u64;
        let lap_b = laplace_of(&base, base.bounds(), &base.best_fit().unwrap()).unwrap();
        let so_b = screen_options(seed, base.dim());
        let eb = screened_evidence(
            &base,
            base.bounds(),
            Some(&lap_b),
            &[],
            Estimator::GeneralisedSteppingStone,
            None,
            &so_b,
            None,
        )
        .unwrap();
        let lap_e = laplace_of(&ext, ext.bounds(), &ext.best_fit().unwrap()).unwrap();
        let x = Extension {
            base: BaseEvidence {
                ln_z: eb.ln_z,
                ln_z_laplace: Some(lap_b.laplace.ln_z),
                max_ln_likelihood: 0.0,
            },
            gain_bound_nats: gain_bound(p.gain, 0.0),
            rival_floor_nats: f64::NEG_INFINITY,
        };
        let so_e = screen_options(seed + 1, ext.dim());
        let d_lap = x.delta_laplace(Some(lap_e.laplace.ln_z)).unwrap();
        let exact = p.ln_bayes_factor();
        eprintln!(
            "{}: gain {:.2}, exact {exact:.3}, Laplace {d_lap:.3} (error {:+.3})",
            p.name,
            p.gain,
            d_lap - exact
        );
        assert!(
            (d_lap - exact).abs() < LAPLACE_ALLOWANCE_NATS,
            "{}: Laplace Delta {d_lap:.3} against exact {exact:.3}",
            p.name
        );
        let est = choose_estimator(x.gain_bound_nats, Some(d_lap), &so_e);
        if p.gain < thr {
            assert_eq!(est, Estimator::GainBound, "{}", p.name);
        } else if p.name.starts_with("clear") || p.name.starts_with("decisive") {
            // Laplace's branches: clearly below (exact Delta ~ -12, gain 8) and clearly
            // above (exact Delta ~ 275).
            assert_eq!(est, Estimator::Laplace, "{}", p.name);
        } else {
            assert_ne!(est, Estimator::GainBound, "{}", p.name);
        }
        let effect: Vec<usize> = (ext.n_base()..ext.dim()).collect();
        let e = screened_evidence(
            &ext,
            ext.bounds(),
            Some(&lap_e),
            &effect,
            est,
            Some(&x),
            &so_e,
            None,
        )
        .unwrap();
        let delta = e.ln_z - eb.ln_z;
        let sd = e.ln_z_sd.hypot(eb.ln_z_sd);
        eprintln!(
            "  {}: Delta {delta:.3} +- {sd:.3} by {}",
            p.name,
            e.estimator.label()
        );
        assert!(exact <= x.gain_bound_nats + 1e-9 && delta <= x.gain_bound_nats + 1e-9);
        match est {
            Estimator::GainBound => assert_eq!(e.ln_z_sd, 0.0),
            Estimator::Laplace => {
                // Laplace decides only where the exact value agrees, with room to spare.
                let decisive = delta - 2.0 * sd >= thr;
                assert!(decisive || delta + 2.0 * sd < thr, "{}", p.name);
                assert_eq!(decisive, exact >= thr, "{}: Laplace's decision", p.name);
                assert!((delta - exact).abs() < LAPLACE_ALLOWANCE_NATS, "{}", p.name);
            }
            _ => assert!(
                (delta - exact).abs() < T3_9995 * sd + 0.2,
                "{}: Delta {delta:.4} +- {sd:.4}, exact {exact:.4}",
                p.name
            ),
        }
    }
}

#[test]
#[ignore = "measurement: both estimators over seeds on the validation problems (minutes)"]
fn measure_estimators() {
    let seeds: u64 = std::env::var("EVIDENCE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    println!("| problem | k | exact Delta ln Z | gain | method | bias Delta | sd Delta | bias ln Z_ext | sd ln Z_ext | mean se | s per model | evals per model |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for p in problems() {
        let (base, ext) = (p.base(), p.extension());
        for method in [
            "stepping-stone (2 replicates)",
            "generalised stepping-stone (4 replicates)",
            "bridge (warp-III, logit)",
        ] {
            let mut rows = Vec::new();
            for s in 0..seeds {
                let run = |t: &dyn Fn(u64) -> Estimate, k: u64| t(100 * s + k);
                let (eb, ee) = if method.starts_with("stepping") {
                    (
                        run(&|x| stepping(&base, x), 1),
                        run(&|x| stepping(&ext, x), 2),
                    )
                } else if method.starts_with("generalised") {
                    (
                        run(&|x| referenced(&base, x), 1),
                        run(&|x| referenced(&ext, x), 2),
                    )
                } else {
                    (run(&|x| bridge(&base, x), 1), run(&|x| bridge(&ext, x), 2))
                };
                rows.push((eb, ee));
            }
            let stat = |v: Vec<f64>, exact: f64| {
                let n = v.len() as f64;
                let m = v.iter().sum::<f64>() / n;
                let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                (m - exact, sd)
            };
            let (bd, sdd) = stat(
                rows.iter().map(|(b, e)| e.ln_z - b.ln_z).collect(),
                p.ln_bayes_factor(),
            );
            let (be, sde) = stat(rows.iter().map(|(_, e)| e.ln_z).collect(), p.ln_z_extension);
            let n = rows.len() as f64;
            let se = rows.iter().map(|(b, e)| b.se.hypot(e.se)).sum::<f64>() / n;
            let secs = rows.iter().map(|(b, e)| b.seconds + e.seconds).sum::<f64>() / (2.0 * n);
            let evals = rows
                .iter()
                .map(|(b, e)| (b.evaluations + e.evaluations) as f64)
                .sum::<f64>()
                / (2.0 * n);
            println!(
                "| {} | {} | {:.3} | {:.2} | {method} | {bd:+.3} | {sdd:.3} | {be:+.3} | {sde:.3} | {se:.3} | {secs:.2} | {evals:.0} |",
                p.name,
                p.effect_bounds.len(),
                p.ln_bayes_factor(),
                p.gain
            );
        }
    }
}

/// Writes the problems (designs, data, priors, exact `ln Z`) for other tools.
#[test]
#[ignore = "writes experiments/evidence/problems.json"]
fn export_problems() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/evidence/problems.json");
    let json = serde_json::to_string(&problems()).unwrap();
    std::fs::write(&path, json).unwrap();
    println!("wrote {}", path.display());
}
