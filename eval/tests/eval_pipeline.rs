//! The eval pipeline end to end on a small real dataset: run -> MCAP ->
//! metrics -> gate, and bad input at each step.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use coppertag_eval::gate::{baseline_of, check, Tolerances};
use coppertag_eval::metrics::{evaluate, MatchRule};
use coppertag_eval::runlog::{self, RunLog};
use coppertag_eval::runner::{self, DetectorSpec};
use coppertag_eval::truth::Dataset;

use crate::common;
use common::{coppertag, render_rotated_z, repo, succeed};

/// A 13-image rotated-z CopperTag dataset, rendered once per test run.
fn dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        render_rotated_z(dir.path());
        dir
    })
    .path()
    .join("ds")
    .leak()
}

fn run_ours(tmp: &Path) -> (PathBuf, runner::RunOutput) {
    let ds = Dataset::open(dataset()).unwrap();
    let spec =
        DetectorSpec::by_name("coppertag", Path::new("unused"), Path::new("unused")).unwrap();
    let out = runner::run(&spec, &ds, |_, _| {}).unwrap();
    let path = tmp.join("run.mcap");
    runlog::save(&path, &out).unwrap();
    (path, out)
}

/// Several sessions at once, each on a shard, give exactly the results of
/// one session in dataset order (per-image times aside), one progress tick
/// per image, and the sessions' images and errors summed.
#[test]
fn parallel_sessions_give_the_sequential_results() {
    let ds = Dataset::open(dataset()).unwrap();
    let spec =
        DetectorSpec::by_name("coppertag", Path::new("unused"), Path::new("unused")).unwrap();
    let without_times = |out: &runner::RunOutput| {
        out.results
            .iter()
            .map(|r| {
                let mut r = r.clone();
                r.result.ms = None;
                r
            })
            .collect::<Vec<_>>()
    };
    let one = runner::run(&spec, &ds, |_, _| {}).unwrap();
    for workers in [1, 3, 40] {
        let ticks = std::sync::atomic::AtomicUsize::new(0);
        let last = std::sync::Mutex::new((0, 0));
        let par = runner::run_parallel(&spec, &ds, workers, |done, total| {
            ticks.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let mut l = last.lock().unwrap();
            *l = (l.0.max(done), total);
        })
        .unwrap();
        assert_eq!(
            without_times(&par),
            without_times(&one),
            "{workers} workers"
        );
        assert!(par.results.iter().all(|r| r.result.ms.is_some()));
        assert_eq!(ticks.into_inner(), 13, "{workers} workers");
        assert_eq!(*last.lock().unwrap(), (13, 13));
        assert_eq!((par.resources.images, par.resources.errors), (13, 0));
        assert!(par.info.shard.is_empty());
        assert_eq!(par.info.sessions, workers.min(13));
        assert!(par.results.iter().any(|r| !r.result.detections.is_empty()));
    }
}

