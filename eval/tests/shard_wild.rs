//! Sharded runs evaluate to exactly the unsharded result, and the wild
//! evaluation and report work end to end on a small sampled-style dataset
//! (a rendered set plus a hand-written draws.csv).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use coppertag_eval::runlog::{self, RunLog};
use coppertag_eval::runner::{RunOutput, RunResources};

use crate::common;
use common::{coppertag, render_rotated_z};

/// A 13-image rotated-z CopperTag dataset (indices 0, 30, ..., 360) with a
/// draws.csv: image-level defocus and occluder kind, a per-marker roll and
/// jitter groups of three images.
fn dataset() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let out = render_rotated_z(dir.path());
        let mut draws = String::from("index,marker_index,factor,value\n");
        for k in 0..13 {
            let i = 30 * k;
            draws.push_str(&format!("{i},,defocus_px,{}\n", 0.25 * k as f64));
            draws.push_str(&format!("{i},,jitter_group,{}\n", k / 3));
            let kind = if k % 2 == 0 { "stick" } else { "tape" };
            draws.push_str(&format!("{i},,occluder_kind,{kind}\n"));
            draws.push_str(&format!("{i},0,roll_deg,{}\n", 3 * i));
        }
        std::fs::write(out.join("draws.csv"), draws).unwrap();
        dir
    })
    .path()
    .join("ds")
    .leak()
}

