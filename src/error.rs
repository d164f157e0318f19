//! Library errors. Every error names what was wrong (file, line, parameter) and why.

use std::path::PathBuf;

/// The error type of every fallible funcorr function.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read or write a file.
    #[error("{path}: {source}")]
    Io {
        /// The file that could not be read or written.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A file's content is malformed.
    #[error("{path}{}: {msg}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        /// The file being read.
        path: PathBuf,
        /// 1-based line number, for text formats, when known.
        line: Option<usize>,
        /// What is wrong.
        msg: String,
    },
    /// A parameter or an in-memory input is invalid (wrong size, out of range, NaN, ...).
    #[error("invalid {what}: {msg}")]
    Invalid {
        /// The parameter or input concerned (e.g. `k`, `mesh`, `landmarks`).
        what: String,
        /// Why it is invalid.
        msg: String,
    },
    /// A numerical method failed (factorization, non-convergence, residual check).
    #[error("numerical failure in {stage}: {msg}")]
    Numerical {
        /// The computation that failed (e.g. `eigensolver`).
        stage: String,
        /// What happened.
        msg: String,
    },
}

/// Result alias with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Builds an [`Error::Parse`].
    pub fn parse(path: impl Into<PathBuf>, line: Option<usize>, msg: impl Into<String>) -> Self {
        Error::Parse { path: path.into(), line, msg: msg.into() }
    }
    /// Builds an [`Error::Invalid`].
    pub fn invalid(what: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Invalid { what: what.into(), msg: msg.into() }
    }
    /// Builds an [`Error::Numerical`].
    pub fn numerical(stage: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Numerical { stage: stage.into(), msg: msg.into() }
    }
    /// Builds an [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
}
