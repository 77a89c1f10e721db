//! The command line itself: arguments, the dispatch to the commands, and how errors are
//! reported. Shared by the `frfbayes` binary and the MPI build's `frfbayes-mpi`
//! (`mpi/`), which differ only in the world they install before the command runs.

use clap::{Parser, Subcommand};

/// FRF-based model updating with Bayesian uncertainty and missing-physics diagnosis.
#[derive(Debug, Parser)]
#[command(name = "frfbayes", version, about, long_about = None)]
struct Cli {
    /// Worker threads (default: all logical cores, or RAYON_NUM_THREADS).
    #[arg(long, global = true, value_name = "N")]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read and validate a campaign, and summarise it.
    Check(super::check::Args),
    /// Find what physics the nominal model leaves out (verdict, location, effect, evidence).
    Diagnose(super::diagnose::Args),
    /// Run `diagnose` on the simulated missing-physics benchmark and score it.
    DiagnoseBenchmark(super::diagnose::BenchArgs),
    /// Estimate FRFs (H1, coherence, half-power bands) from a campaign's recordings.
    Frf(super::frf::Args),
    /// Print the nominal natural frequencies and mode shapes of a campaign's model.
    Modes(super::modes::Args),
    /// Timed multistart updating of saved problems (ProblemSpec JSON files).
    Multistart(super::multistart::Args),
    /// Reproduce the paper (Tables 1-2, Figures 4, 5, 8, 9) on the bundled campaign.
    Repro(super::repro::ReproArgs),
    /// Run an experiment file (experiments/<name>.toml).
    Run(super::repro::RunArgs),
    /// Studies on real measurements (../shared/data/real): four-story-modal, wheel-frf, tower-hmd.
    Real(super::real::Args),
    /// Sample the posterior of masses, stiffnesses and damping given a campaign's FRFs
    /// (shear frame or general model: the campaign's manifest gives the variables).
    Sample(super::sample::Args),
    /// Maximum-likelihood update of the same model (multistart least squares on the
    /// standardised FRF magnitudes, Gauss-Newton sd): takes `sample`'s flags, writes fit.json.
    Fit(super::sample::Args),
    /// Simulate a campaign with known truth from a model file.
    Simulate(super::simulate::Args),
}

/// Parses the command line and runs the command; `init_world` runs after the thread
/// pool is set up and before the command, and what it returns lives until the command
/// has finished (the `frfbayes-mpi` binary's MPI session, [`frfbayes::dist`]).
pub fn main_with<S>(init_world: impl FnOnce() -> frfbayes::Result<S>) -> std::process::ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        if n == 0 {
            eprintln!("error: --threads 0: give a number of threads of at least 1");
            return std::process::ExitCode::FAILURE;
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: --threads {n}: {e}");
            return std::process::ExitCode::FAILURE;
        }
    }
    // Under `mpirun` (the `frfbayes-mpi` binary), every rank runs the command
    // (frfbayes::dist).
    let _world = match init_world() {
        Ok(session) => session,
        Err(e) => {
            eprintln!("error: MPI: {e}");
            return std::process::ExitCode::FAILURE;
        }
    };
    frfbayes::io::output::set_command(command_name(&cli.command));
    if !frfbayes::dist::is_root() && !spreads_over_ranks(&cli.command) {
        // A command that does not spread its work runs on rank 0 alone.
        return std::process::ExitCode::SUCCESS;
    }
    let result = match cli.command {
        Command::Check(a) => super::check::run(a),
        Command::Diagnose(a) => super::diagnose::run(a),
        Command::DiagnoseBenchmark(a) => super::diagnose::bench(a),
        Command::Frf(a) => super::frf::run(a),
        Command::Modes(a) => super::modes::run(a),
        Command::Multistart(a) => super::multistart::run(a),
        Command::Repro(a) => super::repro::repro(a),
        Command::Run(a) => super::repro::run(a),
        Command::Real(a) => super::real::run_cmd(a),
        Command::Sample(a) => super::sample::run(a),
        Command::Fit(a) => super::sample::fit(a),
        Command::Simulate(a) => super::simulate::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            let world = frfbayes::dist::world();
            if world.size() > 1 {
                report_rank_failure(&e, world);
                return std::process::ExitCode::FAILURE;
            }
            eprintln!("error: {}", error_text(&e));
            if let Some(hint) = io_hint(&e) {
                eprintln!("hint: {hint}");
            }
            std::process::ExitCode::FAILURE
        }
    }
}

/// A failed command on one rank of several: an error every rank shares (gathered,
/// `Error::Distributed`) is reported once, by rank 0, and every rank ends normally; any
/// other error is this rank's alone, so the others would wait for it forever: it is
/// reported with the rank and the whole run is aborted.
fn report_rank_failure(e: &anyhow::Error, world: &dyn frfbayes::dist::Comm) {
    let shared = e.chain().any(|c| {
        matches!(
            c.downcast_ref::<frfbayes::Error>(),
            Some(frfbayes::Error::Distributed { .. })
        )
    });
    if shared {
        if world.rank() == 0 {
            eprintln!("error: {}", error_text(e));
        }
    } else {
        eprintln!(
            "error on rank {} of {}: {}; aborting every rank",
            world.rank(),
            world.size(),
            error_text(e)
        );
        world.abort(1);
    }
}

/// Commands whose work is spread over the ranks of an MPI run (every rank runs them).
fn spreads_over_ranks(c: &Command) -> bool {
    matches!(
        c,
        Command::Sample(_)
            | Command::Diagnose(_)
            | Command::DiagnoseBenchmark(_)
            | Command::Repro(_)
            | Command::Run(_)
            | Command::Real(_)
    )
}

/// The subcommand's name as typed (recorded in the output folders' manifests).
fn command_name(c: &Command) -> &'static str {
    match c {
        Command::Check(_) => "check",
        Command::Diagnose(_) => "diagnose",
        Command::DiagnoseBenchmark(_) => "diagnose-benchmark",
        Command::Frf(_) => "frf",
        Command::Modes(_) => "modes",
        Command::Multistart(_) => "multistart",
        // `repro` is `run experiments/paper_repro.toml`: one family, one folder.
        Command::Repro(_) => "run",
        Command::Run(_) => "run",
        Command::Real(_) => "real",
        Command::Sample(_) => "sample",
        Command::Fit(_) => "fit",
        Command::Simulate(_) => "simulate",
    }
}

/// The error and its causes, each cause shown once (an I/O error is both in its
/// parent's message and the parent's source).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if !text.contains(&s) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&s);
        }
    }
    text
}

/// What to do about an error of the file system (issue 16): outputs are built aside,
/// so the previous results are as they were.
fn io_hint(e: &anyhow::Error) -> Option<&'static str> {
    use std::io::ErrorKind as K;
    let kind = e
        .chain()
        .find_map(|c| c.downcast_ref::<std::io::Error>())?
        .kind();
    Some(match kind {
        K::StorageFull | K::FileTooLarge | K::QuotaExceeded => {
            "the disk (or a size limit) is full: free space or write elsewhere; nothing \
             was replaced, previous results are as they were"
        }
        K::PermissionDenied | K::ReadOnlyFilesystem => {
            "that folder is not writable: fix its permissions or choose another output \
             folder; nothing was replaced, previous results are as they were"
        }
        _ => return None,
    })
}
