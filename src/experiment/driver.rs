//! Runs an experiment file end to end: read the campaign, estimate FRFs, update every
//! variant, and write tables, figures, `comparison.md`, `summary.json` and `run.json`
//! into the output folder, which replaces an existing one only when complete.

use super::config::ExperimentConfig;
use super::figures::{comparison_figure, estimate_figures};
use super::pipeline::{run_variant, run_variant_with, TableId, Variant, VariantRun};
use super::report::comparison_markdown;
use super::tables::{PaperTables, ParamTable};
use crate::error::{Error, Result};
use crate::io::{
    read_campaign, resolve_data, write_atomic, Campaign, OutputClaim, RunInfo, StagedDir,
};
use crate::signal::{estimate_campaign, TestFrf};
use crate::update::DampingModel;
use crate::update::{MultistartOptions, Problem, UpdateRecord, UpdateResult};
use std::path::{Path, PathBuf};

/// Progress of a run: `(stage, done, total)`.
pub type Progress<'a> = &'a (dyn Fn(&str, usize, usize) + Sync);

/// What a run produced.
#[derive(Debug)]
pub struct Outcome {
    pub out: PathBuf,
    pub campaign: Campaign,
    pub frfs: Vec<TestFrf>,
    pub runs: Vec<VariantRun>,
    pub info: RunInfo,
}

fn table_from_runs(
    id: TableId,
    runs: &[VariantRun],
    cfg: &ExperimentConfig,
    campaign: &Campaign,
) -> Option<ParamTable> {
    let mine: Vec<&VariantRun> = runs.iter().filter(|r| r.variant.table == id).collect();
    if mine.is_empty() {
        return None;
    }
    let n = campaign.nominal.n_floors();
    let mut t = ParamTable {
        rows: ParamTable::paper_rows(n),
        ..Default::default()
    };
    for (i, m) in campaign.nominal.floor_mass_kg.iter().enumerate() {
        t.initial.insert(format!("m{}", i + 1), *m);
    }
    for (i, k) in campaign.nominal.story_stiffness_n_per_m.iter().enumerate() {
        t.initial.insert(format!("k{}", i + 1), *k);
    }
    let v = &cfg.update.variables;
    t.initial.insert("a0".into(), v.initial_a0_per_s);
    t.initial.insert("a1".into(), v.initial_a1_s);
    for i in 1..=n {
        t.initial.insert(format!("xi{i}"), v.initial_xi);
    }
    for r in mine {
        t.columns
            .insert(r.variant.column(), r.corrected.iter().cloned().collect());
    }
    Some(t)
}

fn summary_json(runs: &[VariantRun]) -> serde_json::Value {
    let variants: Vec<serde_json::Value> = runs
        .iter()
        .map(|r| {
            serde_json::json!({
                "table": r.variant.table.key(),
                "variant": r.variant.column(),
                "n_points": r.n_points,
                "cost": r.result.best.cost,
                "starts": r.result.starts.len(),
                "starts_at_best": r.result.n_at_best,
                "termination": format!("{:?}", r.result.best.termination),
                "on_bounds": r.on_bounds(),
                "fitted": r.fitted.iter().map(|(n, v)| (n.clone(), *v)).collect::<std::collections::BTreeMap<_, _>>(),
                "window_corrected": r.corrected.iter().map(|(n, v)| (n.clone(), *v)).collect::<std::collections::BTreeMap<_, _>>(),
                "window_tau_s": r.window_tau_s,
                "fdac": r.fdac.iter().map(|(l, a, b)| serde_json::json!({"frf": l, "initial": a, "updated": b})).collect::<Vec<_>>(),
                "wall_s": r.wall_s,
            })
        })
        .collect();
    serde_json::json!({ "variants": variants })
}

/// Paper figure number of a figure spec (4, 5, 8, 9), for file names.
fn figure_name(table: &str, damping: DampingModel) -> String {
    let (n, what) = match (table, damping) {
        ("table1", DampingModel::Rayleigh) => (4, "hammer_rayleigh"),
        ("table1", DampingModel::Caughey) => (5, "hammer_caughey"),
        (_, DampingModel::Rayleigh) => (8, "shake_table_rayleigh"),
        (_, DampingModel::Caughey) => (9, "shake_table_caughey"),
    };
    format!("fig{n}_{what}")
}

