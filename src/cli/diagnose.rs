//! `frfbayes diagnose <CAMPAIGN> --out <DIR>`: what physics, if any, the nominal model
//! leaves out; and `frfbayes diagnose-benchmark`: the same on the simulated benchmark.

use frfbayes::discrepancy::benchmark::{
    benchmark_markdown, read_cases, BenchmarkCase, CaseOutcome,
};
use frfbayes::discrepancy::data::{DataOptions, GainCarrier};
use frfbayes::discrepancy::diagnose::{
    diagnose_resumable, DiagnoseOptions, DiagnoseStage, Diagnosis,
};
use frfbayes::discrepancy::output::write_diagnosis_into;
use frfbayes::discrepancy::report::record;
use frfbayes::discrepancy::DiagnosisRecord;
use frfbayes::dist;
use frfbayes::infer::evidence::EvidenceOptions;
use frfbayes::infer::evidence::Stage;
use frfbayes::io::stages::{fingerprint_folder, fingerprint_setting, Stages};
use frfbayes::io::{
    read_campaign, read_tree, write_atomic, write_tree, Campaign, OutputClaim, ScratchDir,
    StagedDir,
};
use frfbayes::simulate::{SimModel, Simulator};
use frfbayes::Error;
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The analysed band and the noise model of a diagnosis: `diagnose`'s and
/// `diagnose-benchmark`'s flags.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct NoiseModelArgs {
    /// Do not correct the hammer estimates' own systematic error (the previous impact's
    /// ringing, the cut before the next one), which is otherwise measured by replaying
    /// the tests at the nominal fit and again at each accepted model's (see
    /// docs/diagnose.md, "False alarms").
    #[arg(long)]
    pub no_estimator_bias: bool,
    /// Compare the models with the measured ratios times 1 + 2 eps^2 (capped at 1.1), which
    /// removes to second order the bias of errors scaled by the measured |h| (experimental:
    /// see docs/diagnose.md, "Why the structural sizes are biased").
    #[arg(long)]
    pub weight_bias_correction: bool,
    /// What the input-gain error of a hammer segment multiplies in the likelihood's
    /// covariance (docs/diagnose.md, "Why the structural sizes are biased"): `model-at-map`, each
    /// model's own H at its MAP (the default); `measured`, the measured h (the former
    /// default: its noise is correlated with the residual it weighs); `model`, the
    /// model's H at every evaluation.
    #[arg(long, value_enum)]
    pub gain_carrier: Option<GainCarrierArg>,
    /// Take the channels of a shake-table record as independent, without the relative
    /// error the ground channel's noise puts on all of them at once, bin by bin (the
    /// former default; docs/diagnose.md, "The shake table's common input error").
    #[arg(long)]
    pub channels_independent: bool,
    /// Same as `--gain-carrier model-at-map` (kept for earlier scripts).
    #[arg(long, hide = true, conflicts_with_all = ["gain_carrier", "gain_on_model"])]
    pub gain_at_map: bool,
    /// Same as `--gain-carrier model` (kept for earlier scripts).
    #[arg(long, hide = true, conflicts_with = "gain_carrier")]
    pub gain_on_model: bool,
    /// Top of the analysed band, Hz (default: 4 x the nominal model's highest mode; a
    /// model of more than 200 DOFs, reduced for the diagnosis, 0.4 x the sample rate).
    /// In `diagnose-benchmark` a case's own `freq_max_hz` comes first.
    #[arg(long)]
    pub freq_max_hz: Option<f64>,
}

/// The `--gain-carrier` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum GainCarrierArg {
    Measured,
    Model,
    ModelAtMap,
}

impl NoiseModelArgs {
    /// The carrier the flags ask for; the library's default without them.
    fn carrier(self) -> GainCarrier {
        match (self.gain_carrier, self.gain_on_model, self.gain_at_map) {
            (Some(GainCarrierArg::Measured), _, _) => GainCarrier::Measured,
            (Some(GainCarrierArg::Model), _, _) | (None, true, _) => GainCarrier::Model,
            (Some(GainCarrierArg::ModelAtMap), _, _) | (None, _, true) => GainCarrier::ModelAtMap,
            (None, false, false) => DataOptions::default().gain_carrier,
        }
    }

