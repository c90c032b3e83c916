//! `coppertag detect` on images end to end: the same detections on any
//! number of threads (`--threads`, `--unpinned`), the flags' misuse
//! refused with exit code 2 before any image is read, and a list of
//! images answered in its own order, unreadable ones included, whether
//! they are decoded ahead of the detector on a thread of their own (a
//! one-thread detector) or one by one (`--threads 2`).

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

/// A list with unreadable images among good ones, decoded ahead of a
/// one-thread detector on a thread of their own or one by one for a
/// two-thread detector: one JSON line per readable image in the list's
/// order, one error per unreadable one on stderr, and a failing exit that
/// names them, after every image was processed.
#[test]
fn a_list_is_answered_in_order_with_its_unreadable_images_named() {
    let tmp = tempfile::tempdir().unwrap();
    let fixtures = repo().join("detector/tests/fixtures/ct14");
    let corrupt = tmp.path().join("corrupt.png");
    // A PNG signature and then nothing a decoder can use.
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot a png at all").unwrap();
    let missing = tmp.path().join("missing.png");
    let list = [
        fixtures.join("1.png"),
        corrupt.clone(),
        fixtures.join("42.png"),
        missing.clone(),
        fixtures.join("200.png"),
        fixtures.join("1.png"),
    ];
    for threads in ["1", "2"] {
        let out = coppertag()
            .arg("detect")
            .args(&list)
            .args(["--json", "--threads", threads])
            .output()
            .unwrap();
        check_list_answer(&list, &[&corrupt, &missing], &out);
    }
}

/// The answer `out` of `detect --json` on `list` of `fixtures/ct14` tags
/// (each the id its file names) and the unreadable images `bad`.
fn check_list_answer(
    list: &[std::path::PathBuf],
    bad: &[&std::path::PathBuf],
    out: &std::process::Output,
) {
    let err = String::from_utf8_lossy(&out.stderr);
    // Exit code 2: bad input (`main.rs`).
    assert_eq!(out.status.code(), Some(2), "{err}");
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let seen: Vec<(String, Vec<u64>)> = lines
        .iter()
        .map(|j| {
            let ids = j["detections"]
                .as_array()
                .unwrap()
                .iter()
                .map(|d| d["id"].as_u64().unwrap())
                .collect();
            (j["image"].as_str().unwrap().to_string(), ids)
        })
        .collect();
    let want: Vec<(String, Vec<u64>)> = list
        .iter()
        .filter(|p| !bad.contains(p))
        .map(|p| {
            let id = p.file_stem().unwrap().to_str().unwrap().parse().unwrap();
            (p.display().to_string(), vec![id])
        })
        .collect();
    assert_eq!(seen, want, "{err}");
    for b in bad {
        assert!(
            err.contains(&format!("cannot read image {}", b.display())),
            "{err}"
        );
    }
    assert!(
        err.contains(&format!("{} of {} images failed", bad.len(), list.len())),
        "{err}"
    );
}