/// Divides the low-pass `filter` out of every estimate of a channel of its quantity, at
/// `s = j omega + 1/tau` under an exponential window (exact for any LTI sensor). Ground
/// tests' accelerance is relative: `(H_rel + 1) / G - 1`.
pub fn remove_sensor_low_pass(
    frfs: &mut [TestFrf],
    filter: &crate::signal::SensorLowPass,
) -> Result<()> {
    if !(filter.freq_hz > 0.0 && filter.damping_ratio > 0.0) {
        return Err(Error::Usage(format!(
            "sensor_low_pass: freq_hz and damping_ratio must be positive, got {} and {}",
            filter.freq_hz, filter.damping_ratio
        )));
    }
    for t in frfs.iter_mut() {
        let sigma = t.exp_window_tau_s.map_or(0.0, |tau| 1.0 / tau);
        let ground = matches!(t.input, crate::signal::InputKind::Ground { .. });
        let freq = t.freq_hz.clone();
        for r in t
            .responses
            .iter_mut()
            .filter(|r| r.channel.quantity == filter.quantity)
        {
            for (k, f) in freq.iter().enumerate() {
                let s = num_complex::Complex64::new(sigma, 2.0 * std::f64::consts::PI * f);
                let g = crate::discrepancy::hypotheses::low_pass(
                    filter.freq_hz,
                    filter.damping_ratio,
                    s,
                );
                for h in [&mut r.h1[k], &mut r.h2[k]] {
                    *h = if ground { (*h + 1.0) / g - 1.0 } else { *h / g };
                }
            }
        }
    }
    Ok(())
}

/// Every variant's multistart update, one farmed task each (dealt over the ranks of an
/// MPI run, [`crate::dist::farm`]); the variants are then completed from their updates
/// on every rank.
fn update_variants(
    model: &crate::model::StructuralModel,
    frfs: &[TestFrf],
    variants: &[Variant],
    cfg: &ExperimentConfig,
    progress: Progress,
) -> Result<Vec<VariantRun>> {
    let n = variants.len();
    let label = |v: &Variant| format!("updating {} {}", v.table.key(), v.column());
    if let Some(v) = variants.first() {
        progress(&label(v), 0, n);
    }
    let updates = crate::dist::farm(
        n,
        |i| {
            let run = run_variant(model, frfs, variants[i], cfg, cfg.seed)?;
            Ok((UpdateRecord::from(&run.result), run.wall_s))
        },
        |i, _| {
            if let Some(v) = variants.get(i + 1) {
                progress(&label(v), i + 1, n);
            }
            Ok(())
        },
    )?;
    variants
        .iter()
        .zip(updates)
        .map(|(v, (u, wall_s))| {
            let solved = std::cell::RefCell::new(Some(u));
            let solve = |_: &Problem, _: &MultistartOptions| {
                solved
                    .borrow_mut()
                    .take()
                    .map(UpdateResult::from)
                    .ok_or_else(|| Error::Usage("a variant's update was used twice".into()))
            };
            let mut run = run_variant_with(model, frfs, *v, cfg, cfg.seed, &solve)?;
            run.wall_s = wall_s;
            Ok(run)
        })
        .collect()
}

/// Runs the experiment and writes its output folder.
pub fn run_experiment(cfg: &ExperimentConfig, progress: Progress) -> Result<Outcome> {
    // Claim the output folder first: a refusal comes before minutes of updating. Under
    // MPI only rank 0 writes (the others compute alongside and write nothing).
    let claim = match crate::dist::is_root() {
        true => Some(OutputClaim::claim(&cfg.out)?),
        false => None,
    };
    let config_json = serde_json::to_value(cfg).map_err(|e| Error::Usage(e.to_string()))?;
    let mut info = RunInfo::start(cfg.seed, config_json, cfg.data.clone());
    let root = resolve_data(&cfg.data)?;
    progress("reading campaign", 0, 1);
    let campaign = info.time("read_campaign", || read_campaign(&root))?;
    let model = campaign.nominal.structural_model()?;
    progress("estimating FRFs", 0, 1);
    let mut frfs = info.time("estimate_frfs", || {
        estimate_campaign(&campaign, &cfg.estimate.options())
    })?;
    for filter in &cfg.estimate.sensor_low_pass {
        remove_sensor_low_pass(&mut frfs, filter)?;
    }
    let variants: Vec<Variant> = Variant::all()
        .into_iter()
        .filter(|v| frfs.iter().any(|f| v.table.includes(f)))
        .collect();
    let t_update = std::time::Instant::now();
    let runs = update_variants(&model, &frfs, &variants, cfg, progress)?;
    progress("updating", variants.len(), variants.len());
    info.timings_s.push((
        "update_all_variants".into(),
        t_update.elapsed().as_secs_f64(),
    ));
    let posteriors = match &cfg.bayes {
        Some(b) => info.time("sample_posteriors", || {
            super::posterior::sample_variants(cfg, b, &model, &frfs, progress)
        })?,
        None => Vec::new(),
    };

    let Some(claim) = claim else {
        return Ok(Outcome {
            out: cfg.out.clone(),
            campaign,
            frfs,
            runs,
            info,
        });
    };
    let staged = StagedDir::in_claim(claim)?;
    let dir = staged.path().to_path_buf();
    write_tables(&dir, cfg, &runs, &campaign)?;
    info.time("figures", || {
        write_figures(&dir, cfg, &runs, &frfs, progress)
    })?;
    // The eight problems as solved, for side-by-side solver comparisons
    // (`paper_repro/scipy_multistart.py --problems <out>/problems`).
    for r in &runs {
        r.problem.spec().write(&dir.join("problems").join(format!(
            "{}_{}.json",
            r.variant.table.key(),
            r.variant.column()
        )))?;
    }
    info.time("identifiability", || {
        write_identifiability(&dir, &runs, &frfs, &posteriors)
    })?;
    info.write(&dir)?;
    write_html(&dir)?;
    let out = staged.commit()?;
    Ok(Outcome {
        out,
        campaign,
        frfs,
        runs,
        info,
    })
}

