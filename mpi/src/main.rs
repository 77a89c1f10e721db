//! `frfbayes-mpi`: the `frfbayes` command line built against the system's MPI library,
//! for runs spread over ranks (`mpirun -n N frfbayes-mpi sample ...`; see
//! [`frfbayes::dist`]). Started without an MPI launcher it is one process, as
//! `frfbayes`. A package of its own, so that the MPI build compiles only the MPI crates
//! and this binary against the library the default build compiled.

#[path = "../../src/cli/mod.rs"]
mod cli;
mod world;

fn main() -> std::process::ExitCode {
    cli::app::main_with(world::init)
}
