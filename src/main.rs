//! The `frfbayes` command line: parses arguments and calls the library
//! ([`cli::app::main_with`]; one process, no MPI world).

mod cli;

fn main() -> std::process::ExitCode {
    cli::app::main_with(|| Ok(()))
}
