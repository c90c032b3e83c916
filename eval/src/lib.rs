//! Evaluation of fiducial marker detectors on synthetic datasets.
//!
//! Data flows one way: a dataset (`truth.csv` + images, from
//! `coppertag-synth`) -> [`runner`] runs one detector over it and
//! [`runlog`] logs every result to an MCAP file -> [`metrics`] reads runs
//! and ground truth and computes detection rates, corner errors and speed ->
//! [`report`] writes the paper's tables and figures -> [`gate`] compares a
//! summary with a committed baseline.
#![deny(missing_docs)]

pub mod atomic;
mod error;
pub mod gate;
pub mod metrics;
pub mod plot;
pub mod protocol;
pub mod report;
pub mod resources;
pub mod runlog;
pub mod runner;
pub mod speed;
pub mod truth;

pub use error::{EvalError, Result};
