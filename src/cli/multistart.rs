//! `frfbayes multistart`: multistart updating of saved problems, timed.
//!
//! For every `*.json` [`ProblemSpec`] in `--problems` (sorted by name; `*.starts.json`
//! files are skipped) it runs [`update`] with `--starts` and `--seed`, and reports per
//! problem the wall time, best cost, best `theta`, how many starts reached the best
//! minimum, and the total wall time. Beside each problem (or in the folder of `--out`)
//! it writes `<name>.starts.json`: the variables, the internal box, the exact start
//! points (internal `z` and physical `theta`), the local solver's settings, and the
//! residuals at two points, so that another solver (paper_repro/scipy_multistart.py)
//! runs the very same objective from the very same starts.
//!
//! ```text
//! frfbayes multistart --problems results/paper_repro/problems --starts 64 --seed 0 \
//!     --out results/speed/rust.json
//! ```
//!
//! The side-by-side speed comparison with scipy runs this command itself:
//!
//! ```text
//! python3 paper_repro/scipy_multistart.py --problems results/paper_repro/problems \
//!     --starts 64 --seed 0 --report results/speed/scipy_vs_rust
//! ```

use anyhow::Context;
use frfbayes::update::{
    internal_start_points, update, MultistartOptions, Problem, ProblemSpec, Scale, TrfOptions,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `frfbayes multistart`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Folder of problem files (`*.json` ProblemSpecs, e.g. written by `frfbayes repro`).
    #[arg(long)]
    pub problems: PathBuf,
    /// Local solves per problem (the first from the variables' start values).
    #[arg(long, default_value_t = 64)]
    pub starts: usize,
    /// Seed of the Latin hypercube start points.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write the JSON summary here (and the start files beside it); without it the JSON
    /// goes to stdout and the start files beside the problems.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// One problem's outcome.
#[derive(Debug, serde::Serialize)]
struct ProblemReport {
    name: String,
    file: PathBuf,
    n_residuals: usize,
    n_free: usize,
    names: Vec<String>,
    wall_s: f64,
    best_cost: f64,
    best_index: usize,
    theta: Vec<f64>,
    physical: Vec<f64>,
    units: Vec<String>,
    n_at_best: usize,
    n_failed: usize,
    n_evaluations: usize,
    n_jacobians: usize,
    n_iterations: usize,
    starts_file: PathBuf,
}

/// The whole run.
#[derive(Debug, serde::Serialize)]
struct Report {
    command: String,
    version: &'static str,
    n_starts: usize,
    seed: u64,
    threads: usize,
    /// Sum of the per-problem solve times.
    total_solve_s: f64,
    /// The whole command, reading and writing included.
    total_wall_s: f64,
    problems: Vec<ProblemReport>,
}

/// A variable as the start file describes it.
#[derive(Debug, serde::Serialize)]
struct VariableEntry {
    name: String,
    unit: String,
    lower: f64,
    upper: f64,
    initial: f64,
    /// `linear` (`z = theta`) or `log` (`z = ln theta`).
    scale: &'static str,
    fixed: Option<f64>,
}

/// Residuals at one `theta`, for checking another implementation of the objective.
#[derive(Debug, serde::Serialize)]
struct Check {
    theta: Vec<f64>,
    residuals: Vec<f64>,
    cost: f64,
}

/// The start file: everything a second solver needs besides the problem itself.
#[derive(Debug, serde::Serialize)]
struct StartsFile {
    problem: String,
    seed: u64,
    n_starts: usize,
    variables: Vec<VariableEntry>,
    /// Indices into `theta` of the free variables, in `z` order.
    free: Vec<usize>,
    lower_z: Vec<f64>,
    upper_z: Vec<f64>,
    starts_z: Vec<Vec<f64>>,
    starts_theta: Vec<Vec<f64>>,
    trf: TrfOptions,
    checks: Vec<Check>,
}

/// Problem files in `dir`, sorted, without start files and without `skip`.
fn problem_files(dir: &Path, skip: Option<&Path>) -> anyhow::Result<Vec<PathBuf>> {
    let entries =
        std::fs::read_dir(dir).with_context(|| format!("cannot list {}", dir.display()))?;
    let skip = skip.and_then(|p| p.canonicalize().ok());
    let mut files = Vec::new();
    for e in entries {
        let path = e
            .with_context(|| format!("cannot list {}", dir.display()))?
            .path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if !name.ends_with(".json") || name.ends_with(".starts.json") {
            continue;
        }
        if skip.is_some() && path.canonicalize().ok() == skip {
            continue;
        }
        files.push(path);
    }
    files.sort();
    if files.is_empty() {
        anyhow::bail!(
            "{} holds no problem files (*.json ProblemSpecs)",
            dir.display()
        );
    }
    Ok(files)
}

fn starts_file(
    problem: &Problem,
    name: &str,
    options: &MultistartOptions,
) -> anyhow::Result<StartsFile> {
    let vars = problem.variables();
    let starts_z = internal_start_points(problem, options)?;
    let starts_theta: Vec<Vec<f64>> = starts_z.iter().map(|z| vars.theta(z)).collect();
    let mut checks = Vec::new();
    for theta in starts_theta.iter().take(2) {
        let residuals = problem.residuals_at(theta)?;
        let cost = 0.5 * residuals.iter().map(|r| r * r).sum::<f64>();
        checks.push(Check {
            theta: theta.clone(),
            residuals,
            cost,
        });
    }
    let bounds = vars.internal_bounds();
    Ok(StartsFile {
        problem: name.to_string(),
        seed: options.seed,
        n_starts: options.n_starts,
        variables: vars
            .variables()
            .iter()
            .map(|v| VariableEntry {
                name: v.name.clone(),
                unit: v.unit.clone(),
                lower: v.lower,
                upper: v.upper,
                initial: v.initial,
                scale: match v.scale {
                    Scale::Linear => "linear",
                    Scale::Log => "log",
                },
                fixed: v.fixed,
            })
            .collect(),
        free: vars.free().to_vec(),
        lower_z: bounds.lower().to_vec(),
        upper_z: bounds.upper().to_vec(),
        starts_z,
        starts_theta,
        trf: options.trf.clone(),
        checks,
    })
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let t_all = Instant::now();
    let files = problem_files(&args.problems, args.out.as_deref())?;
    let options = MultistartOptions {
        n_starts: args.starts,
        seed: args.seed,
        ..Default::default()
    };
    let starts_dir = match &args.out {
        Some(out) => out
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf(),
        None => args.problems.clone(),
    };
    let mut reports = Vec::new();
    for file in &files {
        let name = file
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("problem")
            .to_string();
        let spec = ProblemSpec::read(file)?;
        let problem = Problem::from_spec(&spec)
            .with_context(|| format!("{}: not a valid problem", file.display()))?;
        let starts = starts_file(&problem, &name, &options)
            .with_context(|| format!("{}: cannot prepare the starts", file.display()))?;
        let starts_path = starts_dir.join(format!("{name}.starts.json"));
        frfbayes::io::write_atomic(&starts_path, serde_json::to_string(&starts)?.as_bytes())?;

        let t = Instant::now();
        let result = update(&problem, &options)
            .with_context(|| format!("{}: updating failed", file.display()))?;
        let wall_s = t.elapsed().as_secs_f64();

        let fits: Vec<_> = result
            .starts
            .iter()
            .filter_map(|s| s.fit.as_ref().ok())
            .collect();
        reports.push(ProblemReport {
            name,
            file: file.clone(),
            n_residuals: problem.measured().len(),
            n_free: problem.variables().free().len(),
            names: result.names.clone(),
            wall_s,
            best_cost: result.best.cost,
            best_index: result.best_index,
            theta: result.best.theta.clone(),
            physical: result.best.physical.clone(),
            units: result.units.clone(),
            n_at_best: result.n_at_best,
            n_failed: result.starts.len() - fits.len(),
            n_evaluations: fits.iter().map(|f| f.n_evaluations).sum(),
            n_jacobians: fits.iter().map(|f| f.n_jacobians).sum(),
            n_iterations: fits.iter().map(|f| f.n_iterations).sum(),
            starts_file: starts_path,
        });
    }
    let report = Report {
        command: std::env::args().collect::<Vec<_>>().join(" "),
        version: env!("CARGO_PKG_VERSION"),
        n_starts: args.starts,
        seed: args.seed,
        threads: rayon::current_num_threads(),
        total_solve_s: reports.iter().map(|r| r.wall_s).sum(),
        total_wall_s: t_all.elapsed().as_secs_f64(),
        problems: reports,
    };
    let json = serde_json::to_string_pretty(&report)?;
    match &args.out {
        Some(out) => {
            frfbayes::io::write_atomic(out, json.as_bytes())?;
            println!(
                "{:<28} {:>7} {:>4} {:>9} {:>12} {:>8}",
                "problem", "points", "free", "wall_s", "best_cost", "at_best"
            );
            for r in &report.problems {
                println!(
                    "{:<28} {:>7} {:>4} {:>9.3} {:>12.5e} {:>5}/{}",
                    r.name,
                    r.n_residuals,
                    r.n_free,
                    r.wall_s,
                    r.best_cost,
                    r.n_at_best,
                    args.starts
                );
            }
            println!(
                "total {:.3} s solving ({:.3} s in all) on {} threads; summary in {}",
                report.total_solve_s,
                report.total_wall_s,
                report.threads,
                out.display()
            );
        }
        None => println!("{json}"),
    }
    Ok(())
}
