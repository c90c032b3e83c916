//! The synth crate's one error type.
//!
//! Owned jointly: the SVG writer uses `InvalidParameter` and `Tag`; the
//! dataset side adds its variants here (spec parsing with file and line,
//! I/O, rendering) rather than a second enum.
//!
//! Errors about files a person wrote (dataset specs, occlusion patterns)
//! name the file, line and column, so that a message reads like a
//! compiler's: `datasets/x.toml:12:1: markers[0].size_m: -0.1 must be
//! positive`.

use std::path::PathBuf;

use thiserror::Error;

/// Everything that can go wrong while building or writing a dataset.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SynthError {
    /// A spec or pattern file that does not parse or holds a bad value.
    #[error("{}:{line}:{column}: {message}", path.display())]
    Input {
        /// The file.
        path: PathBuf,
        /// Line, from 1.
        line: usize,
        /// Column, from 1.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A parameter outside its valid range (wrapped into
    /// [`SynthError::Input`] when it comes from a spec and a position is
    /// known).
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// Parameter name as the user wrote it.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
    /// A marker or scene that cannot be rendered as asked (for example a
    /// marker behind the camera).
    #[error("{0}")]
    Scene(String),
    /// File-system failure.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// An image that cannot be read, encoded or decoded.
    #[error("image {}: {message}", path.display())]
    Image {
        /// The image file (or a description of the image).
        path: PathBuf,
        /// The cause.
        message: String,
    },
    /// Writing the MCAP file failed.
    #[error("writing MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
    /// Writing `truth.csv` failed.
    #[error("writing truth.csv: {0}")]
    Csv(#[from] csv::Error),
    /// Writing JSON failed.
    #[error("writing JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// The output directory exists and replacing it was not asked for.
    #[error("{} already exists (pass --force to replace it)", path.display())]
    OutputExists {
        /// The directory.
        path: PathBuf,
    },
    /// A tag family or id that the CopperTag library rejects.
    #[error(transparent)]
    Tag(#[from] coppertag::Error),
}

impl SynthError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        SynthError::Io {
            path: path.into(),
            source,
        }
    }
}

/// Shorthand for `Result<T, SynthError>`.
pub type Result<T> = std::result::Result<T, SynthError>;
