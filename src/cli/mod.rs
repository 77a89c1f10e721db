//! Command implementations; each file parses nothing itself beyond its clap `Args` and
//! calls the library.

pub mod app;
pub mod check;
pub mod diagnose;
pub mod frf;
pub mod modes;
pub mod multistart;
pub mod real;
pub mod repro;
pub mod sample;
pub mod simulate;
