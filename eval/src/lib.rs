//! Evaluation of fiducial marker detectors on synthetic datasets.
//!
//! Data flows one way: a dataset (`truth.csv` + images, from
//! `coppertag-synth`) -> [`runner`] runs one detector over it and
//! [`runlog`] logs every result to an MCAP file -> [`metrics`] reads runs
//! and ground truth and computes detection rates, corner errors and speed ->
//! [`report`] writes the paper's tables and figures -> [`gate`] compares a
//! summary with a committed baseline.
//!
//! Sampled ("wild") datasets add a marker-by-marker evaluation
//! ([`wild`]: correct, rough and missed markers, pose error through one
//! solver, [`pose_error`]), aggregated per system with factor curves and
//! jitter ([`wild_summary`]) and the honesty of reported corner
//! uncertainties ([`sigma`]) into a report section ([`wild_report`]). Runs
//! can be split over machines and merged exactly ([`shard`]).
#![deny(missing_docs)]

pub mod atomic;
pub mod binning;
pub mod draws;
mod error;
pub mod gate;
pub mod metrics;
pub mod plot;
pub mod pose_error;
pub mod protocol;
pub mod report;
pub mod resources;
pub mod ros2;
pub mod runlog;
pub mod runner;
pub mod shard;
pub mod sigma;
pub mod speed;
pub mod truth;
pub mod wild;
pub mod wild_report;
pub mod wild_scenarios;
pub mod wild_summary;

pub use error::{EvalError, Result};
