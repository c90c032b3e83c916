//! The detector crate's integration tests, one test binary: each file beside
//! this one is a module of it. One binary instead of one per file, because
//! each test binary links the crate and its dependencies again and
//! instantiates their generic code again (about 100 s of CPU for the
//! workspace's 35 files on CI's 2 cores), and `cargo test` runs binaries
//! one after another, so a binary with one long test kept a core idle.
//! Run one file's tests with `cargo test -p coppertag --test suite <file>::`.

mod common;
mod detect_api;
mod detect_blurred;
mod detect_clean;
mod detect_clutter;
mod detect_occlusion;
mod detect_photo;
mod detect_rim;
mod detect_robustness;
mod detect_small;
mod detect_sticks;
mod detect_threads;
mod detect_verify;
mod golden;
mod golden_detections;
mod round_trip;
mod rs;
