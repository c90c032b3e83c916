//! `coppertag.generate` and `coppertag.generate_svg`: print-ready tags, the
//! same pixels and the same SVG as `coppertag generate`.

use coppertag::geometry::tag_shapes;
use coppertag::Family;
use coppertag_synth::raster::{tag_image, TAG_PX_RANGE};
use coppertag_synth::svg::tag_svg;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

fn family(name: &str) -> PyResult<&'static Family> {
    Family::by_name(name).map_err(crate::errors::to_py)
}

/// The tag `id` of `family` as a px x px uint8 numpy image (white
/// background, the whole tag; its data square is the middle half).
///
/// Raises ValueError for an unknown family, an id out of the family's
/// range or px outside 16..=16384.
#[pyfunction]
#[pyo3(signature = (family, id, px = 1024))]
pub fn generate<'py>(
    py: Python<'py>,
    family: &str,
    id: u64,
    px: u32,
) -> PyResult<Bound<'py, PyArray2<u8>>> {
    let fam = self::family(family)?;
    if !TAG_PX_RANGE.contains(&px) {
        return Err(PyValueError::new_err(format!(
            "invalid parameter px: {px} (must be {}..={}, as coppertag generate --px)",
            TAG_PX_RANGE.start(),
            TAG_PX_RANGE.end()
        )));
    }
    let shapes = tag_shapes(fam, id).map_err(crate::errors::to_py)?;
    let img = tag_image(&shapes, px)
        .ok_or_else(|| PyValueError::new_err(format!("cannot make a {px} x {px} image")))?;
    let side = px as usize;
    let array = Array2::from_shape_vec((side, side), img.into_raw())
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

/// The tag `id` of `family` as SVG text, size_mm millimetres on a side
/// (the whole tag; its data square is half of it).
///
/// Raises ValueError for an unknown family, an id out of range or a size
/// that is not positive.
#[pyfunction]
#[pyo3(signature = (family, id, size_mm = 100.0))]
pub fn generate_svg(family: &str, id: u64, size_mm: f64) -> PyResult<String> {
    tag_svg(self::family(family)?, id, size_mm).map_err(crate::errors::synth_to_py)
}
