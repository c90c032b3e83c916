//! The crate's one error type. User input (family names, ids, parameters,
//! received words) returns `Result<_, Error>`; panics are kept for broken
//! internal invariants only.

use thiserror::Error;

/// Everything that can go wrong in the `coppertag` library.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum Error {
    /// A family name that is not one of the built-in families.
    #[error("unknown tag family '{name}' (known: {known})")]
    UnknownFamily {
        /// The name asked for.
        name: String,
        /// The known family names, comma separated.
        known: String,
    },
    /// An id outside the family's id range.
    #[error("id {id} is out of range for family {family} (valid: {min}..={max})")]
    IdOutOfRange {
        /// Family name.
        family: String,
        /// The id asked for.
        id: u64,
        /// Smallest valid id.
        min: u64,
        /// Largest valid id.
        max: u64,
    },
    /// Parameters of a Reed-Solomon code that do not describe a valid code.
    #[error("invalid Reed-Solomon code: {reason}")]
    InvalidCode {
        /// What is wrong with the parameters.
        reason: String,
    },
    /// A slice of the wrong length was handed to the codec or decoder.
    #[error("wrong length: expected {expected} symbols, got {got}")]
    BadLength {
        /// Length the operation needs.
        expected: usize,
        /// Length it was given.
        got: usize,
    },
    /// A symbol value that does not fit in the code's symbol size.
    #[error("symbol {index} has value {value}, which does not fit in {bits} bits")]
    SymbolOutOfRange {
        /// Position of the symbol.
        index: usize,
        /// Its value.
        value: u8,
        /// The code's symbol size in bits.
        bits: u32,
    },
    /// An erasure position outside the codeword.
    #[error("erasure position {index} is outside the codeword of {n} symbols")]
    BadErasure {
        /// The position given.
        index: usize,
        /// Codeword length.
        n: usize,
    },
    /// The received word is too damaged to decode (more errors than the code
    /// can correct, or a correction that would leave the transmitted code).
    #[error("uncorrectable received word")]
    Uncorrectable,
    /// A family definition (for example from a JSON file) that is inconsistent.
    #[error("invalid family definition '{family}': {reason}")]
    InvalidFamily {
        /// Family name.
        family: String,
        /// What is inconsistent.
        reason: String,
    },
    /// No pose fits the corners given (degenerate or inconsistent with a
    /// planar square seen by the camera).
    #[error("pose estimation failed: {reason}")]
    PoseFailed {
        /// Why no pose was found.
        reason: String,
    },
    /// A configuration or call parameter outside its valid range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
}

/// Shorthand for `Result<T, coppertag::Error>`.
pub type Result<T> = std::result::Result<T, Error>;