    /// Default diagnosis options with these flags applied.
    fn options(self) -> DiagnoseOptions {
        DiagnoseOptions {
            estimator_bias: !self.no_estimator_bias,
            data: DataOptions {
                weight_bias_correction: self.weight_bias_correction,
                gain_carrier: self.carrier(),
                common_input_error: !self.channels_independent,
                freq_max_hz: self.freq_max_hz,
                ..DataOptions::default()
            },
            ..DiagnoseOptions::default()
        }
    }
}

/// Arguments of `frfbayes diagnose`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Campaign folder (the recording format of ../shared/spec), or bundled:four-story.
    pub campaign: String,
    /// Output folder (diagnosis.json, diagnosis.md, figures); replaced only on success.
    #[arg(long)]
    pub out: PathBuf,
    /// Master seed (same seed, same result, whatever the thread count).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only these hypotheses (comma separated names); all by default.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    #[command(flatten)]
    pub noise: NoiseModelArgs,
    /// Continue an interrupted run into the same --out from its last complete stage
    /// (the result is the same as an uninterrupted run's). Without it, an interrupted
    /// run's stages are discarded.
    #[arg(long)]
    pub resume: bool,
    /// Tiny settings (2 frame starts, 1 effect start, short evidence runs) for tests of
    /// the command itself: the verdict is not meaningful.
    #[arg(long, hide = true)]
    pub quick: bool,
}

fn spinner() -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{elapsed_precise} {spinner} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    pb.enable_steady_tick(std::time::Duration::from_millis(200));
    pb
}

fn stage_message(stage: &DiagnoseStage<'_>) -> String {
    match stage {
        DiagnoseStage::Data => "estimating FRFs".into(),
        DiagnoseStage::NominalFit => "fitting the nominal model".into(),
        DiagnoseStage::Search {
            hypothesis,
            location,
        } => format!("fitting {hypothesis} at {location}"),
        DiagnoseStage::Evidence { model, progress } => match progress.stage {
            Stage::Tempering { temperature, beta } => format!(
                "evidence of {model}: replicate {}/{}, temperature {temperature}, beta {beta:.2e}",
                progress.replicate + 1,
                progress.n_replicates
            ),
            Stage::Sampling { step, of } => format!(
                "evidence of {model}: replicate {}/{}, posterior draws {step}/{of}",
                progress.replicate + 1,
                progress.n_replicates
            ),
        },
        DiagnoseStage::HeldOut {
            hypothesis,
            done,
            of,
        } => format!("held-out check of {hypothesis}: {done}/{of} segments"),
        DiagnoseStage::TimeDomain { hypothesis } => {
            format!("refitting {hypothesis} by replaying the tests in the time domain")
        }
    }
}

fn open_campaign(spec: &str) -> anyhow::Result<(Campaign, PathBuf)> {
    let path = frfbayes::io::resolve_data(spec)?;
    let c = read_campaign(&path)?;
    for w in &c.warnings {
        eprintln!("warning: {w}");
    }
    Ok((c, path))
}

/// The hidden `--quick` settings.
fn quick_options(mut opts: DiagnoseOptions) -> DiagnoseOptions {
    opts.n_frame_starts = 2;
    opts.n_effect_starts = 1;
    opts.map.trf.max_evaluations = Some(40);
    opts.map.max_eta_rounds = 2;
    opts.evidence = Some(EvidenceOptions {
        n_replicates: 2,
        min_steps_per_temperature: 1,
        max_steps_per_temperature: 3,
        final_steps: 10,
        ..EvidenceOptions::new(1, 0)
    });
    opts
}

