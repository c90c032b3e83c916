//! Synthetic CopperTag (and peer marker) images with exact ground truth.
//!
//! `raster` turns the detector crate's vector tag geometry into pixels with
//! tiny-skia; `svg` writes the same geometry as print-ready SVG.
#![deny(missing_docs)]

mod error;
pub mod raster;
pub mod svg;

pub use error::SynthError;
