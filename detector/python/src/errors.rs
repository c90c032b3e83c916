//! Rust errors as Python exceptions. Every fallible call returns a
//! `PyResult`; nothing panics across the boundary (pyo3 would turn a panic
//! into `pyo3_runtime.PanicException`, which is a bug, not an answer).

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::PyErr;

create_exception!(
    coppertag,
    PoseError,
    PyValueError,
    "No pose fits the tag's corners (degenerate or inconsistent with a planar \
     square seen by the camera)."
);

/// The Python exception for a library error: `ValueError` for bad input
/// (names, ids, settings), `PoseError` (a `ValueError`) when no pose fits.
pub fn to_py(e: coppertag::Error) -> PyErr {
    use coppertag::Error as E;
    match e {
        E::PoseFailed { .. } => PoseError::new_err(e.to_string()),
        E::UnknownFamily { .. }
        | E::IdOutOfRange { .. }
        | E::InvalidParameter { .. }
        | E::InvalidFamily { .. }
        | E::BadLength { .. }
        | E::SymbolOutOfRange { .. }
        | E::BadErasure { .. }
        | E::InvalidCode { .. } => PyValueError::new_err(e.to_string()),
        _ => PyRuntimeError::new_err(e.to_string()),
    }
}

/// The Python exception for a generator error (always bad input).
pub fn synth_to_py(e: coppertag_synth::SynthError) -> PyErr {
    PyValueError::new_err(e.to_string())
}