/// Diagnoses `campaign` (its folder `source`) into `out`: the folder is claimed first,
/// every long stage is saved beside it (`.<out>.frfbayes-partial`) for `resume`, and the
/// output replaces `out` only when complete. Under MPI this is rank 0's part; the other
/// ranks run [`compute_elsewhere`] alongside.
fn run_one(
    campaign: &Campaign,
    source: &Path,
    opts: &DiagnoseOptions,
    out: &Path,
    resume: bool,
) -> anyhow::Result<frfbayes::discrepancy::DiagnosisRecord> {
    let opened = open_stages(source, opts, out, resume);
    // The other ranks read the stages only once they are checked (or cleared).
    dist::barrier(opened.as_ref().map(|_| ()).map_err(|e| e.to_string()))?;
    let (claim, stages) = opened?;
    let partial = claim.partial_path();
    let pb = spinner();
    let mut cb = |s: DiagnoseStage<'_>| pb.set_message(stage_message(&s));
    let d = diagnose_resumable(campaign, opts, Some(&stages), &mut cb);
    pb.finish_and_clear();
    let d = d?;
    let staged = StagedDir::in_claim(claim)?;
    write_diagnosis_into(&d, &campaign.title, staged.path())?;
    let dir = staged.commit()?;
    if let Err(e) = std::fs::remove_dir_all(&partial) {
        eprintln!("warning: {}: could not delete ({e})", partial.display());
    }
    let rec = record(&d);
    println!(
        "{}: verdict {} at {} ({:.0} s); written to {}",
        campaign.title,
        rec.verdict,
        rec.location,
        d.elapsed_s,
        dir.display()
    );
    Ok(rec)
}

/// Claims `out` and opens the stages of its diagnosis.
fn open_stages(
    source: &Path,
    opts: &DiagnoseOptions,
    out: &Path,
    resume: bool,
) -> anyhow::Result<(OutputClaim, Stages)> {
    let claim = OutputClaim::claim(out)?;
    let partial = claim.partial_path();
    if partial.exists() && !resume {
        eprintln!(
            "note: discarding the stages of an interrupted run in {} (--resume continues it)",
            partial.display()
        );
    }
    let mut inputs = fingerprint_folder(source)?;
    inputs.push(fingerprint_setting("settings", &format!("{opts:?}")));
    inputs.push(fingerprint_setting("version", env!("CARGO_PKG_VERSION")));
    let stages = Stages::open(&partial, resume, &inputs)?;
    Ok((claim, stages))
}

/// The diagnosis [`run_one`] makes, on a rank other than 0 of an MPI run: computed
/// alongside rank 0 (the evidence runs of the hypotheses are shared out), reading back
/// the stages rank 0 saved when resuming, writing nothing.
fn compute_elsewhere(
    campaign: &Campaign,
    opts: &DiagnoseOptions,
    out: &Path,
    resume: bool,
) -> anyhow::Result<Diagnosis> {
    dist::barrier(Ok(()))?;
    let partial = frfbayes::io::partial_path_of(out);
    let stages = (resume && partial.is_dir()).then(|| Stages::read_only(&partial));
    Ok(diagnose_resumable(
        campaign,
        opts,
        stages.as_ref(),
        &mut |_| {},
    )?)
}

/// Runs `frfbayes diagnose`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (campaign, source) = open_campaign(&args.campaign)?;
    let mut opts = DiagnoseOptions {
        seed: args.seed,
        only: args.only,
        ..args.noise.options()
    };
    if args.quick {
        opts = quick_options(opts);
    }
    if !dist::is_root() {
        compute_elsewhere(&campaign, &opts, &args.out, args.resume)?;
        return Ok(());
    }
    let rec = run_one(&campaign, &source, &opts, &args.out, args.resume)?;
    println!("{}", rec.explanation);
    Ok(())
}

