//! A numpy array as the detector's input: checked, then read in place when
//! its memory layout allows it, copied otherwise.
//!
//! The detector reads a [`GrayView`]: rows of bytes one after the other,
//! `stride` bytes apart. A numpy array whose pixels are adjacent within a row
//! (column stride 1) is exactly that, whatever its row stride: a C-order
//! frame, an ROI slice `frame[y0:y1, x0:x1]` or a row-subsampled
//! `frame[::2, :]`. Any other layout (Fortran order, `frame[:, ::2]`,
//! negative strides, rows overlapping as in `np.broadcast_to`) is copied
//! into a packed buffer first, which costs one pass over the pixels.
//!
//! Colour input is rejected, not converted: which grey a colour frame should
//! become (BGR or RGB order, which luma weights) is the caller's knowledge,
//! and a silent guess would give results that differ from the Rust path.

use coppertag::GrayView;
use numpy::{
    PyArray2, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// Smallest image side accepted, in pixels. The smallest tag (ct8: a data
/// square of 8 + 2 border cells, half the tag's side) is 20 px wide at one
/// pixel per cell, so nothing can be found in a narrower image; rejecting it
/// tells the caller that an empty or degenerate array came in (a failed
/// camera read, a slice with the wrong bounds) instead of "no tags".
pub const MIN_SIDE: usize = 20;

/// The image a detection reads: a checked array, borrowed or copied.
pub enum Input<'py> {
    /// The array's own memory (column stride 1, rows `stride` bytes apart).
    Borrowed {
        array: PyReadonlyArray2<'py, u8>,
        stride: usize,
    },
    /// A packed copy of the pixels (any other layout).
    Copied(Vec<u8>),
}

/// A checked grey image: its size and where its pixels are.
pub struct Image<'py> {
    width: usize,
    height: usize,
    input: Input<'py>,
}

impl<'py> Image<'py> {
    /// Checks that `obj` is a 2-D `uint8` numpy array of at least
    /// [`MIN_SIDE`] pixels each way; the error says what to change.
    pub fn from_py(obj: &Bound<'py, PyAny>) -> PyResult<Self> {
        let untyped = obj.cast::<PyUntypedArray>().map_err(|_| {
            PyTypeError::new_err(format!(
                "image must be a numpy array (2-D, dtype uint8), got {}",
                type_name(obj)
            ))
        })?;
        let shape = untyped.shape().to_vec();
        match shape.as_slice() {
            [_, _] => {}
            [h, w, c] if *c == 3 || *c == 4 => {
                return Err(PyValueError::new_err(format!(
                    "image has {c} channels (shape ({h}, {w}, {c})); detect takes a 2-D grey \
                     image: convert it first, e.g. cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) \
                     (COLOR_RGB2GRAY for RGB, COLOR_BGRA2GRAY for 4 channels)"
                )))
            }
            [h, w, 1] => {
                return Err(PyValueError::new_err(format!(
                    "image has shape ({h}, {w}, 1); pass the 2-D array image[:, :, 0]"
                )))
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "image must be 2-D (rows, columns), got {} dimension(s) with shape {other:?}",
                    other.len()
                )))
            }
        }
        let dtype = untyped.dtype();
        if !dtype.is_equiv_to(&numpy::dtype::<u8>(obj.py())) {
            return Err(PyTypeError::new_err(format!(
                "image must have dtype uint8 (grey levels 0..255), got {}; convert it, e.g. \
                 image.astype(numpy.uint8) for integers in 0..255 or \
                 (image * 255).round().astype(numpy.uint8) for floats in [0, 1]",
                dtype_name(&dtype)
            )));
        }
        let (height, width) = (shape[0], shape[1]);
        if height == 0 || width == 0 {
            return Err(PyValueError::new_err(format!(
                "image is empty (shape ({height}, {width}))"
            )));
        }
        if height < MIN_SIDE || width < MIN_SIDE {
            return Err(PyValueError::new_err(format!(
                "image is {width} x {height} pixels; at least {MIN_SIDE} x {MIN_SIDE} are \
                 needed (no tag fits in less)"
            )));
        }
        if u32::try_from(width).is_err() || u32::try_from(height).is_err() {
            return Err(PyValueError::new_err(format!(
                "image is {width} x {height} pixels; each side must be below 2^32"
            )));
        }
        let array = untyped
            .cast::<PyArray2<u8>>()
            .map_err(|e| PyTypeError::new_err(e.to_string()))?
            .try_readonly()
            .map_err(|e| PyValueError::new_err(format!("image cannot be read: {e}")))?;
        let strides = untyped.strides();
        let (row, col) = (strides[0], strides[1]);
        let input = match usize::try_from(row) {
            Ok(stride) if col == 1 && stride >= width => Input::Borrowed { array, stride },
            // Logical (row-major) order whatever the strides' signs.
            _ => Input::Copied(array.as_array().iter().copied().collect()),
        };
        Ok(Self {
            width,
            height,
            input,
        })
    }

    /// Whether the pixels are read in place (no copy was made).
    pub fn is_borrowed(&self) -> bool {
        matches!(self.input, Input::Borrowed { .. })
    }

    /// The detector's view of the pixels.
    pub fn view(&self) -> PyResult<GrayView<'_>> {
        let (w, h) = (self.width as u32, self.height as u32);
        let view = match &self.input {
            Input::Copied(data) => GrayView::new(data, w, h, self.width),
            Input::Borrowed { array, stride } => {
                let len = (self.height - 1) * stride + self.width;
                let data = array.data().cast_const();
                // SAFETY: `data` points at pixel (0, 0) of an array whose
                // column stride is 1 and row stride `stride` > 0, so pixel
                // (x, y) is at `data + y * stride + x` and the last one,
                // (w - 1, h - 1), at `data + len - 1`: the `len` bytes span
                // from the first pixel to the last one of one numpy buffer
                // (the bytes between rows belong to the same allocation, the
                // parent array's; numpy's own `byte_bounds` assumes the
                // same). The read-only borrow held in `array` keeps the
                // array alive and stops Rust code from writing to it for
                // the lifetime of the slice, which is tied to `self`.
                #[allow(unsafe_code)]
                let bytes = unsafe { std::slice::from_raw_parts(data, len) };
                GrayView::new(bytes, w, h, *stride)
            }
        };
        view.map_err(crate::errors::to_py)
    }
}

/// `type(obj).__name__`, for error messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "an unknown type".into(), |n| n.to_string())
}

/// numpy's name of a dtype (`float64`), for error messages.
fn dtype_name(dtype: &Bound<'_, numpy::PyArrayDescr>) -> String {
    dtype
        .str()
        .map_or_else(|_| "another dtype".into(), |s| s.to_string())
}
