//! `coppertag detect --threads` and `--unpinned` end to end: the same
//! detections on any number of threads, pinned or not, and the flags'
//! misuse refused with exit code 2 before any image is read.

use crate::common;
use common::{coppertag, repo, succeed};

/// `detect --json` on the golden ct14 tag 1 with `args`, its stdout with
/// the time per image taken out.
fn detections(args: &[&str]) -> String {
    let img = repo().join("detector/tests/fixtures/ct14/1.png");
    let out = succeed(
        coppertag().arg("detect").arg(&img).arg("--json").args(args),
        &format!("{args:?}"),
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    json["detections"].to_string()
}

#[test]
fn threads_pinned_or_not_give_the_same_detections() {
    let one = detections(&[]);
    assert!(one.contains("\"id\":1"), "{one}");
    assert_eq!(detections(&["--threads", "2"]), one);
    assert_eq!(detections(&["--threads", "2", "--unpinned"]), one);
}

#[test]
fn unpinned_needs_threads_and_images() {
    for (args, expect) in [
        (&["x.png", "--unpinned"][..], "--threads"),
        (
            &[
                "--mcap",
                "x.mcap",
                "-o",
                "y.mcap",
                "--threads",
                "2",
                "--unpinned",
            ][..],
            "--mcap",
        ),
    ] {
        let out = coppertag().arg("detect").args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
    }
}

/// `coppertag detect ... | head -1`: once the reader has closed the pipe,
/// the command stops quietly with exit code 0, where `println!` panicked
/// (a backtrace on the user's terminal) on the next line it wrote.
#[test]
fn a_reader_closing_the_pipe_stops_it_quietly() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let img = repo().join("detector/tests/fixtures/ct14/1.png");
    // Enough images that it is still writing when the reader goes.
    let mut child = coppertag()
        .arg("detect")
        .args(std::iter::repeat_n(&img, 400))
        .arg("--json")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("\"id\":1"), "{first}");
    // The reader is dropped here, closing the pipe.
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
}