/// Arguments of `frfbayes diagnose-benchmark`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Case list.
    #[arg(long, default_value = "experiments/models/discrepancy/cases.toml")]
    pub cases: PathBuf,
    /// Folder for the simulated campaigns (reused when present) and every diagnosis.
    #[arg(long)]
    pub work: PathBuf,
    /// The report (Markdown; a JSON of every outcome is written beside it).
    #[arg(long, default_value = "results/discrepancy_benchmark.md")]
    pub report: PathBuf,
    /// Only these case ids (comma separated); all by default.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// The noise model of every diagnosis (as `diagnose`'s flags).
    #[command(flatten)]
    pub noise: NoiseModelArgs,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Continue the case an interrupted run was diagnosing from its last complete stage
    /// (cases already diagnosed are always read back).
    #[arg(long)]
    pub resume: bool,
    /// `diagnose --quick` settings (tests of the command itself).
    #[arg(long, hide = true)]
    pub quick: bool,
    /// Only these hypotheses in every diagnosis (`diagnose --only`; tests of the
    /// command itself: the benchmark's verdicts need all of them).
    #[arg(long, hide = true, value_delimiter = ',')]
    pub hypotheses: Vec<String>,
}

/// One diagnosed case as it travels to rank 0: the files of its output folder when
/// another rank computed it (rank 0 writes its own cases directly).
#[derive(serde::Serialize, serde::Deserialize)]
struct CaseRun {
    record: DiagnosisRecord,
    seconds: f64,
    files: Vec<(String, Vec<u8>)>,
}

/// The case's campaign folder and output folder.
fn case_dirs(work: &Path, case: &BenchmarkCase) -> (PathBuf, PathBuf) {
    (
        work.join("campaigns").join(&case.id),
        work.join("diagnoses").join(&case.id),
    )
}

/// Simulates the campaigns not yet in `work` (rank 0; the others wait and read them).
fn simulate_missing(work: &Path, cases: &[BenchmarkCase]) -> anyhow::Result<()> {
    let simulate = || -> anyhow::Result<()> {
        if !dist::is_root() {
            return Ok(());
        }
        for case in cases {
            let (campaign_dir, _) = case_dirs(work, case);
            if !campaign_dir.join("campaign.toml").exists() {
                eprintln!("simulating {}", case.id);
                let sim = Simulator::new(SimModel::from_path(&case.model)?)?;
                let campaign = sim.run(case.seed, &|_| {})?;
                frfbayes::io::write_campaign(&campaign, &campaign_dir)?;
            }
        }
        Ok(())
    };
    let done = simulate();
    dist::barrier(done.as_ref().map(|_| ()).map_err(|e| format!("{e:#}")))?;
    done
}

/// Diagnoses one case: on rank 0 into its output folder (with resumable stages), on
/// another rank into a scratch folder whose files go to rank 0.
fn diagnose_case(args: &BenchArgs, case: &BenchmarkCase) -> anyhow::Result<CaseRun> {
    let (campaign_dir, out_dir) = case_dirs(&args.work, case);
    let campaign = read_campaign(&campaign_dir)?;
    let t0 = Instant::now();
    let mut opts = DiagnoseOptions {
        seed: args.seed,
        only: args.hypotheses.clone(),
        ..args.noise.options()
    };
    if case.freq_max_hz.is_some() {
        opts.data.freq_max_hz = case.freq_max_hz;
    }
    if args.quick {
        opts = quick_options(opts);
    }
    if dist::is_root() {
        let record = run_one(&campaign, &campaign_dir, &opts, &out_dir, args.resume)?;
        let seconds = t0.elapsed().as_secs_f64();
        write_seconds(&out_dir, seconds)?;
        return Ok(CaseRun {
            record,
            seconds,
            files: Vec::new(),
        });
    }
    let d = compute_elsewhere(&campaign, &opts, &out_dir, args.resume)?;
    let scratch = ScratchDir::new("diagnosis")?;
    write_diagnosis_into(&d, &campaign.title, scratch.path())?;
    eprintln!("{}: diagnosed on rank {}", case.id, dist::world().rank());
    Ok(CaseRun {
        record: record(&d),
        seconds: t0.elapsed().as_secs_f64(),
        files: read_tree(scratch.path())?,
    })
}

fn write_seconds(out_dir: &Path, seconds: f64) -> anyhow::Result<()> {
    write_atomic(
        &out_dir.join("seconds.txt"),
        format!("{seconds:.1}\n").as_bytes(),
    )?;
    Ok(())
}

