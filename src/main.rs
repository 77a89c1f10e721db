//! The `frfbayes` command line: parses arguments and calls the library.

mod cli;

use clap::{Parser, Subcommand};

/// FRF-based model updating with Bayesian uncertainty and missing-physics diagnosis.
#[derive(Debug, Parser)]
#[command(name = "frfbayes", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Read and validate a campaign, and summarise it.
    Check(cli::check::Args),
    /// Estimate FRFs (H1, coherence, half-power bands) from a campaign's recordings.
    Frf(cli::frf::Args),
    /// Print the nominal natural frequencies and mode shapes of a campaign's model.
    Modes(cli::modes::Args),
    /// Timed multistart updating of saved problems (ProblemSpec JSON files).
    Multistart(cli::multistart::Args),
    /// Reproduce the paper (Tables 1-2, Figures 4, 5, 8, 9) on the bundled campaign.
    Repro(cli::repro::ReproArgs),
    /// Run an experiment file (experiments/<name>.toml).
    Run(cli::repro::RunArgs),
    /// Studies on real measurements (../shared/data/real): four-story-modal, wheel-frf, tower-hmd.
    Real(cli::real::Args),
    /// Sample the posterior of masses, stiffnesses and damping given a campaign's FRFs.
    Sample(cli::sample::Args),
    /// Simulate a campaign with known truth from a model file.
    Simulate(cli::simulate::Args),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Check(a) => cli::check::run(a),
        Command::Frf(a) => cli::frf::run(a),
        Command::Modes(a) => cli::modes::run(a),
        Command::Multistart(a) => cli::multistart::run(a),
        Command::Repro(a) => cli::repro::repro(a),
        Command::Run(a) => cli::repro::run(a),
        Command::Real(a) => cli::real::run_cmd(a),
        Command::Sample(a) => cli::sample::run(a),
        Command::Simulate(a) => cli::simulate::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
