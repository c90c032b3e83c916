//! The synth crate's one error type.
//!
//! Owned jointly: the SVG writer uses `InvalidParameter` and `Tag`; the
//! dataset side adds its variants here (spec parsing with file and line,
//! I/O, rendering) rather than a second enum.

use thiserror::Error;

/// Everything that can go wrong while rendering tags or datasets.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum SynthError {
    /// A parameter outside its valid range.
    #[error("invalid {name}: {reason}")]
    InvalidParameter {
        /// Parameter name as the user wrote it.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
    /// An error from the tag library (unknown family, id out of range...).
    #[error(transparent)]
    Tag(#[from] coppertag::Error),
}
