//! The crate's one error type. Every variant names what went wrong and, where a user
//! file is involved, which file (and line/column) and what to fix.

use std::path::PathBuf;

/// Errors from frfbayes. User input never panics: it ends up here.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file is present but its content is wrong; `what` says what to fix.
    #[error("{path}: {what}")]
    Invalid { path: PathBuf, what: String },
    /// A data file has a bad cell, with its 1-based line and column.
    #[error("{path}:{line}:{column}: {what}")]
    Cell {
        path: PathBuf,
        line: usize,
        column: usize,
        what: String,
    },
    /// A model (matrices or parameters) is not physically admissible.
    #[error("model: {0}")]
    Model(String),
    /// A numerical failure (eigen-solver, singular matrix, non-finite value).
    #[error("numerical: {0}")]
    Numerical(String),
    /// A caller passed arguments that do not fit together.
    #[error("{0}")]
    Usage(String),
    /// A rank of a run spread over several processes failed (see [`crate::dist`]);
    /// every rank returns the same error.
    #[error("rank {rank} of {size} failed: {what}")]
    Distributed {
        rank: usize,
        size: usize,
        what: String,
    },
}

/// Result with the crate's error.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Wrap an `std::io::Error` with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// A content error in `path`.
    pub fn invalid(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        Error::Invalid {
            path: path.into(),
            what: what.into(),
        }
    }
}