/// The report quotes no time for a run whose sessions ran side by side
/// (their per-image times are not comparable), and quotes it otherwise;
/// the sessions survive the run log.
#[test]
fn runs_of_parallel_sessions_show_no_time() {
    let tmp = tempfile::tempdir().unwrap();
    let ds = Dataset::open(dataset()).unwrap();
    let spec =
        DetectorSpec::by_name("coppertag", Path::new("unused"), Path::new("unused")).unwrap();
    let mut summaries = Vec::new();
    for workers in [1, 2] {
        let out = runner::run_parallel(&spec, &ds, workers, |_, _| {}).unwrap();
        let path = tmp.path().join(format!("run{workers}.mcap"));
        runlog::save(&path, &out).unwrap();
        let log = RunLog::read(&path).unwrap();
        assert_eq!(log.info.sessions, workers);
        let s = evaluate(&log, &ds, MatchRule::default());
        assert_eq!(s.sessions, workers);
        summaries.push(s);
    }
    let machine = coppertag_eval::report::Machine {
        cores: 2,
        memory: 1 << 30,
    };
    let md = coppertag_eval::report::write_report(
        &summaries,
        &tmp.path().join("reports"),
        machine,
        "",
        None,
    )
    .unwrap();
    let rows: Vec<&str> = md
        .lines()
        .filter(|l| l.starts_with("| coppertag-rotated-z | coppertag |"))
        .collect();
    assert_eq!(rows.len(), 2, "{md}");
    let time = |row: &str| {
        row.trim_end_matches(" |")
            .rsplit("| ")
            .next()
            .unwrap()
            .to_string()
    };
    assert!(time(rows[0]).parse::<f64>().unwrap() > 0.0, "{}", rows[0]);
    assert_eq!(time(rows[1]), "-", "{}", rows[1]);
    // Table I's times come from the one-session run alone, and are dashes
    // with none (`reproduce --no-times`, the gate's quick run); so is the
    // baseline's record of the median.
    let table1_times = |summaries: &[coppertag_eval::metrics::Summary], name: &str| {
        let md = coppertag_eval::report::write_report(
            summaries,
            &tmp.path().join(name),
            machine,
            "",
            None,
        )
        .unwrap();
        let row = md
            .lines()
            .find(|l| l.starts_with("| CopperTag |"))
            .unwrap_or_else(|| panic!("no Table I row: {md}"))
            .to_string();
        let cells: Vec<String> = row.split(" | ").map(str::to_string).collect();
        (cells[2].clone(), cells[3].clone(), cells[4].clone())
    };
    let (mean, median, tail) = table1_times(&summaries, "both");
    assert!(
        mean.split(' ').next().unwrap().parse::<f64>().is_ok(),
        "{mean}"
    );
    assert_eq!(median, format!("{:.2}", summaries[0].time_ms.median));
    assert!(tail.contains(" / ") && !tail.contains('-'), "{tail}");
    let (mean, median, tail) = table1_times(&summaries[1..], "untimed");
    assert!(mean.starts_with("- ("), "{mean}");
    assert_eq!((median.as_str(), tail.as_str()), ("-", "- / -"));
    let b = baseline_of(&summaries[1..], None, None, "test");
    assert_eq!(b.entries.values().next().unwrap().time_median_ms, None);
    let b = baseline_of(&summaries[..1], None, None, "test");
    assert!(b.entries.values().next().unwrap().time_median_ms.unwrap() > 0.0);
}

#[test]
fn run_log_round_trips_and_scores() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, out) = run_ours(tmp.path());
    assert_eq!(out.results.len(), 13);
    let log = RunLog::read(&path).unwrap();
    assert_eq!(log.info.detector, "coppertag");
    assert_eq!(log.images.len(), 13);
    assert_eq!(log.results(), out.results);
    assert!(log.resources.cpu_s > 0.0 && log.resources.peak_rss > 0);
    let ds = Dataset::open(dataset()).unwrap();
    let s = evaluate(&log, &ds, MatchRule::default());
    assert_eq!(
        (
            s.markers,
            s.found,
            s.wrong_ids,
            s.false_positives,
            s.duplicates
        ),
        (13, 13, 0, 0, 0)
    );
    assert!(
        s.corner_error_real.median < 0.5,
        "{:?}",
        s.corner_error_real
    );
    assert_eq!(s.time_ms.n, 13);
}

#[test]
fn run_log_opens_in_python_mcap() {
    let python = repo().join(".venv/bin/python");
    if !python.exists() {
        // `make test` always creates .venv first; plain `cargo test` may not.
        assert!(
            std::env::var_os("COPPERTAG_REQUIRE_VENV").is_none(),
            "no .venv: run `make venv`"
        );
        eprintln!("skipped: {} missing (run `make venv`)", python.display());
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (path, _) = run_ours(tmp.path());
    let script = r#"
import json, sys
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    s = r.get_summary()
    schemas = sorted(sch.name for sch in s.schemas.values())
    topics = sorted(ch.topic for ch in s.channels.values())
    meta = sorted(m.name for m in r.iter_metadata())
    n = 0
    for schema, channel, message in r.iter_messages(topics=["/detections"]):
        d = json.loads(message.data)
        assert "detections" in d and "index" in d
        n += 1
print(json.dumps({"schemas": schemas, "topics": topics, "metadata": meta, "detections": n}))
"#;
    let out = succeed(
        Command::new(&python).arg("-c").arg(script).arg(&path),
        "reading our MCAP with the mcap package",
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        v["schemas"],
        serde_json::json!(["coppertag.Detections", "foxglove.ImageAnnotations"])
    );
    assert_eq!(
        v["topics"],
        serde_json::json!(["/detections", "/detections/annotations"])
    );
    assert_eq!(
        v["metadata"],
        serde_json::json!(["coppertag.resources", "coppertag.run"])
    );
    assert_eq!(v["detections"], 13);
}

#[test]
fn gate_passes_on_baseline_and_fails_on_degraded_run() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, _) = run_ours(tmp.path());
    let ds = Dataset::open(dataset()).unwrap();
    let good = evaluate(&RunLog::read(&path).unwrap(), &ds, MatchRule::default());
    let base = baseline_of(std::slice::from_ref(&good), None, None, "test");
    assert!(check(&base, std::slice::from_ref(&good), Tolerances::default()).is_empty());

    // Degrade: lose the detection in 3 images, push corners 0.4 px off in
    // the others.
    let mut log = RunLog::read(&path).unwrap();
    for (i, m) in log.images.iter_mut().enumerate() {
        if i % 4 == 0 {
            m.result.detections.clear();
        } else {
            for d in &mut m.result.detections {
                for c in &mut d.corners {
                    c[0] += 0.4;
                }
            }
        }
    }
    let bad = evaluate(&log, &ds, MatchRule::default());
    let fails = check(&base, &[bad], Tolerances::default());
    assert!(
        fails.iter().any(|f| f.contains("detection rate fell")),
        "{fails:?}"
    );
    assert!(
        fails.iter().any(|f| f.contains("median corner error grew")),
        "{fails:?}"
    );
}

