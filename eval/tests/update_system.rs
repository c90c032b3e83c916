//! `coppertag gate --update-system NAME` adds one system's entries (and,
//! with --speed, its speed ratio) to a baseline and leaves every other
//! entry as it was: how a newly added peer (the fractal markers) joins the
//! gate without re-measuring the others.

use std::path::Path;

use crate::common;
use common::{coppertag, repo};

fn fixture(name: &str) -> std::path::PathBuf {
    repo().join("eval/tests/fixtures").join(name)
}

fn gate(d: &Path, summary: &Path, extra: &[&str]) -> std::process::Output {
    coppertag()
        .arg("gate")
        .arg("--baseline")
        .arg(d.join("baseline.json"))
        .arg("--summary")
        .arg(summary)
        .args(extra)
        .output()
        .unwrap()
}

fn baseline(d: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(d.join("baseline.json")).unwrap()).unwrap()
}

#[test]
fn update_system_adds_one_system_and_keeps_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A STag-only baseline, as before the fractal markers were added.
    let both: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fixture("summary-stag-fractal.json")).unwrap(),
    )
    .unwrap();
    let stag_only = serde_json::json!({
        "summaries": both["summaries"].as_array().unwrap().iter()
            .filter(|s| s["detector"] == "stag").cloned().collect::<Vec<_>>()
    });
    let stag_path = d.join("stag.json");
    std::fs::write(&stag_path, stag_only.to_string()).unwrap();
    assert!(gate(d, &stag_path, &["--update"]).status.success());
    let before = baseline(d);
    assert_eq!(before["entries"].as_object().unwrap().len(), 1);

    let summary = fixture("summary-stag-fractal.json");
    // The old baseline does not know fractal, so it gates only STag.
    assert_eq!(gate(d, &summary, &[]).status.code(), Some(0));
    let out = gate(d, &summary, &["--update-system", "fractal"]);
    assert!(out.status.success(), "{out:?}");
    let after = baseline(d);
    let entries = after["entries"].as_object().unwrap();
    assert_eq!(entries.len(), 2);
    assert_eq!(
        entries["stag/stag-occlusion"],
        before["entries"]["stag/stag-occlusion"]
    );
    assert_eq!(entries["fractal/fractal-occlusion"]["detection_rate"], 0.75);
    assert_eq!(after["speed_ratio_vs"], before["speed_ratio_vs"]);
    // Now the fractal entry is gated: the summary passes against it.
    assert_eq!(gate(d, &summary, &[]).status.code(), Some(0));

    // With --speed, the system's ratio is taken too (the saved run has
    // apriltag3, aruco3 and stag), and only that one.
    let speed = fixture("speed-run.json");
    let speed = speed.to_str().unwrap();
    let out = gate(d, &summary, &["--update-system", "stag", "--speed", speed]);
    assert!(out.status.success(), "{out:?}");
    let ratios = baseline(d)["speed_ratio_vs"].as_object().unwrap().clone();
    assert_eq!(ratios.keys().collect::<Vec<_>>(), ["stag"]);
    assert_eq!(baseline(d)["entries"], after["entries"]);

    // A system with no entries, or no ratio in the speed file, is refused
    // (exit 2) and the baseline is left alone.
    let kept = std::fs::read_to_string(d.join("baseline.json")).unwrap();
    assert_eq!(
        gate(d, &summary, &["--update-system", "apriltag3"])
            .status
            .code(),
        Some(2)
    );
    assert_eq!(
        gate(
            d,
            &summary,
            &["--update-system", "fractal", "--speed", speed]
        )
        .status
        .code(),
        Some(2)
    );
    assert_eq!(
        std::fs::read_to_string(d.join("baseline.json")).unwrap(),
        kept
    );
}
