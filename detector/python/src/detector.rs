//! `coppertag.Detector`: the Rust detector behind a Python class.

use pyo3::prelude::*;
use pyo3::types::{PyAny, PyDict, PyList};

use crate::detection::Detection;
use crate::image::Image;
use crate::settings;

/// Finds and decodes CopperTags in grey images.
///
/// Detector(families=("ct14", "ct8"), **settings)
///
/// families: the families to decode, in the order they are tried: names
/// ("ct14", "ct8") or (name, max_corrected) pairs. settings: any field of
/// the Rust DetectorConfig as a keyword, with the same default (see
/// coppertag.DEFAULT_SETTINGS); a bad value raises ValueError naming the
/// setting, an unknown keyword TypeError.
///
/// Create one detector and reuse it: it keeps its buffers between frames.
/// detect() releases the GIL, so detectors in several threads run in
/// parallel; one detector serves one thread at a time (a second concurrent
/// call on the same detector raises RuntimeError).
#[pyclass(module = "coppertag")]
pub struct Detector {
    inner: coppertag::Detector,
}

#[pymethods]
impl Detector {
    #[new]
    #[pyo3(signature = (families = None, **settings))]
    fn new(
        families: Option<&Bound<'_, PyAny>>,
        settings: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let config = settings::config(families, settings)?;
        let inner = coppertag::Detector::new(config).map_err(crate::errors::to_py)?;
        Ok(Self { inner })
    }

    /// Finds every tag in `image` and returns a list of Detection, sorted
    /// by family and id, one per physical tag.
    ///
    /// image: a 2-D numpy uint8 array (rows, columns) of grey levels, any
    /// strides: an array whose rows are made of adjacent pixels (C order,
    /// ROI slices such as frame[y0:y1, x0:x1], frame[::2, :]) is read in
    /// place; any other layout (Fortran order, frame[::2, ::2], negative
    /// strides) is copied once. Colour images are not converted: convert
    /// with cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) first. TypeError for a
    /// non-array or another dtype, ValueError for another shape or an image
    /// smaller than 20 x 20 pixels.
    ///
    /// The GIL is released while the detector runs. Do not write to the
    /// array from another thread meanwhile.
    fn detect(&mut self, py: Python<'_>, image: &Bound<'_, PyAny>) -> PyResult<Vec<Detection>> {
        let image = Image::from_py(image)?;
        let view = image.view()?;
        let detector = &mut self.inner;
        let found = py.detach(move || detector.detect(view));
        Ok(found.into_iter().map(Detection::new).collect())
    }

    /// Per-stage times of the last detect() call, in seconds: a dict from
    /// stage name (pipeline order: downsample, threshold, contours, lines,
    /// corners, ellipses, quads, decode, small, rim, dedup, verify) to time, then "total".
    /// All zero before the first call; "downsample" is always zero, as the
    /// downsampling is done (and timed) in the threshold's pass.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for (stage, t) in self.inner.stats().times.iter() {
            dict.set_item(stage, t.as_secs_f64())?;
        }
        Ok(dict)
    }

    /// The settings in force (every keyword but families), as a dict.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        settings::settings_dict(py, self.inner.config())
    }

    /// The families decoded, in order, as (name, correction limit) pairs.
    #[getter]
    fn families<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let items: Vec<(String, usize)> = self
            .inner
            .config()
            .families
            .iter()
            .map(|f| (f.family.name().to_string(), f.correction_limit()))
            .collect();
        PyList::new(py, items)
    }

    fn __repr__(&self) -> String {
        let names: Vec<&str> = self
            .inner
            .config()
            .families
            .iter()
            .map(|f| f.family.name())
            .collect();
        format!("Detector(families={names:?})")
    }
}

/// Whether detect() would read `image` in place (True) or copy it first
/// (False); raises as detect() does for an image it does not take.
#[pyfunction]
pub fn reads_in_place(image: &Bound<'_, PyAny>) -> PyResult<bool> {
    Ok(Image::from_py(image)?.is_borrowed())
}
