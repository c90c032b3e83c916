//! The eval crate's integration tests, one test binary: each file beside
//! this one is a module of it. One binary instead of one per file, because
//! each test binary links the crate and its dependencies again and
//! instantiates their generic code again (about 100 s of CPU for the
//! workspace's 35 files on CI's 2 cores), and `cargo test` runs binaries
//! one after another, so a binary with one long test kept a core idle.
//! Run one file's tests with `cargo test -p coppertag-eval --test suite <file>::`.

mod common;
mod detect_threads_cli;
mod eval_pipeline;
mod generate_cli;
mod ros2_bags;
mod same_detections_tool;
mod shard_wild;
mod speed_gate;
mod update_system;
mod wild_gate;