/// `table1`, `table2` (ours, when the runs have them), `comparison.md` against the
/// paper's tables and `summary.json` into `dir`.
fn write_tables(
    dir: &Path,
    cfg: &ExperimentConfig,
    runs: &[VariantRun],
    campaign: &Campaign,
) -> Result<()> {
    let paper = PaperTables::bundled()?;
    let t1 = table_from_runs(TableId::Table1, runs, cfg, campaign);
    let t2 = table_from_runs(TableId::Table2, runs, cfg, campaign);
    if let Some(t) = &t1 {
        t.write(
            dir,
            "table1",
            "Table 1. Model updating results from impact hammer tests (ours)",
        )?;
    }
    if let Some(t) = &t2 {
        t.write(
            dir,
            "table2",
            "Table 2. Model updating results from ground excitation (ours)",
        )?;
    }
    let tau = runs.iter().find_map(|r| r.window_tau_s);
    let md = comparison_markdown(
        t1.as_ref(),
        t2.as_ref(),
        &paper.table1,
        &paper.table2,
        runs,
        tau,
    );
    write_atomic(&dir.join("comparison.md"), md.as_bytes())?;
    let summary =
        serde_json::to_vec_pretty(&summary_json(runs)).map_err(|e| Error::Usage(e.to_string()))?;
    write_atomic(&dir.join("summary.json"), &summary)
}

/// The configured comparison figures, and per test its `frf/<test>/frf.csv` and
/// estimation figures, into `dir`.
fn write_figures(
    dir: &Path,
    cfg: &ExperimentConfig,
    runs: &[VariantRun],
    frfs: &[TestFrf],
    progress: Progress,
) -> Result<()> {
    for (i, f) in cfg.figures.iter().enumerate() {
        progress("figures", i, cfg.figures.len());
        comparison_figure(f, runs, frfs, &dir.join(figure_name(&f.table, f.damping)))?;
    }
    for frf in frfs {
        let d = dir.join("frf").join(&frf.test);
        crate::signal::frf_csv::write_frf_csv(&d.join("frf.csv"), frf)?;
        estimate_figures(frf, &d)?;
    }
    Ok(())
}

/// The posterior files and figures (when sampled) and `identifiability.md` into `dir`.
fn write_identifiability(
    dir: &Path,
    runs: &[VariantRun],
    frfs: &[TestFrf],
    posteriors: &[super::posterior::VariantPosterior],
) -> Result<()> {
    use super::posterior_report as pr;
    if !posteriors.is_empty() {
        pr::write_posterior_json(posteriors, dir)?;
        super::posterior_figures::write_posterior_figures(posteriors, dir)?;
    }
    let md = pr::posterior_markdown(posteriors);
    super::identifiability_report::write_identifiability(runs, frfs, dir, &md)?;
    Ok(())
}

/// `report.html` from the Markdown files in `dir`.
fn write_html(dir: &Path) -> Result<()> {
    crate::report::write_html_report(
        dir,
        &crate::report::HtmlReport {
            markdown: &[
                "table1.md",
                "table2.md",
                "comparison.md",
                "identifiability.md",
            ],
            lead: &["In short", "What this says about the paper"],
            tail: crate::report::TAIL,
            title: Some("Paper reproduction: FRF-based model updating of the four-story frame"),
        },
    )?;
    Ok(())
}

/// The output folder of an experiment relative to `base` when it is relative.
pub fn output_dir(base: &Path, out: &Path) -> PathBuf {
    if out.is_absolute() {
        out.to_path_buf()
    } else {
        base.join(out)
    }
}
