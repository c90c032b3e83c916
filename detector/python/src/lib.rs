//! The `coppertag` Python module: the CopperTag detector and tag generator
//! for Python (numpy in, numpy out), built with maturin into one abi3 wheel
//! for every CPython from 3.9. The type stubs are `coppertag.pyi` beside
//! this crate's `pyproject.toml`; the tests are the pytest suite in
//! `tests/`, run by `make test` on the built wheel.

mod detection;
mod detector;
mod errors;
mod generate;
mod image;
mod settings;

use pyo3::prelude::*;

/// CopperTag fiducial markers: detection, pose and generation.
///
/// Detector(...).detect(grey_uint8_array) -> [Detection]; generate(family,
/// id, px=...) -> uint8 image; generate_svg(family, id, size_mm=...) -> str.
/// Pixel-centre coordinates (the centre of the top-left pixel is (0, 0));
/// corners TL, BL, BR, TR; metres and radians.
#[pymodule]
fn coppertag(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<detector::Detector>()?;
    m.add_class::<detection::Detection>()?;
    m.add_class::<detection::Pose>()?;
    m.add("PoseError", py.get_type::<errors::PoseError>())?;
    m.add("DEFAULT_SETTINGS", settings::defaults_dict(py)?)?;
    m.add("MIN_IMAGE_SIDE", image::MIN_SIDE)?;
    m.add(
        "FAMILIES",
        ::coppertag::Family::builtin()
            .iter()
            .map(|f| f.name().to_string())
            .collect::<Vec<_>>(),
    )?;
    m.add_function(wrap_pyfunction!(detector::reads_in_place, m)?)?;
    m.add_function(wrap_pyfunction!(generate::generate, m)?)?;
    m.add_function(wrap_pyfunction!(generate::generate_svg, m)?)?;
    Ok(())
}
