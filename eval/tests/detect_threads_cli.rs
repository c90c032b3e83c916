//! `coppertag detect --threads` and `--unpinned` end to end: the same
//! detections on any number of threads, pinned or not, and the flags'
//! misuse refused with exit code 2 before any image is read.

mod common;
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
