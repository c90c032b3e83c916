//! `eval/tools/same_detections.py` (the comparison `make native-check`
//! makes) on real `coppertag detect --json` output: two runs of the same
//! images agree though their timings differ; a corner moved, an image
//! missing, a line that is no detect output and a file that is not there
//! are each told apart by the exit status (0 same, 1 different, 2 bad
//! input).

use crate::common;

use common::{coppertag, render_rotated_z, repo, succeed};
use std::path::Path;
use std::process::{Command, Output};

/// The tool on files `a` and `b` (standard-library Python only, so the
/// machine's `python3`, as the Makefile runs it).
fn compare(a: &Path, b: &Path) -> Output {
    Command::new("python3")
        .arg(repo().join("eval/tools/same_detections.py"))
        .arg(a)
        .arg(b)
        .output()
        .expect("python3 runs")
}

#[test]
fn same_detections_tells_equal_runs_from_changed_and_bad_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let ds = render_rotated_z(tmp.path());
    let mut images: Vec<_> = std::fs::read_dir(ds.join("images"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    images.sort();
    let run = |name: &str| {
        let out = succeed(
            coppertag().arg("detect").arg("--json").args(&images),
            "detect --json",
        );
        let path = tmp.path().join(name);
        std::fs::write(&path, &out.stdout).unwrap();
        (path, String::from_utf8(out.stdout).unwrap())
    };
    let (a, text) = run("a.jsonl");
    let (b, _) = run("b.jsonl");
    let out = compare(&a, &b);
    let said = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{said}");
    assert!(
        said.contains("13 images") && said.contains("0 images differ"),
        "{said}"
    );

    // One corner coordinate of the first detection changed in its last digit.
    let lines: Vec<&str> = text.lines().collect();
    let at = text.find("\"corners\":[[").expect("a detection") + "\"corners\":[[".len();
    let digit = text[at..].find(',').unwrap() + at - 1;
    let mut moved = text.clone();
    let d = moved.as_bytes()[digit];
    moved.replace_range(digit..digit + 1, if d == b'1' { "2" } else { "1" });
    let c = tmp.path().join("moved.jsonl");
    std::fs::write(&c, moved).unwrap();
    let out = compare(&a, &c);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 images differ"));

    // An image missing from one file.
    let d = tmp.path().join("short.jsonl");
    std::fs::write(&d, lines[1..].join("\n")).unwrap();
    let out = compare(&a, &d);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("missing from one file"));

    // A line that is no detect output, and a file that is not there.
    let e = tmp.path().join("bad.jsonl");
    std::fs::write(&e, "{\"image\": \"x.png\"\n").unwrap();
    let out = compare(&a, &e);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("bad.jsonl:1: not a detect --json line"));
    let out = compare(&a, &tmp.path().join("absent.jsonl"));
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.jsonl"));
}
