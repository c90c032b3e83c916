//! The eval crate's integration tests, one test binary: each file beside
//! this one is a module of it. One binary instead of one per file, because
//! each test binary links the crate and its dependencies again and
//! instantiates their generic code again (the workspace's 35 test binaries
//! took 133 s of CPU to build; as three, CI's test build on 2 cores took
//! 4 min 32 s instead of 5 min 12 s), and `cargo test` runs binaries one
//! after another, so a binary with one long test kept a core idle.
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
