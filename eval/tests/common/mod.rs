//! Helpers shared by the eval integration tests: the repository root, the
//! `coppertag` binary under test, a command run to success, and a small
//! real dataset.

// Each test binary uses its own subset of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The workspace root (the committed specs live below it).
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The `coppertag` binary built for this test run.
pub fn coppertag() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coppertag"))
}

/// Runs `cmd` and asserts it succeeded, the failure naming `what` and
/// showing the command's standard error; its output.
pub fn succeed(cmd: &mut Command, what: &str) -> Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Renders the 13-image rotated-z CopperTag dataset (every 30th image of
/// the paper's sweep: indices 0, 30, ..., 360) into `dir/ds`.
pub fn render_rotated_z(dir: &Path) -> PathBuf {
    let out = dir.join("ds");
    let st = coppertag()
        .args(["synth", "--quiet", "--every", "30", "-o"])
        .arg(&out)
        .arg(repo().join("datasets/paper/coppertag-rotated-z.toml"))
        .status()
        .unwrap();
    assert!(st.success(), "synth failed");
    out
}
