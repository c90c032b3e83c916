//! The eval library's one error type. Every variant names the file or the
//! detector it is about, because a user reading it has many of each.

use std::path::PathBuf;

use thiserror::Error;

/// Everything that can go wrong while running or evaluating detectors.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum EvalError {
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Writing an output file failed (nothing is left behind).
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file is not what it should be (truncated MCAP, bad CSV...).
    #[error("{}: {message}", path.display())]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A detector failed: could not start, crashed, or spoke garbage.
    #[error("detector {detector}: {message}")]
    Detector {
        /// Detector name.
        detector: String,
        /// What happened.
        message: String,
    },
    /// A parameter outside its valid range, or an unknown name.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// Parameter.
        name: &'static str,
        /// Why.
        reason: String,
    },
}

impl EvalError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
    pub(crate) fn bad(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::BadFile {
            path: path.into(),
            message: message.into(),
        }
    }
}

/// Shorthand for `Result<T, EvalError>`.
pub type Result<T> = std::result::Result<T, EvalError>;
