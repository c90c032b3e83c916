//! The wild half of the regression gate: CopperTag's row of the wild slice
//! passes against itself, and fails when any gated figure gets worse, both
//! in the library (`check_wild`) and through `coppertag gate` (exit 1);
//! `--update-wild` adds the wild entries and leaves every other byte of
//! the baseline as it was.

use std::path::Path;

use coppertag_eval::gate::{baseline_of, check_wild, dense_key, wild_key, Baseline};
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

/// After a change to the wild specs, every system's per-dataset entries of
/// the wild datasets change with the wild entry, and the sweep check
/// compares them exactly too: `--update-wild` re-makes them from
/// --summary (a first CI run of such a change failed on a peer's
/// `*-wild` entry when only the wild entry was re-made), and keeps every
/// other entry, and a wild dataset's entry the summary lacks, as it was.
#[test]
fn update_wild_re_makes_the_wild_datasets_entries_and_keeps_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fixture = common::repo().join("eval/tests/fixtures/summary-stag-fractal.json");
    let fixture: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture).unwrap()).unwrap();
    let stag = fixture["summaries"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["detector"] == "stag")
        .unwrap()
        .clone();
    // `as_wild(detector, dataset, rate)`: the STag summary renamed.
    let as_wild = |detector: &str, dataset: &str, rate: f64| {
        let mut s = stag.clone();
        s["detector"] = detector.into();
        s["dataset"] = dataset.into();
        s["detection_rate"] = rate.into();
        s
    };
    // The committed baseline: a sweep entry, and entries of two wild
    // datasets made before the wild specs changed.
    let old = serde_json::json!({ "summaries": [
        stag.clone(),
        as_wild("coppertag", "coppertag-wild", 0.95),
        as_wild("apriltag3", "fp-clutter", 1.0),
    ]});
    write_json(&d.join("old.json"), &old);
    let gate = |summary: &str, extra: &[&str]| {
        coppertag()
            .arg("gate")
            .arg("--baseline")
            .arg(d.join("baseline.json"))
            .arg("--summary")
            .arg(d.join(summary))
            .arg("--wild")
            .arg(d.join("wild.json"))
            .args(extra)
            .output()
            .unwrap()
    };
    write_json(&d.join("wild.json"), &summary(1, 1, 0, 2));
    let baseline = || -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("baseline.json")).unwrap()).unwrap()
    };
    assert!(gate("old.json", &["--update"]).status.success());
    let before = baseline();
    // The changed specs' run: the coppertag-wild rate falls to 0.9; no
    // apriltag3 run this time.
    let new = serde_json::json!({ "summaries": [
        stag.clone(),
        as_wild("coppertag", "coppertag-wild", 0.9),
    ]});
    write_json(&d.join("new.json"), &new);
    let out = gate("new.json", &[]);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("coppertag/coppertag-wild"));

    let out = gate("new.json", &["--update-wild"]);
    assert!(out.status.success(), "{out:?}");
    let after = baseline();
    let e = &after["entries"];
    assert_eq!(e["coppertag/coppertag-wild"]["detection_rate"], 0.9);
    assert_eq!(
        e["stag/stag-occlusion"],
        before["entries"]["stag/stag-occlusion"]
    );
    assert_eq!(
        e["apriltag3/fp-clutter"],
        before["entries"]["apriltag3/fp-clutter"]
    );
    assert_eq!(e.as_object().unwrap().len(), 3);
    assert!(after["wild"]["coppertag/wild"].is_object(), "{after}");
    // The gate passes on the run, but for the wild dataset it did not
    // cover, which the gate still asks for.
    let out = gate("new.json", &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert!(!err.contains("coppertag/coppertag-wild"), "{err}");
    assert!(err.contains("apriltag3/fp-clutter"), "{err}");
    let mut all = new.clone();
    all["summaries"]
        .as_array_mut()
        .unwrap()
        .push(as_wild("apriltag3", "fp-clutter", 1.0));
    write_json(&d.join("all.json"), &all);
    assert_eq!(gate("all.json", &[]).status.code(), Some(0));

    // A wild summary without CopperTag's row, or one that is not a wild
    // summary, is refused (exit 2) and the baseline is left as it was.
    let kept = std::fs::read_to_string(d.join("baseline.json")).unwrap();
    write_json(&d.join("wild.json"), &summarise(&slice("stag", 0, 0, 0, 0)));
    let out = gate("all.json", &["--update-wild"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stderr).contains("no gated system"));
    std::fs::write(d.join("wild.json"), "{ \"systems\": 3 ").unwrap();
    assert_eq!(gate("all.json", &["--update-wild"]).status.code(), Some(2));
    assert_eq!(
        std::fs::read_to_string(d.join("baseline.json")).unwrap(),
        kept
    );
}

/// The dense sets (`*-dense`) are summarised apart from the wild set, so
/// their larger markers and 1080p frames move none of the wild set's
/// figures, and gated apart: a rough detection more on the dense frames
/// fails the gate under `coppertag/dense`.
#[test]
fn dense_sets_are_summarised_and_gated_apart() {
    let with_dense = |rough: usize| {
        let mut runs = slice("coppertag", 1, 1, 0, 2);
        let mut dense = slice("coppertag", rough, 3, 0, 0).remove(0);
        dense.dataset = "coppertag-dense".into();
        dense.times_ms = vec![30.0; 10];
        runs.push(dense);
        summarise(&runs)
    };
    let w = with_dense(1);
    let alone = summary(1, 1, 0, 2);
    // The wild set's row is what it is without the dense set.
    let row = |s: &WildSummary| s.systems.iter().find(|r| r.system == "coppertag").cloned();
    assert_eq!(row(&w), row(&alone));
    assert_eq!(w.datasets, ["coppertag-wild", "fp-clutter"]);
    let d = w.dense.as_deref().expect("a dense summary");
    assert_eq!(d.datasets, ["coppertag-dense"]);
    let r = &d.systems[0];
    assert_eq!((r.markers, r.rough, r.tag_free_images), (10, 1, 0));
    assert!((r.detection_rate - 0.7).abs() < 1e-12);
    assert_eq!(r.time_ms.median, 30.0);
    // No tag-free frames: 0 MP, not -0 (the CSV printed "-0.0000").
    assert!(r.tag_free_megapixels.is_sign_positive() && r.tag_free_megapixels == 0.0);
    assert!(!d.systems_csv().contains("-0.0000"), "{}", d.systems_csv());
    assert_eq!(
        w.all_datasets().collect::<Vec<_>>(),
        ["coppertag-wild", "fp-clutter", "coppertag-dense"]
    );

    let b = baseline_of(&[], None, Some(&w), "test");
    assert_eq!(
        b.wild.keys().collect::<Vec<_>>(),
        [&dense_key("coppertag"), &wild_key("coppertag")]
    );
    assert!(check_wild(&b, &w).is_empty());
    let fails = check_wild(&b, &with_dense(2));
    assert_eq!(fails.len(), 1, "{fails:?}");
    assert!(
        fails[0].starts_with("coppertag/dense: rough detections grew"),
        "{fails:?}"
    );
    // Without the dense set in the run, its entry is missing.
    let fails = check_wild(&b, &alone);
    assert!(fails[0].contains("coppertag/dense: missing"), "{fails:?}");
}
