//! One evaluation of `diagnose`'s forward model ([`ExtendedModel::predict`]) on a
//! campaign of a general model: the modal fast path against the dense solve
//! ([`ExtendedModel::dense`]), for the nominal model, an oscillator and a damper.
//!
//! The campaign is the user's (a folder, `FRFBAYES_BENCH_CAMPAIGN`), for example the
//! bridge null campaign of the README:
//!
//! ```text
//! frfbayes simulate --model experiments/models/discrepancy/bridge/bridge-none.toml --out /tmp/bridge-none
//! FRFBAYES_BENCH_CAMPAIGN=/tmp/bridge-none FRFBAYES_BENCH_FREQ_MAX_HZ=15.5 \
//!     cargo bench --bench diagnose_forward
//! ```
//!
//! Without the variable the bench says so and measures nothing.

use criterion::{criterion_group, Criterion};
use frfbayes::discrepancy::data::{DataOptions, DiagnosisData};
use frfbayes::discrepancy::forward::{BaseParams, ExtendedModel};
use frfbayes::discrepancy::hypotheses::hypothesis_by_name;
use frfbayes::discrepancy::hypothesis::Hypothesis;
use frfbayes::io::read_campaign;
use std::path::PathBuf;
use std::sync::Arc;

/// The nominal model, and the first location of an oscillator and of a damper, with
/// effect values inside their priors.
fn models(data: &Arc<DiagnosisData>) -> Vec<(String, ExtendedModel, Vec<f64>)> {
    let mut out = vec![(
        "nominal".to_string(),
        ExtendedModel::new(data.clone(), None).unwrap(),
        Vec::new(),
    )];
    for name in ["secondary_oscillator", "nonproportional_damping"] {
        let h: Arc<dyn Hypothesis> = Arc::from(hypothesis_by_name(name).unwrap());
        let Some(loc) = h.locations(data).into_iter().next() else {
            continue;
        };
        let params = h.parameters(data, &loc).unwrap();
        let z: Vec<f64> = params.iter().map(|p| 0.5 * (p.lower + p.upper)).collect();
        let effect = h.physical(data, &loc, &z).unwrap();
        let model = ExtendedModel::new(data.clone(), Some((h, loc))).unwrap();
        out.push((name.to_string(), model, effect));
    }
    out
}

fn bench(c: &mut Criterion) {
    let Some(dir) = std::env::var_os("FRFBAYES_BENCH_CAMPAIGN").map(PathBuf::from) else {
        eprintln!(
            "diagnose_forward: set FRFBAYES_BENCH_CAMPAIGN to a campaign folder; nothing measured"
        );
        return;
    };
    let campaign = read_campaign(&dir).unwrap();
    let options = DataOptions {
        freq_max_hz: std::env::var("FRFBAYES_BENCH_FREQ_MAX_HZ")
            .ok()
            .map(|v| v.parse().unwrap()),
        ..DataOptions::default()
    };
    let data = Arc::new(DiagnosisData::from_campaign(&campaign, &options).unwrap());
    let base = BaseParams {
        stiffness_scale: vec![1.0; data.model.n_alpha()],
        mass_scale: vec![1.0; data.model.n_beta()],
        xi: vec![0.015; data.nominal_freq_hz.len()],
    };
    eprintln!(
        "diagnose_forward: {} DOFs, {} points",
        data.model.n_dof(),
        data.n_points()
    );
    let mut group = c.benchmark_group("diagnose_forward");
    group.sample_size(20);
    for (name, model, effect) in models(&data) {
        let dense = model.clone().dense();
        group.bench_function(format!("{name}/modal"), |b| {
            b.iter(|| model.predict(&base, &effect).unwrap())
        });
        group.bench_function(format!("{name}/dense"), |b| {
            b.iter(|| dense.predict(&base, &effect).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
}