/// Rank 0 writes a case another rank diagnosed (as [`run_one`] would have).
fn write_case(out_dir: &Path, run: &CaseRun) -> anyhow::Result<()> {
    if run.files.is_empty() {
        return Ok(());
    }
    let claim = OutputClaim::claim(out_dir)?;
    let partial = claim.partial_path();
    let staged = StagedDir::in_claim(claim)?;
    write_tree(staged.path(), &run.files)?;
    staged.commit()?;
    if partial.exists() {
        if let Err(e) = std::fs::remove_dir_all(&partial) {
            eprintln!("warning: {}: could not delete ({e})", partial.display());
        }
    }
    write_seconds(out_dir, run.seconds)
}

/// A case diagnosed by an earlier run, read back from `work`.
fn read_back(out_dir: &Path) -> anyhow::Result<(DiagnosisRecord, f64)> {
    let done = out_dir.join("diagnosis.json");
    let text = std::fs::read_to_string(&done)?;
    let record: DiagnosisRecord =
        serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", done.display()))?;
    let seconds = std::fs::read_to_string(out_dir.join("seconds.txt"))
        .ok()
        .and_then(|t| t.trim().parse().ok())
        .unwrap_or(f64::NAN);
    Ok((record, seconds))
}

/// Channel name -> quantity name of a campaign.
fn channel_quantities(campaign: &Campaign) -> BTreeMap<String, String> {
    campaign
        .tests
        .iter()
        .flat_map(|t| t.channels.iter())
        .map(|c| {
            (
                c.name.clone(),
                serde_json::to_value(c.quantity)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default(),
            )
        })
        .collect()
}

/// Runs `frfbayes diagnose-benchmark`. Under MPI the cases not yet diagnosed are dealt
/// over the ranks (`frfbayes::dist::farm`) and rank 0 writes each as its round ends.
pub fn bench(args: BenchArgs) -> anyhow::Result<()> {
    let (hypotheses, cases) = read_cases(&args.cases)?;
    let cases: Vec<BenchmarkCase> = cases
        .into_iter()
        .filter(|c| args.only.is_empty() || args.only.contains(&c.id))
        .collect();
    simulate_missing(&args.work, &cases)?;
    // Resumable: a case already diagnosed in `work` is read back, not run again (rank 0
    // decides, from the folders it wrote).
    let done = |c: &BenchmarkCase| case_dirs(&args.work, c).1.join("diagnosis.json").exists();
    let pending: Vec<usize> = (0..cases.len()).filter(|&i| !done(&cases[i])).collect();
    let pending = dist::from_root(&pending)?;
    let runs = dist::farm(
        pending.len(),
        |k| diagnose_case(&args, &cases[pending[k]]).map_err(|e| Error::Usage(format!("{e:#}"))),
        |k, run| {
            let (_, out_dir) = case_dirs(&args.work, &cases[pending[k]]);
            write_case(&out_dir, run).map_err(|e| Error::Usage(format!("{e:#}")))
        },
    )?;
    if !dist::is_root() {
        return Ok(());
    }
    let mut runs: BTreeMap<usize, CaseRun> = pending.into_iter().zip(runs).collect();
    let mut outcomes = Vec::new();
    for (i, case) in cases.into_iter().enumerate() {
        let (campaign_dir, out_dir) = case_dirs(&args.work, &case);
        let campaign = read_campaign(&campaign_dir)?;
        let (record, seconds) = match runs.remove(&i) {
            Some(run) => (run.record, run.seconds),
            None => {
                eprintln!("{}: read back from {}", case.id, out_dir.display());
                read_back(&out_dir)?
            }
        };
        outcomes.push(CaseOutcome {
            channel_quantity: channel_quantities(&campaign),
            case,
            record,
            seconds,
        });
    }
    let md = benchmark_markdown(&outcomes, &hypotheses, "Missing-physics benchmark");
    write_atomic(&args.report, md.as_bytes())?;
    let json = serde_json::to_string_pretty(&outcomes)?;
    write_atomic(&args.report.with_extension("json"), json.as_bytes())?;
    println!("{md}");
    Ok(())
}
