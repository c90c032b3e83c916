//! The detector crate's integration tests, one test binary: each file beside
//! this one is a module of it. One binary instead of one per file, because
//! each test binary links the crate and its dependencies again and
//! instantiates their generic code again (the workspace's 35 test binaries
//! took 133 s of CPU to build; as three, CI's test build on 2 cores took
//! 4 min 32 s instead of 5 min 12 s), and `cargo test` runs binaries one
//! after another, so a binary with one long test kept a core idle.
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
