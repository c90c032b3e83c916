//! The wild half of the regression gate: CopperTag's row of the wild slice
//! passes against itself, and fails when any gated figure gets worse, both
//! in the library (`check_wild`) and through `coppertag gate` (exit 1);
//! `--update-wild` adds the wild entries and leaves every other byte of
//! the baseline as it was.

use std::path::Path;

use coppertag_eval::gate::{baseline_of, check_wild, wild_key, Baseline};
use coppertag_eval::wild::{MarkerOutcome, Status, WildRun};
use coppertag_eval::wild_summary::{summarise, WildSummary};

use crate::common;
use common::coppertag;

fn outcome(index: usize, status: Status) -> MarkerOutcome {
    MarkerOutcome {
        index,
        marker_index: 0,
        status,
        corner_error_max_px: None,
        corners: None,
        corner_errors_px: None,
        corner_sigma: None,
        estimated: [false; 4],
        likelihood: false,
        pose: None,
        read_at_truth: None,
        factors: Default::default(),
    }
}

/// A wild slice of `system`: 10 markers of which `rough` are rough and
/// `missed` missed, `wrong` wrong ids, and `fp` false positives on a
/// tag-free set of 2 MP.
fn slice(system: &str, rough: usize, missed: usize, wrong: usize, fp: usize) -> Vec<WildRun> {
    let outcomes = (0..10)
        .map(|i| {
            let status = if i < missed {
                Status::Missed
            } else if i < missed + rough {
                Status::Rough
            } else {
                Status::Correct
            };
            outcome(i, status)
        })
        .collect();
    let tagged = WildRun {
        detector: system.into(),
        dataset: format!("{system}-wild"),
        images: 10,
        image_errors: 0,
        megapixels: 3.072,
        tag_free: false,
        false_positives: 0,
        wrong_ids: wrong,
        duplicates: 0,
        times_ms: vec![1.0; 10],
        outcomes,
    };
    let free = WildRun {
        detector: system.into(),
        dataset: "fp-clutter".into(),
        images: 4,
        image_errors: 0,
        megapixels: 2.0,
        tag_free: true,
        false_positives: fp,
        wrong_ids: 0,
        duplicates: 0,
        times_ms: vec![1.0; 4],
        outcomes: Vec::new(),
    };
    vec![tagged, free]
}

fn summary(rough: usize, missed: usize, wrong: usize, fp: usize) -> WildSummary {
    let mut runs = slice("coppertag", rough, missed, wrong, fp);
    // A peer doing badly is reported, never gated.
    runs.extend(slice("apriltag3", 0, 9, 3, 50));
    summarise(&runs)
}

fn baseline() -> Baseline {
    baseline_of(&[], None, Some(&summary(1, 1, 0, 2)), "test")
}

#[test]
fn only_coppertag_is_gated_and_it_passes_against_itself() {
    let b = baseline();
    assert_eq!(b.wild.keys().collect::<Vec<_>>(), [&wild_key("coppertag")]);
    let e = &b.wild[&wild_key("coppertag")];
    assert_eq!((e.markers, e.rough, e.tag_free_images), (10, 1, 4));
    assert!((e.detection_rate - 0.9).abs() < 1e-12);
    assert_eq!(e.false_positives_per_mp, Some(1.0));
    assert!(check_wild(&b, &summary(1, 1, 0, 2)).is_empty());
    // Better is fine.
    assert!(check_wild(&b, &summary(0, 0, 0, 0)).is_empty());
}

#[test]
fn every_gated_figure_getting_worse_fails() {
    let b = baseline();
    for (worse, what) in [
        (summary(1, 2, 0, 2), "detection rate fell"),
        (summary(2, 1, 0, 2), "rough detections grew"),
        (summary(1, 1, 1, 2), "wrong ids grew"),
        (summary(1, 1, 0, 3), "false positives per megapixel grew"),
    ] {
        let fails = check_wild(&b, &worse);
        assert_eq!(fails.len(), 1, "{what}: {fails:?}");
        assert!(fails[0].contains(what), "{what}: {fails:?}");
    }
    // Another slice (a changed spec) is not compared figure by figure.
    let mut runs = slice("coppertag", 1, 1, 0, 2);
    runs[0].outcomes.pop();
    let fails = check_wild(&b, &summarise(&runs));
    assert!(fails[0].contains("not the same slice"), "{fails:?}");
    // CopperTag missing from the run fails.
    let fails = check_wild(&b, &summarise(&slice("stag", 0, 0, 0, 0)));
    assert!(fails[0].contains("missing"), "{fails:?}");
}

fn write_json(path: &Path, v: &impl serde::Serialize) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

#[test]
fn the_gate_command_fails_on_a_worse_wild_slice_and_update_wild_only_adds() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A baseline without wild entries, as committed before them.
    let old = baseline_of(&[], None, None, "before");
    write_json(&d.join("baseline.json"), &old);
    let before = std::fs::read_to_string(d.join("baseline.json")).unwrap();
    write_json(
        &d.join("summary.json"),
        &serde_json::json!({ "summaries": [] }),
    );
    write_json(&d.join("wild.json"), &summary(1, 1, 0, 2));
    write_json(&d.join("worse.json"), &summary(1, 1, 0, 3));
    let gate = |wild: &str, extra: &[&str]| {
        coppertag()
            .arg("gate")
            .arg("--baseline")
            .arg(d.join("baseline.json"))
            .arg("--summary")
            .arg(d.join("summary.json"))
            .arg("--wild")
            .arg(d.join(wild))
            .args(extra)
            .output()
            .unwrap()
    };
    let add = gate("wild.json", &["--update-wild"]);
    assert!(add.status.success(), "{add:?}");
    let after = std::fs::read_to_string(d.join("baseline.json")).unwrap();
    // Only lines added: the old file's lines are all still there, in order.
    let mut rest = after.lines();
    for line in before.lines() {
        assert!(rest.any(|l| l == line), "lost line {line:?}:\n{after}");
    }
    assert!(after.contains("\"coppertag/wild\""), "{after}");
    assert_eq!(gate("wild.json", &[]).status.code(), Some(0));
    let out = gate("worse.json", &[]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("false positives per megapixel grew"));
    // Without --wild, a baseline with wild entries is refused (exit 2).
    let st = coppertag()
        .arg("gate")
        .arg("--baseline")
        .arg(d.join("baseline.json"))
        .arg("--summary")
        .arg(d.join("summary.json"))
        .status()
        .unwrap();
    assert_eq!(st.code(), Some(2));
}
