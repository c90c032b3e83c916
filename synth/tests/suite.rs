//! The synth crate's integration tests, one test binary: each file beside
//! this one is a module of it. One binary instead of one per file, because
//! each test binary links the crate and its dependencies again and
//! instantiates their generic code again (the workspace's 35 test binaries
//! took 133 s of CPU to build; as three, CI's test build on 2 cores took
//! 4 min 32 s instead of 5 min 12 s), and `cargo test` runs binaries one
//! after another, so a binary with one long test kept a core idle.
//! Run one file's tests with `cargo test -p coppertag-synth --test suite <file>::`.

mod bad_input;
mod common;
mod cutouts;
mod dataset;
mod geometry;
mod golden_png;
mod occlusion_patterns;
mod paper_specs;
mod peers;
mod sample;
mod thinning;