#[test]
fn bad_run_files_are_named_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let (path, _) = run_ours(tmp.path());
    let bytes = std::fs::read(&path).unwrap();
    let truncated = tmp.path().join("truncated.mcap");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let e = RunLog::read(&truncated).unwrap_err().to_string();
    assert!(
        e.contains("truncated.mcap") && e.contains("truncated"),
        "{e}"
    );
    // A foreign MCAP: the dataset's own file has no run metadata.
    let e = RunLog::read(&dataset().join("dataset.mcap"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not a coppertag run"), "{e}");
    let junk = tmp.path().join("junk.mcap");
    std::fs::write(&junk, b"hello").unwrap();
    assert!(RunLog::read(&junk)
        .unwrap_err()
        .to_string()
        .contains("not an MCAP file"));

    // The CLI: one good run, one truncated, one whose dataset is gone. The
    // good one is still written; exit code 2 names the others.
    let moved = tmp.path().join("moved");
    copy_dir(dataset(), &moved);
    let orphan = tmp.path().join("orphan.mcap");
    let st = coppertag()
        .args(["run", "--quiet", "--detector", "coppertag", "--dataset"])
        .arg(&moved)
        .arg("-o")
        .arg(&orphan)
        .status()
        .unwrap();
    assert!(st.success());
    std::fs::remove_dir_all(&moved).unwrap();
    let results = tmp.path().join("results");
    let out = coppertag()
        .arg("eval")
        .args([&path, &truncated, &orphan])
        .arg("-o")
        .arg(&results)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("truncated.mcap"), "{err}");
    assert!(err.contains("moved"), "{err}");
    assert!(results.join("summary.json").exists());
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let dst = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &dst);
        } else {
            std::fs::copy(e.path(), dst).unwrap();
        }
    }
}

/// A peer that crashes, one that prints garbage, and a missing Python: each
/// a clear error naming the detector, exit 2, no run file.
#[test]
fn broken_peers_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let crash = tmp.path().join("crash.sh");
    std::fs::write(
        &crash,
        "#!/bin/sh\n[ \"$1\" = --version ] && { echo '{\"package\": \"crash\", \"version\": \"1\"}'; exit 0; }\nread line\necho 'boom' >&2\nexit 3\n",
    )
    .unwrap();
    let garbage = tmp.path().join("garbage.sh");
    std::fs::write(
        &garbage,
        "#!/bin/sh\n[ \"$1\" = --version ] && { echo 1.0; exit 0; }\nwhile read line; do echo 'not json'; done\n",
    )
    .unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "--command".into(),
                format!("sh {}", crash.display()),
                "--name".into(),
                "crashy".into(),
            ],
            "crashy",
        ),
        (
            vec![
                "--command".into(),
                format!("sh {}", garbage.display()),
                "--name".into(),
                "noisy".into(),
            ],
            "garbage",
        ),
        (
            vec![
                "--detector".into(),
                "apriltag3".into(),
                "--python".into(),
                "/nonexistent/python".into(),
            ],
            "apriltag3",
        ),
    ];
    for (args, expect) in cases {
        let out_path = tmp.path().join("x.mcap");
        let out = coppertag()
            .args(["run", "--quiet", "--dataset"])
            .arg(dataset())
            .args(&args)
            .arg("-o")
            .arg(&out_path)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!out_path.exists());
    }
}
