//! CopperTag: an occlusion-resilient fiducial marker.
//!
//! This crate is the library a robot program depends on: the tag families
//! (`ct14`, `ct8`), their Reed-Solomon code, the tag geometry shared by every
//! renderer, decoding from four corners, the detector that finds tags in
//! images (including partly hidden ones) and planar pose estimation.
//!
//! Conventions used everywhere: pixel-centre image coordinates (the centre of
//! the top-left pixel is (0, 0), x right, y down); tag corners in the order
//! TL, BL, BR, TR of the white data square, "top" being the side away from
//! the printed id; metres and radians in files.
#![deny(missing_docs)]

mod deblur;
pub mod decode;
pub mod detect;
pub mod digits;
mod error;
pub mod family;
pub mod geometry;
pub mod grid_code;
pub mod homography;
mod likelihood;
mod math;
mod motion;
mod nearest;
pub mod pose;
pub mod rs;
mod shaded;
#[cfg(test)]
mod test_images;
pub mod view;

pub use decode::{decode_quad, decode_quad_with, DecodeParams, QuadReading};
pub use detect::{Detection, DetectionStats, Detector, DetectorConfig, FamilySetting, StageTimes};
pub use error::{Error, Result};
pub use family::Family;
pub use view::GrayView;