fn run_cli(args: &[&str], out: &Path) {
    let o = coppertag()
        .args(["run", "--quiet", "--detector", "coppertag", "--dataset"])
        .arg(dataset())
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Rewrites a run log with deterministic measurements: image `i` took
/// `1 + i / 8` ms; each image is worth 1 s of wall time and 0.5 s of CPU.
/// Detection times are the one thing two runs never share, so this is what
/// makes byte equality testable; everything else is as the detector said.
fn with_fixed_measurements(path: &Path) {
    let log = RunLog::read(path).unwrap();
    let mut results = log.results();
    for r in &mut results {
        r.result.ms = Some(1.0 + r.index as f64 / 8.0);
    }
    let n = results.len();
    let out = RunOutput {
        info: log.info.clone(),
        results,
        resources: RunResources {
            images: n,
            errors: 0,
            wall_s: n as f64,
            cpu_s: 0.5 * n as f64,
            peak_rss: 64 << 20,
        },
    };
    runlog::save(path, &out).unwrap();
}

fn eval(runs: &[&Path], out: &Path) -> std::process::Output {
    coppertag()
        .args(["eval", "--wild", "-o"])
        .arg(out)
        .args(runs)
        .output()
        .unwrap()
}

const OUTPUTS: [&str; 5] = [
    "summary.json",
    "summary.csv",
    "wild.json",
    "wild-systems.csv",
    "wild-factors.csv",
];

#[test]
fn sharded_runs_evaluate_exactly_as_the_unsharded_run() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let whole = t.join("whole.mcap");
    run_cli(&[], &whole);
    let shards: Vec<PathBuf> = (0..3).map(|k| t.join(format!("shard-{k}.mcap"))).collect();
    for (k, p) in shards.iter().enumerate() {
        run_cli(&["--shard", &format!("{k}/3")], p);
    }
    // Each shard ran exactly its slice, with the unsharded detections.
    let all = RunLog::read(&whole).unwrap();
    assert_eq!(all.images.len(), 13);
    let mut seen = 0;
    for (k, p) in shards.iter().enumerate() {
        let log = RunLog::read(p).unwrap();
        assert_eq!(log.info.shard, format!("{k}/3"));
        for m in &log.images {
            assert_eq!(m.index % 3, k);
            let same = all.images.iter().find(|a| a.index == m.index).unwrap();
            assert_eq!(same.result.detections, m.result.detections);
        }
        seen += log.images.len();
    }
    assert_eq!(seen, 13);

    for p in std::iter::once(&whole).chain(&shards) {
        with_fixed_measurements(p);
    }
    let (a, b) = (t.join("a"), t.join("b"));
    let o = eval(&[&whole], &a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Shards in any order.
    let o = eval(&[&shards[2], &shards[0], &shards[1]], &b);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in OUTPUTS {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(
            x == y,
            "{f} differs between sharded and unsharded evaluation"
        );
    }
    let summary = std::fs::read_to_string(a.join("summary.json")).unwrap();
    assert!(summary.contains("\"found\": 13"), "{summary:.400}");

    // A missing shard is an error naming it, exit 2.
    let o = eval(&[&shards[0], &shards[2]], &t.join("c"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("missing shard(s) 1/3"), "{err}");
    // The same shard twice, too.
    let o = eval(&[&shards[0], &shards[1], &shards[1]], &t.join("d"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("shard 1/3 given twice"), "{err}");
}

#[test]
fn bad_shard_values_are_rejected() {
    let tmp = tempfile::tempdir().unwrap();
    for bad in ["3/3", "1/0", "a/2", "2"] {
        let out = tmp.path().join("x.mcap");
        let o = coppertag()
            .args([
                "run",
                "--quiet",
                "--detector",
                "coppertag",
                "--shard",
                bad,
                "--dataset",
            ])
            .arg(dataset())
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("shard"), "{bad}: {err}");
        assert!(!out.exists());
    }
}

#[test]
fn wild_evaluation_and_report_section() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let run = t.join("run.mcap");
    run_cli(&[], &run);
    let results = t.join("results");
    let o = eval(&[&run], &results);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let w: serde_json::Value =
        serde_json::from_slice(&std::fs::read(results.join("wild.json")).unwrap()).unwrap();
    let row = &w["systems"][0];
    assert_eq!(row["system"], "coppertag");
    // Our detector reports corner sigmas, carried through the run log: the
    // five counted markers are fitted, sharp and unoccluded, so every
    // corner is observed and within 2 sigma; the share is printed.
    let sigma = &row["corner_sigma"];
    assert_eq!(sigma["detections"], 5, "{sigma}");
    assert_eq!(sigma["all"]["corners"], 20, "{sigma}");
    assert_eq!(sigma["all"]["within"], 20, "{sigma}");
    assert_eq!(sigma["estimated"]["corners"], 0, "{sigma}");
    assert!(
        err.contains("coppertag wild corners within 2 sigma: 100.0% of 20"),
        "{err}"
    );
    // Jitter groups of three images: 13 images -> 5 groups, 5 markers
    // counted (the first render of each).
    assert_eq!(row["markers"], 5);
    assert_eq!(row["correct"], 5);
    // Groups 0..3 have three renders, group 4 one: four groups measured.
    assert_eq!(row["jitter_groups"], 4);
    // Exact renders, clean corners: the pose is good to millimetres.
    let t_med = row["translation_mm"]["median"].as_f64().unwrap();
    assert!(t_med > 0.0 && t_med < 5.0, "{t_med}");
    assert!(row["rotation_deg"]["median"].as_f64().unwrap() < 1.0);
    assert_eq!(row["flipped_rate"], 0.0);
    let factors: Vec<&str> = w["factors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["factor"].as_str().unwrap())
        .collect();
    // The drawn factors (side_px, measured, joins them when it varies);
    // the jitter group names scenes and is no factor.
    for f in ["defocus_px", "occluder_kind", "roll_deg"] {
        assert!(factors.contains(&f), "{factors:?}");
    }
    assert!(!factors.contains(&"jitter_group"));
    let csv = std::fs::read_to_string(results.join("wild-systems.csv")).unwrap();
    assert!(csv.starts_with("system,images,markers,correct,rough,missed,"));
    assert!(csv
        .lines()
        .nth(1)
        .unwrap()
        .starts_with("coppertag,5,5,5,0,0,"));

    let reports = t.join("reports");
    let o = coppertag()
        .args(["report", "--summary"])
        .arg(results.join("summary.json"))
        .arg("-o")
        .arg(&reports)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(reports.join("README.md")).unwrap();
    assert!(md.contains("## In the wild: sampled scenes"), "{md}");
    assert!(md.contains("| CopperTag | 5 | 100.0% | 0.0% | 0 |"), "{md}");
    assert!(
        md.contains("| min. size (px) | corners within 2 sigma (observed / estimated) |"),
        "{md}"
    );
    assert!(
        md.contains("| 100.0% (100.0% / -) |")
            && md.contains("Corners within 2 sigma: of the corners"),
        "{md}"
    );
    for f in [
        "wild-defocus_px.png",
        "wild-defocus_px.svg",
        "wild-roll_deg.svg",
        "wild-systems.csv",
        "wild-factors.csv",
    ] {
        assert!(reports.join(f).exists(), "{f}");
    }
    // Categories are a table, not a curve.
    assert!(md.contains("| occluder_kind | CopperTag |"), "{md}");
    assert!(!reports.join("wild-occluder_kind.png").exists());
}
