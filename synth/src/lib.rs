//! Synthetic CopperTag (and peer marker) images with exact ground truth.
//!
//! `raster` turns the detector crate's vector tag geometry into pixels with
//! tiny-skia; `svg` writes the same geometry as print-ready SVG.
//!
//! The dataset side renders markers of four systems (CopperTag, AprilTag 3,
//! ArUco 3, STag) through a calibrated camera ([`camera`], [`pose`],
//! [`markers`]) with exact pixel coverage ([`coverage`]), adds
//! backgrounds, occluders, lighting, blur and sensor noise ([`background`],
//! [`occlusion`], [`effects`]), and writes whole datasets described by TOML
//! specs ([`spec`], [`dataset`]): PNG images, `truth.csv`, `dataset.json`
//! and an MCAP file for Foxglove ([`foxglove`]).
//!
//! Conventions: pixel-centre image coordinates (the centre of the top-left
//! pixel is (0, 0), x right, y down); camera frame x right, y down, z
//! forward (OpenCV); marker corners TL, BL, BR, TR of the upright marker;
//! metres and radians in files.
#![deny(missing_docs)]

pub mod background;
pub mod camera;
pub mod coverage;
pub mod cutout;
pub mod dataset;
pub mod effects;
mod error;
pub mod floor_occluders;
pub mod foxglove;
pub mod halton;
pub mod markers;
pub mod occlusion;
pub mod polygon;
pub mod pose;
pub mod raster;
pub mod rng;
pub mod scene;
pub mod spec;
pub mod svg;
mod toml_input;

pub use dataset::{generate, generate_shard, GenerateOptions, GenerateReport, Shard};
pub use error::{Result, SynthError};
pub use markers::{MarkerModel, MarkerSystem};
pub use spec::{DatasetSpec, LoadOptions};
